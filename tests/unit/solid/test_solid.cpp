// The paper's solid: the collocation round trip (exact), the kinematic tangent against finite differences,
// exact kinematics for linear velocity fields, and the Eq. (10) data in simple states. The materials:
// test_materials.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <barrier>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <thread>

#include <unistd.h>

#include "geometry/builders.hpp"
#include "geometry/measures.hpp"
#include "geometry/quadrature.hpp"
#include "solid/material.hpp"
#include "solid/nurbs_solid.hpp"
#include "solid/solid_output.hpp"

using namespace cellfsi;
using solid::Mat3;
using solid::Vec3;

namespace {
std::shared_ptr<const solid::Material> membrane_material() {
  return std::make_shared<solid::DeviatoricNeoHookean>(7500.0);
}

/// One step of 1e-3 s in the homogeneous velocity v = L (x - c): every collocation point gets the same linear
/// displacement, which the collocation reproduces exactly.
void step_homogeneously(solid::NurbsSolid& s, const Mat3& L, const Vec3& c) {
  s.begin_step(solid::TimeParameters::from_rho_inf(0.5, 1e-3));
  std::vector<solid::VelocitySample> vs(s.n_points());
  const std::vector<Vec3> x = s.collocation_points();
  for (int i = 0; i < s.n_points(); ++i) vs[i].v = L * (x[i] - c), vs[i].grad_v = L;
  s.kinematic_update(vs);
  s.end_step();
}

/// The deformation gradient I + A of the least-squares map A of (X - c) to the displacement x - X over the
/// quadrature points (q0: the reference ones, q: the moved ones).
Mat3 fitted_deformation(const std::vector<solid::QuadratureData>& q0,
                        const std::vector<solid::QuadratureData>& q, const Vec3& c) {
  Eigen::Matrix3d XtX = Eigen::Matrix3d::Zero(), XtU = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < q.size(); ++i) {
    const Vec3 X = q0[i].x - c, u = q[i].x - q0[i].x;
    XtX += X * X.transpose();
    XtU += X * u.transpose();
  }
  return Mat3::Identity() + XtX.ldlt().solve(XtU).transpose();
}
}  // namespace

TEST(NurbsSolid, CollocationRoundTripIsExact) {
  // Control variables -> values at the Greville points -> control variables, and the other way round, for a
  // closed membrane (seam layers identified), a disk (degenerate centre) and a 3D shell (closed azimuth,
  // poles).
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  for (const geometry::Patch& p :
       {geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 64, 2), geometry::bulky_ellipse(2e-4, 2e-4, 8, 32, 2),
        geometry::hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 8, 16, 2)}) {
    const solid::NurbsSolid s("body", p, membrane_material(), 1.1);
    const int D = p.physical_dim();
    Eigen::MatrixXd c(s.n_points(), D);
    for (int i = 0; i < c.rows(); ++i)
      for (int j = 0; j < D; ++j) c(i, j) = U(rng);
    const Eigen::MatrixXd back = s.control_from_points(s.points_from_control(c));
    EXPECT_LT((back - c).cwiseAbs().maxCoeff(), 1e-12) << "patch with " << p.n_elements() << " elements";
    const Eigen::MatrixXd vals = s.points_from_control(c);
    EXPECT_LT((s.points_from_control(s.control_from_points(vals)) - vals).cwiseAbs().maxCoeff(), 1e-12);
  }
  // The closed membrane has one collocation point (and one unknown) per distinct control point.
  const geometry::Patch e = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 208, 2);
  EXPECT_EQ(solid::NurbsSolid("m", e, membrane_material(), 1.1).n_points(), 3 * (e.n_control(1) - 1));
}

TEST(NurbsSolid, KinematicTangentMatchesFiniteDifferences) {
  const solid::TimeParameters t = solid::TimeParameters::from_rho_inf(0.5, 5e-4);
  const Vec3 X(1e-4, -2e-4, 0), u_n(1e-6, 2e-6, 0), rate_n(0.01, -0.02, 0);
  const Vec3 v0(0.03, 0.01, 0);
  Mat3 L = Mat3::Zero();
  L.topLeftCorner(2, 2) << 10, 70, -20, 5;
  // v(x) linear: R(u) = udot_{alpha_m}(u) - v(X + u_n + alpha_f (u - u_n)).
  auto R = [&](const Vec3& u) {
    const Vec3 x = X + u_n + t.alpha_f * (u - u_n);
    return solid::NurbsSolid::kinematic_residual(u, u_n, rate_n, t, v0 + L * x);
  };
  const Vec3 u(3e-6, 1e-6, 0);
  const Mat3 T = solid::NurbsSolid::kinematic_tangent(t, L, 2);
  const double h = 1e-9;
  for (int j = 0; j < 2; ++j) {
    Vec3 e = Vec3::Zero();
    e[j] = h;
    const Vec3 fd = (R(u + e) - R(u - e)) / (2 * h);
    for (int i = 0; i < 2; ++i) EXPECT_NEAR(T(i, j), fd[i], 1e-6 * T.norm()) << i << "," << j;
  }
}

TEST(NurbsSolid, RestoredStateContinuesTheStepsExactly) {
  // A checkpoint: a body restored from another's state steps on bit for bit like the one that never stopped.
  const geometry::Patch e = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 32, 2, Vec3(1.2e-3, 6e-4, 0), 0.5);
  solid::NurbsSolid a("capsule", e, membrane_material(), 1.1), b("capsule", e, membrane_material(), 1.1);
  const solid::TimeParameters t = solid::TimeParameters::from_rho_inf(0.5, 5e-4);
  Mat3 L = Mat3::Zero();
  L(0, 1) = 70;
  auto step = [&](solid::NurbsSolid& s) {
    s.begin_step(t);
    for (int it = 0; it < 2; ++it) {
      std::vector<solid::VelocitySample> vs(s.n_points());
      const std::vector<Vec3> x = s.collocation_points();
      for (int i = 0; i < s.n_points(); ++i) vs[i].v = L * x[i], vs[i].grad_v = L;
      s.kinematic_update(vs);
    }
    s.end_step();
  };
  for (int k = 0; k < 3; ++k) step(a);
  b.set_state(a.state());
  for (int k = 0; k < 3; ++k) step(a), step(b);
  EXPECT_EQ(a.state(), b.state());
  EXPECT_EQ(a.current_patch().control_points(), b.current_patch().control_points());
  std::vector<double> bad = a.state();
  bad.push_back(0);
  EXPECT_THROW(b.set_state(bad), std::invalid_argument);
}

