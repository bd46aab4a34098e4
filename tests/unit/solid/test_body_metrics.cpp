// Body metrics (solid/body_metrics.hpp) on prescribed motions with known answers: a rigid rotation at a known
// rate, an inclination oscillating about a known mean, a uniform dilation, a round membrane (no axis).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>

#include "geometry/builders.hpp"
#include "solid/body_metrics.hpp"

using namespace cellfsi;
using geometry::Mat3;
using geometry::Patch;
using geometry::Vec3;

namespace {

constexpr double kPi = std::numbers::pi;
const Vec3 kCentre(1.2e-3, 6e-4, 0);

/// The patch rotated by `angle` (counter-clockwise) about kCentre and scaled by `scale`.
Patch moved(const Patch& p, double angle, double scale = 1.0) {
  const Mat3 A = scale * Eigen::AngleAxisd(angle, Vec3::UnitZ()).toRotationMatrix();
  return geometry::transformed(p, A, kCentre - A * kCentre);
}

std::map<std::string, double> as_map(const std::vector<solid::Metric>& m) { return {m.begin(), m.end()}; }

}  // namespace

TEST(BodyTracker, RigidRotationGivesTheRateAndKeepsAreaAndPerimeter) {
  // The paper's capsule across the flow, turned clockwise at 3 turns per second.
  const Patch capsule = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 32, 2, kCentre, kPi / 2);
  solid::BodyTracker t(capsule, true);
  ASSERT_TRUE(t.elongated());
  const double turns = 3.0, dt = 1e-3;
  for (int k = 0; k <= 200; ++k) {
    t.record(k * dt, moved(capsule, -2 * kPi * turns * k * dt));
    const auto m = as_map(t.metrics());
    EXPECT_NEAR(m.at("r_A"), 0.0, 1e-12);
    EXPECT_NEAR(m.at("r_P"), 0.0, 1e-12);
    // theta = 90 deg - the turned angle, folded into (-90, 90].
    double expect = 90.0 - 360.0 * turns * k * dt;
    expect = std::fmod(expect + 90.0 + 3600.0, 180.0) - 90.0;
    if (expect <= -90.0) expect += 180.0;
    EXPECT_NEAR(m.at("theta_deg"), expect, 1e-6) << "step " << k;
    if (k > 0) {
      EXPECT_NEAR(m.at("omega_tt"), turns, 1e-9);
      EXPECT_NEAR(m.at("omega_tu"), turns, 1e-9);
    }
  }
  const auto s = as_map(t.summary(0.1));
  EXPECT_NEAR(s.at("omega_tt"), turns, 1e-9);
  EXPECT_NEAR(s.at("omega_tu"), turns, 1e-9);
  EXPECT_NEAR(s.at("average_from"), 0.1, 1e-12);
  EXPECT_NEAR(s.at("average_to"), 0.2, 1e-12);
}

TEST(BodyTracker, OscillatingInclinationAveragesToItsMean) {
  // theta(t) = 26 deg + 1 deg sin(2 pi 5 t): over whole periods the mean is 26 deg, the oscillation 1 deg.
  const Patch capsule = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 32, 2, kCentre, 0.0);
  solid::BodyTracker t(capsule, true);
  const double dt = 1e-3;
  for (int k = 0; k <= 600; ++k) {
    const double time = k * dt;
    t.record(time, moved(capsule, (26.0 + std::sin(2 * kPi * 5 * time)) * kPi / 180));
  }
  const auto s = as_map(t.summary(0.2));  // 0.2 .. 0.6 s: two whole periods
  EXPECT_NEAR(s.at("theta_deg"), 26.0, 1e-4);
  EXPECT_NEAR(s.at("theta_oscillation_deg"), 1.0, 1e-3);
  EXPECT_NEAR(s.at("omega_tu"), 0.0, 1e-9);
}

TEST(BodyTracker, UniformDilationChangesAreaAndPerimeterExactly) {
  const Patch disk = geometry::bulky_ellipse(1e-4, 1e-4, 4, 32, 2, kCentre);
  const Patch capsule = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 64, 2, kCentre, 0.3);
  solid::BodyTracker td(disk, false), tc(capsule, true);
  EXPECT_FALSE(td.elongated()) << "a disk has no long axis";
  const double s = 1.01;
  td.record(0, disk);
  td.record(1e-3, moved(disk, 0.0, s));
  tc.record(0, capsule);
  tc.record(1e-3, moved(capsule, 0.0, s));
  for (const auto* t : {&td, &tc}) {
    const auto m = as_map(t->metrics());
    EXPECT_NEAR(m.at("r_A"), s * s - 1, 1e-10);
    EXPECT_NEAR(m.at("r_P"), s - 1, 1e-10);
  }
  EXPECT_EQ(as_map(td.metrics()).count("theta_deg"), 0u);
}

TEST(BodyTracker, RoundBodyTurnsAsAWhole) {
  // A disk turned rigidly: no axis, but its material points turn at the rate (omega_tu of a bulky body).
  const Patch disk = geometry::bulky_ellipse(1e-4, 1e-4, 4, 32, 2, kCentre);
  solid::BodyTracker t(disk, false);
  for (int k = 0; k <= 20; ++k) t.record(k * 1e-3, moved(disk, -2 * kPi * 4.68 * k * 1e-3));
  EXPECT_NEAR(as_map(t.summary(0.0)).at("omega_tu"), 4.68, 1e-9);
}

TEST(BodyTracker, RejectsTimeGoingBackwards) {
  const Patch disk = geometry::bulky_ellipse(1e-4, 1e-4, 4, 32, 2, kCentre);
  solid::BodyTracker t(disk, false);
  t.record(1.0, disk);
  EXPECT_THROW(t.record(1.0, disk), std::invalid_argument);
}
