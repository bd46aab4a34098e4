// cellfsi: runs a scene (apps/launch.hpp has the launch modes).
//
//   cellfsi                                   # the default scene: a capsule in shear, a few minutes
//   cellfsi scenes/capsule_shear.yaml         # a scene file: YAML read as PETSc options
//   cellfsi scenes/shear.yaml -fluid_elements 128,64 -final_time 0.1 -output_every 10
//   mpirun -np 2 cellfsi scenes/poiseuille.yaml
//   mpirun -np 3 cellfsi scenes/capsule_shear.yaml -solid_ranks 1      # 2 fluid ranks, 1 solid rank
//   cellfsi scenes/capsule_shear.yaml -help   # every option with its default
//
// Writes the run contract of docs/design.md §4 to -output_dir (default out/<scene>): summary.json,
// metrics.csv, options.yaml, fluid.pvd, solid.pvd. Bad input stops the run before any work with one message
// and exit code 1; a run that fails mid-way (diverged iteration, a body leaving the domain) says why, exits
// with code 2 and leaves its output intact.
#include "apps/launch.hpp"

int main(int argc, char** argv) { return cellfsi::app::launch(argc, argv, cellfsi::app::Role::combined); }
