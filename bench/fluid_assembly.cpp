// Fluid assembly cost per element: residual and Jacobian for p = 2, 3 in 2D (and 3D), on however many ranks it is
// launched with. Prints one table row per case; bench/run_fluid_bench.sh runs it on 1 and 2 ranks and writes the
// table of docs/performance.md.
//
//   bench/fluid_assembly [-n2d 128] [-n3d 16] [-repeat 5] [-three_d true]
#include <petscsys.h>

#include <algorithm>
#include <cstdio>
#include <vector>

#include "fluid/fluid_solver.hpp"
#include "common/petsc_error.hpp"
#include "geometry/builders.hpp"

using namespace cellfsi;
using geometry::Vec3;

namespace {

struct Timing {
  double residual_us = 0, jacobian_us = 0;
};

/// Best-of-`repeat` time per element of one residual and one Jacobian assembly (us), on a perturbed shear flow.
Timing time_assembly(const geometry::Patch& patch, int repeat) {
  fluid::FluidOptions opt;
  const int D = patch.param_dim();
  opt.wall_velocity[D - 1][0] = Vec3(-0.042, 0, 0);
  opt.wall_velocity[D - 1][1] = Vec3(0.042, 0, 0);
  fluid::FluidSolver fs(PETSC_COMM_WORLD, patch, opt);
  fs.set_initial_velocity([](const Vec3& x) { return Vec3(70 * x[1] + 1e-3 * std::sin(3e3 * x[0]), 1e-3, 0); });
  Vec F;
  Mat J;
  CELLFSI_PETSC(VecDuplicate(fs.solution(), &F));
  CELLFSI_PETSC(DMCreateMatrix(fs.dm(), &J));  // the solver's matrix type (DMSetMatType in FluidSolver)
  fs.evaluate_residual(fs.solution(), F);  // warm-up
  Timing t{1e300, 1e300};
  for (int r = 0; r < repeat; ++r) {
    CELLFSI_PETSC(MPI_Barrier(PETSC_COMM_WORLD));
    double t0 = MPI_Wtime();
    fs.evaluate_residual(fs.solution(), F);
    CELLFSI_PETSC(MPI_Barrier(PETSC_COMM_WORLD));
    double t1 = MPI_Wtime();
    fs.evaluate_jacobian(fs.solution(), J);
    CELLFSI_PETSC(MPI_Barrier(PETSC_COMM_WORLD));
    double t2 = MPI_Wtime();
    t.residual_us = std::min(t.residual_us, (t1 - t0) * 1e6 / patch.n_elements());
    t.jacobian_us = std::min(t.jacobian_us, (t2 - t1) * 1e6 / patch.n_elements());
  }
  CELLFSI_PETSC(VecDestroy(&F));
  CELLFSI_PETSC(MatDestroy(&J));
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, nullptr));
  PetscInt n2 = 128, n3 = 16, repeat = 5;
  PetscBool three_d = PETSC_TRUE;
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-n2d", &n2, nullptr));
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-n3d", &n3, nullptr));
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-repeat", &repeat, nullptr));
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-three_d", &three_d, nullptr));
  int size = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "| dim | p | elements | ranks | residual us/el | Jacobian us/el |\n"));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "|---|---|---|---|---|---|\n"));
  try {
    for (int p : {2, 3}) {
      const auto box = geometry::rectangle(0.0024, 0.0012, n2, n2 / 2, p, {true, false});
      const Timing t = time_assembly(box, static_cast<int>(repeat));
      PetscCall(PetscPrintf(PETSC_COMM_WORLD, "| 2 | %d | %dx%d | %d | %.2f | %.2f |\n", p, (int)n2, (int)n2 / 2, size,
                            t.residual_us, t.jacobian_us));
    }
    if (three_d)
      for (int p : {2, 3}) {
        const auto box = geometry::box(0.0012, 0.0012, 0.0012, n3, n3, n3, p, {true, true, false});
        const Timing t = time_assembly(box, static_cast<int>(repeat));
        PetscCall(PetscPrintf(PETSC_COMM_WORLD, "| 3 | %d | %d^3 | %d | %.2f | %.2f |\n", p, (int)n3, size,
                              t.residual_us, t.jacobian_us));
      }
  } catch (const std::exception& e) {
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "fluid_assembly: error: %s\n", e.what()));
    PetscCall(PetscFinalize());
    return 1;
  }
  PetscCall(PetscFinalize());
  return 0;
}
