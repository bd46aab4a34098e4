#pragma once
// The scene file itself (YAML, read by PETSc as options): checked with yaml-cpp before PETSc sees it, so that
// a malformed file gets one message naming the file and the line instead of PETSc's traceback, and the
// mistakes PETSc accepts silently (a duplicate key, an empty file) are refused.
#include <string>

namespace cellfsi::app {

/// Throws std::invalid_argument naming `path` (and the line, 1-based) when the file cannot be read or parsed,
/// is empty, is not a map of options at its top level, or repeats a key in any map.
void check_scene_file(const std::string& path);

}  // namespace cellfsi::app
