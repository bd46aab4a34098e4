// The LU in single precision (solvers/single_precision_lu.hpp) and its PC type cellfsi_lu_single: a solve is
// correct to single precision, FGMRES around it reaches double precision in a few iterations (also with rows
// scaled like the s_I band's), AIJ and BAIJ give the same factors, the analysis is kept for the same pattern,
// and 2 ranks solve as one.
#include <gtest/gtest.h>

#include <petscksp.h>

#include <random>
#include <string>

#include "common/petsc_error.hpp"
#include "solvers/pc_types.hpp"
#include "solvers/single_precision_lu.hpp"
#include "test_operators.hpp"

using cellfsi::test::Grid;
using cellfsi::test::kBs;
using cellfsi::test::relative_difference;
using cellfsi::test::relative_residual;
constexpr auto set_up_once = cellfsi::test::set_up_pc_types_once;
namespace solvers = cellfsi::solvers;

namespace {

/// A Jacobian-like BAIJ matrix on the test grid; `strip` scales the cells of one column of the grid by 1e10,
/// as s_I scales the band's rows, and a random right-hand side (the same on every rank).
struct Problem {
  Grid g;
  Mat K = nullptr;
  Vec r = nullptr, x = nullptr;
  explicit Problem(bool strip, unsigned seed = 5) {
    std::mt19937 rng(seed);
    K = g.assemble(
        rng, [](int, int) { return true; }, [&](int i, int) { return strip && i == 6 ? 1e10 : 1.0; });
    CELLFSI_PETSC(MatCreateVecs(K, &x, &r));
    cellfsi::test::fill_random(r, rng);
  }
  ~Problem() {
    MatDestroy(&K);
    VecDestroy(&r);
    VecDestroy(&x);
  }
};

/// FGMRES to rtol 1e-12 with the PC of type cellfsi_lu_single (options prefix t_): iterations and reason.
std::pair<PetscInt, KSPConvergedReason> fgmres(Mat K, Vec r, Vec x, std::string* view = nullptr) {
  KSP ksp;
  CELLFSI_PETSC(KSPCreate(PetscObjectComm(reinterpret_cast<PetscObject>(K)), &ksp));
  CELLFSI_PETSC(KSPSetOptionsPrefix(ksp, "t_"));
  CELLFSI_PETSC(KSPSetType(ksp, KSPFGMRES));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, solvers::kPCLUSingle));
  CELLFSI_PETSC(KSPSetTolerances(ksp, 1e-12, 1e-50, PETSC_DEFAULT, 30));
  CELLFSI_PETSC(KSPSetFromOptions(ksp));
  CELLFSI_PETSC(KSPSetOperators(ksp, K, K));
  CELLFSI_PETSC(KSPSolve(ksp, r, x));
  PetscInt its = 0;
  KSPConvergedReason reason;
  CELLFSI_PETSC(KSPGetIterationNumber(ksp, &its));
  CELLFSI_PETSC(KSPGetConvergedReason(ksp, &reason));
  if (view) *view = cellfsi::test::view_text(ksp);
  KSPDestroy(&ksp);
  return {its, reason};
}

}  // namespace

TEST(SinglePrecisionLU, SolvesToSinglePrecisionAndFgmresRefinesItToDouble) {
  set_up_once();
  for (const bool strip : {false, true}) {
    SCOPED_TRACE(strip ? "a strip of rows scaled by 1e10" : "unscaled");
    Problem p(strip);
    solvers::SinglePrecisionLU lu(PETSC_COMM_SELF);
    lu.factor(p.K);
    lu.solve(p.r, p.x);
    // One solve: single precision (float's epsilon 6e-8), not double (measured: 1.2e-7 both).
    const double once = relative_residual(p.K, p.x, p.r);
    EXPECT_LT(once, 1e-5);
    EXPECT_GT(once, 1e-12);
    EXPECT_GT(lu.operations(), 0);
    EXPECT_GT(lu.factor_entries(), 0);
    // As the preconditioner of FGMRES: double precision in a few iterations (measured: 2 both).
    const auto [its, reason] = fgmres(p.K, p.r, p.x);
    EXPECT_GT(reason, 0);
    EXPECT_LE(its, 5);
    EXPECT_LT(relative_residual(p.K, p.x, p.r), 1e-11);
  }
}

TEST(SinglePrecisionLU, TakesAIJAndBAIJAndKeepsTheAnalysisWhileThePatternIsTheSame) {
  Problem p(true);
  Mat aij;
  CELLFSI_PETSC(MatConvert(p.K, MATAIJ, MAT_INITIAL_MATRIX, &aij));
  Vec y;
  CELLFSI_PETSC(VecDuplicate(p.x, &y));
  solvers::SinglePrecisionLU lu(PETSC_COMM_SELF), lu_aij(PETSC_COMM_SELF);
  lu.factor(p.K);
  lu.solve(p.r, p.x);
  lu_aij.factor(aij);
  lu_aij.solve(p.r, y);
  // The same entries in the same order of elimination (the node graph is the same): the same factors.
  EXPECT_LT(relative_difference(p.x, y), 1e-6);
  EXPECT_EQ(lu.operations(), lu_aij.operations());
  // New values, the same pattern: refactorised without a new analysis, and solving the new matrix.
  CELLFSI_PETSC(MatShift(p.K, 3.0));
  lu.factor(p.K);
  EXPECT_EQ(lu.analyses(), 1);
  lu.solve(p.r, p.x);
  EXPECT_LT(relative_residual(p.K, p.x, p.r), 1e-5);
  // Another matrix: analysed anew.
  lu.factor(aij);
  EXPECT_EQ(lu.analyses(), 2);
  // MUMPS' own ordering solves the same system.
  lu.set_ordering("mumps");
  lu.factor(aij);
  EXPECT_EQ(lu.analyses(), 3);
  lu.solve(p.r, p.x);
  EXPECT_LT(relative_residual(aij, p.x, p.r), 1e-5);
  EXPECT_THROW(lu.set_ordering("amd"), std::invalid_argument);
  lu.solve(p.r, p.x);  // a refused ordering changes nothing
  EXPECT_LT(relative_residual(aij, p.x, p.r), 1e-5);
  VecDestroy(&y);
  MatDestroy(&aij);
}