TEST(NurbsSolid, LinearVelocityFieldsAreFollowedExactly) {
  // For v(x) = v0 + L x the kinematic equation is linear in u: one Newton update (steps 1-3) solves it, and a
  // uniform velocity translates the body by v t exactly.
  const geometry::Patch e = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 32, 2, Vec3(1.2e-3, 6e-4, 0), 0.5);
  solid::NurbsSolid s("capsule", e, membrane_material(), 1.1);
  const solid::TimeParameters t = solid::TimeParameters::from_rho_inf(0.5, 5e-4);
  const Vec3 v0(0.03, -0.01, 0);
  s.set_rate(std::vector<Vec3>(s.n_points(), v0));
  for (int step = 0; step < 4; ++step) {
    s.begin_step(t);
    std::vector<solid::VelocitySample> vs(s.n_points());
    for (auto& x : vs) x.v = v0;
    s.kinematic_update(vs);
    EXPECT_LT(s.kinematic_update(vs), 1e-14);
    s.end_step();
  }
  const geometry::Patch moved = s.current_patch();
  for (double xi1 : {0.0, 0.3, 0.77}) {
    const Vec3 d = moved.point({0.5, xi1, 0}) - e.point({0.5, xi1, 0});
    EXPECT_LT((d - 4 * 5e-4 * v0).norm(), 1e-15);
  }
  // A shear field: after one update the residual is zero to round-off.
  Mat3 L = Mat3::Zero();
  L(0, 1) = 70;
  s.begin_step(t);
  std::vector<solid::VelocitySample> vs(s.n_points());
  auto sample = [&] {
    const std::vector<Vec3> x = s.collocation_points();
    for (int i = 0; i < s.n_points(); ++i) vs[i].v = L * x[i], vs[i].grad_v = L;
  };
  sample();
  const double r0 = s.kinematic_update(vs);
  sample();
  EXPECT_LT(s.kinematic_update(vs), 1e-12 * r0);
}

TEST(NurbsSolid, AStepCompressingFasterThanOneAndAHalfPerDtTurnsTheBodyOver) {
  // The kinematic update (generalized-alpha, rho_inf 0.5) in v = -k (y - c_y) e_y, a uniaxial compression
  // followed exactly: every length along y, a membrane's thickness as much as the gap between two membranes,
  // scales by one s_n. It stays positive and falls like exp(-k t) while k dt < 3/2; above it the update
  // overshoots through zero within a few steps (docs/validation-future-work.md, "Cells that come close").
  // (Centred at the origin, so that x - c loses no digits however small s_n gets.)
  const Vec3 c = Vec3::Zero();
  const geometry::Patch e = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 16, 2, c, 0.0);
  const std::vector<Vec3> X = solid::NurbsSolid("capsule", e, membrane_material(), 1.1).collocation_points();
  const double dt = 1e-3;
  auto scales = [&](double k_dt, int steps) {
    solid::NurbsSolid s("capsule", e, membrane_material(), 1.1);
    Mat3 L = Mat3::Zero();
    L(1, 1) = -k_dt / dt;
    std::vector<Vec3> rate(s.n_points());  // (moving with the field from the start: no start-up error)
    for (int i = 0; i < s.n_points(); ++i) rate[i] = L * (X[i] - c);
    s.set_rate(rate);
    std::vector<double> out;
    for (int n = 0; n < steps; ++n) {
      s.begin_step(solid::TimeParameters::from_rho_inf(0.5, dt));
      std::vector<solid::VelocitySample> vs(s.n_points());
      for (int it = 0; it < 2; ++it) {
        const std::vector<Vec3> x = s.collocation_points();
        for (int i = 0; i < s.n_points(); ++i) vs[i].v = L * (x[i] - c), vs[i].grad_v = L;
        s.kinematic_update(vs);
      }
      s.end_step();
      // s_n from the point farthest from c along y (the map is x - c = diag(1, s_n) (X - c)).
      const std::vector<Vec3> x = s.collocation_points();
      int far = 0;
      for (int i = 0; i < s.n_points(); ++i)
        if (std::abs(X[i][1] - c[1]) > std::abs(X[far][1] - c[1])) far = i;
      out.push_back((x[far][1] - c[1]) / (X[far][1] - c[1]));
      EXPECT_NEAR(x[far][0], X[far][0], 1e-15);
    }
    return out;
  };
  // Ten steps: at k dt = 1.45 s_n is 5e-12 after them, beyond which it reaches the positions' round-off.
  for (double k_dt : {0.01, 0.5, 1.0, 1.45}) {
    const std::vector<double> s = scales(k_dt, 10);
    EXPECT_GT(*std::min_element(s.begin(), s.end()), 0.0) << "k dt = " << k_dt;
  }
  // Second order: after 40 steps of k dt = 0.01, within 1e-5 of exp(-0.4).
  EXPECT_NEAR(scales(0.01, 40).back(), std::exp(-0.4), 1e-5);
  for (double k_dt : {1.55, 2.0, 10.0}) {
    const std::vector<double> s = scales(k_dt, 6);
    EXPECT_LT(*std::min_element(s.begin(), s.end()), -1e-3) << "k dt = " << k_dt;
  }
}

