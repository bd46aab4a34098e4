// Body metrics (solid/body_metrics.hpp) on prescribed motions with known answers: a rigid rotation at a known
// rate, an inclination oscillating about a known mean, a uniform dilation, a round membrane (no axis).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>

#include "geometry/builders.hpp"
#include "geometry/measures.hpp"
#include "geometry/refine.hpp"
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

TEST(BodyTracker, TumblingRbcDiscHasItsInclinationInTheShearPlane) {
  // A 3D RBC (oblate: its two largest second moments are equal, so its 3D long axis may be any direction in
  // its disc) standing across the flow, its axis of symmetry along x, turned clockwise about z at 3 turns per
  // second: theta is that of the disc's section in the shear plane, 90 deg minus the turned angle (before it
  // was taken from the 3D long axis, which may leave the plane).
  const Vec3 c(6e-4, 6e-4, 6e-4);
  const Mat3 stand = Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()).toRotationMatrix();
  const Patch rbc = geometry::transformed(geometry::biconcave_rbc_3d(3e-5, 8, 16, 2, c), stand, c - stand * c);
  solid::BodyTracker t(rbc, true);
  ASSERT_TRUE(t.elongated());
  const double turns = 3.0, dt = 2e-3;
  for (int k = 0; k <= 40; ++k) {
    const Mat3 A = Eigen::AngleAxisd(-2 * kPi * turns * k * dt, Vec3::UnitZ()).toRotationMatrix();
    t.record(k * dt, geometry::transformed(rbc, A, c - A * c));
    double expect = 90.0 - 360.0 * turns * k * dt;
    if (expect <= -90.0) expect += 180.0;
    EXPECT_NEAR(as_map(t.metrics()).at("theta_deg"), expect, 1e-6) << "step " << k;
  }
  const auto s = as_map(t.summary(0.0));
  EXPECT_NEAR(s.at("omega_tu"), turns, 1e-9);
  EXPECT_EQ(t.regime(0.0), "tumbling");
}

TEST(BodyTracker, ShortAxisToVorticityTellsRollingFromTumbling) {
  // The 3D RBC's axis of symmetry (its short axis, along z as built) turned about y by a: its angle to the
  // vorticity direction (z, normal to the x-y shear plane) is a, whatever the turn about z that follows (a
  // flip keeps it); with the gradient along z (plane_dir 2) the vorticity is y, and the same body gives 90
  // deg.
  const Vec3 c(6e-4, 6e-4, 6e-4);
  const Patch rbc = geometry::biconcave_rbc_3d(3e-5, 8, 16, 2, c);
  for (const double a : {0.0, 30.0, 45.0, 60.0, 90.0}) {
    const Mat3 tilt = Eigen::AngleAxisd(a * kPi / 180, Vec3::UnitY()).toRotationMatrix();
    const Patch tilted = geometry::transformed(rbc, tilt, c - tilt * c);
    solid::BodyTracker t(tilted, true);
    for (int k = 0; k <= 4; ++k) {
      const Mat3 A = Eigen::AngleAxisd(-0.4 * k, Vec3::UnitZ()).toRotationMatrix();
      t.record(1e-3 * k, geometry::transformed(tilted, A, c - A * c));
      EXPECT_NEAR(as_map(t.metrics()).at("short_axis_to_vorticity_deg"), a, 1e-6) << a << " deg, step " << k;
    }
    solid::BodyTracker across(tilted, true, 2);
    across.record(0.0, tilted);
    EXPECT_NEAR(as_map(across.metrics()).at("short_axis_to_vorticity_deg"), 90.0, 1e-6) << a << " deg";
  }
  // 2D bodies have no such metric.
  const Patch capsule = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 32, 2, kCentre, 0.0);
  solid::BodyTracker flat(capsule, true);
  flat.record(0.0, capsule);
  EXPECT_EQ(as_map(flat.metrics()).count("short_axis_to_vorticity_deg"), 0u);
}

