// The thin shell's kinematics from its mid-surface (solid/shell_kinematics.hpp): F against finite differences
// of the two maps, the incompressible mid-surface, rigid motions, and a cylinder dilated exactly.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "geometry/patch.hpp"
#include "solid/shell_kinematics.hpp"

using namespace cellfsi;
using solid::Mat3;
using solid::Vec3;

namespace {

/// A rational biquadratic surface over [0, 1]^2, 3 x 3 elements, doubly curved: control points (x, y, f(x,
/// y)), weights 0.8-1.2.
geometry::Patch curved_surface(std::mt19937& rng) {
  const int p = 2, n = 3;
  const geometry::KnotVector kv = geometry::KnotVector::open_uniform(p, n);
  const int m = kv.n_basis();
  std::uniform_real_distribution<double> w(0.8, 1.2);
  std::vector<Vec3> cp;
  std::vector<double> weights;
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < m; ++i) {
      const double x = 1e-4 * i / (m - 1), y = 1e-4 * j / (m - 1);
      cp.emplace_back(x, y, 0.3e-4 * std::sin(2e4 * x) * std::cos(1.5e4 * y) + 0.2e-4 * x * y * 1e4);
      weights.push_back(w(rng));
    }
  return geometry::Patch({kv, kv}, 3, cp, weights);
}

/// The same surface with its control points moved by a smooth finite deformation, a rotation and noise.
geometry::Patch deformed(const geometry::Patch& ref, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  const Mat3 Rot = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  std::vector<Vec3> cp;
  for (const Vec3& X : ref.control_points()) {
    const Vec3 y(1.3 * X.x() + 0.4 * X.y() + 2e3 * X.x() * X.y(), 0.8 * X.y() - 0.2 * X.x(),
                 X.z() + 1e3 * X.x() * X.x());
    cp.push_back(Rot * y + Vec3(1e-4, -2e-4, 3e-4) + 2e-6 * Vec3(u(rng), u(rng), u(rng)));
  }
  return geometry::Patch(ref.all_knots(), 3, cp, ref.weights());
}

/// The shell's point found from positions alone (first derivatives of the surface): X(theta) + zeta N and
/// x(theta)
/// + zeta lambda3 n, with N, n and lambda3 from the tangents.
Vec3 point_of(const geometry::Patch& ref, const geometry::Patch& cur, double t0, double t1, double zeta,
              bool current) {
  const geometry::MapValues r = ref.evaluate({t0, t1, 0}, 1), c = cur.evaluate({t0, t1, 0}, 1);
  const Vec3 cr = r.dx.col(0).cross(r.dx.col(1)), cc = c.dx.col(0).cross(c.dx.col(1));
  if (!current) return r.x + zeta * cr.normalized();
  return c.x + zeta * (cr.norm() / cc.norm()) * cc.normalized();
}

}  // namespace

TEST(ShellKinematics, DeformationGradientIsTheDerivativeOfTheTwoMaps) {
  std::mt19937 rng(7);
  const geometry::Patch ref = curved_surface(rng);
  const geometry::Patch cur = deformed(ref, rng);
  const double h = 0.32e-4;
  double worst_F = 0, worst_J = 0, worst_x = 0;
  std::uniform_real_distribution<double> u(0.05, 0.95);
  for (int k = 0; k < 20; ++k) {
    const double t0 = u(rng), t1 = u(rng), zeta = (u(rng) - 0.5) * h;
    const solid::ShellPoint p =
        solid::shell_point(ref.evaluate({t0, t1, 0}, 2), cur.evaluate({t0, t1, 0}, 2), zeta);
    // Central differences in (theta_1, theta_2, zeta) of both maps: F = dx (dX)^{-1}.
    const double e[3] = {1e-5, 1e-5, 1e-3 * h};
    Mat3 dX, dx;
    for (int d = 0; d < 3; ++d) {
      const double s0 = d == 0 ? e[0] : 0, s1 = d == 1 ? e[1] : 0, s2 = d == 2 ? e[2] : 0;
      for (int which = 0; which < 2; ++which) {
        const Vec3 plus = point_of(ref, cur, t0 + s0, t1 + s1, zeta + s2, which == 1);
        const Vec3 minus = point_of(ref, cur, t0 - s0, t1 - s1, zeta - s2, which == 1);
        (which == 0 ? dX : dx).col(d) = (plus - minus) / (2 * e[d]);
      }
    }
    const Mat3 F_fd = dx * dX.inverse();
    worst_F = std::max(worst_F, (p.F - F_fd).norm() / F_fd.norm());
    worst_J = std::max(worst_J, std::abs(p.ref_jacobian - dX.determinant()) / dX.determinant());
    worst_x = std::max(worst_x, (p.x - point_of(ref, cur, t0, t1, zeta, true)).norm() / h);
  }
  EXPECT_LT(worst_F, 1e-6);  // (central differences: truncation ~ e^2 times the third derivatives)
  EXPECT_LT(worst_J, 1e-6);
  EXPECT_LT(worst_x, 1e-10);
}

