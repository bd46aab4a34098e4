// Solves a saved linear system with whatever solver the PETSc options database describes, and prints one
// line: size, set-up and solve time, iterations, reason, true relative residual. For studying solvers on a
// matrix the coupled run saved, e.g. the Fourier solver's region (docs/design.md §8):
//
//   cellfsi SCENE ... -final_time 5e-4 -coupling_fourier_region_ksp_view_mat binary:region.bin
//       -coupling_fourier_region_ksp_view_rhs binary:rhs.bin
//   bench/saved_matrix_solve -f region.bin -rhs rhs.bin -ksp_type gmres -pc_type ilu ...
//
// (the run appends one matrix and right-hand side per region solve; the first of each is read). Without
// -rhs the right-hand side is random. The matrix is read as AIJ unless -mat_type says otherwise. The region's
// ordering cellfsi_nd (solvers/nested_dissection.hpp) is registered: -pc_factor_mat_ordering_type cellfsi_nd;
// so is the LU in single precision (solvers/single_precision_lu.hpp): -ksp_type fgmres -pc_type cellfsi_lu_single.
#include <petscksp.h>

#include <cstdio>
#include <exception>

#include "common/petsc_error.hpp"
#include "solvers/pc_types.hpp"

namespace {

int run() {
  char file[PETSC_MAX_PATH_LEN] = "", rhs_file[PETSC_MAX_PATH_LEN] = "";
  PetscBool has_file = PETSC_FALSE, has_rhs = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsGetString(nullptr, nullptr, "-f", file, sizeof file, &has_file));
  CELLFSI_PETSC(PetscOptionsGetString(nullptr, nullptr, "-rhs", rhs_file, sizeof rhs_file, &has_rhs));
  if (!has_file) {
    std::fprintf(stderr, "saved_matrix_solve: give the matrix with -f FILE (PETSc binary)\n");
    return 1;
  }
  PetscViewer viewer;
  Mat A;
  Vec b, x, r;
  CELLFSI_PETSC(PetscViewerBinaryOpen(PETSC_COMM_WORLD, file, FILE_MODE_READ, &viewer));
  CELLFSI_PETSC(MatCreate(PETSC_COMM_WORLD, &A));
  CELLFSI_PETSC(MatSetType(A, MATAIJ));
  CELLFSI_PETSC(MatSetFromOptions(A));
  CELLFSI_PETSC(MatLoad(A, viewer));
  CELLFSI_PETSC(PetscViewerDestroy(&viewer));
  CELLFSI_PETSC(MatCreateVecs(A, &x, &b));
  if (has_rhs) {
    CELLFSI_PETSC(PetscViewerBinaryOpen(PETSC_COMM_WORLD, rhs_file, FILE_MODE_READ, &viewer));
    CELLFSI_PETSC(VecLoad(b, viewer));
    CELLFSI_PETSC(PetscViewerDestroy(&viewer));
  } else {
    CELLFSI_PETSC(VecSetRandom(b, nullptr));
  }
  KSP ksp;
  CELLFSI_PETSC(KSPCreate(PETSC_COMM_WORLD, &ksp));
  CELLFSI_PETSC(KSPSetOperators(ksp, A, A));
  CELLFSI_PETSC(KSPSetFromOptions(ksp));
  PetscLogDouble t0, t1, t2;
  CELLFSI_PETSC(PetscTime(&t0));
  CELLFSI_PETSC(KSPSetUp(ksp));
  CELLFSI_PETSC(PetscTime(&t1));
  CELLFSI_PETSC(KSPSolve(ksp, b, x));
  CELLFSI_PETSC(PetscTime(&t2));
  PetscInt its = 0, n = 0;
  KSPConvergedReason reason;
  CELLFSI_PETSC(KSPGetIterationNumber(ksp, &its));
  CELLFSI_PETSC(KSPGetConvergedReason(ksp, &reason));
  CELLFSI_PETSC(MatGetSize(A, &n, nullptr));
  CELLFSI_PETSC(VecDuplicate(b, &r));
  CELLFSI_PETSC(MatMult(A, x, r));
  CELLFSI_PETSC(VecAXPY(r, -1.0, b));
  PetscReal r_norm = 0, b_norm = 0;
  CELLFSI_PETSC(VecNorm(r, NORM_2, &r_norm));
  CELLFSI_PETSC(VecNorm(b, NORM_2, &b_norm));
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                            "unknowns %" PetscInt_FMT "  set-up %.3f s  solve %.3f s  iterations %" PetscInt_FMT
                            "  %s  |b - A x| / |b| %.2e\n",
                            n, t1 - t0, t2 - t1, its, KSPConvergedReasons[reason], r_norm / b_norm));
  CELLFSI_PETSC(KSPDestroy(&ksp));
  CELLFSI_PETSC(MatDestroy(&A));
  CELLFSI_PETSC(VecDestroy(&x));
  CELLFSI_PETSC(VecDestroy(&b));
  CELLFSI_PETSC(VecDestroy(&r));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (PetscInitialize(&argc, &argv, nullptr, nullptr) != 0) return 1;
  int rc = 1;
  try {
    // -pc_factor_mat_ordering_type cellfsi_nd, -pc_type cellfsi_lu_single
    cellfsi::solvers::register_pc_types();
    rc = run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "saved_matrix_solve: %s\n", e.what());
  }
  PetscFinalize();
  return rc;
}