TEST(BodyTracker, RestoredStateContinuesTheRecordsExactly) {
  // A checkpoint: a tracker restored from another's state after 60 records gives, after 60 more, the same
  // metrics and summary bit for bit as the tracker that never stopped (the unwrapped angles carry over).
  const Patch capsule = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 32, 2, kCentre, kPi / 2);
  solid::BodyTracker a(capsule, true), b(capsule, true);
  const double dt = 2e-3;
  for (int k = 0; k < 60; ++k) a.record(k * dt, moved(capsule, -2 * kPi * 3.0 * k * dt));
  b.restore(a.state());
  for (int k = 60; k < 120; ++k) {
    a.record(k * dt, moved(capsule, -2 * kPi * 3.0 * k * dt));
    b.record(k * dt, moved(capsule, -2 * kPi * 3.0 * k * dt));
  }
  EXPECT_EQ(a.metrics(), b.metrics());
  EXPECT_EQ(a.summary(0.05), b.summary(0.05));
  EXPECT_EQ(a.regime(0.05), b.regime(0.05));
  std::vector<double> bad = a.state();
  bad.pop_back();
  EXPECT_THROW(b.restore(bad), std::invalid_argument);
}

TEST(BodyTracker, LargestStretchOfTheMidSurface) {
  // Prescribed deformations with known stretches (issue 28: the laws compared by their largest stretch). The
  // largest is sampled at 4 points per element, so a peak between samples is read slightly low.
  // 2D: a rigid turn stretches nothing; a dilation by s stretches every point by s; an area-preserving map
  // diag(l, 1/l) of a circle stretches its mid-line most where the tangent is along x: by l.
  const Patch circle = geometry::hollow_ellipse(1.5e-4, 1.5e-4, 5e-7, 32, 2, kCentre);
  solid::BodyTracker t(circle, true);
  t.record(0.0, circle);
  EXPECT_NEAR(as_map(t.summary(0.0)).at("max_stretch"), 1.0, 1e-12);
  t.record(1e-3, moved(circle, 0.7));
  EXPECT_NEAR(as_map(t.summary(0.0)).at("max_stretch"), 1.0, 1e-12);
  t.record(2e-3, moved(circle, 0.0, 1.2));
  EXPECT_NEAR(as_map(t.summary(0.0)).at("max_stretch"), 1.2, 1e-12);
  const double l = 1.5;
  const Mat3 A = Vec3(l, 1 / l, 1).asDiagonal();
  t.record(3e-3, geometry::transformed(circle, A, kCentre - A * kCentre));
  EXPECT_NEAR(as_map(t.summary(0.0)).at("max_stretch"), l, 2e-3 * l);
  EXPECT_LE(as_map(t.summary(0.0)).at("max_stretch"), l * (1 + 1e-12));
  // The checkpoint keeps it; a state written before it was kept (9 numbers per record) restores with it 0.
  solid::BodyTracker r(circle, true);
  r.restore(t.state());
  EXPECT_EQ(as_map(r.summary(0.0)).at("max_stretch"), as_map(t.summary(0.0)).at("max_stretch"));
  std::vector<double> old = t.state(), old9;
  const auto n_angles = static_cast<std::size_t>(old[0]);
  old9.assign(old.begin(), old.begin() + static_cast<long>(n_angles + 2));
  for (std::size_t k = n_angles + 2; k < old.size(); k += 10)
    old9.insert(old9.end(), old.begin() + static_cast<long>(k), old.begin() + static_cast<long>(k + 9));
  r.restore(old9);
  EXPECT_EQ(as_map(r.summary(0.0)).at("max_stretch"), 0.0);
  // 3D: a sphere stretched by diag(l, 1/sqrt(l), 1/sqrt(l)) (volume kept): the equator's tangent along x is
  // stretched by l, the largest principal stretch of the surface.
  const Patch sphere = geometry::hollow_ellipsoid(1.5e-4, 1.5e-4, 1.5e-4, 5e-7, 8, 16, 2, kCentre);
  solid::BodyTracker t3(sphere, true);
  const Mat3 B = Vec3(l, 1 / std::sqrt(l), 1 / std::sqrt(l)).asDiagonal();
  t3.record(0.0, sphere);
  // (round-off of the closed-form eigenvalue near the poles, where the metric is nearly singular: 5e-9)
  EXPECT_NEAR(as_map(t3.summary(0.0)).at("max_stretch"), 1.0, 1e-7);
  t3.record(1e-3, geometry::transformed(sphere, B, kCentre - B * kCentre));
  EXPECT_NEAR(as_map(t3.summary(0.0)).at("max_stretch"), l, 5e-3 * l);
  // A bulky body has no mid-surface: no max_stretch.
  solid::BodyTracker bulky(geometry::transformed(sphere, Mat3::Identity(), Vec3::Zero()), false);
  bulky.record(0.0, sphere);
  EXPECT_EQ(as_map(bulky.summary(0.0)).count("max_stretch"), 0u);
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
  EXPECT_TRUE(std::isnan(as_map(td.metrics()).at("theta_deg"))) << "a uniformly dilated disk has no axis";
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

TEST(MotionRegime, DecidedFromTheAxisAndTheMaterial) {
  // Prescribed angle histories over 0.3 s (clockwise: negative angles), the rule of solid::motion_regime.
  std::vector<double> fixed, wobble, swing, turn, material, still;
  for (int k = 0; k <= 300; ++k) {
    const double t = k * 1e-3;
    fixed.push_back(0.4);
    wobble.push_back(0.4 + 0.5 * kPi / 180 * std::sin(2 * kPi * 7 * t));  // +-0.5 deg: tank-treading
    swing.push_back(0.4 + 6 * kPi / 180 * std::sin(2 * kPi * 7 * t));     // +-6 deg: swinging
    turn.push_back(-2 * kPi * 3.5 * t);                                   // 1.05 turns of the axis
    material.push_back(-2 * kPi * 3.8 * t);
    still.push_back(0.01 * t);
  }
  EXPECT_EQ(solid::motion_regime(false, true, fixed, material), "tank-treading");
  EXPECT_EQ(solid::motion_regime(false, true, wobble, material), "tank-treading");
  EXPECT_EQ(solid::motion_regime(false, true, swing, material), "swinging");
  EXPECT_EQ(solid::motion_regime(false, true, turn, material), "tumbling");
  EXPECT_EQ(solid::motion_regime(false, false, turn, turn), "tumbling");
  // A window shorter than a half-turn: 0.45 turns of the axis with the material, as a tumbling capsule.
  const std::vector<double> part(turn.begin(), turn.begin() + 130);
  EXPECT_EQ(solid::motion_regime(false, true, part, part), "tumbling");
  EXPECT_EQ(solid::motion_regime(false, true, fixed, still), "steady");
  // A membrane whose material turns 4 times faster than its axis, caught across one passage of the vertical
  // (axis from -60 to -130 deg: 70 deg, less than half the material's turn), is tumbling; the same axis
  // range on the near side of the vertical (-10 to -80 deg) is not. Lambda = 6 in docs/notes/2026-11-26-val-viscosity.md was
  // called swinging over such a window before this rule.
  std::vector<double> across, near, fast;
  for (int k = 0; k <= 100; ++k) {
    across.push_back((-60.0 - 0.7 * k) * kPi / 180);
    near.push_back((-10.0 - 0.7 * k) * kPi / 180);
    fast.push_back(4 * across.back());
  }
  EXPECT_EQ(solid::motion_regime(false, true, across, fast), "tumbling");
  EXPECT_NE(solid::motion_regime(false, true, near, fast), "tumbling");
  // An axis that starts across the flow (90 deg, exactly or a hair beyond) and turns to tank-tread has not
  // passed the vertical.
  for (const double start : {90.0, 90.0 + 1e-9}) {
    std::vector<double> settle;
    for (int k = 0; k <= 100; ++k) settle.push_back((start - 0.7 * k) * kPi / 180);
    EXPECT_NE(solid::motion_regime(false, true, settle, fast), "tumbling") << start;
  }
  // A body round in its reference shape has no axis of its own: a bulky one turns as a whole.
  EXPECT_EQ(solid::motion_regime(true, false, still, material), "tumbling");
  EXPECT_EQ(solid::motion_regime(true, true, still, material), "tank-treading");
  // ... unless its material does not turn (a circular cell squeezed through a narrowing: its long axis swaps
  // by 90 deg, the material stays).
  std::vector<double> swap(still.size());
  for (size_t k = 0; k < swap.size(); ++k) swap[k] = k < swap.size() / 2 ? 0.0 : kPi / 2;
  EXPECT_EQ(solid::motion_regime(true, true, swap, still), "steady");
  EXPECT_EQ(solid::motion_regime(true, false, swap, still), "steady");
  EXPECT_THROW(solid::motion_regime(false, true, {0.0}, {0.0}), std::invalid_argument);
}

TEST(MotionRegime, TumblingFrequencyOverWholeHalfTurns) {
  // An axis turning at 2 turns/s with a non-uniform speed (faster across the flow, as a tumbling ellipse):
  // over a window of 0.6 half-periods more, the plain window average is off; over whole half-turns it is
  // exact.
  const double f = 2.0;
  std::vector<double> t, a;
  for (int k = 0; k <= 700; ++k) {
    t.push_back(k * 1e-3);
    const double phase = 2 * kPi * f * t.back();
    a.push_back(-(phase + 0.3 * std::sin(2 * phase)) / 1.0);
  }
  int n = 0;
  const double w = solid::tumbling_frequency(t, a, &n);
  EXPECT_EQ(n, 2);  // 1.4 turns of the axis: two whole half-turns
  EXPECT_NEAR(w, f, 1e-3);
  const double plain = -(a.back() - a.front()) / (2 * kPi * (t.back() - t.front()));
  EXPECT_GT(std::abs(plain - f), 0.05) << "the window average is biased by the non-uniform speed";
  // A bulky ellipse turned rigidly: BodyTracker's summary gives the rate and the regime.
  const Patch ellipse = geometry::bulky_ellipse(2e-4, 1e-4, 4, 32, 2, kCentre);
  solid::BodyTracker tr(ellipse, false);
  for (int k = 0; k <= 200; ++k) tr.record(k * 1e-3, moved(ellipse, -2 * kPi * 4.68 * k * 1e-3));
  const auto m = as_map(tr.summary(0.0));
  EXPECT_NEAR(m.at("omega_tu"), 4.68, 1e-6);
  EXPECT_EQ(m.at("omega_tu_half_turns"), 1.0);
  EXPECT_EQ(tr.regime(0.0), "tumbling");
}

TEST(DimensionlessNumbers, ThePapersCapsulesAndCompoundCapsule) {
  // Paper Sec. 3.3: a = 2e-4, b = 1e-4, h = 5e-7 cm, G_m = 7500, mu = 0.012, rho_1 = 1.025, gammadot = 70,
  // H = 0.0012 cm: Delta_m = 0.841, chi = 0.257, Ca_m = 0.0345, Re = 0.000142 (R0 = 0.0001542 cm).
  const solid::FlowScales flow{0.012, 1.025, 70.0, 6e-4};
  const Patch capsule = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 64, 2, kCentre, kPi / 2);
  auto m = as_map(solid::dimensionless_numbers(capsule, true, 5e-7, 7500, flow));
  EXPECT_NEAR(m.at("Delta"), 0.841, 5e-4);
  EXPECT_NEAR(m.at("R0"), 1.542e-4, 5e-8);
  EXPECT_NEAR(m.at("chi"), 0.257, 5e-4);
  EXPECT_NEAR(m.at("Ca"), 0.0345, 5e-5);
  EXPECT_NEAR(m.at("Re"), 0.000142, 5e-7);
  // Sec. 3.6: the inclusion's bulk capillary number mu gammadot / G_i = 0.021; a disk has Delta = 1.
  const Patch nucleus = geometry::bulky_ellipse(5e-5, 5e-5, 4, 32, 2, kCentre);
  m = as_map(solid::dimensionless_numbers(nucleus, false, 0, 40, flow));
  EXPECT_NEAR(m.at("Ca"), 0.021, 1e-12);
  EXPECT_NEAR(m.at("Delta"), 1.0, 1e-9);
  EXPECT_NEAR(solid::filling_fraction(nucleus, capsule), 0.125, 1e-4);  // r^2 / (a b)
  // Sec. 3.6, 3D: ellipsoid 3e-4 x 2e-4 x 2e-4, sphere r = 1e-4 in a cube of side 0.0012: Delta_m = 0.960,
  // chi = 0.387, Ca_m = 0.0520, Re = 0.000322, phi = 0.083 (R0 = 0.000232 cm).
  const Patch shell = geometry::hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 8, 16, 2, kCentre);
  const Patch sphere = geometry::solid_ellipsoid(1e-4, 1e-4, 1e-4, 2, 8, 16, 2, kCentre);
  m = as_map(solid::dimensionless_numbers(shell, true, 5e-7, 7500, flow));
  EXPECT_NEAR(m.at("Delta"), 0.960, 5e-4);
  EXPECT_NEAR(m.at("R0"), 2.32e-4, 5e-7);
  EXPECT_NEAR(m.at("chi"), 0.387, 1e-3);
  EXPECT_NEAR(m.at("Ca"), 0.0520, 1e-4);
  EXPECT_NEAR(m.at("Re"), 0.000322, 1e-6);
  EXPECT_NEAR(solid::filling_fraction(sphere, shell), 0.083, 5e-4);
}

