// Measures against closed forms and the paper's values (Sec. 3.3 and 3.6, docs/design.md §3).
#include <gtest/gtest.h>

#include <array>
#include <numbers>

#include "geometry/builders.hpp"
#include "geometry/measures.hpp"
#include "geometry/refine.hpp"
#include "test_support.hpp"

using namespace cellfsi::geometry;
using cellfsi::geometry::testing::ellipse_perimeter;
using cellfsi::geometry::testing::prolate_area;
using cellfsi::geometry::testing::rel;
constexpr double pi = std::numbers::pi;

TEST(Measures, CircleAreaAndPerimeterMatchClosedForms) {
  const double r = 1.5e-4;
  const Patch mid = isoparametric(hollow_ellipse(r, r, 1e-6, 64, 2), 0, 0.5);
  const RegionMoments m = enclosed_moments(mid);
  EXPECT_LT(rel(m.measure, pi * r * r), 1e-10);
  EXPECT_LT(rel(patch_measure(mid), 2 * pi * r), 1e-10);
}

TEST(Measures, EllipseAreaPerimeterAndMomentsMatchClosedForms) {
  const double a = 2e-4, b = 1e-4, angle = 0.4;
  const Vec3 c(1.2e-3, 6e-4, 0);
  const Patch mid = isoparametric(hollow_ellipse(a, b, 5e-7, 64, 2, c, angle), 0, 0.5);
  const RegionMoments m = enclosed_moments(mid);
  EXPECT_LT(rel(m.measure, pi * a * b), 1e-10);
  EXPECT_LT(rel(patch_measure(mid), ellipse_perimeter(a, b)), 1e-10);
  EXPECT_LT((m.centroid - c).norm(), 1e-10 * a);
  // Central second moments of an ellipse: pi a^3 b / 4 along the long axis, pi a b^3 / 4 across.
  const PrincipalAxes pa = principal_axes(m, 2);
  EXPECT_LT(rel(pa.values[0], pi * a * a * a * b / 4), 1e-10);
  EXPECT_LT(rel(pa.values[1], pi * a * b * b * b / 4), 1e-10);
  EXPECT_NEAR(long_axis_angle(m), angle, 1e-10);
}

TEST(Measures, PaperCapsuleSwellingDegreeAndEffectiveRadius) {
  // Paper Sec. 3.3: a = 2e-4 cm, b = 1e-4 cm gives Delta_m = 0.841 and R_0 = 1.542e-4 cm (values rounded).
  const MembraneShape s = membrane_shape(hollow_ellipse(2e-4, 1e-4, 5e-7, 208, 2));
  EXPECT_NEAR(s.swelling, 0.841, 5e-4);
  EXPECT_NEAR(s.effective_radius, 1.542e-4, 5e-8);
  // And to 1e-10 against the closed forms of the mid-line ellipse.
  const double P = ellipse_perimeter(2e-4, 1e-4), A = pi * 2e-8;
  EXPECT_LT(rel(s.swelling, 4 * pi * A / (P * P)), 1e-10);
  EXPECT_LT(rel(s.effective_radius, P / (2 * pi)), 1e-10);
}

TEST(Measures, PaperEllipsoidShellSwellingDegreeAndEffectiveRadius) {
  // Paper Sec. 3.6: semi-axes 3e-4, 2e-4, 2e-4 cm give Delta_m = 0.960 and R_0 = 2.32e-4 cm.
  const double a = 3e-4, b = 2e-4;
  const MembraneShape s = membrane_shape(hollow_ellipsoid(a, b, b, 5e-7, 16, 32, 2), 0, 3);
  EXPECT_NEAR(s.swelling, 0.960, 5e-4);
  EXPECT_NEAR(s.effective_radius, 2.32e-4, 5e-7);
  EXPECT_LT(rel(s.enclosed, 4.0 / 3.0 * pi * a * b * b), 1e-10);
  EXPECT_LT(rel(s.boundary, prolate_area(a, b)), 1e-10);
  EXPECT_LT(s.moments.centroid.norm(), 1e-10 * a);
}

TEST(Measures, BulkyEllipseAndSphereRegions) {
  const double a = 7e-5, b = 4e-5;
  const RegionMoments disk = patch_moments(bulky_ellipse(a, b, 8, 32, 2, Vec3(1e-4, 2e-4, 0), 1.0));
  EXPECT_LT(rel(disk.measure, pi * a * b), 1e-10);
  EXPECT_LT((disk.centroid - Vec3(1e-4, 2e-4, 0)).norm(), 1e-10 * a);
  EXPECT_NEAR(long_axis_angle(disk), 1.0, 1e-10);
  const double r = 1e-4;
  const RegionMoments ball = patch_moments(solid_ellipsoid(r, r, r, 2, 8, 16, 2), 3);
  EXPECT_LT(rel(ball.measure, 4.0 / 3.0 * pi * r * r * r), 1e-10);
  // Central second moment of a ball: (4/15) pi r^5 along every axis.
  for (int i = 0; i < 3; ++i)
    EXPECT_LT(rel(ball.second_moment(i, i), 4.0 / 15.0 * pi * std::pow(r, 5)), 1e-9);
}

