#pragma once
// A session directory of its own for each MPI singleton the tests start. The test environment isolates
// singletons (OMPI_MCA_ess_singleton_isolated=1, tests/CMakeLists.txt: no daemon per process), and Open MPI then
// gives every isolated singleton the same session directory, <tmpdir>/ompi.<host>.<uid>/jf.0/1: concurrent
// tests created and removed it under each other (seen in a fresh-clone CI run: "A call to mkdir was unable to
// create the desired directory: /tmp/ompi.vm.0/jf.0/1", orte_init failed, and a run that should have failed
// with its own message failed with that one). A private OMPI_MCA_orte_tmpdir_base per process removes the
// sharing. Only for a process that mpiexec did not start: its ranks must keep the launcher's directory.
#include <stdlib.h>

#include <filesystem>
#include <string>

namespace cellfsi_test {

/// Whether mpiexec started this process (Open MPI's launcher sets these).
inline bool started_by_mpiexec() { return getenv("OMPI_COMM_WORLD_SIZE") || getenv("PMIX_RANK"); }

/// Makes a private temporary directory the base of Open MPI's session directory for this process and the
/// processes it starts (unless mpiexec started it, or one is set already); returns it ("" if none was made).
inline std::string private_ompi_session_base() {
  if (started_by_mpiexec() || getenv("OMPI_MCA_orte_tmpdir_base")) return "";
  char tmpl[] = "/tmp/cellfsi-ompi-XXXXXX";
  if (!mkdtemp(tmpl)) return "";
  setenv("OMPI_MCA_orte_tmpdir_base", tmpl, 1);
  return tmpl;
}

/// Removes what private_ompi_session_base made (errors ignored: a leftover temporary directory is harmless).
inline void remove_ompi_session_base(const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}

}  // namespace cellfsi_test
