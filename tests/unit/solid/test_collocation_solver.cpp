// Step 3's solver (solid/collocation_solver.hpp): the direction-by-direction solve against a sparse LU of the
// assembled collocation matrix, on every kind of body the builders make, and its fallback where the split
// does not hold.
#include <gtest/gtest.h>

#include <random>

#include <Eigen/SparseLU>

#include "geometry/builders.hpp"
#include "solid/collocation_solver.hpp"

using namespace cellfsi;

namespace {
/// Largest difference, relative to the largest entry, between the solver's c and a sparse LU's for three
/// random right-hand sides; and R c against the right-hand sides (the solve's own residual).
void expect_solves_like_sparse_lu(const solid::CollocationSolver& s, double tol) {
  const Eigen::SparseMatrix<double>& R = s.matrix();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1, 1);
  Eigen::MatrixXd v(R.rows(), 3);
  for (Eigen::Index i = 0; i < v.size(); ++i) v.data()[i] = U(rng);
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(R);
  ASSERT_EQ(lu.info(), Eigen::Success);
  const Eigen::MatrixXd reference = lu.solve(v);
  const Eigen::MatrixXd c = s.solve(v);
  const double scale = reference.lpNorm<Eigen::Infinity>();
  EXPECT_LE((c - reference).lpNorm<Eigen::Infinity>(), tol * scale);
  EXPECT_LE((R * c - v).lpNorm<Eigen::Infinity>(), tol);
}
}  // namespace

TEST(CollocationSolver, SolvesByDirectionLikeASparseLuOnEveryBuiltBody) {
  // A 2D membrane (closed, open knots: a folded seam), a disk (degenerate centre), a 3D shell (folded
  // azimuth, poles), a biconcave cell, a solid ball (centre, poles, azimuth), a box periodic in one
  // direction, all rational except the box. The two solves differ only in the order of their operations,
  // each a few round-offs amplified by the condition numbers of the univariate Greville collocation matrices
  // (of order 1 to 10 at degrees 2-3: their product at most about 1e3). Measured: at most a few 1e-15 (the
  // 44 892-unknown membrane 1.0e-15); 1e-13 relative allows for that product.
  const std::vector<geometry::Patch> bodies = {
      geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 64, 2),
      geometry::bulky_ellipse(2e-4, 2e-4, 8, 32, 2),
      geometry::hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 8, 16, 2),
      geometry::biconcave_rbc_3d(3e-5, 10, 20, 3),
      geometry::solid_ellipsoid(2e-4, 2e-4, 2e-4, 3, 8, 16, 2),
      geometry::box(1.0, 0.5, 0.25, 6, 4, 3, 2, {true, false, false}),
  };
  for (const geometry::Patch& p : bodies) {
    const solid::CollocationSolver s(p);
    EXPECT_TRUE(s.by_direction()) << s.fallback_reason();
    EXPECT_TRUE(s.fallback_reason().empty());
    expect_solves_like_sparse_lu(s, 1e-13);
  }
}

TEST(CollocationSolver, FallsBackToASparseLuWhenTheSeamsWeightsDiffer) {
  // The seam's two control layers at one place, with different weights: the folded unknown's function is
  // then w_first N_first + w_last N_last, not one weight times a univariate sum, so the split does not hold.
  geometry::Patch p = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 32, 2);
  ASSERT_TRUE(p.closed(1));
  const int last = p.n_control(1) - 1;
  for (int a = 0; a < p.n_control(0); ++a) p.weights()[p.control_index(a, last)] *= 1.01;
  const solid::CollocationSolver s(p);
  EXPECT_FALSE(s.by_direction());
  EXPECT_NE(s.fallback_reason().find("weights"), std::string::npos) << s.fallback_reason();
  expect_solves_like_sparse_lu(s, 1e-13);
}

TEST(CollocationSolver, FoldsAClosedDirectionsSeamIntoOneUnknown) {
  const geometry::Patch p = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 16, 2);
  const solid::CollocationSolver s(p);
  EXPECT_FALSE(s.folded(0));
  EXPECT_TRUE(s.folded(1));
  EXPECT_EQ(s.n_points(1), p.n_control(1) - 1);
  EXPECT_EQ(s.n_points(2), 1);
  for (int a = 0; a < p.n_control(0); ++a)
    EXPECT_EQ(s.unknown(p.control_index(a, p.n_control(1) - 1)), s.unknown(p.control_index(a, 0)));
  EXPECT_EQ(s.matrix().rows(), s.n_points(0) * s.n_points(1));
  EXPECT_EQ(s.matrix().cols(), s.matrix().rows());
}