TEST(BodyTracker, ABulkyBodysMomentsComeFromItsFaceOnlyWhereTheFaceBoundsIt) {
  // A solid ellipsoid (direction 0 from a degenerate centre): its moments by the divergence theorem over its
  // outer face equal its volume's, the anisotropy of geometry::patch_moments to round-off and quadrature (the
  // two rules differ). A thick hollow ellipsoid flagged bulky: its inner face has a measure, so it keeps its
  // volume's moments (the shell's anisotropy), not those of the ball its outer face encloses, which differ.
  const auto anisotropy = [](const geometry::RegionMoments& m) {
    const geometry::PrincipalAxes ax = geometry::principal_axes(m, 3);
    return ax.values[0] / ax.values[2] - 1;
  };
  const Patch ball = geometry::solid_ellipsoid(3e-4, 2e-4, 1e-4, 2, 8, 16, 2, kCentre);
  const Patch shell = geometry::hollow_ellipsoid(3e-4, 2e-4, 1e-4, 8e-5, 8, 16, 2, kCentre);
  for (const Patch* p : {&ball, &shell}) {
    solid::BodyTracker t(*p, false);
    t.record(0.0, *p);
    const double expected = anisotropy(geometry::patch_moments(*p));
    EXPECT_NEAR(as_map(t.summary(0.0)).at("max_anisotropy"), expected, 1e-6 * expected) << (p == &ball);
  }
  const double enclosed =
      anisotropy(geometry::enclosed_moments(geometry::isoparametric(shell, 0, shell.knots(0).b())));
  EXPECT_GT(std::abs(enclosed - anisotropy(geometry::patch_moments(shell))), 1e-2);  // (the test can tell)
}

