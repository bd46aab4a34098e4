// The locator (closed form on affine patches; CGAL AABB tree + NURBS inversion otherwise) and s^h marking.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include "coupling/interface_marking.hpp"
#include "coupling/locator.hpp"
#include "geometry/builders.hpp"
#include "geometry/inversion.hpp"
#include "geometry/refine.hpp"

using namespace cellfsi;
using geometry::Vec3;

TEST(Locator, FindsRandomPointsInTheNarrowingChannel) {
  const geometry::NarrowingChannel ch;
  const geometry::Patch channel = geometry::narrowing_channel(ch, 96, 32, 3);
  const coupling::Locator loc(channel);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  size_t max_candidates = 0;
  for (int i = 0; i < 500; ++i) {
    const geometry::Param xi{U(rng), U(rng), 0};
    const Vec3 x = channel.point(xi);
    const coupling::Location l = loc.locate(x);
    ASSERT_TRUE(l.found);
    EXPECT_LT(std::abs(l.xi[0] - xi[0]) + std::abs(l.xi[1] - xi[1]), 1e-12);
    EXPECT_EQ(l.element, channel.find_element(xi));
    max_candidates = std::max(max_candidates, loc.candidates(x).size());
    // A periodic image is the same point.
    const coupling::Location li = loc.locate(x + Vec3(ch.length, 0, 0));
    ASSERT_TRUE(li.found);
    EXPECT_LT(std::abs(li.xi[0] - xi[0]), 1e-12);
  }
  std::printf("  at most %zu candidate boxes of %d elements\n", max_candidates, channel.n_elements());
  // The tree narrows 3072 elements down to a handful of boxes (control-point boxes overlap their
  // neighbours').
  EXPECT_LE(max_candidates, 30u);
  EXPECT_GE(max_candidates, 1u);
}

TEST(Locator, WarmStartAndOutsidePoints) {
  const geometry::Patch box = geometry::rectangle(0.0024, 0.0012, 64, 32, 3, {true, false});
  const coupling::Locator loc(box);
  const coupling::Location a = loc.locate(Vec3(0.001, 0.0005, 0));
  ASSERT_TRUE(a.found);
  const coupling::Location b = loc.locate(Vec3(0.0010004, 0.0005001, 0), &a);
  ASSERT_TRUE(b.found);
  EXPECT_NEAR(b.xi[0], 0.0010004 / 0.0024, 1e-12);
  EXPECT_FALSE(loc.locate(Vec3(0.001, 0.0013, 0)).found);
  try {
    loc.locate_or_throw(Vec3(0.001, 0.0013, 0));
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("left the fluid domain"), std::string::npos) << e.what();
  }
}

