// BandSchurSolver: the exact inverse of K_fixed + K_band after one factorisation of K_fixed, for any K_band
// confined to the band, including band values 1e10 times the rest (the s_I band of the FSI Jacobian).
#include <gtest/gtest.h>

#include <random>

#include "common/petsc_error.hpp"
#include "solvers/band_schur.hpp"
#include "test_operators.hpp"

using cellfsi::solvers::BandSchurSolver;

namespace {

using cellfsi::test::Grid;
using cellfsi::test::kBs;

/// |(K_fixed + K_band) x - r| / |r| for x = solver.solve(r).
double relative_residual(BandSchurSolver& solver, Mat fixed, Mat band, Vec r) {
  Vec x;
  CELLFSI_PETSC(VecDuplicate(r, &x));
  solver.solve(r, x);
  Mat K;
  CELLFSI_PETSC(MatDuplicate(fixed, MAT_COPY_VALUES, &K));
  CELLFSI_PETSC(MatAXPY(K, 1.0, band, SAME_NONZERO_PATTERN));
  const double rel = cellfsi::test::relative_residual(K, x, r);
  MatDestroy(&K);
  VecDestroy(&x);
  return rel;
}

}  // namespace

class BandSchurSolverModes : public ::testing::TestWithParam<bool> {};

TEST_P(BandSchurSolverModes, InvertsFixedPlusAnyBandAfterOneFactorisation) {
  const Grid g;
  std::mt19937 rng(7);
  // The band region: cells with 5 <= i < 9 (their nodes 5..9 are the band unknowns B).
  auto in_region = [](int i, int) { return i >= 5 && i < 9; };
  Mat fixed = g.assemble(
      rng, [&](int i, int j) { return !in_region(i, j); }, [](int, int) { return 1.0; });
  std::vector<PetscInt> band;
  for (int j = 0; j < g.ny; ++j)
    for (int i = 5; i <= 9; ++i)
      for (int c = 0; c < kBs; ++c) band.push_back(g.node(i, j) * kBs + c);
  IS is;
  CELLFSI_PETSC(ISCreateGeneral(PETSC_COMM_SELF, static_cast<PetscInt>(band.size()), band.data(),
                                PETSC_COPY_VALUES, &is));
  BandSchurSolver solver;
  solver.set_fused_solve(GetParam());
  solver.set_blr_tolerance(0);  // exact factors: the test measures the block elimination's exactness
  solver.factor(fixed, is);
  EXPECT_EQ(solver.n_band(), static_cast<PetscInt>(band.size()));
  EXPECT_EQ(solver.n_total(), g.n());
  // The band's edge (its nodes 5 and 9, which border the rest) is what MUMPS keeps; nodes 6-8 are inner.
  EXPECT_EQ(solver.n_edge(), 2 * g.ny * kBs);

  Vec r;
  CELLFSI_PETSC(MatCreateVecs(fixed, &r, nullptr));
  cellfsi::test::fill_random(r, rng);

  // Three different band parts, the last two with a moving strip of cells scaled by 1e10 (like s_I), with the
  // one factorisation of the fixed part. Measured: 2e-16 in every round (both solve modes); the tolerance
  // leaves room for pivot growth.
  for (int round = 0; round < 3; ++round) {
    Mat bandm =
        g.assemble(rng, in_region, [&](int i, int) { return round > 0 && i == 5 + round ? 1e10 : 1.0; });
    solver.set_band(bandm);
    const double rel = relative_residual(solver, fixed, bandm, r);
    EXPECT_LT(rel, 1e-12) << "round " << round;
    MatDestroy(&bandm);
  }
  // Sparse, dense only on the edge: each edge column (10 nodes) couples densely through its side of the rest,
  // the two sides not with each other; far fewer entries than a dense band Schur complement.
  EXPECT_GE(solver.schur_nonzeros(), 2 * g.ny * g.ny * kBs * kBs);
  EXPECT_LT(solver.schur_nonzeros(), solver.n_band() * solver.n_band() / 2);
  VecDestroy(&r);
  ISDestroy(&is);
  MatDestroy(&fixed);
}

INSTANTIATE_TEST_SUITE_P(FusedAndExplicit, BandSchurSolverModes, ::testing::Bool());

TEST(BandSchurSolver, RejectsABandThatIsNotWholeBlocks) {
  const Grid g;
  std::mt19937 rng(3);
  Mat fixed = g.assemble(
      rng, [](int, int) { return true; }, [](int, int) { return 1.0; });
  // Two unknowns of a node; three unknowns that are not one node's (a multiple of the block size).
  for (const std::vector<PetscInt>& idx : {std::vector<PetscInt>{0, 1}, std::vector<PetscInt>{0, 1, 5}}) {
    IS is;
    CELLFSI_PETSC(ISCreateGeneral(PETSC_COMM_SELF, static_cast<PetscInt>(idx.size()), idx.data(),
                                  PETSC_COPY_VALUES, &is));
    BandSchurSolver solver;
    EXPECT_THROW(solver.factor(fixed, is), std::invalid_argument) << idx.size() << " unknowns";
    EXPECT_FALSE(solver.factored());
    ISDestroy(&is);
  }
  MatDestroy(&fixed);
}