TEST(PCTypes, LUSingleIsChosenByOptionsViewedAndRefusesABadOrdering) {
  set_up_once();
  Problem p(false);
  {
    PetscOptionsSetValue(nullptr, "-t_pc_lu_single_ordering", "mumps");
    std::string view;
    const auto [its, reason] = fgmres(p.K, p.r, p.x, &view);
    PetscOptionsClearValue(nullptr, "-t_pc_lu_single_ordering");
    EXPECT_GT(reason, 0);
    EXPECT_LE(its, 5);
    EXPECT_NE(view.find("type: cellfsi_lu_single"), std::string::npos) << view;
    EXPECT_NE(view.find("MUMPS LU in single precision, ordering mumps"), std::string::npos) << view;
    EXPECT_NE(view.find("420 unknowns"), std::string::npos) << view;
  }
  PetscOptionsSetValue(nullptr, "-t_pc_lu_single_ordering", "amd");
  try {
    fgmres(p.K, p.r, p.x);
    ADD_FAILURE() << "no error";
  } catch (const std::exception& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("amd"), std::string::npos) << what;
    EXPECT_NE(what.find("cellfsi_nd"), std::string::npos) << what;
  }
  PetscOptionsClearValue(nullptr, "-t_pc_lu_single_ordering");
}

// Run on 2 ranks by the test solvers_parallel_2ranks (on 1 rank it compares the solver with itself).
TEST(FourierParallel, SinglePrecisionLUOnAllRanksAsOnOne) {
  // The problem's matrix as MPIBAIJ on PETSC_COMM_WORLD (rows split between the ranks, triplets distributed
  // to MUMPS, the ordering made on the host from the gathered pattern): the same solve as on one rank, to
  // single precision.
  Problem p(true);
  solvers::SinglePrecisionLU one(PETSC_COMM_SELF);
  one.factor(p.K);
  one.solve(p.r, p.x);
  const PetscInt n = p.g.n();
  Mat K;
  CELLFSI_PETSC(MatCreate(PETSC_COMM_WORLD, &K));
  CELLFSI_PETSC(MatSetSizes(K, PETSC_DECIDE, PETSC_DECIDE, n, n));
  CELLFSI_PETSC(MatSetType(K, MATBAIJ));
  CELLFSI_PETSC(MatSetBlockSize(K, kBs));
  CELLFSI_PETSC(MatSeqBAIJSetPreallocation(K, kBs, 9, nullptr));
  CELLFSI_PETSC(MatMPIBAIJSetPreallocation(K, kBs, 9, nullptr, 9, nullptr));
  PetscInt begin = 0, end = 0;
  CELLFSI_PETSC(MatGetOwnershipRange(K, &begin, &end));
  for (PetscInt row = begin; row < end; ++row) {
    PetscInt nc = 0;
    const PetscInt* cols = nullptr;
    const PetscScalar* vals = nullptr;
    CELLFSI_PETSC(MatGetRow(p.K, row, &nc, &cols, &vals));
    CELLFSI_PETSC(MatSetValues(K, 1, &row, nc, cols, vals, INSERT_VALUES));
    CELLFSI_PETSC(MatRestoreRow(p.K, row, &nc, &cols, &vals));
  }
  CELLFSI_PETSC(MatAssemblyBegin(K, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(K, MAT_FINAL_ASSEMBLY));
  Vec r, x;
  CELLFSI_PETSC(MatCreateVecs(K, &x, &r));
  const PetscScalar* rr = nullptr;
  CELLFSI_PETSC(VecGetArrayRead(p.r, &rr));
  for (PetscInt row = begin; row < end; ++row) CELLFSI_PETSC(VecSetValue(r, row, rr[row], INSERT_VALUES));
  CELLFSI_PETSC(VecRestoreArrayRead(p.r, &rr));
  CELLFSI_PETSC(VecAssemblyBegin(r));
  CELLFSI_PETSC(VecAssemblyEnd(r));
  solvers::SinglePrecisionLU all(PETSC_COMM_WORLD);
  all.factor(K);
  all.solve(r, x);
  EXPECT_LT(relative_residual(K, x, r), 1e-5);
  EXPECT_EQ(all.operations(), one.operations());  // the same ordering on the same graph
  // Rank by rank, this rank's part against the one-rank solution.
  const PetscScalar *xa = nullptr, *xo = nullptr;
  CELLFSI_PETSC(VecGetArrayRead(x, &xa));
  CELLFSI_PETSC(VecGetArrayRead(p.x, &xo));
  double diff = 0, scale = 0;
  for (PetscInt row = begin; row < end; ++row) {
    diff = std::max(diff, std::abs(xa[row - begin] - xo[row]));
    scale = std::max(scale, std::abs(xo[row]));
  }
  CELLFSI_PETSC(VecRestoreArrayRead(x, &xa));
  CELLFSI_PETSC(VecRestoreArrayRead(p.x, &xo));
  EXPECT_LT(diff, 1e-5 * scale);
  VecDestroy(&r);
  VecDestroy(&x);
  MatDestroy(&K);
}
