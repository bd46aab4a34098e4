// cellfsi-fluid: the fluid side of an MPMD run (apps/launch.hpp):
//   mpirun -np 2 cellfsi-fluid scenes/capsule_shear.yaml : -np 1 cellfsi-solid scenes/capsule_shear.yaml
// Options go to both executables alike (both read the scene); the fluid side writes the output.
#include "apps/launch.hpp"

int main(int argc, char** argv) { return cellfsi::app::launch(argc, argv, cellfsi::app::Role::fluid); }
