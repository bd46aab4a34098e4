// Point inversion: round trips to 1e-12, a bounded number of Newton steps from a warm start, and points
// outside reported as outside with their distance.
#include <gtest/gtest.h>

#include <random>

#include "geometry/builders.hpp"
#include "geometry/inversion.hpp"

using namespace cellfsi::geometry;

namespace {

struct Sample {
  Param xi;
  Vec3 x;
  Index3 element;
};

std::vector<Sample> random_points(const Patch& patch, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::vector<Sample> s;
  for (int i = 0; i < n; ++i) {
    Sample q{{0, 0, 0}, Vec3::Zero(), {0, 0, 0}};
    for (int d = 0; d < patch.param_dim(); ++d) {
      const KnotVector& kv = patch.knots(d);
      q.xi[d] = kv.a() + (kv.b() - kv.a()) * U(rng);
    }
    q.x = patch.point(q.xi);
    q.element = patch.find_element(q.xi);
    s.push_back(q);
  }
  return s;
}

double param_error(const Patch& patch, const Param& a, const Param& b) {
  double e = 0;
  for (int d = 0; d < patch.param_dim(); ++d) {
    double diff = std::abs(a[d] - b[d]);
    if (patch.closed(d)) diff = std::min(diff, patch.knots(d).period() - diff);  // seam: u = a ~ u = b
    e = std::max(e, diff);
  }
  return e;
}

void expect_round_trips(const Patch& patch, int n, double tol) {
  const PointInverter inv(patch);
  for (const Sample& s : random_points(patch, n, 11)) {
    const InversionResult r = inv.invert(s.x);
    ASSERT_TRUE(r.inside) << "distance " << r.distance;
    EXPECT_LT(param_error(patch, r.xi, s.xi), tol);
    EXPECT_LT((patch.point(r.xi) - s.x).norm(), 1e-13 * (1e-3 + s.x.norm()));
  }
}

}  // namespace

TEST(Inversion, RoundTripsInTheNarrowingChannel) {
  expect_round_trips(narrowing_channel(NarrowingChannel{}, 96, 32, 3), 300, 1e-12);
}

TEST(Inversion, RoundTripsInTheHollowEllipse) {
  expect_round_trips(hollow_ellipse(2e-4, 1e-4, 5e-7, 208, 2, Vec3(1.2e-3, 6e-4, 0), 1.2), 300, 1e-12);
}

TEST(Inversion, RoundTripsInA3dShellAndAPeriodicBox) {
  expect_round_trips(hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 8, 16, 2), 100, 1e-12);
  expect_round_trips(box(1.2e-3, 1.2e-3, 1.2e-3, 8, 8, 8, 2, {true, true, false}), 100, 1e-12);
}

TEST(Inversion, WarmStartTakesFewNewtonSteps) {
  // A point that moved by a small fraction of an element (as a solid point does in one time step) is found
  // from its previous (element, xi) in at most 3 Newton iterations (quadratic convergence from ~1e-2).
  const Patch channel = narrowing_channel(NarrowingChannel{}, 96, 32, 3);
  const PointInverter inv(channel);
  int worst = 0;
  for (const Sample& s : random_points(channel, 200, 5)) {
    Param guess = s.xi;
    guess[0] += 0.05 * (channel.knots(0).element_end(0) - channel.knots(0).element_begin(0));
    guess[1] -= 0.05 * (channel.knots(1).element_end(0) - channel.knots(1).element_begin(0));
    const InversionResult r = inv.invert(s.x, channel.find_element(guess), guess);
    ASSERT_TRUE(r.inside);
    EXPECT_LT(param_error(channel, r.xi, s.xi), 1e-12);
    worst = std::max(worst, r.iterations);
  }
  EXPECT_LE(worst, 3);
  // The affine rectangle needs exactly one Newton step.
  const Patch rect = rectangle(2.4e-3, 1.2e-3, 32, 16, 3, {true, false});
  const PointInverter rinv(rect);
  const InversionResult r =
      rinv.invert(Vec3(1.0e-3, 3e-4, 0), rect.find_element({0.41, 0.26, 0}), {0.41, 0.26, 0});
  EXPECT_TRUE(r.inside);
  EXPECT_EQ(r.iterations, 1);
}