TEST(NurbsSolid, ControlIncrementIsTheKinematicUpdatesDerivative) {
  // Steps 2-3 are linear in the sampled velocity for a fixed grad v (the tangent's): two bodies updated from
  // v and v + h dv differ in their control variables by exactly h dc / alpha_f, dc = control_increment(dv).
  // Asserted to 1e-9 of max|dc| (round-off of the collocation solve), in 2D and 3D.
  const solid::TimeParameters t = solid::TimeParameters::from_rho_inf(0.5, 5e-4);
  for (int dim : {2, 3}) {
    const geometry::Patch p =
        dim == 2
            ? geometry::rectangle(2e-4, 1e-4, 4, 3, 2, {false, false}, Vec3(1e-4, 2e-4, 0))
            : geometry::box(2e-4, 1e-4, 1.5e-4, 3, 2, 2, 2, {false, false, false}, Vec3(1e-4, 2e-4, 3e-4));
    solid::NurbsSolid a("a", p, membrane_material(), 1.1), b("b", p, membrane_material(), 1.1);
    a.begin_step(t);
    b.begin_step(t);
    Mat3 M;
    M << 10, 70, -5, -20, 5, 12, 3, -8, -15;
    Mat3 L = Mat3::Zero();
    L.topLeftCorner(dim, dim) = M.topLeftCorner(dim, dim);
    const std::vector<Vec3> x = a.collocation_points();
    std::vector<solid::VelocitySample> va(a.n_points()), vb(a.n_points());
    std::vector<Vec3> dv(a.n_points());
    const double h = 1e-3;
    for (int i = 0; i < a.n_points(); ++i) {
      va[i].v = Vec3(std::sin(1e4 * x[i][1]), std::cos(2e4 * x[i][0]), dim == 3 ? x[i][2] * 1e3 : 0.0) * 1e-2;
      dv[i] = Vec3(std::cos(3e4 * x[i][0] + i), 0.5 * std::sin(1e4 * x[i][1]), dim == 3 ? 0.3 : 0.0);
      vb[i].v = va[i].v + h * dv[i];
      va[i].grad_v = vb[i].grad_v = L;
    }
    a.kinematic_update(va);
    b.kinematic_update(vb);
    a.end_step();
    b.end_step();
    Eigen::MatrixXd dc;
    ASSERT_TRUE(a.control_increment(dv, dc));
    ASSERT_EQ(dc.rows(), a.n_control());
    const std::vector<Vec3> ca = a.current_patch().control_points(), cb = b.current_patch().control_points();
    double err = 0;
    for (int k = 0; k < a.n_control(); ++k)
      for (int c = 0; c < dim; ++c)
        err = std::max(err, std::abs(dc(k, c) - t.alpha_f * (cb[k][c] - ca[k][c]) / h));
    EXPECT_LT(err, 1e-9 * dc.cwiseAbs().maxCoeff()) << dim << "D";
    // One column alone (the coupler deals them out to the ranks): that column to round-off, the others zero.
    for (int c = 0; c < dim; ++c) {
      Eigen::MatrixXd one;
      ASSERT_TRUE(a.control_increment(dv, one, c));
      ASSERT_EQ(one.rows(), dc.rows());
      ASSERT_EQ(one.cols(), dc.cols());
      for (int d = 0; d < dim; ++d)
        EXPECT_LE((one.col(d) - (d == c ? Eigen::VectorXd(dc.col(d)) : Eigen::VectorXd::Zero(dc.rows())))
                      .cwiseAbs()
                      .maxCoeff(),
                  1e-12 * dc.cwiseAbs().maxCoeff())
            << dim << "D, column " << c << " of " << d;
    }
    EXPECT_THROW(a.control_increment(dv, dc, dim), std::invalid_argument);
    // A share among ranks needs its exchanges; one rank's share counts its operations.
    solid::KinematicShare lone;
    double operations = 0;
    lone.operations = &operations;
    b.begin_step(t);
    b.kinematic_update(vb, lone);
    EXPECT_GT(operations, 0.0);
    solid::KinematicShare broken;
    broken.parts = 2;
    EXPECT_THROW(b.kinematic_update(vb, broken), std::invalid_argument);
  }
}

TEST(NurbsSolid, AKinematicUpdateSharedAmongPartsEqualsTheWholeOne) {
  // Threads stand for the ranks of a KinematicShare (each updates its run of the points and its columns; the
  // gather and the sum go through shared memory, summed in part order): on 2 and 4 parts (4: more than the
  // columns, some parts without one), the columns dealt from first_column 1, the residual's norm, the control
  // and the linearisation (control_increment, from the gathered tangents) equal to the whole update's to
  // 1e-12.
  const solid::TimeParameters t = solid::TimeParameters::from_rho_inf(0.5, 5e-4);
  const geometry::Patch p =
      geometry::box(2e-4, 1e-4, 1.5e-4, 3, 2, 2, 2, {false, false, false}, Vec3(1e-4, 2e-4, 3e-4));
  solid::NurbsSolid whole("whole", p, membrane_material(), 1.1);
  whole.begin_step(t);
  const std::vector<Vec3> x = whole.collocation_points();
  const int n = whole.n_points();
  Mat3 L;
  L << 10, 70, -5, -20, 5, 12, 3, -8, -15;
  std::vector<solid::VelocitySample> vs(n);
  std::vector<Vec3> dv(n);
  for (int i = 0; i < n; ++i) {
    vs[i].v = Vec3(std::sin(1e4 * x[i][1]), std::cos(2e4 * x[i][0]), x[i][2] * 1e3) * 1e-2;
    vs[i].grad_v = L;
    dv[i] = Vec3(std::cos(3e4 * x[i][0] + i), 0.5 * std::sin(1e4 * x[i][1]), 0.3);
  }
  const double r_whole = whole.kinematic_update(vs);
  Eigen::MatrixXd dc_whole;
  ASSERT_TRUE(whole.control_increment(dv, dc_whole));
  const std::vector<Vec3> c_whole = whole.current_patch().control_points();
  double scale = 0;
  for (const Vec3& c : c_whole) scale = std::max(scale, c.cwiseAbs().maxCoeff());
  for (int parts : {2, 4}) {
    std::vector<std::unique_ptr<solid::NurbsSolid>> body(parts);
    for (auto& b : body) {
      b = std::make_unique<solid::NurbsSolid>("part", p, membrane_material(), 1.1);
      b->begin_step(t);
    }
    std::barrier sync(parts);
    std::vector<double> shared(static_cast<std::size_t>(n) * 12);
    std::vector<std::vector<double>> slots(parts);
    std::vector<double> residual(parts), operations(parts, 0.0);
    std::vector<std::thread> threads;
    for (int q = 0; q < parts; ++q)
      threads.emplace_back([&, q] {
        solid::KinematicShare share;
        share.part = q, share.parts = parts, share.first_column = 1;
        share.operations = &operations[q];
        share.gather = [&, q](double* v, int width) {
          const std::size_t a = static_cast<std::size_t>(n) * q / parts * width,
                            e = static_cast<std::size_t>(n) * (q + 1) / parts * width;
          std::copy(v + a, v + e, shared.begin() + static_cast<std::ptrdiff_t>(a));
          sync.arrive_and_wait();
          std::copy(shared.begin(), shared.begin() + static_cast<std::ptrdiff_t>(n) * width, v);
          sync.arrive_and_wait();
        };
        share.sum = [&, q](double* v, int m) {
          slots[q].assign(v, v + m);
          sync.arrive_and_wait();
          for (int k = 0; k < m; ++k) {
            double total = 0;
            for (int r = 0; r < parts; ++r) total += slots[r][k];
            v[k] = total;
          }
          sync.arrive_and_wait();
        };
        residual[q] = body[q]->kinematic_update(vs, share);
      });
    for (auto& th : threads) th.join();
    for (int q = 0; q < parts; ++q) {
      EXPECT_NEAR(residual[q], r_whole, 1e-12 * r_whole) << parts << " parts, part " << q;
      EXPECT_GT(operations[q], 0.0);
      const std::vector<Vec3> c = body[q]->current_patch().control_points();
      double diff = 0;
      for (std::size_t k = 0; k < c.size(); ++k)
        diff = std::max(diff, (c[k] - c_whole[k]).cwiseAbs().maxCoeff());
      EXPECT_LE(diff, 1e-12 * scale) << parts << " parts, part " << q;
      Eigen::MatrixXd dc;
      ASSERT_TRUE(body[q]->control_increment(dv, dc));
      EXPECT_LE((dc - dc_whole).cwiseAbs().maxCoeff(), 1e-12 * dc_whole.cwiseAbs().maxCoeff())
          << parts << " parts, part " << q;
    }
  }
}

