// Rheology of a suspension in a channel (solid/suspension_metrics.hpp) on prescribed records: a plug of cells
// moving at a known speed gives the known zeta and H_d; the plasma flow gives eta = 1.
#include <cmath>

#include <gtest/gtest.h>

#include "solid/suspension_metrics.hpp"

using cellfsi::solid::suspension_rheology;
using cellfsi::solid::SuspensionRecord;

namespace {

// Three cells of area 1e-8 cm^2 each moving at speed u in a 0.003 x 0.001 channel whose mean velocity is vm;
// the walls 2e-5 and 4e-5 cm from the nearest membrane points.
std::vector<SuspensionRecord> plug(double u, double vm, int n, double dt) {
  std::vector<SuspensionRecord> out;
  for (int k = 0; k < n; ++k) {
    SuspensionRecord r;
    r.time = k * dt;
    r.mean_velocity = vm;
    r.cell_area = 3e-8;
    r.cell_x = {0.0005 + u * r.time, 0.0015 + u * r.time, 0.0025 + u * r.time};
    r.gap_low = 2e-5, r.gap_high = 4e-5;
    out.push_back(r);
  }
  return out;
}

}  // namespace

TEST(SuspensionRheology, PlugOfCellsFasterThanTheMeanGivesTheFahraeusRatio) {
  const double area = 0.003 * 0.001, vm = 0.01, u = 0.0125, vp = 0.0116;
  const auto rec = plug(u, vm, 41, 0.01);
  const auto r = suspension_rheology(rec, area, vp, 0.1);
  EXPECT_EQ(r.records, 31);
  EXPECT_NEAR(r.tube_hematocrit, 0.01, 1e-15);
  EXPECT_NEAR(r.cell_velocity, u, 1e-15);
  EXPECT_NEAR(r.mean_velocity, vm, 1e-15);
  EXPECT_NEAR(r.fahraeus, vm / u, 1e-14);  // 0.8 < 1: cells faster than the blood
  EXPECT_NEAR(r.discharge_hematocrit, 0.01 * u / vm, 1e-15);
  EXPECT_NEAR(r.tube_hematocrit / r.discharge_hematocrit, r.fahraeus, 1e-14);  // zeta = H_t / H_d
  EXPECT_NEAR(r.relative_viscosity, vp / vm, 1e-14);
  EXPECT_NEAR(r.cell_free_layer, 3e-5, 1e-18);
}

TEST(SuspensionRheology, PlasmaFlowGivesUnitViscosityAndShortWindowsNothing) {
  const double vp = 0.01157;
  const auto r = suspension_rheology(plug(vp, vp, 5, 0.01), 3e-6, vp, 0.0);
  EXPECT_DOUBLE_EQ(r.relative_viscosity, 1.0);
  EXPECT_DOUBLE_EQ(r.fahraeus, 1.0);
  EXPECT_EQ(suspension_rheology(plug(vp, vp, 5, 0.01), 3e-6, vp, 0.035).records, 1);
  EXPECT_EQ(suspension_rheology(plug(vp, vp, 5, 0.01), 3e-6, vp, 0.035).fahraeus, 0.0);
  EXPECT_THROW(suspension_rheology(plug(vp, vp, 5, 0.01), 0.0, vp, 0.0), std::invalid_argument);
  auto bad = plug(vp, vp, 5, 0.01);
  bad[3].cell_x.pop_back();
  EXPECT_THROW(suspension_rheology(bad, 3e-6, vp, 0.0), std::invalid_argument);
}

// The throat of the default narrowing (0.002 cm high, 0.0008 at the throat, [0.0025, 0.0035]): its walls at
// y = +-0.0004. Points outside the throat do not count, a point a period further along does.
TEST(ThroatGaps, GapsFromTheThroatWallsToTheNearestPointsInsideIt) {
  const cellfsi::geometry::NarrowingChannel c;
  using V = cellfsi::geometry::Vec3;
  const std::vector<V> pts{V(0.0027, -0.0004 + 1e-5, 0), V(0.0030, -0.0004 + 2e-5, 0),
                           V(0.0033 + c.length, 0.0004 - 3e-5, 0),          // a period along: in the throat
                           V(0.0010, -0.00099, 0), V(0.0040, 0.00099, 0)};  // outside it: nearer the walls
  const cellfsi::solid::ThroatGaps g = cellfsi::solid::throat_gaps(pts, c);
  EXPECT_EQ(g.points, 3);
  EXPECT_NEAR(g.low, 1e-5, 1e-15);
  EXPECT_NEAR(g.high, 3e-5, 1e-15);
  EXPECT_NEAR(g.mean(), 2e-5, 1e-15);
  const cellfsi::solid::ThroatGaps none = cellfsi::solid::throat_gaps({V(0.001, 0, 0)}, c);
  EXPECT_EQ(none.points, 0);
  EXPECT_TRUE(std::isnan(none.mean()));
  // A throat centred at x = 0 straddles the period's ends: points on both sides of it count.
  cellfsi::geometry::NarrowingChannel wrapped;
  wrapped.throat_center = 0;
  const cellfsi::solid::ThroatGaps w = cellfsi::solid::throat_gaps(
      {V(0.0003, -0.0004 + 1e-5, 0), V(wrapped.length - 0.0003, 0.0004 - 2e-5, 0), V(0.003, 0, 0)}, wrapped);
  EXPECT_EQ(w.points, 2);
  EXPECT_NEAR(w.low, 1e-5, 1e-15);
  EXPECT_NEAR(w.high, 2e-5, 1e-15);
}