TEST(LateralMigration, OffsetsAndTheTimeToTheCentreLine) {
  // A centroid approaching y = 5e-4 as 2e-4 exp(-t / 0.1): a tenth of the offset at t = 0.1 ln 10.
  std::vector<std::pair<double, cellfsi::geometry::Vec3>> track;
  for (int k = 0; k <= 1000; ++k) {
    const double t = 1e-3 * k;
    track.emplace_back(t, cellfsi::geometry::Vec3(0.001 + 0.01 * t, 5e-4 + 2e-4 * std::exp(-t / 0.1), 0));
  }
  const solid::Migration m = solid::lateral_migration(track, 1, 5e-4);
  EXPECT_NEAR(m.offset_start, 2e-4, 1e-18);
  EXPECT_NEAR(m.offset_final, 2e-4 * std::exp(-10.0), 1e-18);
  EXPECT_NEAR(m.time_to_centreline, 0.1 * std::log(10.0), 1e-3);  // the first record past it
  track.resize(100);                                              // to t = 0.099: not there yet
  EXPECT_TRUE(std::isnan(solid::lateral_migration(track, 1, 5e-4).time_to_centreline));
}

TEST(LateralMigration, EquilibriumOfAnOffsetThatRelaxesToAValueOffTheCentreLine) {
  // y(t) = mid - 0.2 + 0.1 exp(-t / 0.1) over t in [0, 1] (1001 records): the offset settles at -0.2.
  std::vector<std::pair<double, cellfsi::geometry::Vec3>> track;
  const double mid = 0.5;
  for (int k = 0; k <= 1000; ++k) {
    const double t = 1e-3 * k;
    track.emplace_back(t, cellfsi::geometry::Vec3(3 * t, mid - 0.2 + 0.1 * std::exp(-t / 0.1), 0));
  }
  const solid::LateralEquilibrium e = solid::lateral_equilibrium(track, 1, mid, 1e-3);
  // Over the last tenth (t in [0.9, 1]) the offset is -0.2 + ~1e-5 and its slope -exp(-9.5) ~ -7.5e-5.
  EXPECT_NEAR(e.offset, -0.2, 2e-5);
  EXPECT_NEAR(e.drift, -std::exp(-9.5), 1e-5);
  // Within 1e-3 of the final offset from 0.1 ln(0.1 / 1e-3) = 0.46 s on (to the record, and to the window
  // mean).
  EXPECT_NEAR(e.settle_time, 0.1 * std::log(100.0), 2e-3);
  // A track that ends still moving by more than the tolerance per record never settled.
  for (auto& [t, c] : track) c[1] = mid + 0.05 * t;
  EXPECT_NEAR(solid::lateral_equilibrium(track, 1, mid, 1e-3, 0.5).drift, 0.05, 1e-12);
  EXPECT_TRUE(std::isnan(solid::lateral_equilibrium(track, 1, mid, 1e-5).settle_time));
  EXPECT_THROW(solid::lateral_equilibrium({}, 1, mid, 1e-3), std::invalid_argument);
  EXPECT_THROW(solid::lateral_equilibrium(track, 1, mid, 1e-3, 0.0), std::invalid_argument);
}

