#pragma once
// What was built: the source revision (git describe --dirty, taken at build time by cmake/build_info.cmake).

namespace cellfsi::app {

/// e.g. "c985716a1b2c" or "c985716a1b2c-dirty" (uncommitted changes), or "unknown (...)" outside git.
const char* build_commit();

}  // namespace cellfsi::app
