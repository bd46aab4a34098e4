// The locator (CGAL AABB tree + NURBS inversion) and s^h marking.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <numbers>
#include <random>

#include "coupling/interface_marking.hpp"
#include "coupling/locator.hpp"
#include "geometry/builders.hpp"
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
