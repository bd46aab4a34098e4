#pragma once
// The three ways to run a scene, one code path (docs/design.md §2, run contract §4):
//   cellfsi SCENE.yaml                     fluid and bodies in every process (the bodies are cheap)
//   mpirun -np A+B cellfsi SCENE.yaml -solid_ranks B
//                                          one job, the last B ranks the solid side (communicators)
//   mpirun -np A cellfsi-fluid SCENE.yaml : -np B cellfsi-solid SCENE.yaml
//                                          MPMD: two executables, one job
// In the last two the ranks are split into a fluid group and a solid group joined by an intercommunicator;
// both groups read the same scene, the solid group builds and owns the bodies (body i on solid rank i mod B)
// and serves the fluid group's requests (coupling/remote_solid.hpp). The numbers are the same in all modes.
namespace cellfsi::app {

enum class Role {
  combined,  // cellfsi: fluid only, or split by -solid_ranks
  fluid,     // cellfsi-fluid
  solid      // cellfsi-solid
};

/// main() of the three executables: MPI and PETSc start-up, the split, the run, exit codes (0 done, 1 bad
/// input, 2 failed mid-way, 128 + S stopped by signal S: apps/interrupt.hpp). A job must be made of cellfsi
/// alone or of cellfsi-fluid with cellfsi-solid; any other mix is refused at start-up.
int launch(int argc, char** argv, Role role);

}  // namespace cellfsi::app