TEST(MirrorAsymmetry, TellsAnAlignedEllipseAnInclinedOneAndAParachuteApart) {
  // 400 points of each curve around the origin.
  auto curve = [](auto point) {
    std::vector<cellfsi::geometry::Vec3> c;
    for (int i = 0; i < 400; ++i) c.push_back(point(2 * kPi * i / 400));
    return c;
  };
  const auto aligned =
      curve([](double t) { return cellfsi::geometry::Vec3(2 * std::cos(t), std::sin(t), 0); });
  const double a = 0.5;  // inclined by 0.5 rad
  const auto inclined = curve([&](double t) {
    const double x = 2 * std::cos(t), y = std::sin(t);
    return cellfsi::geometry::Vec3(std::cos(a) * x - std::sin(a) * y, std::sin(a) * x + std::cos(a) * y, 0);
  });
  // A bullet / parachute: round at the front (x > 0), flattened and hollowed at the rear.
  const auto parachute = curve([](double t) {
    const double x = std::cos(t), y = std::sin(t);
    return cellfsi::geometry::Vec3(x > 0 ? x : 0.3 * x - 0.3 * (1 - y * y), y, 0);
  });
  const cellfsi::geometry::Vec3 o = cellfsi::geometry::Vec3::Zero();
  EXPECT_LT(solid::mirror_asymmetry(aligned, o, 0), 0.01);
  EXPECT_LT(solid::mirror_asymmetry(aligned, o, 1), 0.01);
  EXPECT_GT(solid::mirror_asymmetry(inclined, o, 0), 0.1);
  EXPECT_GT(solid::mirror_asymmetry(inclined, o, 1), 0.1);
  EXPECT_LT(solid::mirror_asymmetry(parachute, o, 0), 0.01);  // symmetric about the flow axis
  EXPECT_GT(solid::mirror_asymmetry(parachute, o, 1), 0.1);   // but not front to back
  EXPECT_THROW(solid::mirror_asymmetry({o, o}, o, 0), std::invalid_argument);
}