TEST(NurbsSolid, BasisGradientsReproduceTheCurrentPosition) {
  // The spatial gradients d N / d x at the quadrature points of a deformed body: sum_k x_k (x) grad N_k = I
  // (the current position is the isoparametric sum of the control points) and sum_k grad N_k = 0 (partition
  // of unity), to 1e-9 relative.
  const solid::TimeParameters t = solid::TimeParameters::from_rho_inf(0.5, 5e-4);
  const geometry::Patch p = geometry::box(2e-4, 1e-4, 1.5e-4, 3, 2, 2, 2, {false, false, false});
  solid::NurbsSolid s("s", p, membrane_material(), 1.1);
  s.begin_step(t);
  const std::vector<Vec3> x = s.collocation_points();
  std::vector<solid::VelocitySample> vs(s.n_points());
  for (int i = 0; i < s.n_points(); ++i)
    vs[i].v = Vec3(30 * x[i][1] + 1e4 * x[i][2] * x[i][2], 20 * x[i][0] * x[i][0] * 1e4, 10 * x[i][1]);
  s.kinematic_update(vs);
  s.end_step();
  std::vector<int> begin, unknown;
  std::vector<double> grad;
  ASSERT_TRUE(s.basis_gradients(begin, unknown, grad));
  ASSERT_EQ(begin.size(), s.quadrature_data(1.0, false).size() + 1);
  const std::vector<Vec3> cp = s.current_patch().control_points();
  double err_identity = 0, err_sum = 0, scale = 0;
  for (size_t q = 0; q + 1 < begin.size(); ++q) {
    Mat3 I = Mat3::Zero();
    Vec3 sum = Vec3::Zero();
    for (int k = begin[q]; k < begin[q + 1]; ++k) {
      const Vec3 g(grad[3 * k], grad[3 * k + 1], grad[3 * k + 2]);
      I += cp[unknown[k]] * g.transpose();
      sum += g;
      scale = std::max(scale, g.cwiseAbs().maxCoeff());
    }
    err_identity = std::max(err_identity, (I - Mat3::Identity()).cwiseAbs().maxCoeff());
    err_sum = std::max(err_sum, sum.cwiseAbs().maxCoeff());
  }
  EXPECT_LT(err_identity, 1e-9);
  EXPECT_LT(err_sum, 1e-9 * scale);
}

TEST(NurbsSolid, AnInvertedElementIsReportedWithItsBodyElementAndStretchesOnEveryRank) {
  // v = L (x - c) with L = diag(-a, 0) squeezes the body in x: F = diag(f, 1) everywhere, f falling each step
  // (the implicit update slows it, so f < 0 takes a few steps). The error names the body, the element and the
  // stretch along each reference direction: at element (0, 0) (next to the ellipse's end on the x axis) the
  // thickness runs along x, so its stretch is |f| = |det F|, and the stretch around the ellipse is about 1.
  const Vec3 c(1.2e-3, 6e-4, 0);
  const geometry::Patch e = geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 32, 2, c, 0.0);
  solid::NurbsSolid s("capsule", e, membrane_material(), 1.1);
  const solid::TimeParameters t = solid::TimeParameters::from_rho_inf(0.5, 5e-4);
  Mat3 L = Mat3::Zero();
  L(0, 0) = -8000;
  std::string m, none;
  for (int step = 0; step < 10 && m.empty(); ++step) {
    s.begin_step(t);
    std::vector<solid::VelocitySample> vs(s.n_points());
    const std::vector<Vec3> x = s.collocation_points();
    for (int i = 0; i < s.n_points(); ++i) vs[i].v = L * (x[i] - c), vs[i].grad_v = L;
    s.kinematic_update(vs);
    try {
      s.quadrature_data(1.025, false);
    } catch (const std::runtime_error& err) {
      m = err.what();
    }
    // Every fluid rank asks, each wanting its own points (coupling::FsiCoupler): the ranks that own none of
    // the inverted element's points must refuse it too, or they would go on alone into the next collective
    // call.
    try {
      s.quadrature_data(1.025, false, [](std::size_t, const Vec3&) { return false; });
    } catch (const std::runtime_error& err) {
      none = err.what();
    }
    s.end_step();
  }
  ASSERT_FALSE(m.empty()) << "no inverted element was reported";
  EXPECT_EQ(none, m);
  double det = 0, through = 0, around = 0;
  ASSERT_EQ(std::sscanf(m.c_str(), "inverted solid element: det F = %lf", &det), 1) << m;
  EXPECT_LT(det, 0) << m;
  EXPECT_NE(m.find("; body 'capsule', element (0, 0) of 1 x 32, at x = ("), std::string::npos) << m;
  EXPECT_NE(m.find("(direction 0: through the membrane's thickness)"), std::string::npos) << m;
  ASSERT_EQ(std::sscanf(m.c_str() + m.find("directions:") + 11, " %lf, %lf", &through, &around), 2) << m;
  EXPECT_NEAR(through, -det, 0.05 * std::abs(det)) << m;
  EXPECT_NEAR(around, 1.0, 0.05) << m;
}