namespace {

/// Locates x by the closed form and by inversion and checks that they agree: both found or both not; xi to
/// 1e-14 of the parameter range (modulo the period in a periodic direction), inside the element returned; the
/// same element, or, within 1e-12 of an element boundary, a neighbour (both contain the point). Returns the
/// largest |xi difference| / range. `previous` warm-starts the inversion.
double expect_same_location(const coupling::Locator& closed, const coupling::Locator& inverted, const Vec3& x,
                            const coupling::Location* previous = nullptr) {
  const geometry::Patch& patch = closed.patch();
  const coupling::Location a = closed.locate(x), b = inverted.locate(x, previous);
  EXPECT_EQ(a.found, b.found) << "x = " << x.transpose();
  if (!a.found || !b.found) return 0;
  double worst = 0;
  for (int d = 0; d < patch.param_dim(); ++d) {
    const geometry::KnotVector& kv = patch.knots(d);
    double dxi = a.xi[d] - b.xi[d];
    if (kv.periodic()) dxi -= std::round(dxi / kv.period()) * kv.period();
    worst = std::max(worst, std::abs(dxi) / (kv.b() - kv.a()));
    EXPECT_LE(std::abs(dxi), 1e-14 * (kv.b() - kv.a())) << "direction " << d << ", x = " << x.transpose();
    const double lo = kv.element_begin(a.element[d]), hi = kv.element_end(a.element[d]);
    EXPECT_TRUE(lo <= a.xi[d] && a.xi[d] <= hi)
        << "xi " << a.xi[d] << " outside its element [" << lo << ", " << hi << "]";
    if (a.element[d] != b.element[d]) {
      const double gap = std::min(a.xi[d] - lo, hi - a.xi[d]);
      EXPECT_LE(gap, 1e-12 * (kv.b() - kv.a()))
          << "elements " << a.element[d] << " and " << b.element[d] << " in direction " << d
          << " for a point not on their boundary, x = " << x.transpose();
    }
  }
  return worst;
}

/// Compares the closed form with inversion on random points of the patch (and their periodic images), points
/// on element boundaries, points within round-off outside each non-periodic face (found, on the face, as by
/// the inversion) and points clearly outside (refused by both). Outside points are compared with the
/// inversion warm-started from the face (as the coupler locates its points): cold, the general path does not
/// even try a point beyond its AABB tree's padding of 1e-12 of the diagonal, though the inversion itself
/// accepts 1e-10.
void compare_with_inversion(const geometry::Patch& patch, unsigned seed) {
  const coupling::Locator closed(patch), inverted(patch, coupling::LocatorMethod::inversion);
  ASSERT_TRUE(closed.closed_form());
  ASSERT_FALSE(inverted.closed_form());
  const int P = patch.param_dim();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::uniform_int_distribution<int> image(-2, 2);
  Vec3 lo, hi;
  patch.bounding_box(lo, hi);
  const double diagonal = (hi - lo).norm();
  auto random_xi = [&] {
    geometry::Param xi{0, 0, 0};
    for (int d = 0; d < P; ++d)
      xi[d] = patch.knots(d).a() + U(rng) * (patch.knots(d).b() - patch.knots(d).a());
    return xi;
  };
  auto with_images = [&](Vec3 x) {
    for (int d = 0; d < P; ++d)
      if (patch.knots(d).periodic()) x += image(rng) * patch.shift(d);
    return x;
  };
  double worst = 0;
  int n_outside = 0, n_found = 0;
  auto check = [&](const Vec3& x, const coupling::Location* previous = nullptr) {
    worst = std::max(worst, expect_same_location(closed, inverted, x, previous));
    n_found += closed.locate(x).found;
  };
  for (int i = 0; i < 300; ++i) check(with_images(patch.point(random_xi())));
  // On element boundaries (knots), in every direction at once and one at a time.
  for (int i = 0; i < 100; ++i) {
    geometry::Param xi = random_xi();
    for (int d = 0; d < P; ++d)
      if (i % (P + 1) == 0 || i % (P + 1) == d + 1) {
        const std::vector<double> bp = patch.knots(d).breakpoints();
        xi[d] = bp[rng() % bp.size()];
      }
    check(with_images(patch.point(xi)));
  }
  // Just outside each open face: 1e-11 of the diagonal is within the inverter's inside tolerance (1e-10),
  // 1e-9 and 1e-6 are not.
  for (int d = 0; d < P; ++d) {
    if (patch.knots(d).periodic()) continue;
    for (const double side : {0.0, 1.0})
      for (const double out : {0.0, 1e-11, 1e-9, 1e-6})
        for (int i = 0; i < 10; ++i) {
          geometry::Param xi = random_xi();
          xi[d] = side == 0 ? patch.knots(d).a() : patch.knots(d).b();
          Vec3 x = patch.point(xi);
          const coupling::Location on_face = inverted.locate(x);
          EXPECT_TRUE(on_face.found);
          const Vec3 normal = (patch.point(xi) - patch.point(random_xi())).cwiseProduct(Vec3::Unit(d));
          x += out * diagonal * normal.normalized();
          const bool should_find = out <= 1e-11;
          EXPECT_EQ(closed.locate(x).found, should_find) << "outside by " << out << " of the diagonal";
          n_outside += !should_find;
          check(with_images(x), &on_face);
        }
  }
  std::printf("  %d elements, degree %d: %d points found, %d outside refused, largest |xi difference| %.1e\n",
              patch.n_elements(), patch.degree(0), n_found, n_outside, worst);
}

}  // namespace