TEST(BodyTracker, RecordsSharedAmongRanksAreTheWholeBodysRecords) {
  // Two "ranks" in one process: each integrates its half of the elements and samples half the stretch points;
  // `sum` adds the other half's partial integrals and `max` takes the larger stretch, both taken in a first
  // pass where the two only keep them. The records then equal one tracker's that integrates everything, to
  // the round-off of the sums' order: 1e-12 relative for values above 1, absolutely below (r_A, r_P, the
  // anisotropy and the angles are of order 1e-2 to 1).
  for (bool membrane : {true, false}) {
    const Patch p = membrane
                        ? geometry::hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 6, 12, 2, Vec3(1e-3, 6e-4, 6e-4))
                        : geometry::solid_ellipsoid(3e-4, 2e-4, 1e-4, 2, 6, 12, 2, Vec3(1e-3, 6e-4, 6e-4));
    // Stretched (the anisotropy changes: its largest is at a definite record) and turned.
    const Mat3 A =
        Vec3(1.03, 0.98, 1.0).asDiagonal() * Eigen::AngleAxisd(0.3, Vec3::UnitZ()).toRotationMatrix();
    const Patch q = geometry::transformed(p, A, Vec3(1e-3, 6e-4, 6e-4) - A * Vec3(1e-3, 6e-4, 6e-4));
    std::vector<double> kept[2][2];  // [rank][record]
    double stretch[2][2] = {{0, 0}, {0, 0}};
    for (int pass = 0; pass < 2; ++pass) {
      solid::BodyTracker whole(p, membrane), rank[2] = {{p, membrane}, {p, membrane}};
      int record = 0;
      for (const Patch* config : {&p, &q}) {
        whole.record(record * 1e-3, *config);
        for (int r = 0; r < 2; ++r) {
          solid::MetricShare share;
          share.elements = {r, 2};
          share.sum = [&, r](double* v, int n) {
            if (pass == 0) {
              kept[r][record].assign(v, v + n);
            } else {
              for (int i = 0; i < n; ++i) v[i] += kept[1 - r][record][i];
            }
          };
          share.max = [&, r](double* v, int n) {
            if (pass == 0) {
              stretch[r][record] = *v;
            } else {
              *v = std::max(*v, stretch[1 - r][record]);
            }
            (void)n;
          };
          rank[r].record(record * 1e-3, *config, share);
        }
        ++record;
      }
      if (pass == 0) continue;
      for (int r = 0; r < 2; ++r) {
        std::vector<solid::Metric> a = whole.metrics(), b = rank[r].metrics();
        const std::vector<solid::Metric> sa = whole.summary(0), sb = rank[r].summary(0);  // (max_stretch)
        a.insert(a.end(), sa.begin(), sa.end());
        b.insert(b.end(), sb.begin(), sb.end());
        ASSERT_EQ(a.size(), b.size());
        for (size_t i = 0; i < a.size(); ++i) {
          EXPECT_EQ(a[i].first, b[i].first);
          EXPECT_NEAR(a[i].second, b[i].second, 1e-12 * std::max(1.0, std::abs(a[i].second))) << a[i].first;
        }
      }
    }
  }
}

