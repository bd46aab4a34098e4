// Measures against closed forms and the paper's values (Sec. 3.3 and 3.6, docs/design.md §3).
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <numbers>
#include <vector>

#include "geometry/builders.hpp"
#include "geometry/measures.hpp"
#include "geometry/quadrature.hpp"
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

// A membrane made of parts: one part gives the whole patch's measures; the red cell's six faces give the
// polar shell's (Evans-Fung: 134.09 um^2, 94.09 um^3) and its centroid and moments, about one reference
// point.
TEST(Measures, MembraneShapeOfPartsAddsThemAboutOnePoint) {
  const Patch shell = hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 16, 32, 2, Vec3(1e-3, 2e-3, 3e-3));
  const MembraneShape whole = membrane_shape(shell, 0, 3),
                      one = membrane_shape(std::vector<Patch>{shell}, 0, 3);
  EXPECT_LT(rel(one.enclosed, whole.enclosed), 1e-12);
  EXPECT_LT(rel(one.boundary, whole.boundary), 1e-12);
  EXPECT_LT((one.moments.centroid - whole.moments.centroid).norm(), 1e-12 * 3e-4);
  const double h = 3.1623e-5;
  const Vec3 c(6e-4, 6e-4, 6e-4);
  const MembraneShape faces = membrane_shape(biconcave_rbc_3d_faces(h, 8, 2, c), 0, 3);
  const MembraneShape polar = membrane_shape(biconcave_rbc_3d(h, 40, 80, 2, c), 0, 3);
  std::printf("  six faces: %.4f um^2, %.4f um^3; polar 1 x 40 x 80: %.4f um^2, %.4f um^3\n",
              faces.boundary * 1e8, faces.enclosed * 1e12, polar.boundary * 1e8, polar.enclosed * 1e12);
  EXPECT_NEAR(faces.boundary * 1e8, 134.09, 1e-3 * 134.09);
  EXPECT_NEAR(faces.enclosed * 1e12, 94.09, 1e-3 * 94.09);
  EXPECT_LT((faces.moments.centroid - c).norm(), 1e-6 * 3.91e-4);
  const PrincipalAxes pf = principal_axes(faces.moments, 3), pp = principal_axes(polar.moments, 3);
  for (int k = 0; k < 3; ++k) EXPECT_LT(rel(pf.values[k], pp.values[k]), 2e-3) << k;
  EXPECT_GT(std::abs(pf.axes(2, 2)), 1 - 1e-9);  // the short axis along the cell's axis (z)
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

namespace {
/// patch_measure and patch_moments the long way: Patch::basis and Patch::map at element_quadrature's points.
RegionMoments moments_by_patch_evaluation(const Patch& p, int extra_gauss, double& measure) {
  const int P = p.param_dim();
  std::vector<QuadraturePoint> qp;
  BasisValues bv;
  MapValues mv;
  Vec3 lo, hi;
  p.bounding_box(lo, hi);
  const Vec3 ref = 0.5 * (lo + hi);
  double M0 = 0;
  Vec3 M1 = Vec3::Zero();
  Mat3 M2 = Mat3::Zero();
  measure = 0;
  for (int e = 0; e < p.n_elements(); ++e) {
    const Index3 m = p.element_multi_index(e);
    element_quadrature(p, m, default_gauss(p, extra_gauss), qp);
    for (const QuadraturePoint& q : qp) {
      p.basis(q.xi, 1, bv, &m);
      p.map(bv, mv);
      const Eigen::MatrixXd J = mv.dx.leftCols(P);
      measure += q.weight * std::sqrt(std::abs((J.transpose() * J).determinant()));
      if (P != p.physical_dim()) continue;
      const double w = q.weight * std::abs(mv.dx.topLeftCorner(P, P).determinant());
      const Vec3 y = mv.x - ref;
      M0 += w, M1 += w * y, M2 += w * y * y.transpose();
    }
  }
  RegionMoments r;
  r.measure = M0;
  r.centroid = ref + M1 / M0;
  r.second_moment = M2 - M1 * M1.transpose() / M0;
  return r;
}

/// The patch with every control point moved by up to `amount` of its extent (a deformed body).
Patch perturbed(const Patch& p, double amount) {
  std::vector<Vec3> X = p.control_points();
  Vec3 lo, hi;
  p.bounding_box(lo, hi);
  const double size = (hi - lo).norm();
  for (size_t i = 0; i < X.size(); ++i)
    for (int c = 0; c < p.physical_dim(); ++c) X[i][c] += amount * size * std::sin(1.7 * i + 2.3 * c);
  return Patch(p.all_knots(), p.physical_dim(), X, p.weights(), p.shifts());
}
}  // namespace

