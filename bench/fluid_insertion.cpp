// Cost of putting element matrices into the fluid's Jacobian, per element, one rank: the question of issue 11
// whether PETSc's public COO assembly (MatSetPreallocationCOO / MatSetValuesCOO) can replace the SeqBAIJ
// inserter (fluid/seq_baij_inserter.hpp) within 10 % of the whole Jacobian assembly.
//
// The fluid's DMDA (the paper's shear box: periodic in x, walls in y (and z periodic in 3D), stencil width p,
// dof dim + 1) with one dense element matrix per element (random values; the insertion does not depend on
// them), inserted by
//   direct  the SeqBAIJ inserter (what FluidSolver::assemble does on one rank),
//   blocked MatSetValuesBlockedLocal on the BAIJ matrix (PETSc's public per-block insertion),
//   coo     MatSetValuesCOO on an AIJ matrix (values copied into the COO array element by element, then one
//           call; the pattern set once, not timed), and the same on the BAIJ matrix (coo_baij: PETSc 3.18 has
//           no native BAIJ COO and falls back to MatSetValues).
// Prints one markdown table row per method: best of -repeat assemblies, microseconds per element.
//   bench/fluid_insertion -dim 2 -p 3 -n 128 -repeat 5
#include <petscdmda.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/petsc_error.hpp"
#include "fluid/seq_baij_inserter.hpp"

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  CELLFSI_PETSC(PetscInitialize(&argc, &argv, nullptr, nullptr));
  {
    PetscInt dim = 2, p = 3, n = 128, repeat = 5;
    CELLFSI_PETSC(PetscOptionsGetInt(nullptr, nullptr, "-dim", &dim, nullptr));
    CELLFSI_PETSC(PetscOptionsGetInt(nullptr, nullptr, "-p", &p, nullptr));
    CELLFSI_PETSC(PetscOptionsGetInt(nullptr, nullptr, "-n", &n, nullptr));
    CELLFSI_PETSC(PetscOptionsGetInt(nullptr, nullptr, "-repeat", &repeat, nullptr));
    const int nd = static_cast<int>(dim) + 1;
    // Elements per direction: n x n/2 (2D), n^3 (3D); control points per direction: periodic n, walls n + p.
    const PetscInt ne[3] = {n, dim == 2 ? n / 2 : n, dim == 3 ? n : 1};
    const PetscInt nc[3] = {ne[0], ne[1] + p, dim == 3 ? ne[2] : 1};
    DM da;
    if (dim == 2)
      CELLFSI_PETSC(DMDACreate2d(PETSC_COMM_WORLD, DM_BOUNDARY_PERIODIC, DM_BOUNDARY_NONE, DMDA_STENCIL_BOX,
                                 nc[0], nc[1], PETSC_DECIDE, PETSC_DECIDE, nd, p, nullptr, nullptr, &da));
    else
      CELLFSI_PETSC(DMDACreate3d(PETSC_COMM_WORLD, DM_BOUNDARY_PERIODIC, DM_BOUNDARY_NONE,
                                 DM_BOUNDARY_PERIODIC, DMDA_STENCIL_BOX, nc[0], nc[1], nc[2], PETSC_DECIDE,
                                 PETSC_DECIDE, PETSC_DECIDE, nd, p, nullptr, nullptr, nullptr, &da));
    CELLFSI_PETSC(DMSetUp(da));
    PetscInt gxs[3], gxm[3];
    CELLFSI_PETSC(DMDAGetGhostCorners(da, &gxs[0], &gxs[1], &gxs[2], &gxm[0], &gxm[1], &gxm[2]));
    const int np = static_cast<int>(std::pow(p + 1, dim)), ne_all = static_cast<int>(ne[0] * ne[1] * ne[2]);
    const std::size_t esize = static_cast<std::size_t>(np * nd) * np * nd;

    // Local nodes of each element (its first function per direction is its index), as the solver's loop.
    std::vector<PetscInt> nodes(static_cast<std::size_t>(ne_all) * np);
    std::size_t at = 0;
    for (PetscInt e2 = 0; e2 < ne[2]; ++e2)
      for (PetscInt e1 = 0; e1 < ne[1]; ++e1)
        for (PetscInt e0 = 0; e0 < ne[0]; ++e0)
          for (int c = 0; c < (dim == 3 ? p + 1 : 1); ++c)
            for (int b = 0; b <= p; ++b)
              for (int a = 0; a <= p; ++a) {
                const PetscInt m[3] = {e0 + a, e1 + b, dim == 3 ? e2 + c : 0};
                nodes[at++] = ((m[2] - gxs[2]) * gxm[1] + (m[1] - gxs[1])) * gxm[0] + (m[0] - gxs[0]);
              }
    std::vector<double> K(esize);
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> unif(-1, 1);
    for (double& k : K) k = unif(rng);

    Mat baij, aij, baij_coo;
    CELLFSI_PETSC(DMSetMatType(da, MATBAIJ));
    CELLFSI_PETSC(DMCreateMatrix(da, &baij));
    CELLFSI_PETSC(DMCreateMatrix(da, &baij_coo));
    CELLFSI_PETSC(DMSetMatType(da, MATAIJ));
    CELLFSI_PETSC(DMCreateMatrix(da, &aij));
    for (Mat M : {baij, aij, baij_coo}) CELLFSI_PETSC(MatSetOption(M, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));

    // COO pattern: every element's (n nd)^2 entries, row-major, global indices.
    ISLocalToGlobalMapping l2g;
    CELLFSI_PETSC(DMGetLocalToGlobalMapping(da, &l2g));
    const PetscInt* g;
    CELLFSI_PETSC(ISLocalToGlobalMappingGetBlockIndices(l2g, &g));
    const std::size_t ncoo = static_cast<std::size_t>(ne_all) * esize;
    std::vector<PetscInt> ci(ncoo), cj(ncoo);
    at = 0;
    for (int e = 0; e < ne_all; ++e) {
      const PetscInt* en = &nodes[static_cast<std::size_t>(e) * np];
      for (int A = 0; A < np; ++A)
        for (int c = 0; c < nd; ++c)
          for (int B = 0; B < np; ++B)
            for (int d = 0; d < nd; ++d, ++at) {
              ci[at] = g[en[A]] * nd + c;
              cj[at] = g[en[B]] * nd + d;
            }
    }
    CELLFSI_PETSC(ISLocalToGlobalMappingRestoreBlockIndices(l2g, &g));
    const auto t_pattern = Clock::now();
    CELLFSI_PETSC(MatSetPreallocationCOO(aij, static_cast<PetscCount>(ncoo), ci.data(), cj.data()));
    const double pattern_aij = seconds_since(t_pattern);
    CELLFSI_PETSC(MatSetPreallocationCOO(baij_coo, static_cast<PetscCount>(ncoo), ci.data(), cj.data()));
    std::vector<PetscInt>().swap(ci);
    std::vector<PetscInt>().swap(cj);
    std::vector<double> coo(ncoo);

    double best[4] = {1e30, 1e30, 1e30, 1e30};
    for (PetscInt r = 0; r < repeat; ++r) {
      // direct
      auto t0 = Clock::now();
      CELLFSI_PETSC(MatZeroEntries(baij));
      {
        cellfsi::fluid::SeqBaijInserter ins(baij, nd);
        if (!ins.usable())
          throw std::runtime_error("the SeqBAIJ inserter is not usable here (one rank only)");
        for (int e = 0; e < ne_all; ++e) {
          if (!ins.prepare(np, &nodes[static_cast<std::size_t>(e) * np]))
            throw std::runtime_error("an element block outside the pattern");
          ins.add_blocks(np, K.data());
        }
      }
      CELLFSI_PETSC(MatAssemblyBegin(baij, MAT_FINAL_ASSEMBLY));
      CELLFSI_PETSC(MatAssemblyEnd(baij, MAT_FINAL_ASSEMBLY));
      best[0] = std::min(best[0], seconds_since(t0));
      // blocked
      t0 = Clock::now();
      CELLFSI_PETSC(MatZeroEntries(baij));
      for (int e = 0; e < ne_all; ++e)
        CELLFSI_PETSC(MatSetValuesBlockedLocal(baij, np, &nodes[static_cast<std::size_t>(e) * np], np,
                                               &nodes[static_cast<std::size_t>(e) * np], K.data(),
                                               ADD_VALUES));
      CELLFSI_PETSC(MatAssemblyBegin(baij, MAT_FINAL_ASSEMBLY));
      CELLFSI_PETSC(MatAssemblyEnd(baij, MAT_FINAL_ASSEMBLY));
      best[1] = std::min(best[1], seconds_since(t0));
      // coo (AIJ): the element loop writes its matrix into the COO array, then one call
      for (int m = 0; m < 2; ++m) {
        if (m == 1 && r > 0) continue;  // the BAIJ fallback is slow: once
        t0 = Clock::now();
        for (int e = 0; e < ne_all; ++e)
          std::copy(K.begin(), K.end(), coo.begin() + static_cast<std::ptrdiff_t>(e * esize));
        CELLFSI_PETSC(MatSetValuesCOO(m == 0 ? aij : baij_coo, coo.data(), INSERT_VALUES));
        best[2 + m] = std::min(best[2 + m], seconds_since(t0));
      }
    }
    const double us = 1e6 / ne_all;
    std::printf(
        "| %d | %d | %s | %.2f | %.2f | %.2f | %.2f | %.0f |\n", static_cast<int>(dim), static_cast<int>(p),
        (dim == 2 ? std::to_string(ne[0]) + "x" + std::to_string(ne[1]) : std::to_string(n) + "^3").c_str(),
        best[0] * us, best[1] * us, best[2] * us, best[3] * us, pattern_aij * 1e3);
    for (Mat M : {baij, aij, baij_coo}) CELLFSI_PETSC(MatDestroy(&M));
    CELLFSI_PETSC(DMDestroy(&da));
  }
  CELLFSI_PETSC(PetscFinalize());
  return 0;
}
