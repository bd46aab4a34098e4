// Cost of the divergence-conforming Fourier solver (fluid/div_conforming/dc_fourier.hpp): build (stencil,
// deviation, factorisations) and one solve, on the Navier-Stokes time-step tangent of DivConformingFluid at a
// Couette state in a channel periodic in x (the operator of the test DcFourierSolver.EqualsTheDirectSolve),
// and its agreement with the fluid's own linear solver (MUMPS LU, the same operator with its pressure pin)
// for a consistent random right-hand side. Prints one markdown table row; measures, asserts nothing. Columns:
// mesh, k, unknowns, ranks, build [s] (the operator assembled before), solve [ms] best and mean of -repeat,
// MUMPS's factorisation and solve [ms], deviation(), max|x_Fourier - x_MUMPS| / max|x_MUMPS| (zero-mean
// pressures), then the product y = A x [ms], best of -repeat, by the stencil (DcFourierSolver::multiply, with
// the moves between the natural and the PETSc numbering) and by MatMult of the assembled matrix, and
// max|y_stencil - y_MatMult| / max|y|.
//   OPENBLAS_NUM_THREADS=1 bench/dc_fourier_solve -nx 256 -ny 128 -k 2 -repeat 20
// Any number of ranks (the wave numbers are dealt out; MUMPS runs on all of them).
#include <petscksp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "common/petsc_error.hpp"
#include "fluid/div_conforming/dc_fluid.hpp"
#include "fluid/div_conforming/dc_fourier.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using cellfsi::fluid::dc::DcFluidOptions;
using cellfsi::fluid::dc::DcFourierSolver;
using cellfsi::fluid::dc::DivConformingFluid;
using cellfsi::fluid::dc::DivConformingSpace;
using cellfsi::fluid::dc::Vec3;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// The slowest rank's time (the solver is collective).
double max_over_ranks(double t, MPI_Comm comm) {
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &t, 1, MPI_DOUBLE, MPI_MAX, comm));
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  CELLFSI_PETSC(PetscInitialize(&argc, &argv, nullptr, nullptr));
  {
    PetscInt nx = 256, ny = 128, k = 2, repeat = 20;
    CELLFSI_PETSC(PetscOptionsGetInt(nullptr, nullptr, "-nx", &nx, nullptr));
    CELLFSI_PETSC(PetscOptionsGetInt(nullptr, nullptr, "-ny", &ny, nullptr));
    CELLFSI_PETSC(PetscOptionsGetInt(nullptr, nullptr, "-k", &k, nullptr));
    CELLFSI_PETSC(PetscOptionsGetInt(nullptr, nullptr, "-repeat", &repeat, nullptr));
    const MPI_Comm comm = PETSC_COMM_WORLD;
    int size = 1;
    CELLFSI_PETSC(MPI_Comm_size(comm, &size));
    const DivConformingSpace sp(2, static_cast<int>(k), {static_cast<int>(nx), static_cast<int>(ny), 1},
                                Vec3(0, 0, 0), Vec3(1, 0.5, 0), {true, false, false});
    DcFluidOptions opt;
    opt.density = 1.0;
    opt.viscosity = 0.1;
    opt.dt = 0.01;
    opt.wall_velocity[1][1] = Vec3(1.0, 0, 0);
    DivConformingFluid fs(comm, sp, opt);
    if (!fs.solve_steady().converged) std::fprintf(stderr, "the steady Couette solve did not converge\n");

    // b: random, 0 on the wall-normal rows, pressure rows of zero sum (consistent; as the unit test).
    const int n = sp.n_dofs();
    std::vector<double> b(n);
    std::mt19937 gen(9);
    std::uniform_real_distribution<double> dist(-1.0, 1.0);
    double mean_p = 0;
    for (int a = 0; a < n; ++a) b[a] = dist(gen);
    for (int a = sp.offset(2); a < n; ++a) mean_p += b[a] / sp.n_pressure();
    for (int a = sp.offset(2); a < n; ++a) b[a] -= mean_p;
    for (int r : sp.wall_normal_dofs()) b[r] = 0.0;

    // The Fourier solver: build once, solve `repeat` times (best and mean).
    std::vector<double> xf;
    Mat A = fs.jacobian(true, false);  // assembled outside the timing
    auto t0 = Clock::now();
    DcFourierSolver fourier(sp, comm, fs.petsc_numbering());
    fourier.build(A, true);
    const double t_build = max_over_ranks(seconds_since(t0), comm);
    double best = 1e30, total = 0;
    for (int r = 0; r < repeat; ++r) {
      CELLFSI_PETSC(MPI_Barrier(comm));
      t0 = Clock::now();
      fourier.solve(b, xf);
      const double t = max_over_ranks(seconds_since(t0), comm);
      best = std::min(best, t);
      total += t;
    }

    // The product y = A x: the stencil's (no matrix) against the assembled matrix's (MatMult; the
    // natural-to-PETSc moves included in the stencil's, as the coupled operator does them), best of `repeat`.
    double best_stencil = 1e30, best_matmult = 1e30, product_diff = 0, product_scale = 0;
    {
      Vec xv, yv;
      CELLFSI_PETSC(MatCreateVecs(A, &xv, &yv));
      fs.scatter(b, xv);
      std::vector<double> xs, ys, ym;
      for (int r = 0; r < repeat; ++r) {
        CELLFSI_PETSC(MPI_Barrier(comm));
        t0 = Clock::now();
        fs.gather(xv, xs);
        fourier.multiply(xs, ys);
        fs.scatter(ys, yv);
        best_stencil = std::min(best_stencil, max_over_ranks(seconds_since(t0), comm));
        CELLFSI_PETSC(MPI_Barrier(comm));
        t0 = Clock::now();
        CELLFSI_PETSC(MatMult(A, xv, yv));
        best_matmult = std::min(best_matmult, max_over_ranks(seconds_since(t0), comm));
      }
      fs.gather(yv, ym);
      for (int a = 0; a < n; ++a) {
        product_diff = std::max(product_diff, std::abs(ys[a] - ym[a]));
        product_scale = std::max(product_scale, std::abs(ym[a]));
      }
      CELLFSI_PETSC(VecDestroy(&xv));
      CELLFSI_PETSC(VecDestroy(&yv));
    }

    // MUMPS: the fluid's own KSP on the same operator with its pressure pin (whose row gets 0).
    Mat J = fs.jacobian(true, true);
    KSP ksp = fs.ksp();
    CELLFSI_PETSC(KSPSetOperators(ksp, J, J));
    Vec bv, xv;
    CELLFSI_PETSC(MatCreateVecs(J, &xv, &bv));
    PetscInt lo = 0, hi = 0;
    CELLFSI_PETSC(VecGetOwnershipRange(bv, &lo, &hi));
    const std::vector<PetscInt>& pidx = fs.petsc_numbering();
    for (int a = 0; a < n; ++a)
      if (pidx[a] >= lo && pidx[a] < hi)
        CELLFSI_PETSC(VecSetValue(bv, pidx[a], a == sp.offset(2) ? 0.0 : b[a], INSERT_VALUES));
    CELLFSI_PETSC(VecAssemblyBegin(bv));
    CELLFSI_PETSC(VecAssemblyEnd(bv));
    t0 = Clock::now();
    CELLFSI_PETSC(KSPSolve(ksp, bv, xv));
    const double t_mumps = max_over_ranks(seconds_since(t0), comm);
    VecScatter to_all;
    Vec x_all;
    CELLFSI_PETSC(VecScatterCreateToAll(xv, &to_all, &x_all));
    CELLFSI_PETSC(VecScatterBegin(to_all, xv, x_all, INSERT_VALUES, SCATTER_FORWARD));
    CELLFSI_PETSC(VecScatterEnd(to_all, xv, x_all, INSERT_VALUES, SCATTER_FORWARD));
    std::vector<double> xd(n);
    const PetscScalar* xp;
    CELLFSI_PETSC(VecGetArrayRead(x_all, &xp));
    for (int a = 0; a < n; ++a) xd[a] = xp[pidx[a]];
    CELLFSI_PETSC(VecRestoreArrayRead(x_all, &xp));
    CELLFSI_PETSC(VecScatterDestroy(&to_all));
    CELLFSI_PETSC(VecDestroy(&x_all));
    CELLFSI_PETSC(VecDestroy(&bv));
    CELLFSI_PETSC(VecDestroy(&xv));

    // Both pressures shifted to zero mean (the two solves pin different constants).
    double mf = 0, md = 0;
    for (int a = sp.offset(2); a < n; ++a) {
      mf += xf[a] / sp.n_pressure();
      md += xd[a] / sp.n_pressure();
    }
    double diff = 0, scale = 0;
    for (int a = 0; a < n; ++a) {
      const double shift = a >= sp.offset(2) ? mf - md : 0.0;
      diff = std::max(diff, std::abs(xf[a] - xd[a] - shift));
      scale = std::max(scale, std::abs(xd[a]));
    }
    CELLFSI_PETSC(
        PetscPrintf(comm,
                    "| %d x %d | %d | %d | %d | %.3f | %.3f | %.3f | %.1f | %.1e | %.1e | %.3f | %.3f | "
                    "%.1e |\n",
                    static_cast<int>(nx), static_cast<int>(ny), static_cast<int>(k), n, size, t_build,
                    1e3 * best, 1e3 * total / repeat, 1e3 * t_mumps, fourier.deviation(), diff / scale,
                    1e3 * best_stencil, 1e3 * best_matmult, product_diff / product_scale));
  }
  CELLFSI_PETSC(PetscFinalize());
  return 0;
}