TEST(Locator, ClosedFormAgreesWithInversionIn2dAnd3dShearBoxesAndAChannel) {
  // The paper's 2D shear box (64 x 32 cubic), the 3D one (periodic in x and z, quadratic), a straight channel
  // away from the origin, a box with walls all round, and non-uniform knots (control points still at the
  // Greville abscissae, so the map is still affine).
  compare_with_inversion(geometry::rectangle(0.0024, 0.0012, 64, 32, 3, {true, false}), 1);
  compare_with_inversion(geometry::box(0.0012, 0.0012, 0.0012, 12, 12, 12, 2, {true, false, true}), 2);
  compare_with_inversion(geometry::rectangle(0.003, 0.001, 96, 32, 3, {true, false}, Vec3(0.003, -0.0005, 0)),
                         3);
  compare_with_inversion(
      geometry::box(0.0012, 0.0009, 0.0006, 8, 6, 5, 3, {false, false, false}, Vec3(-1e-4, 2e-4, 3e-4)), 4);
  compare_with_inversion(geometry::insert_knots(geometry::rectangle(0.0024, 0.0012, 16, 8, 2, {true, false}),
                                                1, {0.01, 0.01, 0.37}),
                         5);
}

TEST(Locator, APointOnAnElementBoundaryGoesToTheLowerElement) {
  // The 3D scene's bodies are centred on the mid-plane knot z = 0.0006 and have points on it, and the s^h
  // marking depends on the element such a point is given. The inversion gives the lower element there (its
  // candidates tie; which comes first is settled by round-off, and elsewhere it can be the upper one, as at
  // z = 0.0009 below); the closed form always gives the lower one, so that the scene's results do not change.
  const geometry::Patch cube = geometry::box(0.0012, 0.0012, 0.0012, 32, 32, 32, 2, {true, false, true});
  const coupling::Locator closed(cube), inverted(cube, coupling::LocatorMethod::inversion);
  const Vec3 centre(0.0006, 0.0006, 0.0006);
  for (const Vec3& x : {centre, Vec3(0.00041, 0.0006, 0.000777), Vec3(0.0006, 0.0003, 0.0009)}) {
    const coupling::Location a = closed.locate(x), b = inverted.locate(x);
    ASSERT_TRUE(a.found && b.found);
    for (int d = 0; d < 3; ++d) {
      const double u = x[d] / 0.0012;
      if (u * 32 != std::round(u * 32)) continue;  // not on a knot in this direction
      EXPECT_EQ(a.element[d], static_cast<int>(std::round(u * 32)) - 1) << "direction " << d;
      EXPECT_EQ(a.xi[d], u);
      if (x == centre) {
        EXPECT_EQ(a.element[d], b.element[d]) << "direction " << d;
      }
    }
  }
}

TEST(Locator, NarrowingChannelTakesTheInversion) {
  const geometry::Patch channel = geometry::narrowing_channel(geometry::NarrowingChannel{}, 96, 32, 3);
  EXPECT_FALSE(geometry::affine_map(channel).has_value());
  EXPECT_FALSE(coupling::Locator(channel).closed_form());
  // A rotated box is not affine along the axes either.
  const geometry::Mat3 rotation = Eigen::AngleAxisd(0.2, Vec3::UnitZ()).toRotationMatrix();
  const geometry::Patch rotated =
      geometry::transformed(geometry::rectangle(0.0024, 0.0012, 16, 8, 2), rotation, Vec3::Zero());
  const coupling::Locator loc(rotated);
  EXPECT_FALSE(loc.closed_form());
  const coupling::Location l = loc.locate(rotated.point({0.3, 0.6, 0}));
  ASSERT_TRUE(l.found);
  EXPECT_NEAR(l.xi[0], 0.3, 1e-12);
  EXPECT_NEAR(l.xi[1], 0.6, 1e-12);
}

