// The contact repulsion (coupling/repulsion.hpp): its pressure law, the force between two parallel sheets
// and from a wall against the law, the pairs found through the fluid elements against an all-pairs search
// (periodic wrap, a curved channel), momentum conservation, and which points take no part.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "../../support/tolerances.hpp"
#include "coupling/locator.hpp"
#include "coupling/repulsion.hpp"
#include "geometry/builders.hpp"

using namespace cellfsi;
using cellfsi_test::agree;
using cellfsi_test::kEps;
using coupling::Location;
using coupling::Repulsion;
using coupling::RepulsionBody;
using geometry::Vec3;

namespace {

// Bodies of points with areas, located in a patch (the coupling's own point location).
struct Cloud {
  std::vector<std::vector<Vec3>> x;
  std::vector<std::vector<double>> area;
  std::vector<std::vector<Location>> loc;
  std::vector<RepulsionBody> bodies(const geometry::Patch& patch) {
    coupling::Locator locator(patch);
    loc.assign(x.size(), {});
    std::vector<RepulsionBody> b(x.size());
    for (size_t k = 0; k < x.size(); ++k) {
      for (const Vec3& p : x[k]) loc[k].push_back(locator.locate_or_throw(p));
      if (!x[k].empty()) b[k] = {&x[k], &area[k], &loc[k]};
    }
    return b;
  }
};

// The same forces by brute force: every point against every point of every other body (nearest one per
// body within r_c, pair force a_q P / 2 both ways), distances through the nearest periodic image along x
// (period lx; 0: none); a body against its own points too where they are nearer through another image.
std::vector<std::vector<Vec3>> all_pairs(const Cloud& c, double rc, double p0, double lx) {
  std::vector<std::vector<Vec3>> f(c.x.size());
  for (size_t a = 0; a < c.x.size(); ++a) f[a].assign(c.x[a].size(), Vec3::Zero());
  const auto sep = [&](const Vec3& u, const Vec3& v) {
    Vec3 r = u - v;
    if (lx > 0) r[0] -= lx * std::round(r[0] / lx);
    return r;
  };
  for (size_t a = 0; a < c.x.size(); ++a)
    for (size_t i = 0; i < c.x[a].size(); ++i)
      for (size_t b = 0; b < c.x.size(); ++b) {
        if (c.x[b].empty()) continue;
        double best = rc;
        int j_best = -1;
        for (size_t j = 0; j < c.x[b].size(); ++j) {
          if (b == a && sep(c.x[a][i], c.x[b][j]) == c.x[a][i] - c.x[b][j]) continue;
          const double d = sep(c.x[a][i], c.x[b][j]).norm();
          if (d < best) best = d, j_best = static_cast<int>(j);
        }
        if (j_best < 0) continue;
        const Vec3 r = sep(c.x[a][i], c.x[b][j_best]);
        const Vec3 force = 0.5 * c.area[a][i] * coupling::repulsion_pressure(best, rc, p0) * r / best;
        f[a][i] += force;
        f[b][j_best] -= force;
      }
  return f;
}

// Every point's force agrees with the all-pairs one to 1e-12 of the largest (the same sums in another order).
void expect_same_forces(const std::vector<std::vector<Vec3>>& f, const std::vector<std::vector<Vec3>>& g) {
  double scale = 0;
  for (const auto& body : g)
    for (const Vec3& v : body) scale = std::max(scale, v.norm());
  ASSERT_EQ(f.size(), g.size());
  for (size_t b = 0; b < g.size(); ++b) {
    ASSERT_EQ(f[b].size(), g[b].size()) << b;
    for (size_t i = 0; i < g[b].size(); ++i)
      EXPECT_LT((f[b][i] - g[b][i]).norm(), 1e-12 * scale) << b << " " << i;
  }
}

}  // namespace