TEST(BodyTracker, DeformationIndexIsTaylorsOfTheEllipseInTheShearPlane) {
  // (L - B) / (L + B) of the ellipse with the enclosed region's second moments in the shear plane: (a - b) /
  // (a + b) for an ellipse (exact conics) whatever its inclination, and for an ellipsoid the in-plane pair of
  // its semi-axes (x-y plane: a, b; with the gradient along z, the x-z plane: a, c). A circle: 0.
  const double a = 2e-4, b = 1e-4, c = 0.6e-4;
  for (const double angle : {0.0, 0.3, 1.2}) {
    const Patch capsule = geometry::hollow_ellipse(a, b, 5e-7, 32, 2, kCentre, angle);
    solid::BodyTracker t(capsule, true);
    t.record(0.0, capsule);
    EXPECT_NEAR(as_map(t.metrics()).at("deformation_index"), (a - b) / (a + b), 1e-9) << angle;
  }
  const Patch circle = geometry::hollow_ellipse(a, a, 5e-7, 32, 2, kCentre);
  solid::BodyTracker round(circle, true);
  round.record(0.0, circle);
  EXPECT_NEAR(as_map(round.metrics()).at("deformation_index"), 0.0, 1e-9);
  const Patch ellipsoid = geometry::hollow_ellipsoid(a, b, c, 5e-7, 8, 16, 2, Vec3(6e-4, 6e-4, 6e-4));
  solid::BodyTracker xy(ellipsoid, true);
  xy.record(0.0, ellipsoid);
  EXPECT_NEAR(as_map(xy.metrics()).at("deformation_index"), (a - b) / (a + b), 1e-6);
  solid::BodyTracker xz(ellipsoid, true, 2);
  xz.record(0.0, ellipsoid);
  EXPECT_NEAR(as_map(xz.metrics()).at("deformation_index"), (a - c) / (a + c), 1e-6);
}