TEST(ShellKinematics, MidSurfaceKeepsItsVolumeAndARigidMotionIsARotation) {
  std::mt19937 rng(11);
  const geometry::Patch ref = curved_surface(rng);
  const geometry::Patch cur = deformed(ref, rng);
  const Mat3 Rot = Eigen::AngleAxisd(1.1, Vec3(-1, 0.5, 2).normalized()).toRotationMatrix();
  std::vector<Vec3> moved;
  for (const Vec3& X : ref.control_points()) moved.push_back(Rot * X + Vec3(3e-4, 1e-4, -2e-4));
  const geometry::Patch rigid(ref.all_knots(), 3, moved, ref.weights());
  const double h = 0.32e-4;
  double worst_det = 0, worst_rot = 0;
  for (double t0 : {0.1, 0.37, 0.8})
    for (double t1 : {0.2, 0.55, 0.93}) {
      const geometry::MapValues r = ref.evaluate({t0, t1, 0}, 2);
      const solid::ShellPoint mid = solid::shell_point(r, cur.evaluate({t0, t1, 0}, 2), 0.0);
      worst_det = std::max(worst_det, std::abs(mid.F.determinant() - 1));
      EXPECT_NEAR(mid.thickness_stretch * (mid.F * mid.frame.col(0)).cross(mid.F * mid.frame.col(1)).norm(),
                  1.0, 1e-12);
      for (double zeta : {-h / 2, 0.0, h / 2}) {
        const solid::ShellPoint p = solid::shell_point(r, rigid.evaluate({t0, t1, 0}, 2), zeta);
        worst_rot = std::max(worst_rot, (p.F - Rot).norm());
        EXPECT_NEAR(p.thickness_stretch, 1.0, 1e-12);
        // The frame: orthonormal, right-handed, its third column the reference normal.
        EXPECT_LT((p.frame.transpose() * p.frame - Mat3::Identity()).norm(), 1e-12);
        EXPECT_NEAR(p.frame.determinant(), 1.0, 1e-12);
      }
    }
  EXPECT_LT(worst_det, 1e-12);
  EXPECT_LT(worst_rot, 1e-10);
}

