// Fluid assembly cost per element: residual and Jacobian for p = 2, 3 in 2D (and 3D), on however many ranks it is
// launched with. Prints one table row per case; bench/run_fluid_bench.sh runs it on 1 and 2 ranks and writes the
// table of docs/performance.md. Then the immersed tangent per solid point, with the solids' isotropic and
// consistent stiffness (-coupling_solid_tangent), p = 2 (each rank alone; -immersed false leaves it out).
//
//   bench/fluid_assembly [-n2d 128] [-n3d 16] [-repeat 5] [-three_d true] [-immersed true] [-points 20000]
#include <petscsys.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <vector>

#include "fluid/fluid_solver.hpp"
#include "fluid/vms_kernel.hpp"
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

/// Best-of-`repeat` time of immersed_tangent per point (us): `points` calls on one point of random data (n =
/// 3^dim functions, p = 2), into one element matrix.
double time_immersed_tangent(int dim, bool consistent, int points, int repeat) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(-1, 1);
  const int n = dim == 2 ? 9 : 27, nd = dim + 1;
  std::vector<double> N(n), dN(3 * n), lapN(3 * n, 0.0), K(static_cast<size_t>(n * nd) * n * nd, 0.0);
  for (int A = 0; A < n; ++A) {
    N[A] = 0.5 + 0.5 * U(rng);
    for (int j = 0; j < 3; ++j) dN[3 * A + j] = (j < dim ? 1e4 : 0.0) * U(rng);
  }
  fluid::VmsParameters prm;
  prm.dim = dim;
  prm.nu = 0.012 / 1.025;
  prm.dt = 5e-4;
  fluid::PointFields f{};
  for (int i = 0; i < dim; ++i) {
    f.v[i] = 0.01 * U(rng);
    for (int j = 0; j < dim; ++j) f.dv[i][j] = 70 * U(rng);
  }
  const fluid::TangentScales ts{0.6, 3000, 1};
  fluid::ImmersedPoint ip;
  ip.weight = 1e-15;
  ip.beta = -0.07;
  ip.stiffness_viscosity = 1.0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j <= i; ++j) ip.stress[i][j] = ip.stress[j][i] = 100 * U(rng);
  if (consistent) {
    ip.stiffness_time = 3e-4;
    for (double& c : ip.stiffness) c = 1e4 * U(rng);
  }
  const fluid::PointBasis basis{n, N.data(), dN.data(), lapN.data()};
  double best = 1e300;
  for (int r = 0; r < repeat; ++r) {
    const double t0 = MPI_Wtime();
    for (int q = 0; q < points; ++q) fluid::immersed_tangent(prm, basis, f, ts, ip, K.data());
    best = std::min(best, (MPI_Wtime() - t0) * 1e6 / points);
  }
  if (!(K[0] == K[0])) std::printf("(nan)\n");  // keeps K alive
  return best;
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
  PetscInt points = 20000;
  PetscBool immersed = PETSC_TRUE;
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-points", &points, nullptr));
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-immersed", &immersed, nullptr));
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
    if (immersed) PetscCall(PetscPrintf(PETSC_COMM_WORLD,
                          "\n| dim | immersed tangent us/point, isotropic | consistent | ratio |\n"
                          "|---|---|---|---|\n"));
    for (int dim : {2, 3}) {
      if (!immersed || (dim == 3 && !three_d)) continue;
      const int np = static_cast<int>(points), nr = static_cast<int>(repeat);
      const double iso = time_immersed_tangent(dim, false, np, nr);
      const double con = time_immersed_tangent(dim, true, np, nr);
      PetscCall(PetscPrintf(PETSC_COMM_WORLD, "| %d | %.3f | %.3f | %.2f |\n", dim, iso, con, con / iso));
    }
  } catch (const std::exception& e) {
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "fluid_assembly: error: %s\n", e.what()));
    PetscCall(PetscFinalize());
    return 1;
  }
  PetscCall(PetscFinalize());
  return 0;
}