TEST(Repulsion, PressureLawStartsSmoothlyAndGrowsWithoutBound) {
  const double rc = 2e-5, p0 = 300;
  EXPECT_EQ(coupling::repulsion_pressure(rc, rc, p0), 0.0);
  EXPECT_EQ(coupling::repulsion_pressure(2 * rc, rc, p0), 0.0);
  EXPECT_TRUE(agree(coupling::repulsion_pressure(rc / 2, rc, p0), p0, 4 * kEps));
  // (1 - s)^2 / s^2: a zero of second order at s = 1 (its slope, by a central difference, vanishes there).
  const double h = 1e-6 * rc;
  const double slope =
      (coupling::repulsion_pressure(rc - h, rc, p0) - coupling::repulsion_pressure(rc - 3 * h, rc, p0)) /
      (2 * h);
  EXPECT_LT(std::abs(slope) * rc, 1e-5 * p0);
  EXPECT_TRUE(agree(coupling::repulsion_pressure(1e-3 * rc, rc, p0), 999.0 * 999.0 * p0, 1e-12));
}

TEST(Repulsion, TwoParallelSheetsFeelThePressureOfTheLawAndNoNetForce) {
  // Two rows of points 0.4 r_c apart, along the periodic direction of a rectangle over 0.9 of its period (a
  // row over the whole period would meet its own image): each point feels a P(d) (half from its own pair,
  // half as the reaction of its partner's).
  const double lx = 1e-3, ly = 5e-4, rc = 2e-5, p0 = 100, gap = 0.4 * rc, a = 1e-6;
  const geometry::Patch fluid = geometry::rectangle(lx, ly, 50, 25, 2, {true, false});
  Cloud c;
  c.x.resize(2), c.area.resize(2);
  for (int i = 0; i < 180; ++i) {
    const double x = (i + 0.5) * lx / 200;
    c.x[0].push_back(Vec3(x, 0.25e-3, 0)), c.x[1].push_back(Vec3(x, 0.25e-3 + gap, 0));
    c.area[0].push_back(a), c.area[1].push_back(a);
  }
  Repulsion rep(fluid, rc, p0, false);
  std::vector<std::vector<Vec3>> f;
  const coupling::RepulsionStats st = rep.forces(c.bodies(fluid), f);
  const double p = coupling::repulsion_pressure(gap, rc, p0);
  Vec3 total = Vec3::Zero();
  for (int i = 0; i < 180; ++i) {
    EXPECT_TRUE(agree(f[0][i][1], -a * p, 1e-12)) << i;
    EXPECT_TRUE(agree(f[1][i][1], a * p, 1e-12)) << i;
    EXPECT_LT(std::abs(f[0][i][0]), 1e-12 * a * p);
    total += f[0][i] + f[1][i];
  }
  EXPECT_LT(total.norm(), 1e-12 * 180 * a * p);
  EXPECT_TRUE(agree(st.cell_gap, gap, 1e-12));
  EXPECT_EQ(st.cell_pairs, 360);
}

TEST(Repulsion, ABodyThatDriftedByWholePeriodsMeetsItsNeighbourAllTheSame) {
  // Bodies of a periodic channel travel several periods: their points' coordinates are not wrapped. The same
  // two sheets, one of them two periods and the other three periods along: the same forces.
  const double lx = 1e-3, ly = 5e-4, rc = 2e-5, p0 = 100, gap = 0.4 * rc;
  const geometry::Patch fluid = geometry::rectangle(lx, ly, 50, 25, 2, {true, false});
  Cloud near, far;
  near.x.resize(2), near.area.resize(2);
  for (int i = 0; i < 50; ++i) {
    const double x = (i + 0.5) * 0.2 * lx / 50;
    near.x[0].push_back(Vec3(x, 2.5e-4, 0)), near.x[1].push_back(Vec3(x, 2.5e-4 + gap, 0));
    near.area[0].push_back(1e-6), near.area[1].push_back(1e-6);
  }
  far = near;
  for (Vec3& x : far.x[0]) x[0] += 2 * lx;
  for (Vec3& x : far.x[1]) x[0] -= 3 * lx;
  Repulsion rep(fluid, rc, p0, false);
  std::vector<std::vector<Vec3>> f, g;
  rep.forces(near.bodies(fluid), f);
  const coupling::RepulsionStats st = rep.forces(far.bodies(fluid), g);
  EXPECT_EQ(st.cell_pairs, 100);
  for (int b = 0; b < 2; ++b)
    for (int i = 0; i < 50; ++i)
      EXPECT_LT((f[b][i] - g[b][i]).norm(), 1e-9 * f[b][i].norm()) << b << " " << i;
}