TEST(Locator, ClosedFormIsFasterInTheCube) {
  // Informative: the cost per point at the paper's 3D resolution (32^3 quadratic), cold and warm-started.
  const geometry::Patch cube = geometry::box(0.0012, 0.0012, 0.0012, 32, 32, 32, 2, {true, false, true});
  const coupling::Locator closed(cube), inverted(cube, coupling::LocatorMethod::inversion);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(0.0, 0.0012);
  std::vector<Vec3> pts(2000);
  for (Vec3& x : pts) x = Vec3(U(rng), U(rng), U(rng));
  auto time_per_point = [&](const coupling::Locator& loc, bool warm) {
    std::vector<coupling::Location> prev(pts.size());
    if (warm)
      for (size_t i = 0; i < pts.size(); ++i) prev[i] = loc.locate(pts[i]);
    const auto t0 = std::chrono::steady_clock::now();
    int found = 0;
    for (size_t i = 0; i < pts.size(); ++i) found += loc.locate(pts[i] + Vec3(1e-8, 0, 0), &prev[i]).found;
    EXPECT_EQ(found, static_cast<int>(pts.size()));
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / pts.size();
  };
  std::printf("  per point: closed form %.2e s; inversion cold %.2e s, warm %.2e s\n",
              time_per_point(closed, false), time_per_point(inverted, false), time_per_point(inverted, true));
}

namespace {

/// 512 points on both faces of the paper's capsule (Sec. 3.3) at the centre of its box, long axis across the
/// flow.
std::vector<Vec3> capsule_interface_points() {
  const geometry::Patch membrane =
      geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 64, 2, Vec3(0.0012, 0.0006, 0), std::numbers::pi / 2);
  std::vector<Vec3> pts;
  for (int k = 0; k < 256; ++k)
    for (double r : {0.0, 1.0}) pts.push_back(membrane.point({r, (k + 0.5) / 256, 0}));
  return pts;
}

}  // namespace

TEST(InterfaceMarking, MarksTheFunctionsAroundAMembrane) {
  // The paper's capsule in the paper's box at 64 x 32 cubic: the marked functions are those of the elements
  // the membrane crosses; a band a few functions wide, never the walls' far side.
  const geometry::Patch box = geometry::rectangle(0.0024, 0.0012, 64, 32, 3, {true, false});
  const coupling::Locator loc(box);
  const std::vector<Vec3> pts = capsule_interface_points();
  const std::vector<int> marked = coupling::functions_near(loc, pts);
  // Every marked function's control point lies within (p + 1) elements of the membrane: h = 3.75e-5 cm.
  const double h = 0.0024 / 64;
  for (int k : marked) {
    const Vec3 X = box.control_points()[k];
    double dmin = 1e300;
    for (const Vec3& p : pts) dmin = std::min(dmin, (X - p).norm());
    EXPECT_LT(dmin, 4 * h * std::sqrt(2.0)) << "function " << k;
  }
  std::printf("  %zu functions marked\n", marked.size());
  // ... and every point has all the functions of its element marked: at least (p+1)^2 = 16, in total a band.
  EXPECT_GT(marked.size(), 100u);
  EXPECT_LT(marked.size(),
            200u);  // measured 120: the membrane crosses ~26 elements, a band ~p+1 functions wide
  const std::vector<double> s = coupling::scaling_values(box.n_control(), marked, 1e10);
  EXPECT_EQ(std::count(s.begin(), s.end(), 1e10), static_cast<long>(marked.size()));
  EXPECT_THROW(coupling::scaling_values(box.n_control(), marked, 0.5), std::invalid_argument);
}