TEST(NurbsSolid, QuadratureDataOfUndeformedAndRotatedBodies) {
  const double a = 2e-4, b = 1e-4, h = 5e-7, rho1 = 1.025, rho2 = 1.1;
  const geometry::Patch e = geometry::hollow_ellipse(a, b, h, 64, 2);
  solid::NurbsSolid s("capsule", e, membrane_material(), rho2);
  std::vector<solid::QuadratureData> q = s.quadrature_data(rho1, false);
  double area = 0, max_stress = 0;
  for (const auto& d : q) {
    area += d.weight;
    max_stress = std::max(max_stress, d.stress.norm());
    EXPECT_NEAR(d.beta, 1 - rho2 / rho1, 1e-15);
  }
  const double band = std::numbers::pi * ((a + h / 2) * (b + h / 2) - (a - h / 2) * (b - h / 2));
  EXPECT_NEAR(area, band, 1e-9 * band);  // the membrane's own area (what r_A of Eq. (21) measures)
  EXPECT_LT(max_stress, 1e-9);
  // A rigid rotation (through the kinematics: v = omega x (x - c)) leaves the stress ~0 (objectivity): rotate
  // by small steps so the collocated displacement follows the circle closely.
  Mat3 W = Mat3::Zero();
  W(0, 1) = -100, W(1, 0) = 100;
  const solid::TimeParameters t = solid::TimeParameters::from_rho_inf(0.5, 1e-5);
  for (int step = 0; step < 20; ++step) {
    s.begin_step(t);
    for (int it = 0; it < 3; ++it) {
      std::vector<solid::VelocitySample> vs(s.n_points());
      const std::vector<Vec3> x = s.collocation_points();
      for (int i = 0; i < s.n_points(); ++i) vs[i].v = W * x[i], vs[i].grad_v = W;
      s.kinematic_update(vs);
    }
    s.end_step();
  }
  // Rotated by 100 * 2e-4 = 0.02 rad: the stress left is the rotation's time-integration error (a 1 % stretch
  // would give ~2 G 0.01 / rho_1 = 146).
  q = s.quadrature_data(rho1, false);
  max_stress = 0;
  for (const auto& d : q) max_stress = std::max(max_stress, d.stress.norm());
  std::printf("  after a 0.02 rad rigid rotation: max |(1/rho_1) F S F^T| = %.3e\n", max_stress);
  EXPECT_LT(max_stress, 1e-8);  // measured 2.2e-10: time-integration error of the rotation only
  // Interface points: both faces of the membrane (the two faces' collocation points).
  EXPECT_EQ(static_cast<int>(s.interface_points().size()), 2 * (e.n_control(1) - 1));
  // A disk has one interface face (its centre is degenerate).
  const solid::NurbsSolid disk("nucleus", geometry::bulky_ellipse(5e-5, 5e-5, 4, 16, 2), membrane_material(),
                               1.1);
  EXPECT_EQ(static_cast<int>(disk.interface_points().size()),
            geometry::bulky_ellipse(5e-5, 5e-5, 4, 16, 2).n_control(1) - 1);
}

TEST(NurbsSolid, QuadratureDataOfAHomogeneousDeformationIn3DIsExact) {
  // A solid ellipsoid (the 3D nucleus) moved by v = L (x - c): every collocation point gets the same linear
  // displacement, the collocation reproduces it exactly, so at every quadrature point F is one matrix and
  // x = X + (F - I)(X - c), X the reference point; the stress is the material's for that F.
  const Vec3 c(6e-4, 6e-4, 6e-4);
  const geometry::Patch e = geometry::solid_ellipsoid(1e-4, 1.2e-4, 0.9e-4, 3, 4, 8, 2, c);
  const auto material = std::make_shared<solid::DeviatoricNeoHookean>(40.0);
  solid::NurbsSolid s("nucleus", e, material, 1.1);
  const std::vector<solid::QuadratureData> q0 = s.quadrature_data(1.025, false);
  Mat3 L;
  L << 30, 70, 0, -10, 20, 15, 5, 0, -40;
  step_homogeneously(s, L, c);
  s.begin_step(solid::TimeParameters::from_rho_inf(0.5, 1e-3));  // t_{n+1} = t_{n+alpha_f} of the next step
  const std::vector<solid::QuadratureData> q = s.quadrature_data(1.025, true);
  ASSERT_EQ(q.size(), q0.size());
  const Mat3 F = fitted_deformation(q0, q, c);
  const Mat3 A = F - Mat3::Identity();  // u = A (X - c)
  ASSERT_GT(A.norm(), 1e-2);            // it moved
  const Mat3 stress = F * material->second_piola(F, 3) * F.transpose() / 1.025;
  double worst_x = 0, worst_stress = 0, worst_w = 0;
  for (size_t i = 0; i < q.size(); ++i) {
    worst_x = std::max(worst_x, (q[i].x - q0[i].x - A * (q0[i].x - c)).norm());
    worst_stress = std::max(worst_stress, (q[i].stress - stress).norm());
    worst_w = std::max(worst_w, std::abs(q[i].weight - q0[i].weight));
  }
  EXPECT_LT(worst_x, 1e-12 * 1e-4);               // round-off of the body's size
  EXPECT_LT(worst_stress, 1e-9 * stress.norm());  // one F everywhere
  EXPECT_EQ(worst_w, 0.0);                        // reference weights
  // The tangent, asked for: the law's spatial tangent of that F over rho_1 (upper triangle, row by row).
  // Not asked for: none, and every other number the same to the bit (the coupler asks for it only where it
  // may assemble its Jacobian).
  const solid::Voigt6 c6 = material->spatial_tangent(F, 3);
  const std::vector<solid::QuadratureData> plain = s.quadrature_data(1.025, false);
  double worst_c = 0;
  for (size_t i = 0; i < q.size(); ++i) {
    ASSERT_TRUE(q[i].has_tangent);
    for (int r = 0, t = 0; r < 6; ++r)
      for (int k = r; k < 6; ++k, ++t)
        worst_c = std::max(worst_c, std::abs(q[i].tangent[t] - c6(r, k) / 1.025));
    EXPECT_FALSE(plain[i].has_tangent);
    EXPECT_EQ(plain[i].x, q[i].x);
    EXPECT_EQ(plain[i].stress, q[i].stress);
    EXPECT_EQ(plain[i].weight, q[i].weight);
  }
  EXPECT_LT(worst_c, 1e-9 * c6.norm() / 1.025);
}

