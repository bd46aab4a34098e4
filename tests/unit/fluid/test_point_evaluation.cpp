// physical_point's fast path on axis-aligned affine patches (the paper's boxes) against its general path
// (rational basis, map, inverse Jacobian): the same functions, values, gradients, Laplacians, tau_M metric
// and Jacobian, at points inside elements, on their faces and across a periodic direction's wrap.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "fluid/point_evaluation.hpp"
#include "geometry/builders.hpp"

using namespace cellfsi;
using fluid::PhysicalPoint;
using geometry::Index3;
using geometry::Param;

namespace {

/// Both paths at (e, xi), compared entry by entry; values relative to the largest entry of their kind.
void expect_paths_agree(const geometry::Patch& patch, const geometry::AffineMap& map, const Index3& e,
                        const Param& xi, int order) {
  geometry::BasisValues bv;
  geometry::MapValues mv;
  PhysicalPoint slow, fast;
  fluid::physical_point(patch, e, xi, order, bv, mv, slow);
  fluid::physical_point(patch, e, xi, order, bv, mv, fast, &map);
  ASSERT_EQ(fast.n, slow.n);
  for (int d = 0; d < 3; ++d) EXPECT_EQ(fast.first[d], slow.first[d]);
  EXPECT_EQ(fast.index, slow.index);
  EXPECT_LE((fast.x - slow.x).norm(), 1e-14 * std::max(1.0, slow.x.norm()));
  EXPECT_NEAR(fast.detJ, slow.detJ, 1e-13 * slow.detJ);
  auto largest = [](const std::vector<double>& v) {
    double m = 0;
    for (double a : v) m = std::max(m, std::abs(a));
    return m;
  };
  const double n_max = largest(slow.N), dn_max = largest(slow.dN);
  for (int k = 0; k < slow.n; ++k) {
    EXPECT_NEAR(fast.N[k], slow.N[k], 1e-14 * n_max) << "function " << k;
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(fast.dN[3 * k + j], slow.dN[3 * k + j], 1e-12 * dn_max);
  }
  if (order < 2) return;
  ASSERT_EQ(fast.lapN.size(), slow.lapN.size());
  const double lap_max = largest(slow.lapN);
  ASSERT_GT(lap_max, 0.0);
  for (int k = 0; k < slow.n; ++k)
    EXPECT_NEAR(fast.lapN[k], slow.lapN[k], 1e-11 * lap_max) << "function " << k;
  const double g_max = std::max({slow.G[0][0], slow.G[1][1], slow.G[2][2]});
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(fast.G[i][j], slow.G[i][j], 1e-13 * g_max);
}

/// Points of element e at fractions t of its parametric extent (0 and 1: its faces).
Param at(const geometry::Patch& patch, const Index3& e, const double t[3]) {
  Param a, b, xi{0, 0, 0};
  patch.element_bounds(e, a, b);
  for (int d = 0; d < patch.param_dim(); ++d) xi[d] = a[d] + t[d] * (b[d] - a[d]);
  return xi;
}

}  // namespace

TEST(PhysicalPointAffine, AgreesWithTheGeneralPathOnAPeriodicBox) {
  // Quadratic and cubic, periodic in x and z like the paper's shear box, away from the origin, unequal sides.
  for (int degree : {2, 3}) {
    const geometry::Patch patch = geometry::box(1.2e-3, 0.8e-3, 1.0e-3, 5, 4, 6, degree, {true, false, true},
                                                geometry::Vec3(-3e-4, 2e-4, 1e-4));
    const auto map = geometry::affine_map(patch);
    ASSERT_TRUE(map.has_value());
    const double fractions[][3] = {
        {0.5, 0.5, 0.5}, {0.0, 0.0, 0.0}, {1.0, 1.0, 1.0}, {0.13, 0.71, 0.97}, {0.88, 0.02, 0.31}};
    for (const Index3& e : {Index3{0, 0, 0}, Index3{4, 3, 5}, Index3{2, 1, 3}, Index3{4, 0, 0}})
      for (const auto& t : fractions)
        for (int order : {1, 2}) expect_paths_agree(patch, *map, e, at(patch, e, t), order);
  }
}

TEST(PhysicalPointAffine, AgreesWithTheGeneralPathOnARectangle) {
  const geometry::Patch patch = geometry::rectangle(2.0, 0.5, 8, 3, 2, {true, false});
  const auto map = geometry::affine_map(patch);
  ASSERT_TRUE(map.has_value());
  const double fractions[][3] = {{0.5, 0.5, 0}, {0.0, 1.0, 0}, {1.0, 0.0, 0}, {0.37, 0.61, 0}};
  for (const Index3& e : {Index3{0, 0, 0}, Index3{7, 2, 0}, Index3{3, 1, 0}})
    for (const auto& t : fractions)
      for (int order : {1, 2}) expect_paths_agree(patch, *map, e, at(patch, e, t), order);
}

TEST(PhysicalPointAffine, APeriodicCoordinateBeyondThePeriodLandsInItsElement) {
  // The last element of a periodic direction, given the coordinate one period on (an unwrapped position):
  // the same functions as the wrapped coordinate, and x one period further along.
  const geometry::Patch patch = geometry::box(1.0, 1.0, 1.0, 4, 4, 4, 2, {true, false, false});
  const auto map = geometry::affine_map(patch);
  ASSERT_TRUE(map.has_value());
  const Index3 e{3, 1, 2};
  const double t[3] = {0.6, 0.4, 0.5};
  Param xi = at(patch, e, t);
  expect_paths_agree(patch, *map, e, xi, 2);
  geometry::BasisValues bv;
  geometry::MapValues mv;
  PhysicalPoint wrapped, unwrapped;
  fluid::physical_point(patch, e, xi, 2, bv, mv, wrapped, &*map);
  xi[0] += patch.knots(0).period();
  fluid::physical_point(patch, e, xi, 2, bv, mv, unwrapped, &*map);
  EXPECT_EQ(unwrapped.index, wrapped.index);
  for (int k = 0; k < wrapped.n; ++k) EXPECT_NEAR(unwrapped.N[k], wrapped.N[k], 1e-14);
  EXPECT_NEAR(unwrapped.x[0] - wrapped.x[0], 1.0, 1e-14);
}
