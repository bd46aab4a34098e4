#pragma once
// What the solver tests share: a test operator shaped like the fluid's Jacobian (SeqBAIJ blocks of 3 unknowns
// on a grid of nodes, with the 9-point block stencil as structure), random vectors, a KSP's view and the
// relative residual of a solution.
#include <petscksp.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include <random>
#include <vector>

#include "common/petsc_error.hpp"
#include "solvers/pc_types.hpp"

namespace cellfsi::test {

constexpr int kBs = 3;  // unknowns per node, as velocity + pressure in 2D

/// Element-by-element assembly on an nx x ny grid of nodes (cells of 2 x 2 nodes), like the fluid's Jacobian:
/// every matrix has the full 9-point block stencil as structure; a cell adds a random 12 x 12 matrix
/// (diagonally dominant, so every principal block is invertible) times `scale(cell)`, if `take(cell)`.
struct Grid {
  int nx = 14, ny = 10;
  int node(int i, int j) const { return i + nx * j; }
  int n() const { return nx * ny * kBs; }

  template <class Take, class Scale>
  Mat assemble(std::mt19937& rng, Take take, Scale scale) const {
    Mat A;
    CELLFSI_PETSC(MatCreateSeqBAIJ(PETSC_COMM_SELF, kBs, n(), n(), 9, nullptr, &A));
    std::vector<PetscScalar> zero(kBs * kBs, 0.0);
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (int dj = -1; dj <= 1; ++dj)
          for (int di = -1; di <= 1; ++di) {
            if (i + di < 0 || i + di >= nx || j + dj < 0 || j + dj >= ny) continue;
            PetscInt r = node(i, j), c = node(i + di, j + dj);
            CELLFSI_PETSC(MatSetValuesBlocked(A, 1, &r, 1, &c, zero.data(), INSERT_VALUES));
          }
    CELLFSI_PETSC(MatAssemblyBegin(A, MAT_FLUSH_ASSEMBLY));  // inserted zeros, then added values
    CELLFSI_PETSC(MatAssemblyEnd(A, MAT_FLUSH_ASSEMBLY));
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int j = 0; j + 1 < ny; ++j)
      for (int i = 0; i + 1 < nx; ++i) {
        if (!take(i, j)) continue;
        PetscInt nodes[4] = {node(i, j), node(i + 1, j), node(i, j + 1), node(i + 1, j + 1)};
        std::vector<PetscScalar> e(144);
        for (int r = 0; r < 12; ++r)
          for (int c = 0; c < 12; ++c) e[r * 12 + c] = scale(i, j) * (u(rng) + (r == c ? 15.0 : 0.0));
        CELLFSI_PETSC(MatSetValuesBlocked(A, 4, nodes, 4, nodes, e.data(), ADD_VALUES));
      }
    CELLFSI_PETSC(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
    return A;
  }
};

/// Registers cellfsi's PC types, and PETSc's error messages go into the exceptions (as in the executables).
inline void set_up_pc_types_once() {
  static const bool done = [] {
    cellfsi::record_petsc_errors();
    cellfsi::solvers::register_pc_types();
    return true;
  }();
  (void)done;
}

/// Fills a sequential vector with values uniform in [-1, 1] from rng.
inline void fill_random(Vec v, std::mt19937& rng) {
  PetscInt n = 0;
  CELLFSI_PETSC(VecGetSize(v, &n));
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (PetscInt k = 0; k < n; ++k) CELLFSI_PETSC(VecSetValue(v, k, u(rng), INSERT_VALUES));
  CELLFSI_PETSC(VecAssemblyBegin(v));
  CELLFSI_PETSC(VecAssemblyEnd(v));
}

/// What KSPView prints (through an ASCII viewer on a file, as -ksp_view does on the console).
inline std::string view_text(KSP ksp) {
  const std::string path = "solvers_test_view.txt";
  PetscViewer v;
  CELLFSI_PETSC(PetscViewerASCIIOpen(PETSC_COMM_SELF, path.c_str(), &v));
  CELLFSI_PETSC(KSPView(ksp, v));
  PetscViewerDestroy(&v);
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  std::remove(path.c_str());
  return text.str();
}

/// |A x - r| / |r|.
inline double relative_residual(Mat A, Vec x, Vec r) {
  Vec y;
  CELLFSI_PETSC(VecDuplicate(r, &y));
  CELLFSI_PETSC(MatMult(A, x, y));
  CELLFSI_PETSC(VecAXPY(y, -1.0, r));
  PetscReal e = 0, n = 0;
  CELLFSI_PETSC(VecNorm(y, NORM_2, &e));
  CELLFSI_PETSC(VecNorm(r, NORM_2, &n));
  VecDestroy(&y);
  return e / n;
}

/// |a - b| / |a|.
inline double relative_difference(Vec a, Vec b) {
  Vec d;
  CELLFSI_PETSC(VecDuplicate(a, &d));
  CELLFSI_PETSC(VecWAXPY(d, -1.0, b, a));
  PetscReal e = 0, n = 0;
  CELLFSI_PETSC(VecNorm(d, NORM_2, &e));
  CELLFSI_PETSC(VecNorm(a, NORM_2, &n));
  VecDestroy(&d);
  return e / n;
}

}  // namespace cellfsi::test
