#pragma once
// The scene file itself (YAML, read by PETSc as options): checked with yaml-cpp before PETSc sees it, so that
// a malformed file gets one message naming the file and the line instead of PETSc's traceback, and the
// mistakes PETSc accepts silently (a duplicate key, an empty file) are refused.
#include <string>
#include <vector>

namespace cellfsi::app {

/// Throws std::invalid_argument naming `path` (and the line, 1-based) when the file cannot be read or parsed,
/// is empty, is not a map of options at its top level, or repeats a key in any map.
void check_scene_file(const std::string& path);

/// Where a bad value came from: for a message about option -NAME ("option -NAME = ... is invalid ...", as
/// OptionTable writes them) whose value the scene file set and the command line did not, the message with
/// "(scene file 'PATH', line L)" appended; otherwise the message unchanged. Nested keys name options joined
/// by '_' (fluid: density: -> -fluid_density), as PETSc reads the file.
std::string with_scene_file_line(const std::string& message, const std::string& path,
                                 const std::vector<std::string>& command_line);

/// options.yaml: the options a run was given, re-runnable as `cellfsi DIR/options.yaml`. The scene file's
/// options (`path`; nested keys joined by '_', as PETSc reads them) overridden by the command line's
/// (`command_line`: the arguments as given, argv[0] first, the scene file maybe second), in that order;
/// without the defaults the program sets itself, -restart, -help and the launch option -solid_ranks; with
/// `scene: NAME` when neither gave it, so a re-run keeps the scene's name. Written by yaml-cpp's emitter:
/// values with spaces, newlines or control characters are quoted and come back as they were.
std::string given_options_yaml(const std::string& path, const std::vector<std::string>& command_line,
                               const std::string& scene_name);

}  // namespace cellfsi::app