TEST(Repulsion, TheElementSearchFindsWhatAllPairsFind) {
  // Three bodies of random points in a periodic rectangle, crowded near x = 0 so that pairs wrap around the
  // period; a cut-off of 1.5 elements (two layers of elements searched). (Each body's points are wrapped into
  // the period, so its points on either side of x = 0 also meet as through its own image, in both searches.)
  const double lx = 1e-3, ly = 5e-4, rc = 1.5 * lx / 40, p0 = 50;
  const geometry::Patch fluid = geometry::rectangle(lx, ly, 40, 20, 3, {true, false});
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> ux(-0.1 * lx, 0.1 * lx), uy(0.2 * ly, 0.8 * ly), ua(0.5e-6, 2e-6);
  Cloud c;
  c.x.resize(4), c.area.resize(4);  // body 2: bulky (no points)
  for (int b : {0, 1, 3})
    for (int i = 0; i < 300; ++i) {
      double x = ux(gen);
      if (x < 0) x += lx;
      c.x[b].push_back(Vec3(x, uy(gen), 0));
      c.area[b].push_back(ua(gen));
    }
  Repulsion rep(fluid, rc, p0, false);
  std::vector<std::vector<Vec3>> f;
  const coupling::RepulsionStats st = rep.forces(c.bodies(fluid), f);
  const std::vector<std::vector<Vec3>> g = all_pairs(c, rc, p0, lx);
  ASSERT_GT(st.cell_pairs, 100);
  expect_same_forces(f, g);
  EXPECT_TRUE(f[2].empty());
  // No net force: the pairs' forces cancel to round-off of the largest.
  double scale = 0;
  Vec3 total = Vec3::Zero();
  for (const auto& body : f)
    for (const Vec3& v : body) scale = std::max(scale, v.norm()), total += v;
  EXPECT_LT(total.norm(), 1e-10 * scale);
}

TEST(Repulsion, TheSearchOnTheCurvedNarrowingFindsWhatAllPairsFind) {
  geometry::NarrowingChannel ch;
  const geometry::Patch fluid = geometry::narrowing_channel(ch, 96, 32, 3);
  const double rc = 2 * ch.throat_height / 32, p0 = 20;
  std::mt19937 gen(3);
  std::uniform_real_distribution<double> ux(ch.throat_center - 1.2e-3, ch.throat_center + 1.2e-3),
      uy(-0.9, 0.9);
  Cloud c;
  c.x.resize(2), c.area.resize(2);
  for (int b = 0; b < 2; ++b)
    for (int i = 0; i < 400; ++i) {
      const double x = ux(gen);
      const double half = ch.height / 2 - ch.wall_offset(x);
      c.x[b].push_back(Vec3(x, uy(gen) * half, 0));
      c.area[b].push_back(1e-6);
    }
  Repulsion rep(fluid, rc, p0, false);
  std::vector<std::vector<Vec3>> f;
  const coupling::RepulsionStats st = rep.forces(c.bodies(fluid), f);
  const std::vector<std::vector<Vec3>> g = all_pairs(c, rc, p0, ch.length);
  ASSERT_GT(st.cell_pairs, 50);
  expect_same_forces(f, g);
}