TEST(Measures, TabulatedQuadratureAgreesWithPatchEvaluation) {
  // The measures form the basis per element from univariate tables; the same integrals from Patch::basis
  // and Patch::map point by point, on deformed rational bodies (3D shell and ball, a 2D ring, a surface in
  // 3D) and a periodic box, to round-off.
  const Vec3 c(6e-4, 5e-4, 4e-4);
  const std::vector<Patch> patches = {
      perturbed(hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-6, 6, 12, 2, c), 1e-3),
      perturbed(solid_ellipsoid(1e-4, 1e-4, 0.8e-4, 3, 4, 8, 2, c), 2e-3),
      perturbed(hollow_ellipse(2e-4, 1e-4, 5e-7, 32, 2, c), 1e-3),
      perturbed(box(1.0, 0.5, 0.7, 3, 2, 4, 3, {true, false, true}), 1e-2),
      isoparametric(perturbed(hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-6, 6, 12, 2, c), 1e-3), 0, 0.5)};
  for (size_t i = 0; i < patches.size(); ++i) {
    const Patch& p = patches[i];
    double measure = 0;
    const RegionMoments ref = moments_by_patch_evaluation(p, 2, measure);
    EXPECT_NEAR(patch_measure(p), measure, 1e-13 * measure) << "patch " << i;
    if (p.param_dim() != p.physical_dim()) continue;
    const RegionMoments r = patch_moments(p);
    EXPECT_NEAR(r.measure, ref.measure, 1e-13 * ref.measure) << "patch " << i;
    EXPECT_LT((r.centroid - ref.centroid).norm(), 1e-13 * c.norm()) << "patch " << i;
    EXPECT_LT((r.second_moment - ref.second_moment).norm(), 1e-11 * ref.second_moment.norm())
        << "patch " << i;
  }
}

TEST(Measures, SmallestElementExtentClosedFormAgreesWithTheEdges) {
  // The closed form (affine boxes, a refined knot vector so the spans differ) against the smallest of
  // element_extents; a curved patch takes the edges' way.
  auto by_edges = [](const Patch& p) {
    double smallest = 1e300;
    for (int e = 0; e < p.n_elements(); ++e) {
      const std::array<double, 3> ext = element_extents(p, e);
      for (int d = 0; d < p.param_dim(); ++d) smallest = std::min(smallest, ext[d]);
    }
    return smallest;
  };
  const Patch b = box(0.3, 0.8, 1.5, 3, 4, 5, 2, {true, false, true});
  EXPECT_NEAR(smallest_element_extent(b), 0.1, 1e-15);
  const Patch uniform = rectangle(1.0, 0.5, 4, 5, 2);
  const KnotVector& kv = uniform.knots(1);  // one span of the second direction split unevenly
  const Patch graded = insert_knots(uniform, 1, {kv.a() + 0.37 * (kv.b() - kv.a())});
  ASSERT_TRUE(affine_map(graded).has_value());
  EXPECT_NEAR(smallest_element_extent(graded), by_edges(graded), 1e-15);
  EXPECT_LT(smallest_element_extent(graded), 0.1 - 1e-3);
  const Patch curved = narrowing_channel(NarrowingChannel{}, 24, 6, 2);
  ASSERT_FALSE(affine_map(curved).has_value());
  EXPECT_EQ(smallest_element_extent(curved), by_edges(curved));
}