TEST(Inversion, WalksAcrossTheSeamOfAClosedMembrane) {
  const Patch ellipse = hollow_ellipse(2e-4, 1e-4, 5e-7, 64, 2);
  const PointInverter inv(ellipse);
  const Param target{0.3, 0.004, 0};
  const Vec3 x = ellipse.point(target);
  const Index3 last{0, ellipse.n_elements(1) - 1, 0};
  const InversionResult r = inv.invert(x, last, {0.5, 0.995, 0});
  ASSERT_TRUE(r.inside);
  EXPECT_EQ(r.element[1], 0);
  EXPECT_LT(std::abs(r.xi[1] - target[1]), 1e-12);
  EXPECT_GE(r.elements_visited, 2);
}

TEST(Inversion, PointsOutsideAreReportedWithTheirDistance) {
  const NarrowingChannel ch;
  const Patch channel = narrowing_channel(ch, 96, 32, 3);
  const PointInverter inv(channel);
  // Above the straight part of the top wall (far from the throat), by 1e-4 cm.
  const InversionResult above = inv.invert(Vec3(0.0003, 0.5 * ch.height + 1e-4, 0));
  EXPECT_FALSE(above.inside);
  EXPECT_NEAR(above.distance, 1e-4, 1e-8);
  // Inside the throat's wall material (above the narrowed wall at the throat centre).
  const InversionResult wall = inv.invert(Vec3(ch.throat_center, 0.5 * ch.throat_height + 2e-4, 0));
  EXPECT_FALSE(wall.inside);
  EXPECT_NEAR(wall.distance, 2e-4, 1e-6);  // the projected wall is flat there to ~1e-7 cm
  // The hole of a capsule is outside the membrane.
  const Patch ellipse = hollow_ellipse(2e-4, 1e-4, 5e-7, 64, 2);
  const Vec3 centre_point(1e-5, 0, 0);
  const InversionResult hole = PointInverter(ellipse).invert(centre_point);
  EXPECT_FALSE(hole.inside);
  // The point found lies on the inner boundary (xi_0 = 0), no closer than the true nearest boundary point.
  EXPECT_NEAR(hole.xi[0], 0.0, 1e-15);
  double nearest = 1e300;
  for (int s = 0; s < 100000; ++s)
    nearest = std::min(nearest, (ellipse.point({0, s / 1e5, 0}) - centre_point).norm());
  EXPECT_GE(hole.distance, nearest * (1 - 1e-9));
  EXPECT_NEAR(hole.distance, (ellipse.point(hole.xi) - centre_point).norm(), 1e-15);
}

TEST(Inversion, PeriodicImagesAndGuessesPastThePeriodEnd) {
  // A warm-start guess just past the end of a periodic direction (xi = 1 + eps) for a point just before it,
  // and a target given as another periodic image (x + L): both are the same point of the periodic domain.
  const NarrowingChannel ch;
  const Patch channel = narrowing_channel(ch, 384, 128, 3);
  const PointInverter inv(channel);
  const Param xi{0.99976911836054483, 0.5737319058740683, 0};
  const Vec3 x = channel.point(xi);
  const Param guess{1.00003, 0.573, 0};
  const InversionResult warm = inv.invert(x, channel.find_element(guess), guess);
  ASSERT_TRUE(warm.inside);
  EXPECT_LE(warm.iterations, 3);
  EXPECT_LT(std::abs(warm.xi[0] - xi[0]), 1e-12);
  for (double k : {-1.0, 1.0, 2.0}) {
    const InversionResult cold = inv.invert(x + k * Vec3(ch.length, 0, 0));
    ASSERT_TRUE(cold.inside) << "k=" << k;
    EXPECT_LT(std::abs(cold.xi[0] - xi[0]), 1e-12);
    EXPECT_LE(cold.iterations, 3);
  }
}

TEST(Inversion, ColdStartsConvergeQuicklyInTheChannel) {
  // From the element whose centre is nearest, Newton needs at most 3 steps at the paper's resolution.
  const Patch channel = narrowing_channel(NarrowingChannel{}, 384, 128, 3);
  const PointInverter inv(channel);
  int worst = 0;
  for (const Sample& s : random_points(channel, 500, 3)) {
    const InversionResult r = inv.invert(s.x);
    ASSERT_TRUE(r.inside);
    worst = std::max(worst, r.iterations);
  }
  EXPECT_LE(worst, 3);
}