TEST(NurbsSolid, QuadratureDataAndBasisGradientsOfSomePointsAreThoseOfAll) {
  // A fluid rank asks for the material only at its own points (coupling::FsiCoupler): the points it wants
  // get the numbers of the full call (the same sums in the same order: asserted to 1e-14 of each value), the
  // others their
  // position, weight, beta and area alone; basis_gradients lists the wanted points only, in order (and
  // evaluates no other). A 3D
  // membrane (its areas; with Skalak's law also its surface frame) moved by a linear velocity field, every
  // third point wanted.
  const Vec3 c(6e-4, 6e-4, 6e-4);
  const geometry::Patch m = geometry::hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 8, 16, 2, c);
  for (const std::shared_ptr<const solid::Material>& law :
       {membrane_material(),
        std::shared_ptr<const solid::Material>(std::make_shared<solid::SkalakMembrane>(7500.0, 10.0))}) {
    SCOPED_TRACE(law->name());
    solid::NurbsSolid s("membrane", m, law, 1.1);
    Mat3 L;
    L << 30, 70, 0, -10, 20, 15, 5, 0, -40;
    step_homogeneously(s, L, c);
    s.begin_step(solid::TimeParameters::from_rho_inf(0.5, 1e-3));
    const std::vector<solid::QuadratureData> all = s.quadrature_data(1.025, true);
    // Two code paths' numbers: equal to 1e-14 of the larger (relative), entry by entry.
    const auto near = [](const auto& a, const auto& b) {
      const auto d =
          (Eigen::ArrayXd::Map(a.data(), a.size()) - Eigen::ArrayXd::Map(b.data(), b.size())).abs();
      const auto m =
          Eigen::ArrayXd::Map(a.data(), a.size()).abs().max(Eigen::ArrayXd::Map(b.data(), b.size()).abs());
      return (d <= 1e-14 * m).all();
    };
    const auto near1 = [](double a, double b) {
      return std::abs(a - b) <= 1e-14 * std::max(std::abs(a), std::abs(b));
    };
    std::vector<char> wanted(all.size(), 0);
    std::vector<Vec3> seen;
    const std::vector<solid::QuadratureData> some =
        s.quadrature_data(1.025, true, [&](std::size_t i, const Vec3& x) {
          seen.push_back(x);
          wanted[i] = i % 3 == 0;
          return wanted[i] != 0;
        });
    ASSERT_EQ(some.size(), all.size());
    ASSERT_EQ(seen.size(), all.size());
    for (size_t i = 0; i < all.size(); ++i) {
      EXPECT_TRUE(near(seen[i], all[i].x)) << i;
      EXPECT_TRUE(near(some[i].x, all[i].x)) << i;
      EXPECT_TRUE(near1(some[i].weight, all[i].weight)) << i;
      EXPECT_TRUE(near1(some[i].area, all[i].area)) << i;
      EXPECT_TRUE(near1(some[i].beta, all[i].beta)) << i;
      EXPECT_TRUE(near1(some[i].shear_modulus, all[i].shear_modulus)) << i;
      if (wanted[i]) {
        ASSERT_TRUE(some[i].has_tangent);
        EXPECT_TRUE(near(some[i].stress, all[i].stress)) << i;
        EXPECT_TRUE(near(some[i].tangent, all[i].tangent)) << i;
      } else {
        EXPECT_FALSE(some[i].has_tangent);
        EXPECT_TRUE(some[i].stress.isZero());
      }
    }
    ASSERT_GT(all[0].stress.norm(), 0);  // it is strained: the comparison has numbers to compare
    // Only the flagged points evaluated at all (the coupler's rank after its first call, which knows its
    // run): the callback sees those alone, they get the full call's numbers, and the others keep what the
    // caller's storage held.
    std::vector<solid::QuadratureData> only(all.size());
    for (solid::QuadratureData& d : only) d.weight = -1;
    std::size_t asked = 0;
    s.quadrature_data(
        1.025, true,
        [&](std::size_t i, const Vec3& x) {
          ++asked;
          EXPECT_TRUE(wanted[i] != 0) << i;
          EXPECT_TRUE(near(x, all[i].x)) << i;
          return true;
        },
        only, &wanted);
    ASSERT_EQ(only.size(), all.size());
    EXPECT_EQ(asked, static_cast<std::size_t>(std::count(wanted.begin(), wanted.end(), 1)));
    for (size_t i = 0; i < all.size(); ++i) {
      if (!wanted[i]) {
        EXPECT_EQ(only[i].weight, -1) << i;
        continue;
      }
      EXPECT_TRUE(near(only[i].x, all[i].x)) << i;
      EXPECT_TRUE(near1(only[i].weight, all[i].weight)) << i;
      EXPECT_TRUE(near1(only[i].area, all[i].area)) << i;
      EXPECT_TRUE(near(only[i].stress, all[i].stress)) << i;
      EXPECT_TRUE(near(only[i].tangent, all[i].tangent)) << i;
    }
    std::vector<int> begin, unknown, begin_some, unknown_some;
    std::vector<double> grad, grad_some;
    ASSERT_TRUE(s.basis_gradients(begin, unknown, grad));
    ASSERT_TRUE(s.basis_gradients(begin_some, unknown_some, grad_some, &wanted));
    ASSERT_EQ(begin_some.size(), static_cast<size_t>(std::count(wanted.begin(), wanted.end(), 1)) + 1);
    for (size_t i = 0, o = 0; i < all.size(); ++i) {
      if (!wanted[i]) continue;
      ASSERT_EQ(begin_some[o + 1] - begin_some[o], begin[i + 1] - begin[i]);
      for (int k = 0; k < begin[i + 1] - begin[i]; ++k) {
        EXPECT_EQ(unknown_some[begin_some[o] + k], unknown[begin[i] + k]);
        for (int l = 0; l < 3; ++l)
          EXPECT_TRUE(near1(grad_some[3 * (begin_some[o] + k) + l], grad[3 * (begin[i] + k) + l]));
      }
      ++o;
    }
    const std::vector<char> short_flags(3, 1);
    EXPECT_THROW(s.basis_gradients(begin, unknown, grad, &short_flags), std::invalid_argument);
  }
}