namespace {
// The Evans-Fung surface of revolution, independently of the builder: the profile c(t), t in [-pi/2, pi/2],
// (rho, z) = (R0 cos t, 1/2 sin t (C0 + C2 cos^2 t + C4 cos^4 t)) revolved about z.
struct EvansFungIntegrals {
  double area = 0, volume = 0, volume_closed_form = 0;
};
EvansFungIntegrals evans_fung_integrals(const EvansFung& s, int pieces) {
  auto rho = [&](double t) { return s.R0 * std::cos(t); };
  auto dz = [&](double t) {  // dz/dt
    const double c = std::cos(t), sn = std::sin(t), c2 = c * c;
    return 0.5 * (c * (s.C0 + s.C2 * c2 + s.C4 * c2 * c2) - 2 * sn * sn * c * (s.C2 + 2 * s.C4 * c2));
  };
  auto drho = [&](double t) { return -s.R0 * std::sin(t); };
  EvansFungIntegrals r;
  // Area 2 pi int rho |c'| dt; volume pi int rho^2 dz (the profile and the axis bound the half-section).
  r.area = cellfsi::geometry::testing::gauss_integral(
      [&](double t) { return 2 * pi * rho(t) * std::hypot(drho(t), dz(t)); }, -pi / 2, pi / 2, pieces);
  r.volume = cellfsi::geometry::testing::gauss_integral(
      [&](double t) { return pi * rho(t) * rho(t) * dz(t); }, -pi / 2, pi / 2, pieces);
  // 2 int_0^R0 2 pi r z(r) dr with z(r) = 1/2 sqrt(1 - x^2)(C0 + C2 x^2 + C4 x^4), x = r/R0:
  // int_0^1 x sqrt(1 - x^2) x^(2k) dx = 1/3, 2/15, 8/105 for k = 0, 1, 2.
  r.volume_closed_form = 2 * pi * s.R0 * s.R0 * (s.C0 / 3 + 2 * s.C2 / 15 + 8 * s.C4 / 105);
  return r;
}
}  // namespace

TEST(Measures, EvansFungIntegralsAreConverged) {
  const EvansFung ef;
  const EvansFungIntegrals a = evans_fung_integrals(ef, 64), b = evans_fung_integrals(ef, 128);
  EXPECT_LT(rel(a.area, b.area), 1e-14);
  EXPECT_LT(rel(b.volume, b.volume_closed_form), 1e-13);
  // The round values: about 135 um^2 and 94 um^3 (1 um = 1e-4 cm).
  EXPECT_NEAR(b.area * 1e8, 135.0, 1.0);
  EXPECT_NEAR(b.volume * 1e12, 94.0, 0.5);
  std::printf("  Evans-Fung: area %.12g um^2, volume %.12g um^3\n", b.area * 1e8, b.volume * 1e12);
}

TEST(Measures, Rbc3dMidSurfaceConvergesToEvansFungIntegrals) {
  // The mid-surface's area and enclosed volume against the integrals, as the profile is refined (p = 2 and
  // 3, 8 to 64 elements from pole to pole). Measured: both errors fall by about 16 per halving from 16
  // elements on (rate 4: p + 2 for p = 2, p + 1 for p = 3); at 64, 3.2e-7 / 6.4e-7 (p = 2) and 1.4e-7 /
  // 2.4e-7 (p = 3).
  const EvansFung ef;
  const EvansFungIntegrals exact = evans_fung_integrals(ef, 128);
  for (int p : {2, 3}) {
    std::array<double, 4> ea{}, ev{};
    const std::array<int, 4> n_polar{8, 16, 32, 64};
    for (int k = 0; k < 4; ++k) {
      // The revolution is exact: few elements around, enough Gauss points for the rational arcs.
      const MembraneShape s = membrane_shape(biconcave_rbc_3d(1e-6, n_polar[k], 8, p), 0, 6);
      ea[k] = rel(s.boundary, exact.area);
      ev[k] = rel(s.enclosed, exact.volume);
      std::printf("  p=%d n_polar=%2d: area error %.3e, volume error %.3e\n", p, n_polar[k], ea[k], ev[k]);
    }
    for (int k = 1; k < 3; ++k) {
      EXPECT_GT(std::log2(ea[k] / ea[k + 1]), 3.4) << "p=" << p << " area, n_polar " << n_polar[k + 1];
      EXPECT_GT(std::log2(ev[k] / ev[k + 1]), 3.4) << "p=" << p << " volume, n_polar " << n_polar[k + 1];
    }
    EXPECT_LT(ea[3], 5e-7) << "p=" << p;
    EXPECT_LT(ev[3], 1e-6) << "p=" << p;
  }
  // Around, the surface is exact: more elements there change the measures only by the rational arcs'
  // quadrature.
  const MembraneShape coarse = membrane_shape(biconcave_rbc_3d(1e-6, 16, 8, 2), 0, 6),
                      fine = membrane_shape(biconcave_rbc_3d(1e-6, 16, 32, 2), 0, 6);
  EXPECT_LT(rel(coarse.boundary, fine.boundary), 1e-12);
  EXPECT_LT(rel(coarse.enclosed, fine.enclosed), 1e-12);
}

