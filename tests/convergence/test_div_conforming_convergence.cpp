// Convergence of the divergence-conforming Galerkin solver (fluid/div_conforming/dc_fluid.hpp, issue 44 part
// 1) on a manufactured steady solution in the unit channel: rates k + 1 (velocity L2), k (velocity H1) and
// k + 1 (pressure L2) within 0.1 over 8^2 .. 64^2 elements for k = 2 and 8^2 .. 32^2 for k = 3, Stokes and
// Navier-Stokes; divergence-free to 1e-9 of the velocity gradient on every mesh; and the velocity independent
// of the pressure's size (pressure robustness).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "fluid/div_conforming/dc_fluid.hpp"

using namespace cellfsi;
using namespace cellfsi::fluid::dc;
using geometry::Mat3;

namespace {

constexpr double kPi = std::numbers::pi;

/// On the unit channel (periodic x, walls y = 0, 1): psi = sin(2 pi x) sin(pi y), v = (psi_y, -psi_x), so
/// div v = 0, v.n = 0 on the walls and the tangential wall velocity varies along them (Nitsche with a wall
/// velocity field); p = P sin(2 pi x) cos(pi y). rho = nu = 1; f = 5 pi^2 nu v + c (v.grad)v + grad p.
/// The pressure's amplitude P: the velocity does not depend on it (pressure robustness), and P = 100 makes the
/// pressure's own approximation error, of order k + 1, dominate its error from the first mesh on (with P = 1 a
/// part of order k + 2 driven by the velocity is as large on these meshes: rates 4.1, 3.8, 3.5 for k = 2).
struct Manufactured {
  double nu = 1.0;
  double P = 100.0;
  Vec3 v(const Vec3& x) const {
    return Vec3(kPi * std::sin(2 * kPi * x[0]) * std::cos(kPi * x[1]),
                -2 * kPi * std::cos(2 * kPi * x[0]) * std::sin(kPi * x[1]), 0);
  }
  Mat3 grad(const Vec3& x) const {
    const double s2 = std::sin(2 * kPi * x[0]), c2 = std::cos(2 * kPi * x[0]);
    const double s1 = std::sin(kPi * x[1]), c1 = std::cos(kPi * x[1]);
    Mat3 m = Mat3::Zero();
    m(0, 0) = 2 * kPi * kPi * c2 * c1;
    m(0, 1) = -kPi * kPi * s2 * s1;
    m(1, 0) = 4 * kPi * kPi * s2 * s1;
    m(1, 1) = -2 * kPi * kPi * c2 * c1;
    return m;
  }
  double p(const Vec3& x) const { return P * std::sin(2 * kPi * x[0]) * std::cos(kPi * x[1]); }
  Vec3 force(const Vec3& x, double convection) const {
    const Vec3 vv = v(x);
    const Mat3 g = grad(x);
    const Vec3 grad_p(P * 2 * kPi * std::cos(2 * kPi * x[0]) * std::cos(kPi * x[1]),
                      -P * kPi * std::sin(2 * kPi * x[0]) * std::sin(kPi * x[1]), 0);
    return 5 * kPi * kPi * nu * vv + convection * (g * vv) + grad_p;
  }
};

struct Rates {
  std::vector<double> v_l2, v_h1, p_l2;
};

Rates manufactured_errors(int k, const std::vector<int>& meshes, bool stokes, double pressure_amplitude = 100.0) {
  Manufactured m;
  m.P = pressure_amplitude;
  Rates r;
  for (int n : meshes) {
    const DivConformingSpace sp(2, k, {n, n, 1}, Vec3(0, 0, 0), Vec3(1, 1, 0), {true, false, false});
    DcFluidOptions opt;
    opt.density = 1.0;
    opt.viscosity = m.nu;
    opt.stokes = stokes;
    opt.body_force_field = [&](const Vec3& x, double) { return m.force(x, stokes ? 0.0 : 1.0); };
    opt.wall_velocity_field = [&](const Vec3& x, double) { return m.v(x); };
    DivConformingFluid fs(sp, opt);
    const DcSolveStats st = fs.solve_steady();
    EXPECT_TRUE(st.converged) << "n=" << n;
    EXPECT_LE(fs.divergence_ratio(), 1e-9) << "n=" << n;
    const auto er = fs.errors([&](const Vec3& x) { return m.v(x); }, [&](const Vec3& x) { return m.grad(x); },
                              [&](const Vec3& x) { return m.p(x); });
    r.v_l2.push_back(er.v_l2 / er.v_l2_norm);
    r.v_h1.push_back(er.v_h1 / er.v_h1_norm);
    r.p_l2.push_back(er.p_l2 / er.p_l2_norm);
    std::printf("  k=%d %s %3dx%-3d: rel errors v L2 %.3e, v H1 %.3e, p L2 %.3e; Newton %d, div ratio %.1e\n", k,
                stokes ? "Stokes" : "NS    ", n, n, r.v_l2.back(), r.v_h1.back(), r.p_l2.back(),
                st.newton_iterations, fs.divergence_ratio());
  }
  return r;
}

void expect_rates(const Rates& r, int k, const char* what) {
  const size_t m = r.v_l2.size();
  auto rate = [&](const std::vector<double>& e, size_t i) { return std::log2(e[i - 1] / e[i]); };
  for (size_t i = 1; i < m; ++i)
    std::printf("  %s k=%d rates (mesh %zu -> %zu): v L2 %.2f, v H1 %.2f, p L2 %.2f\n", what, k, i - 1, i,
                rate(r.v_l2, i), rate(r.v_h1, i), rate(r.p_l2, i));
  EXPECT_NEAR(rate(r.v_l2, m - 1), k + 1, 0.1) << what << " velocity L2, k=" << k;
  EXPECT_NEAR(rate(r.v_h1, m - 1), k, 0.1) << what << " velocity H1, k=" << k;
  EXPECT_NEAR(rate(r.p_l2, m - 1), k + 1, 0.1) << what << " pressure L2, k=" << k;
}

}  // namespace

TEST(DivConformingFluid, ManufacturedStokesConvergesAtTheOptimalRates) {
  expect_rates(manufactured_errors(2, {8, 16, 32, 64}, true), 2, "Stokes");
  expect_rates(manufactured_errors(3, {8, 16, 32}, true), 3, "Stokes");
}

TEST(DivConformingFluid, ManufacturedNavierStokesConvergesAtTheOptimalRates) {
  expect_rates(manufactured_errors(2, {8, 16, 32, 64}, false), 2, "Navier-Stokes");
  expect_rates(manufactured_errors(3, {8, 16, 32}, false), 3, "Navier-Stokes");
}

TEST(DivConformingFluid, TheVelocityDoesNotDependOnThePressure) {
  // Pressure robustness on the manufactured solution: the same velocity for pressures of amplitude 1 and 100
  // (k = 2, 16 x 16, Stokes): the velocity errors agree to 1e-8 of themselves (a method that is not pressure
  // robust has a velocity error ~ h^k |p| / nu, here a hundredfold change).
  const Rates small = manufactured_errors(2, {16}, true, 1.0), large = manufactured_errors(2, {16}, true, 100.0);
  EXPECT_NEAR(small.v_l2[0], large.v_l2[0], 1e-8 * small.v_l2[0]);
  EXPECT_NEAR(small.v_h1[0], large.v_h1[0], 1e-8 * small.v_h1[0]);
}