TEST(NurbsSolid, AMembranesPointAreasSumToItsMidSurfaceAndABulkyBodysAreZero) {
  // QuadratureData::area (the contact repulsion's weight): weight over the thickness, so that a membrane's
  // points sum to the mid-line's length (2D) or about the mid-surface's area (3D). Exact geometry (rational
  // conics), Gauss rules on rational maps: agreement to the rule's error, below 1e-7 here.
  const auto m = std::make_shared<solid::DeviatoricNeoHookean>(40.0);
  const double a = 1e-4, h = 5e-7;
  const auto sum = [](const std::vector<solid::QuadratureData>& q) {
    double s = 0;
    for (const auto& p : q) s += p.area;
    return s;
  };
  const solid::NurbsSolid ring("ring", geometry::hollow_ellipse(a, a, h, 32, 2, Vec3(5e-4, 5e-4, 0)), m, 1.1);
  EXPECT_NEAR(sum(ring.quadrature_data(1.025, false)) / (2 * M_PI * a), 1.0, 1e-6);
  const solid::NurbsSolid sphere(
      "sphere", geometry::hollow_ellipsoid(a, a, a, h, 8, 16, 2, Vec3(5e-4, 5e-4, 5e-4)), m, 1.1);
  // A spherical shell's volume over its thickness: 4 pi (a^2 + h^2 / 12), the mean of its spheres' areas
  // (2.1e-6 above the mid-surface's here).
  EXPECT_NEAR(sum(sphere.quadrature_data(1.025, false)) / (4 * M_PI * (a * a + h * h / 12)), 1.0, 1e-7);
  const solid::NurbsSolid disk("disk", geometry::bulky_ellipse(a, a, 4, 16, 2, Vec3(5e-4, 5e-4, 0)), m, 1.1);
  EXPECT_EQ(sum(disk.quadrature_data(1.025, false)), 0.0);
}

TEST(NurbsSolid, MembranesAndBulkyBodiesAreTold) {
  // A bulky body's centre face is degenerate (no interface there); a membrane has two interface faces. The
  // builders place bodies far from the origin, where the centre's Greville points agree only to round-off.
  const Vec3 c(1.2e-3, 6e-4, 0);
  const auto m = std::make_shared<solid::DeviatoricNeoHookean>(40.0);
  EXPECT_FALSE(
      solid::NurbsSolid("disk", geometry::bulky_ellipse(2e-4, 2e-4, 9, 44, 2, c), m, 1.1).is_membrane());
  EXPECT_FALSE(
      solid::NurbsSolid("ell", geometry::bulky_ellipse(2e-4, 1e-4, 4, 32, 2, c, 0.3), m, 1.1).is_membrane());
  EXPECT_TRUE(
      solid::NurbsSolid("cap", geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 32, 2, c, 1.5707963), m, 1.1)
          .is_membrane());
}

TEST(NurbsSolid, AMembraneSurfaceLawSeesEachPointInItsMembranesFrame) {
  // A spherical membrane moved by a homogeneous deformation F (v = L (x - c), as above): at every quadrature
  // point the stress must be the Skalak law's for F in the point's own frame, whose normal is the sphere's
  // radial direction (X - c) / |X - c| there; and cauchy_stress() the same at a point given by xi. The law
  // given F without the frame (the global axes) would give another stress, checked to differ.
  const Vec3 c(5e-4, 5e-4, 5e-4);
  const double a = 1e-4;
  const auto skalak = std::make_shared<solid::SkalakMembrane>(189.74, 10.0);
  solid::NurbsSolid s("rbc", geometry::hollow_ellipsoid(a, a, a, 3e-6, 8, 16, 2, c), skalak, 1.1);
  const std::vector<solid::QuadratureData> q0 = s.quadrature_data(1.025, false);
  Mat3 L;
  L << 30, 70, 0, -10, 20, 15, 5, 0, -40;
  step_homogeneously(s, L, c);  // the quadrature data and cauchy_stress() at t_{n+1}, the end of the step
  const std::vector<solid::QuadratureData> q = s.quadrature_data(1.025, true);
  const Mat3 F = fitted_deformation(q0, q, c);
  ASSERT_GT((F - Mat3::Identity()).norm(), 1e-2);
  double worst = 0, scale = 0, largest_gap = 0, worst_c = 0, scale_c = 0;
  for (size_t i = 0; i < q.size(); ++i) {
    const Vec3 N = (q0[i].x - c).normalized();
    const Vec3 t1 = N.unitOrthogonal();
    Mat3 Q;
    Q << t1, N.cross(t1), N;
    const Mat3 FQ = F * Q;
    const Mat3 expected = FQ * skalak->second_piola(FQ, 3) * FQ.transpose() / 1.025;
    worst = std::max(worst, (q[i].stress - expected).norm());
    scale = std::max(scale, expected.norm());
    largest_gap = std::max(largest_gap, (solid::kirchhoff_stress(*skalak, F, 3) / 1.025 - expected).norm());
    ASSERT_TRUE(q[i].has_tangent);
    // The tangent in the same frame (upper triangle, row by row).
    const solid::Voigt6 c6 = skalak->spatial_tangent(FQ, 3) / 1.025;
    for (int r = 0, t = 0; r < 6; ++r)
      for (int k = r; k < 6; ++k, ++t) worst_c = std::max(worst_c, std::abs(q[i].tangent[t] - c6(r, k)));
    scale_c = std::max(scale_c, c6.norm());
  }
  EXPECT_LT(worst_c, 1e-6 * scale_c);   // the numerical tangent's own differences (h = 1e-5) of nearby F
  EXPECT_LT(worst, 1e-8 * scale);       // the frame's normal to the geometry's accuracy (exact conics)
  EXPECT_GT(largest_gap, 0.1 * scale);  // the global axes as the frame: another stress
  // cauchy_stress at a point on the mid-surface (xi_0 mid-way), its normal the radial direction there.
  const geometry::Patch ref = s.reference();
  const geometry::Param xi{0.5 * (ref.knots(0).a() + ref.knots(0).b()), 0.37 * ref.knots(1).b(),
                           0.61 * ref.knots(2).b()};
  const Vec3 N = (ref.point(xi) - c).normalized(), t1 = N.unitOrthogonal();
  Mat3 Q;
  Q << t1, N.cross(t1), N;
  const Mat3 FQ = F * Q;
  const Mat3 sigma = s.cauchy_stress({xi})[0];
  EXPECT_LT((sigma - FQ * skalak->second_piola(FQ, 3) * FQ.transpose() / FQ.determinant()).norm(),
            1e-6 * sigma.norm());
  // A bulky body or a 2D membrane cannot take a surface law.
  EXPECT_THROW(solid::NurbsSolid("n", geometry::solid_ellipsoid(a, a, a, 3, 4, 8, 2, c), skalak, 1.1),
               std::invalid_argument);
  EXPECT_THROW(solid::NurbsSolid("m", geometry::hollow_ellipse(a, a, 3e-6, 16, 2, c), skalak, 1.1),
               std::invalid_argument);
}

