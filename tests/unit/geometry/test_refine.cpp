// Knot insertion and degree elevation leave the map unchanged (to 1e-13 of the patch size); uniform
// refinement reaches the requested element count; isoparametric extraction matches the parent patch.
#include <gtest/gtest.h>

#include "geometry/builders.hpp"
#include "geometry/refine.hpp"

using namespace cellfsi::geometry;

namespace {

double size_of(const Patch& p) {
  Vec3 lo, hi;
  p.bounding_box(lo, hi);
  return (hi - lo).norm();
}

/// Largest distance between the maps of two patches on a grid of parametric points.
double max_map_difference(const Patch& a, const Patch& b, int n = 23) {
  double worst = 0;
  const int P = a.param_dim();
  for (int k = 0; k < (P > 2 ? n : 1); ++k)
    for (int j = 0; j < (P > 1 ? n : 1); ++j)
      for (int i = 0; i < n; ++i) {
        Param xi{0, 0, 0};
        const int idx[3] = {i, j, k};
        for (int d = 0; d < P; ++d) {
          const KnotVector& kv = a.knots(d);
          xi[d] = kv.a() + (kv.b() - kv.a()) * (idx[d] + 0.37) / n;
        }
        worst = std::max(worst, (a.point(xi) - b.point(xi)).norm());
      }
  return worst;
}

}  // namespace

TEST(Refine, KnotInsertionPreservesTheMap) {
  const Patch ellipse = hollow_ellipse(2e-4, 1e-4, 5e-7, 4, 2, Vec3(1e-3, 5e-4, 0), 0.3);
  const Patch refined = insert_knots(ellipse, 1, {0.1, 0.1, 0.2, 0.33, 0.55, 0.61, 0.9});
  EXPECT_EQ(refined.knots(1).n_basis(), ellipse.knots(1).n_basis() + 7);
  EXPECT_LT(max_map_difference(ellipse, refined), 1e-13 * size_of(ellipse));
  const Patch thick = insert_knots(refined, 0, {0.25, 0.5, 0.75});
  EXPECT_EQ(thick.n_elements(0), 4);
  EXPECT_LT(max_map_difference(ellipse, thick), 1e-13 * size_of(ellipse));
}

TEST(Refine, DegreeElevationPreservesTheMap) {
  const Patch ellipse = hollow_ellipse(2e-4, 1e-4, 5e-7, 8, 2, Vec3(1e-3, 5e-4, 0), -0.7);
  for (int times : {1, 2, 3}) {
    const Patch elevated = elevate_degree(ellipse, 1, times);
    EXPECT_EQ(elevated.degree(1), 2 + times);
    // Continuity is kept: every distinct knot's multiplicity grows by `times`.
    EXPECT_EQ(elevated.knots(1).multiplicity(0.25), 2 + times);
    EXPECT_LT(max_map_difference(ellipse, elevated), 1e-13 * size_of(ellipse)) << "times=" << times;
  }
  const Patch shell = hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 2, 4, 2);
  const Patch shell3 = elevate_degree(elevate_degree(shell, 1), 2);
  EXPECT_LT(max_map_difference(shell, shell3, 9), 1e-13 * size_of(shell));
}

TEST(Refine, UniformRefinementReachesTheRequestedCount) {
  const Patch ellipse = hollow_ellipse(2e-4, 1e-4, 5e-7, 4, 2);
  const Patch fine = refine_uniform(ellipse, 1, 208);  // the paper's 1 x 208 membrane mesh
  EXPECT_EQ(fine.n_elements(1), 208);
  // p = 2: n_basis = elements + p + (extra multiplicity at the 3 interior quarter knots)
  EXPECT_EQ(fine.n_control(1), 208 + 2 + 3);
  EXPECT_LT(max_map_difference(ellipse, fine), 1e-13 * size_of(ellipse));
  EXPECT_THROW(refine_uniform(ellipse, 1, 10), std::invalid_argument);  // not a multiple of 4
  EXPECT_THROW(refine_uniform(rectangle(1, 1, 4, 4, 2, {true, false}), 0, 8),
               std::invalid_argument);  // periodic
}

TEST(Refine, IsoparametricSubPatchMatchesParent) {
  const Patch ellipse = hollow_ellipse(2e-4, 1e-4, 5e-7, 16, 3, Vec3(0, 0, 0), 0.2);
  for (double r : {0.0, 0.5, 1.0}) {
    const Patch curve = isoparametric(ellipse, 0, r);
    ASSERT_EQ(curve.param_dim(), 1);
    EXPECT_TRUE(curve.closed(0));
    for (double t : {0.0, 0.11, 0.5, 0.93})
      EXPECT_LT((curve.point({t, 0, 0}) - ellipse.point({r, t, 0})).norm(), 1e-19);
  }
  const Patch shell = hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 4, 8, 2);
  const Patch mid = isoparametric(shell, 0, 0.5);
  ASSERT_EQ(mid.param_dim(), 2);
  EXPECT_LT((mid.point({0.3, 0.6, 0}) - shell.point({0.5, 0.3, 0.6})).norm(), 1e-18);
}