// A body made of patches (the red cell's six faces) is measured as the one-patch body it approximates (the
// polar shell, finely meshed): tilted out of the shear plane, sheared, and turned rigidly in the plane, the
// same area and enclosed-volume changes, centroid, inclination, deformation index, axis to the vorticity and
// tank-treading rate, within the two meshes' difference.
TEST(BodyTracker, ABodyMadeOfPatchesIsMeasuredAsOne) {
  const Vec3 c(6e-4, 6e-4, 6e-4);
  const double h = 3.1623e-5;
  const Mat3 tilt = Eigen::AngleAxisd(30 * kPi / 180, Vec3::UnitY()).toRotationMatrix();
  auto moved_all = [&](const std::vector<Patch>& parts, const Mat3& A) {
    std::vector<Patch> out;
    for (const Patch& p : parts) out.push_back(geometry::transformed(p, A, c - A * c));
    return out;
  };
  const std::vector<Patch> faces = moved_all(geometry::biconcave_rbc_3d_faces(h, 8, 2, c), tilt);
  const std::vector<Patch> polar = moved_all({geometry::biconcave_rbc_3d(h, 40, 80, 2, c)}, tilt);
  solid::BodyTracker t_faces(faces, true), t_polar(polar, true);
  Mat3 shear = Mat3::Identity();
  shear(0, 1) = 0.3;
  std::map<std::string, double> mf, mp;
  for (int k = 0; k <= 2; ++k) {
    const Mat3 A = Eigen::AngleAxisd(-0.05 * k, Vec3::UnitZ()).toRotationMatrix() * shear;
    t_faces.record(1e-3 * k, moved_all(faces, A));
    t_polar.record(1e-3 * k, moved_all(polar, A));
    mf = as_map(t_faces.metrics()), mp = as_map(t_polar.metrics());
  }
  for (const char* name : {"r_A", "r_P"}) EXPECT_NEAR(mf.at(name), mp.at(name), 2e-3) << name;
  for (const char* name : {"centroid_x", "centroid_y", "centroid_z"})
    EXPECT_NEAR(mf.at(name), mp.at(name), 1e-6 * 3.91e-4) << name;
  EXPECT_NEAR(mf.at("theta_deg"), mp.at("theta_deg"), 0.1);
  EXPECT_NEAR(mf.at("deformation_index"), mp.at("deformation_index"), 1e-3);
  EXPECT_NEAR(mf.at("short_axis_to_vorticity_deg"), mp.at("short_axis_to_vorticity_deg"), 0.1);
  EXPECT_NEAR(mf.at("omega_tt"), mp.at("omega_tt"), 0.02 * std::abs(mp.at("omega_tt")));
  std::printf(
      "  six faces / polar: r_A %.3e / %.3e, theta %.3f / %.3f deg, DI %.4f / %.4f, omega_TT %.3f / "
      "%.3f 1/s\n",
      mf.at("r_A"), mp.at("r_A"), mf.at("theta_deg"), mp.at("theta_deg"), mf.at("deformation_index"),
      mp.at("deformation_index"), mf.at("omega_tt"), mp.at("omega_tt"));
  // One patch through the list is the patch; the wrong number of patches is refused.
  EXPECT_THROW(t_faces.record(1.0, polar), std::invalid_argument);
  EXPECT_THROW(solid::BodyTracker(std::vector<Patch>{}, true), std::invalid_argument);
}