namespace {

/// A body of a fixed shape (reference and current patches given), for the output writer alone.
class FixedShapeBody final : public solid::SolidSolver {
 public:
  FixedShapeBody(geometry::Patch reference, geometry::Patch current)
      : reference_(std::move(reference)), current_(std::move(current)) {}
  std::string name() const override { return "fixed"; }
  int dim() const override { return reference_.physical_dim(); }
  void begin_step(const solid::TimeParameters&) override {}
  std::vector<Vec3> collocation_points() const override { return {}; }
  double kinematic_update(const std::vector<solid::VelocitySample>&) override { return 0; }
  std::vector<solid::QuadratureData> quadrature_data(double, bool) const override { return {}; }
  std::vector<Vec3> interface_points() const override { return {}; }
  void end_step() override {}
  void set_rate(const std::vector<Vec3>&) override {}
  std::vector<double> state() const override { return {}; }
  void set_state(const std::vector<double>&) override {}
  bool is_membrane() const override { return true; }
  geometry::Patch reference_patch() const override { return reference_; }
  geometry::Patch current_patch() const override { return current_; }
  std::vector<Mat3> cauchy_stress(const std::vector<geometry::Param>& xi) const override {
    return std::vector<Mat3>(xi.size(), Mat3::Zero());
  }

 private:
  geometry::Patch reference_, current_;
};

/// A scratch folder of this process: ctest runs the tests of this file as separate processes side by side,
/// and two of them writing into one fixed folder removed each other's files.
std::filesystem::path scratch_dir(const std::string& name) {
  return std::filesystem::temp_directory_path() / (name + "_" + std::to_string(getpid()));
}

/// The output writer's smallest J of one body (solid_output.hpp), written into a fresh folder.
solid::SmallestJ smallest_written(const geometry::Patch& reference, const geometry::Patch& current) {
  const std::filesystem::path dir = scratch_dir("cellfsi_test_solid_fold");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  FixedShapeBody body(reference, current);
  solid::SolidSeriesWriter writer(dir.string(), true);
  writer.write(0.0, {&body});
  std::filesystem::remove_all(dir);
  return writer.smallest().at(0);
}

}  // namespace

// The output's smallest J: 1 on the reference, the determinant of a uniform stretch, and a fold of the inner
// face between the solver's quadrature points (J > 0 at every one of them) found, with where.
TEST(SolidOutput, SmallestJFindsAFoldBetweenTheQuadraturePoints) {
  const double r = 2e-4, h = 2e-5;
  const geometry::Patch ref = geometry::hollow_ellipse(r, r, h, 8, 2);
  EXPECT_NEAR(smallest_written(ref, ref).J, 1.0, 1e-12);
  geometry::Patch stretched = ref;
  for (Vec3& p : stretched.control_points()) p *= 1.1;
  EXPECT_NEAR(smallest_written(ref, stretched).J, 1.21, 1e-12);
  // The inner control point of angular index 4 pushed out past the mid-surface's: the inner face folds near
  // it.
  geometry::Patch folded = ref;
  const int inner = ref.control_index(0, 4), mid = ref.control_index(1, 4);
  folded.control_points()[inner] += 1.6 * (ref.control_points()[mid] - ref.control_points()[inner]);
  const solid::SmallestJ s = smallest_written(ref, folded);
  EXPECT_LT(s.J, 0.0);
  EXPECT_LT((s.x - folded.control_points()[inner]).norm(), 0.5 * r);
  double at_quadrature = 1e300;
  std::vector<geometry::QuadraturePoint> qp;
  for (int e = 0; e < ref.n_elements(); ++e) {
    geometry::element_quadrature(ref, ref.element_multi_index(e), geometry::default_gauss(ref), qp);
    for (const geometry::QuadraturePoint& q : qp) {
      const geometry::MapValues X = ref.evaluate(q.xi, 1), x = folded.evaluate(q.xi, 1);
      at_quadrature = std::min(
          at_quadrature, x.dx.topLeftCorner(2, 2).determinant() / X.dx.topLeftCorner(2, 2).determinant());
    }
  }
  EXPECT_GT(at_quadrature, 0.0) << "the fold should lie between the quadrature points";
}

// The writer's history over a run's writes: the smallest J and when, and the first write that found a fold,
// kept when a later write folds further and when a restart resumes the history.
TEST(SolidOutput, HistoryKeepsTheSmallestJAndTheFirstFoldAcrossARestart) {
  const double r = 2e-4, h = 2e-5;
  const geometry::Patch ref = geometry::hollow_ellipse(r, r, h, 8, 2);
  const int inner = ref.control_index(0, 4), mid = ref.control_index(1, 4);
  auto pushed = [&](double by) {
    geometry::Patch p = ref;
    p.control_points()[inner] += by * (ref.control_points()[mid] - ref.control_points()[inner]);
    return p;
  };
  const std::filesystem::path dir = scratch_dir("cellfsi_test_solid_history");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  FixedShapeBody rest(ref, ref), folded(ref, pushed(1.6)), further(ref, pushed(2.4));
  solid::SolidSeriesWriter writer(dir.string(), true);
  writer.write(0.0, {&rest});
  ASSERT_EQ(writer.history().size(), 1u);
  EXPECT_NEAR(writer.history()[0].least.J, 1.0, 1e-12);
  EXPECT_FALSE(writer.history()[0].folded);
  writer.write(0.5, {&folded});
  writer.write(1.0, {&further});
  const solid::JHistory run = writer.history()[0];
  ASSERT_TRUE(run.folded);
  EXPECT_EQ(run.first_fold.time, 0.5);
  EXPECT_NEAR(run.first_fold.J, smallest_written(ref, pushed(1.6)).J, 1e-12);
  EXPECT_EQ(run.least.time, 1.0) << "the further push should fold further: J " << run.least.J << " against "
                                 << run.first_fold.J;
  EXPECT_LT(run.least.J, run.first_fold.J);
  // A restart: the history goes on from the checkpoint's, a later write at rest changes neither.
  solid::SolidSeriesWriter resumed(dir.string(), true);
  resumed.resume(writer.entries(), writer.count(), writer.history());
  resumed.write(2.0, {&rest});
  const solid::JHistory after = resumed.history()[0];
  EXPECT_EQ(after.least.time, 1.0);
  EXPECT_EQ(after.least.J, run.least.J);
  EXPECT_TRUE(after.folded);
  EXPECT_EQ(after.first_fold.time, 0.5);
  // A writer that does not write (another rank) keeps no history.
  solid::SolidSeriesWriter quiet(dir.string(), false);
  quiet.write(0.0, {&folded});
  EXPECT_TRUE(quiet.history().empty());
  std::filesystem::remove_all(dir);
}