TEST(Repulsion, In3DTheSearchFindsWhatAllPairsFindAndTheWallsPush) {
  // A box periodic in x and z (walls in y), two bodies of random points crowded near the x = 0 end, a cut-off
  // of 1.2 elements; and a point near each wall (the walls as triangles). (Wrapped into the period, each body
  // also meets its own image across x = 0, in both searches.)
  const double L = 6e-4, rc = 1.2 * L / 12, p0 = 30;
  const geometry::Patch fluid = geometry::box(L, L, L, 12, 12, 12, 2, {true, false, true});
  std::mt19937 gen(11);
  std::uniform_real_distribution<double> ux(-0.15 * L, 0.15 * L), u(0.2 * L, 0.8 * L);
  Cloud c;
  c.x.resize(2), c.area.resize(2);
  for (int b = 0; b < 2; ++b)
    for (int i = 0; i < 400; ++i) {
      double x = ux(gen);
      if (x < 0) x += L;
      c.x[b].push_back(Vec3(x, u(gen), u(gen)));
      c.area[b].push_back(1e-9);
    }
  Repulsion rep(fluid, rc, p0, false);
  std::vector<std::vector<Vec3>> f;
  const coupling::RepulsionStats st = rep.forces(c.bodies(fluid), f);
  const std::vector<std::vector<Vec3>> g = all_pairs(c, rc, p0, L);  // (wraps x only: z pairs stay inside)
  ASSERT_GT(st.cell_pairs, 50);
  expect_same_forces(f, g);

  Repulsion walls(fluid, rc, p0);
  Cloud w;
  w.x = {{Vec3(1e-4, 0.25 * rc, 3e-4), Vec3(5e-4, L - 0.6 * rc, 1e-4)}};
  w.area = {{1e-9, 1e-9}};
  const coupling::RepulsionStats ws = walls.forces(w.bodies(fluid), f);
  EXPECT_TRUE(agree(f[0][0][1], 1e-9 * coupling::repulsion_pressure(0.25 * rc, rc, p0), 1e-12));
  EXPECT_TRUE(agree(f[0][1][1], -1e-9 * coupling::repulsion_pressure(0.6 * rc, rc, p0), 1e-12));
  EXPECT_LT(std::abs(f[0][0][0]) + std::abs(f[0][0][2]), 1e-12 * std::abs(f[0][0][1]));
  EXPECT_EQ(ws.wall_points, 2);
}

TEST(Repulsion, AWallPushesAPointAlongItsNormalByThePressureOfTheLaw) {
  // Flat walls of a periodic rectangle (exact), and the narrowing's curved wall (a polyline of 8 chords per
  // element: its distance within 1e-3 of an element of the exact profile's).
  const double lx = 1e-3, ly = 5e-4, rc = 2e-5, p0 = 10, a = 2e-6;
  const geometry::Patch box = geometry::rectangle(lx, ly, 50, 25, 2, {true, false});
  Repulsion rep(box, rc, p0);
  Cloud c;
  c.x = {{Vec3(3e-4, 0.3 * rc, 0), Vec3(-2e-4, ly - 0.7 * rc, 0), Vec3(5e-4, 2 * rc, 0)}};
  c.area = {{a, a, a}};
  std::vector<std::vector<Vec3>> f;
  const coupling::RepulsionStats st = rep.forces(c.bodies(box), f);
  EXPECT_TRUE(agree(f[0][0][1], a * coupling::repulsion_pressure(0.3 * rc, rc, p0), 1e-12));
  EXPECT_TRUE(agree(f[0][1][1], -a * coupling::repulsion_pressure(0.7 * rc, rc, p0), 1e-12));
  EXPECT_LT(std::abs(f[0][0][0]) + std::abs(f[0][1][0]), 1e-12 * a * p0);
  EXPECT_EQ(f[0][2].norm(), 0.0);
  EXPECT_EQ(st.wall_points, 2);
  EXPECT_TRUE(agree(st.wall_gap, 0.3 * rc, 1e-12));

  geometry::NarrowingChannel ch;
  const geometry::Patch channel = geometry::narrowing_channel(ch, 96, 32, 3);
  Repulsion curved(channel, rc, p0);
  // Points on the transition, at a distance along the exact wall's normal.
  for (double x : {2.1e-3, 2.3e-3, 2.45e-3}) {
    const double h = 1e-8, y = ch.height / 2 - ch.wall_offset(x);
    const double slope = -(ch.wall_offset(x + h) - ch.wall_offset(x - h)) / (2 * h);
    const Vec3 normal = Vec3(slope, -1, 0).normalized();  // into the channel from the upper wall
    const double d = 0.5 * rc;
    Vec3 n;
    const double dist = curved.wall_distance(Vec3(x, y, 0) + d * normal, n);
    EXPECT_LT(std::abs(dist - d), 1e-3 * ch.length / 96) << x;
    EXPECT_LT((n - normal).norm(), 1e-2) << x;
  }
}