TEST(Measures, MembraneBandAreaIsPerimeterTimesThickness) {
  // The membrane's own area (Eq. 21 integrates over the solid) is the difference of the two ellipses' areas.
  const double a = 2e-4, b = 1e-4, h = 5e-7;
  const double band = pi * ((a + h / 2) * (b + h / 2) - (a - h / 2) * (b - h / 2));
  EXPECT_LT(rel(patch_moments(hollow_ellipse(a, b, h, 64, 2)).measure, band), 1e-9);
}

TEST(Measures, RbcEnclosesThePrescribedArea) {
  const Patch rbc = biconcave_rbc(5e-7, 64, 2);
  const MembraneShape s = membrane_shape(rbc);
  EXPECT_LT(rel(s.enclosed, 1.2868e-7), 1e-10);
  // Biconcave: long axis along x for angle 0, and not convex: area well below the disc of the same perimeter.
  EXPECT_NEAR(long_axis_angle(s.moments), 0.0, 1e-10);
  EXPECT_LT(s.swelling, 0.75);
}

TEST(Measures, RbcMidlineConvergesToEvansFungProfile) {
  // Unscaled (target = exact Evans-Fung area): the interpolated mid-line approaches the profile at rate ~p+1.
  const EvansFung ef;
  auto error = [&](int n, int p) {
    const Patch mid = isoparametric(biconcave_rbc(1e-7, n, p, Vec3::Zero(), 0.0, ef.area()), 0, 0.5);
    double worst = 0;
    for (int s = 0; s < 997; ++s) {
      const double u = (s + 0.5) / 997;
      worst = std::max(worst, (mid.point({u, 0, 0}) - ef.point(2 * pi * u)).norm());
    }
    return worst / ef.R0;
  };
  for (int p : {2, 3}) {
    const double e1 = error(32, p), e2 = error(64, p), e3 = error(128, p);
    const double rate = std::log2(e2 / e3);
    EXPECT_GT(rate, p + 0.5) << "p=" << p << " errors " << e1 << " " << e2 << " " << e3;
    EXPECT_LT(e3, 1e-5) << "p=" << p;
  }
}

TEST(Measures, NarrowingChannelAreaIsExact) {
  // The L2 projection of the wall offset preserves its mean, so the channel area is exact.
  const NarrowingChannel ch;
  double integral = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {  // midpoint rule on a C-infinity periodic function: spectrally accurate
    integral += ch.wall_offset((i + 0.5) * ch.length / n) * ch.length / n;
  }
  const double exact = ch.length * ch.height - 2 * integral;
  EXPECT_LT(rel(patch_measure(narrowing_channel(ch, 96, 16, 3)), exact), 1e-12);
}

TEST(Measures, SwellingDegreeAndRadiusFormulas) {
  EXPECT_NEAR(swelling_degree(pi, 2 * pi, 2), 1.0, 1e-15);
  EXPECT_NEAR(swelling_degree(4.0 / 3.0 * pi, 4 * pi, 3), 1.0, 1e-15);
  EXPECT_NEAR(effective_radius(2 * pi * 3, 2), 3.0, 1e-15);
  EXPECT_NEAR(effective_radius(4 * pi * 9, 3), 3.0, 1e-15);
}

TEST(Measures, ElementExtentsOfAUniformBoxAreItsElementSizes) {
  // 3 x 4 x 5 elements of a 0.3 x 0.8 x 1.5 box: every element is 0.1 x 0.2 x 0.3 (the map is affine).
  const Patch b = box(0.3, 0.8, 1.5, 3, 4, 5, 2);
  for (int e = 0; e < b.n_elements(); ++e) {
    const std::array<double, 3> ext = element_extents(b, e);
    EXPECT_NEAR(ext[0], 0.1, 1e-14);
    EXPECT_NEAR(ext[1], 0.2, 1e-14);
    EXPECT_NEAR(ext[2], 0.3, 1e-14);
  }
  // A 2D patch: the third entry is zero.
  const std::array<double, 3> ext = element_extents(rectangle(1.0, 0.5, 4, 5, 3), 7);
  EXPECT_NEAR(ext[0], 0.25, 1e-14);
  EXPECT_NEAR(ext[1], 0.1, 1e-14);
  EXPECT_EQ(ext[2], 0.0);
}