TEST(ShellKinematics, ADilatedCylinderGivesItsExactStretchesThroughTheThickness) {
  // A quarter of a cylinder of radius R (exact: rational quadratic around, linear along z), its control
  // points scaled by s about the axis's origin: the mid-surface's stretches are s around and s along, so
  // lambda3 = 1 / s^2, and at height zeta (outward) the stretch around is (s R + zeta / s^2) / (R + zeta).
  const double R = 3e-4, Lz = 2e-4, s = 1.3;
  const geometry::KnotVector around = geometry::KnotVector::open_uniform(2, 1);
  const geometry::KnotVector along = geometry::KnotVector::open_uniform(1, 1);
  const double w = std::sqrt(0.5);
  std::vector<Vec3> cp, scaled;
  std::vector<double> weights;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 3; ++i) {
      const Vec3 arc[3] = {Vec3(R, 0, 0), Vec3(R, R, 0), Vec3(0, R, 0)};
      cp.push_back(arc[i] + Vec3(0, 0, j * Lz));
      scaled.push_back(s * cp.back());
      weights.push_back(i == 1 ? w : 1.0);
    }
  const geometry::Patch ref({around, along}, 3, cp, weights), cur({around, along}, 3, scaled, weights);
  const double h = 0.32e-4;
  for (double t : {0.0, 0.3, 0.77, 1.0})
    for (double zeta : {-h / 2, -h / 6, 0.0, h / 3, h / 2}) {
      const solid::ShellPoint p =
          solid::shell_point(ref.evaluate({t, 0.4, 0}, 2), cur.evaluate({t, 0.4, 0}, 2), zeta);
      const Vec3 X = ref.evaluate({t, 0.4, 0}, 0).x;
      const Vec3 radial = Vec3(X.x(), X.y(), 0).normalized();  // the outward normal
      const Vec3 hoop = Vec3(0, 0, 1).cross(radial);
      const double around_stretch = (s * R + zeta / (s * s)) / (R + zeta);
      EXPECT_NEAR(p.thickness_stretch, 1 / (s * s), 1e-12);
      EXPECT_NEAR((p.F * hoop).norm(), around_stretch, 1e-12) << "t " << t << ", zeta " << zeta;
      EXPECT_NEAR((p.F * hoop).dot(hoop), around_stretch, 1e-12);
      EXPECT_NEAR((p.F * Vec3(0, 0, 1)).z(), s, 1e-12);
      EXPECT_NEAR((p.F * radial).dot(radial), 1 / (s * s), 1e-12);
      EXPECT_NEAR(std::abs(p.frame.col(2).dot(radial)), 1.0, 1e-12);
      // The reference volume element: (R + zeta) / R of the mid-surface's, times that area element.
      const geometry::MapValues r = ref.evaluate({t, 0.4, 0}, 1);
      EXPECT_NEAR(p.ref_jacobian / r.dx.col(0).cross(r.dx.col(1)).norm(), (R + zeta) / R, 1e-12);
      EXPECT_NEAR((p.x - s * X).norm(), std::abs(zeta) / (s * s), 1e-12 * R);
    }
}

TEST(ShellKinematics, DegenerateSurfacesAndHeightsBeyondTheCurvatureAreRefused) {
  const geometry::KnotVector kv = geometry::KnotVector::open_uniform(1, 1);
  const std::vector<Vec3> flat = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)};
  const std::vector<Vec3> line = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 0), Vec3(1, 0, 0)};
  const geometry::Patch a({kv, kv}, 3, flat, {1, 1, 1, 1}), b({kv, kv}, 3, line, {1, 1, 1, 1});
  EXPECT_NO_THROW(solid::shell_point(a.evaluate({0.5, 0.5, 0}, 2), a.evaluate({0.5, 0.5, 0}, 2), 0.1));
  EXPECT_THROW(solid::shell_point(a.evaluate({0.5, 0.5, 0}, 2), b.evaluate({0.5, 0.5, 0}, 2), 0.0),
               std::invalid_argument);
  EXPECT_THROW(solid::shell_point(b.evaluate({0.5, 0.5, 0}, 2), a.evaluate({0.5, 0.5, 0}, 2), 0.0),
               std::invalid_argument);
  // A cylinder of radius 1: a height of -1.5 (inwards, past the axis) inverts the reference shell.
  const geometry::KnotVector around = geometry::KnotVector::open_uniform(2, 1);
  const double w = std::sqrt(0.5);
  const std::vector<Vec3> cyl = {Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0),
                                 Vec3(1, 0, 1), Vec3(1, 1, 1), Vec3(0, 1, 1)};
  const geometry::Patch c({around, kv}, 3, cyl, {1, w, 1, 1, w, 1});
  const geometry::MapValues m = c.evaluate({0.5, 0.5, 0}, 2);
  const double outward = m.dx.col(0).cross(m.dx.col(1)).dot(m.x - Vec3(0, 0, m.x.z())) > 0 ? 1 : -1;
  EXPECT_NO_THROW(solid::shell_point(m, m, -0.5 * outward));
  EXPECT_THROW(solid::shell_point(m, m, -1.5 * outward), std::invalid_argument);
}