TEST(Repulsion, ABodysOwnPointsAndFarBodiesFeelNothing) {
  const geometry::Patch fluid = geometry::rectangle(1e-3, 5e-4, 50, 25, 2, {true, false});
  const double rc = 2e-5;
  Cloud c;
  // One body's points 0.1 r_c apart, another body far away.
  c.x = {{Vec3(5e-4, 2.5e-4, 0), Vec3(5e-4 + 0.1 * rc, 2.5e-4, 0)}, {Vec3(1e-4, 2.5e-4, 0)}};
  c.area = {{1e-6, 1e-6}, {1e-6}};
  Repulsion rep(fluid, rc, 100);
  std::vector<std::vector<Vec3>> f;
  const coupling::RepulsionStats st = rep.forces(c.bodies(fluid), f);
  for (const auto& body : f)
    for (const Vec3& v : body) EXPECT_EQ(v.norm(), 0.0);
  EXPECT_EQ(st.cell_pairs, 0);
  EXPECT_TRUE(std::isinf(st.cell_gap));
}

TEST(Repulsion, AMembraneSpanningThePeriodMeetsItsOwnImage) {
  // A ring stretched along the periodic x (semi-axes 0.495 and 0.1 of the period): its two tips are 0.01 of
  // the period (half the cut-off) apart through the period, and each tip's points repel the other tip's, as
  // all pairs through the image give them, with no net force; neighbours along the ring (0.03 r_c apart)
  // never. The same ring at 0.45 of the period feels nothing.
  const double lx = 1e-3, ly = 5e-4, rc = 2e-5, p0 = 100;
  const geometry::Patch fluid = geometry::rectangle(lx, ly, 50, 25, 2, {true, false});
  const auto ring = [&](double ax) {
    Cloud c;
    c.x.resize(1), c.area.resize(1);
    for (int i = 0; i < 4000; ++i) {
      const double t = 2 * M_PI * i / 4000;
      c.x[0].push_back(Vec3(0.5 * lx + ax * lx * std::cos(t), 0.5 * ly + 0.1 * lx * std::sin(t), 0));
      c.area[0].push_back(1e-7);
    }
    return c;
  };
  Repulsion rep(fluid, rc, p0, false);
  Cloud c = ring(0.495);
  std::vector<std::vector<Vec3>> f;
  const coupling::RepulsionStats st = rep.forces(c.bodies(fluid), f);
  ASSERT_GT(st.cell_pairs, 0);
  EXPECT_TRUE(agree(st.cell_gap, 0.01 * lx, 1e-9));
  expect_same_forces(f, all_pairs(c, rc, p0, lx));
  Vec3 total = Vec3::Zero();
  double scale = 0;
  for (size_t i = 0; i < f[0].size(); ++i) {
    total += f[0][i], scale = std::max(scale, f[0][i].norm());
    // (Only the tips, within r_c of the other tip through the period.)
    if (f[0][i].norm() > 0) {
      EXPECT_GT(std::abs(c.x[0][i][0] - 0.5 * lx), 0.47 * lx) << i;
    }
  }
  EXPECT_LT(total.norm(), 1e-12 * scale);
  // The right tip is pushed back (-x), the left one forward (+x).
  EXPECT_LT(f[0][0][0], 0.0);
  EXPECT_GT(f[0][2000][0], 0.0);
  // The same ring carried two periods along x (a body's points are not wrapped): the same forces.
  Cloud far = c;
  for (Vec3& x : far.x[0]) x[0] += 2 * lx;
  std::vector<std::vector<Vec3>> g;
  rep.forces(far.bodies(fluid), g);
  for (size_t i = 0; i < f[0].size(); ++i) EXPECT_LT((g[0][i] - f[0][i]).norm(), 1e-9 * scale) << i;
  Cloud shorter = ring(0.45);
  const coupling::RepulsionStats none = rep.forces(shorter.bodies(fluid), f);
  EXPECT_EQ(none.cell_pairs, 0);
  for (const Vec3& v : f[0]) EXPECT_EQ(v.norm(), 0.0);
}

TEST(Repulsion, BadConstantsAreRefused) {
  const geometry::Patch fluid = geometry::rectangle(1e-3, 5e-4, 10, 5, 2, {true, false});
  EXPECT_THROW(Repulsion(fluid, 0, 1), std::invalid_argument);
  EXPECT_THROW(Repulsion(fluid, 1e-5, -1), std::invalid_argument);
  EXPECT_THROW(Repulsion(fluid, std::nan(""), 1), std::invalid_argument);
}