TEST(Measures, SharesOfAPatchsElementsAddUpToTheWhole) {
  // The bodies' metrics split among ranks: each share's partial integrals, added, are the whole patch's,
  // and finish() of the added raw moments its moments. The sums differ only in their order: 1e-13 relative.
  const Patch shell = hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 6, 12, 2);
  const Patch mid = isoparametric(shell, 0, 0.5);
  const Patch ball = solid_ellipsoid(2e-4, 1.5e-4, 1e-4, 2, 6, 12, 2);
  const double whole_band = patch_measure(shell), whole_mid = patch_measure(mid);
  const RegionMoments enclosed = enclosed_moments(mid), own = patch_moments(ball);
  for (int parts : {1, 2, 3, 1000}) {  // 1000: more parts than elements (some shares are empty)
    double band = 0, surface = 0;
    MomentSums e_sum, o_sum;
    for (int part = 0; part < parts; ++part) {
      const ElementShare share{part, parts};
      band += patch_measure(shell, 2, share);
      surface += patch_measure(mid, 2, share);
      const MomentSums e = enclosed_moment_sums(mid, 2, share), o = patch_moment_sums(ball, 2, share);
      e_sum.ref = e.ref, o_sum.ref = o.ref;
      e_sum.m0 += e.m0, e_sum.m1 += e.m1, e_sum.m2 += e.m2;
      o_sum.m0 += o.m0, o_sum.m1 += o.m1, o_sum.m2 += o.m2;
    }
    EXPECT_NEAR(band, whole_band, 1e-13 * whole_band) << parts;
    EXPECT_NEAR(surface, whole_mid, 1e-13 * whole_mid) << parts;
    for (const auto& [sum, whole] : {std::pair{finish(e_sum), enclosed}, std::pair{finish(o_sum), own}}) {
      EXPECT_NEAR(sum.measure, whole.measure, 1e-13 * whole.measure) << parts;
      EXPECT_LE((sum.centroid - whole.centroid).norm(), 1e-13 * 3e-4) << parts;
      EXPECT_LE((sum.second_moment - whole.second_moment).norm(), 1e-12 * whole.second_moment.norm())
          << parts;
    }
  }
  // The shares' operation estimates (-log_view's counts) add up to the whole's and are shared out alike.
  double whole_ops = 0, ops[3] = {0, 0, 0};
  patch_measure(shell, 2, ElementShare{0, 1, &whole_ops});
  for (int part = 0; part < 3; ++part) patch_measure(shell, 2, ElementShare{part, 3, &ops[part]});
  EXPECT_GT(whole_ops, 0.0);
  EXPECT_NEAR(ops[0] + ops[1] + ops[2], whole_ops, 1e-12 * whole_ops);
  for (double o : ops) EXPECT_NEAR(o, whole_ops / 3, 0.1 * whole_ops / 3);
  EXPECT_THROW(patch_measure(shell, 2, ElementShare{2, 2}), std::invalid_argument);
  EXPECT_THROW(patch_measure(shell, 2, ElementShare{0, 0}), std::invalid_argument);
}
