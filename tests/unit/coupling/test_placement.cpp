// Placement checks of immersed bodies (coupling/placement.hpp): inside the domain, overlap (exact polygon
// test in 2D), and the element-size ratio of the paper's Remark 3.
#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "coupling/placement.hpp"
#include "geometry/builders.hpp"

using namespace cellfsi;
using geometry::Vec3;

namespace {
const Vec3 kCentre(1.2e-3, 6e-4, 0);
coupling::BodyPlacement capsule(const Vec3& c = kCentre, int n = 64) {
  return {"membrane", geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, n, 2, c, 1.5707963267948966), true};
}
coupling::BodyPlacement disk(const std::string& name, const Vec3& c, double r) {
  return {name, geometry::bulky_ellipse(r, r, 4, 32, 2, c), false};
}
std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(Placement, InsideAndOutsideTheDomain) {
  const geometry::Patch box = geometry::rectangle(0.0024, 0.0012, 32, 16, 2, {true, false});
  const coupling::Locator loc(box);
  EXPECT_NO_THROW(coupling::check_inside(loc, capsule()));
  // Long axis across the flow: at y = 1.5e-4 the capsule pokes 5e-5 cm through the bottom wall.
  const std::string m = message_of([&] { coupling::check_inside(loc, capsule(Vec3(1.2e-3, 1.5e-4, 0))); });
  EXPECT_NE(m.find("'membrane'"), std::string::npos) << m;
  EXPECT_NE(m.find("outside"), std::string::npos) << m;
  // Across the periodic end in x is inside (the periodic image is in the domain).
  EXPECT_NO_THROW(coupling::check_inside(loc, capsule(Vec3(0.0, 6e-4, 0))));
}

TEST(Placement, OverlapIsExactForMembranesAndNuclei) {
  // A nucleus in the capsule's cavity is a compound capsule: no overlap. One that crosses the membrane,
  // even by 1e-7 cm, overlaps.
  EXPECT_NO_THROW(coupling::check_no_overlap({capsule(), disk("nucleus", kCentre, 5e-5)}));
  // The membrane's inner face at the top is at y = 6e-4 + 2e-4 - 2.5e-7.
  const double inner_top = 6e-4 + 2e-4 - 2.5e-7;
  EXPECT_NO_THROW(coupling::check_no_overlap(
      {capsule(), disk("nucleus", Vec3(1.2e-3, inner_top - 5e-5 - 1e-7, 0), 5e-5)}));
  const std::string m = message_of([&] {
    coupling::check_no_overlap({capsule(), disk("nucleus", Vec3(1.2e-3, inner_top - 5e-5 + 1e-7, 0), 5e-5)});
  });
  EXPECT_NE(m.find("'membrane' and 'nucleus' overlap"), std::string::npos) << m;
  // Two disjoint disks; two overlapping ones.
  EXPECT_NO_THROW(
      coupling::check_no_overlap({disk("a", kCentre, 1e-4), disk("b", kCentre + Vec3(2.01e-4, 0, 0), 1e-4)}));
  EXPECT_THROW(
      coupling::check_no_overlap({disk("a", kCentre, 1e-4), disk("b", kCentre + Vec3(1.99e-4, 0, 0), 1e-4)}),
      std::invalid_argument);
}

TEST(Placement, ResolutionRatioFollowsTheElementCounts) {
  const geometry::Patch box = geometry::rectangle(0.0024, 0.0012, 64, 32, 3, {true, false});
  const coupling::Resolution r32 = coupling::resolution(box, capsule(kCentre, 32));
  const coupling::Resolution r64 = coupling::resolution(box, capsule(kCentre, 64));
  EXPECT_NEAR(r32.fluid_element, 0.0024 / 64, 1e-15);
  // The mid-line perimeter is 9.69e-4 cm: 32 elements average 3.03e-5 cm; the largest is longer.
  EXPECT_GT(r32.solid_element, 3.03e-5);
  EXPECT_LT(r32.solid_element, 4.5e-5);
  EXPECT_NEAR(r32.ratio() / r64.ratio(), 2.0, 0.05);
}
