// cellfsi-solid: the solid side of an MPMD run (apps/launch.hpp); owns the scene's bodies (body i on solid
// rank i mod B) and serves the fluid side:
//   mpirun -np 2 cellfsi-fluid scenes/capsule_shear.yaml : -np 1 cellfsi-solid scenes/capsule_shear.yaml
#include "apps/launch.hpp"

int main(int argc, char** argv) { return cellfsi::app::launch(argc, argv, cellfsi::app::Role::solid); }