TEST(InterfaceMarking, CentralMarkingKeepsTheFunctionsCentredOnTheMembrane) {
  // Marking::central keeps, of the 4 x 4 cubic functions of an element the membrane crosses, the 2 x 2 for
  // which that element is an inner element of their support: their control points (the Greville points, the
  // centres of their supports) are corners of the element, within h sqrt(2) of the membrane, where the
  // support marking reaches 2 h sqrt(2). A subset of the support marking, about half as many.
  const geometry::Patch box = geometry::rectangle(0.0024, 0.0012, 64, 32, 3, {true, false});
  const coupling::Locator loc(box);
  const std::vector<Vec3> pts = capsule_interface_points();
  const std::vector<int> support = coupling::functions_near(loc, pts, coupling::Marking::support);
  const std::vector<int> central = coupling::functions_near(loc, pts, coupling::Marking::central);
  const double h = 0.0024 / 64;
  double reach_support = 0, reach_central = 0;
  for (const auto& [marked, reach] :
       {std::pair{&support, &reach_support}, std::pair{&central, &reach_central}})
    for (int k : *marked) {
      const Vec3 X = box.control_points()[k];
      double dmin = 1e300;
      for (const Vec3& p : pts) dmin = std::min(dmin, (X - p).norm());
      *reach = std::max(*reach, dmin);
    }
  std::printf("  support: %zu functions, reach %.2f h; central: %zu functions, reach %.2f h\n",
              support.size(), reach_support / h, central.size(), reach_central / h);
  EXPECT_TRUE(std::includes(support.begin(), support.end(), central.begin(), central.end()));
  EXPECT_LE(reach_central, h * std::sqrt(2.0) * (1 + 1e-12));
  EXPECT_GT(reach_support, 1.5 * h * std::sqrt(2.0));
  EXPECT_LT(central.size(), support.size() * 2 / 3);
  // s^h at every interface point stays of the order of s_I: per direction the kept functions sum to at least
  // 1/2 (quadratics: the one centred on the element, 1/2 ... 3/4 there) or 5/6 (cubics: 1 - ((1-u)^3 + u^3) /
  // 6).
  for (const int p : {2, 3}) {
    const geometry::Patch bp = geometry::rectangle(0.0024, 0.0012, 64, 32, p, {true, false});
    const coupling::Locator bl(bp);
    const double sI = 1e10;
    const std::vector<double> sv = coupling::scaling_values(
        bp.n_control(), coupling::functions_near(bl, pts, coupling::Marking::central), sI);
    const double bound = p == 2 ? 0.25 : 25.0 / 36.0;
    double smin = 1e300;
    geometry::BasisValues bv;
    for (const Vec3& x : pts) {
      const coupling::Location l = bl.locate_or_throw(x);
      bp.basis(l.xi, 0, bv, &l.element);
      double sh = 0;
      for (int k = 0; k < bv.n; ++k) sh += bv.value[k] * sv[bv.index[k]];
      smin = std::min(smin, sh);
    }
    std::printf("  p = %d: smallest s^h on the membrane %.4f s_I (bound %.4f)\n", p, smin / sI, bound);
    EXPECT_GE(smin, bound * sI * (1 - 1e-12)) << "p = " << p;
  }
  // Every point keeps marked functions around it: its element's 4 corners.
  for (const Vec3& p : pts) {
    const std::vector<int> own = coupling::functions_near(loc, {p}, coupling::Marking::central);
    EXPECT_EQ(own.size(), 4u);
    EXPECT_TRUE(std::includes(central.begin(), central.end(), own.begin(), own.end()));
  }
}

TEST(InterfaceMarking, AutomaticScalingOnTheCapsuleMeshes) {
  // -s_interface auto on the capsule's box (0.0024 cm wide) at 128 x 64 and 256 x 128, cubic, central
  // marking, for |r_A| <= 1e-3: s_I = 6.25e10 (5e-5 cm / 5 h)^2.8 (docs/validation.md, "The automatic s_I").
  const auto automatic = [](int n, int p, coupling::Marking m, double target) {
    return coupling::automatic_interface_scaling(0.0024 / n, p, m, target);
  };
  const coupling::Marking central = coupling::Marking::central;
  const double coarse = automatic(128, 3, central, 1e-3), fine = automatic(256, 3, central, 1e-3);
  EXPECT_NEAR(coarse, 1.0752e10, 1e6);
  EXPECT_NEAR(fine, 7.4879e10, 1e7);
  // About 7 times more per halving of h (measured: 2.65^2), 4 times more per halving of the target.
  EXPECT_NEAR(fine / coarse, std::pow(2.0, 2.8), 1e-12);
  EXPECT_NEAR(automatic(128, 3, central, 5e-4) / coarse, 4, 1e-12);
  // The band is 2p - 1 elements wide (central) or 2p + 1 (support): quadratics, and the support marking's
  // wider band of cubics, need (5 / 3)^2.8 and (5 / 7)^2.8 times the central cubics' s_I.
  EXPECT_NEAR(automatic(128, 2, central, 1e-3) / coarse, std::pow(5.0 / 3, 2.8), 1e-12);
  EXPECT_NEAR(automatic(128, 3, coupling::Marking::support, 1e-3) / coarse, std::pow(5.0 / 7, 2.8), 1e-12);
  EXPECT_DOUBLE_EQ(coupling::interface_band_width(1e-5, 3, central), 5e-5);
  EXPECT_THROW(automatic(128, 3, central, 0), std::invalid_argument);
}
