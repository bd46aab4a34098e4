// Convergence of the divergence-conforming Galerkin solver (fluid/div_conforming/dc_fluid.hpp, issue 44 part
// 1) on a manufactured steady solution in the unit channel: rates k + 1 (velocity L2), k (velocity H1) and
// k + 1 (pressure L2) within 0.1 over 8^2 .. 64^2 elements for k = 2 and 8^2 .. 32^2 for k = 3, Stokes and
// Navier-Stokes; divergence-free to 1e-9 of the velocity gradient on every mesh; the velocity independent of
// the pressure's size (pressure robustness); generalized-alpha second order in time; and a 3D box (periodic
// x, walls y and z) on 6^3 .. 10^3 elements.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include <petscsys.h>

#include "../support/dc_manufactured.hpp"
#include "../support/print_rank0.hpp"
#include "fluid/div_conforming/dc_fluid.hpp"

using namespace cellfsi;
using namespace cellfsi::fluid::dc;
using cellfsi::test_support::Manufactured;
using cellfsi::test_support::print0;
using geometry::Mat3;

namespace {

constexpr double kPi = std::numbers::pi;

struct Rates {
  std::vector<double> v_l2, v_h1, p_l2;
};

Rates manufactured_errors(int k, const std::vector<int>& meshes, bool stokes,
                          double pressure_amplitude = 100.0) {
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
    DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
    const DcSolveStats st = fs.solve_steady();
    EXPECT_TRUE(st.converged) << "n=" << n;
    EXPECT_LE(fs.divergence_ratio(), 1e-9) << "n=" << n;
    const auto er = fs.errors([&](const Vec3& x) { return m.v(x); }, [&](const Vec3& x) { return m.grad(x); },
                              [&](const Vec3& x) { return m.p(x); });
    r.v_l2.push_back(er.v_l2 / er.v_l2_norm);
    r.v_h1.push_back(er.v_h1 / er.v_h1_norm);
    r.p_l2.push_back(er.p_l2 / er.p_l2_norm);
    print0("  k=%d %s %3dx%-3d: rel errors v L2 %.3e, v H1 %.3e, p L2 %.3e; Newton %d, div ratio %.1e\n", k,
           stokes ? "Stokes" : "NS    ", n, n, r.v_l2.back(), r.v_h1.back(), r.p_l2.back(),
           st.newton_iterations, fs.divergence_ratio());
  }
  return r;
}

void expect_rates(const Rates& r, int k, const char* what) {
  const size_t m = r.v_l2.size();
  auto rate = [&](const std::vector<double>& e, size_t i) { return std::log2(e[i - 1] / e[i]); };
  for (size_t i = 1; i < m; ++i)
    print0("  %s k=%d rates (mesh %zu -> %zu): v L2 %.2f, v H1 %.2f, p L2 %.2f\n", what, k, i - 1, i,
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
  const Rates small = manufactured_errors(2, {16}, true, 1.0),
              large = manufactured_errors(2, {16}, true, 100.0);
  EXPECT_NEAR(small.v_l2[0], large.v_l2[0], 1e-8 * small.v_l2[0]);
  EXPECT_NEAR(small.v_h1[0], large.v_h1[0], 1e-8 * small.v_h1[0]);
}

TEST(DivConformingFluid, ManufacturedWithAViscosityFieldConvergesAtTheOptimalRates) {
  // The manufactured flow above with nu = 1 + sin(2 pi x) sin(pi y) / 2 (a factor 3 across the channel),
  // projected onto the pressure space (order k + 1): f = -nu lap v - 2 eps(v) grad nu + (v.grad)v + grad p. k
  // = 2, Navier-Stokes, 8^2 .. 32^2: rates 3, 2, 3 within 0.1 on the last pair.
  const Manufactured m;
  const auto nu = [](const Vec3& x) { return 1 + 0.5 * std::sin(2 * kPi * x[0]) * std::sin(kPi * x[1]); };
  const auto grad_nu = [](const Vec3& x) {
    return Vec3(kPi * std::cos(2 * kPi * x[0]) * std::sin(kPi * x[1]),
                0.5 * kPi * std::sin(2 * kPi * x[0]) * std::cos(kPi * x[1]), 0);
  };
  Rates r;
  for (int n : {8, 16, 32}) {
    const DivConformingSpace sp(2, 2, {n, n, 1}, Vec3(0, 0, 0), Vec3(1, 1, 0), {true, false, false});
    DcFluidOptions opt;
    opt.density = 1.0;
    opt.body_force_field = [&](const Vec3& x, double) {
      const Mat3 g = m.grad(x);
      const Mat3 eps = 0.5 * (g + g.transpose());
      // m.force(x, 1) has 5 pi^2 nu v with nu = 1; replace that viscous part by the variable one.
      return Vec3(m.force(x, 1.0) - 5 * kPi * kPi * m.v(x) + nu(x) * 5 * kPi * kPi * m.v(x) -
                  2 * eps * grad_nu(x));
    };
    opt.wall_velocity_field = [&](const Vec3& x, double) { return m.v(x); };
    DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
    fs.project_viscosity(nu);
    ASSERT_TRUE(fs.solve_steady().converged) << "n=" << n;
    EXPECT_LE(fs.divergence_ratio(), 1e-9);
    const auto er = fs.errors([&](const Vec3& x) { return m.v(x); }, [&](const Vec3& x) { return m.grad(x); },
                              [&](const Vec3& x) { return m.p(x); });
    r.v_l2.push_back(er.v_l2 / er.v_l2_norm);
    r.v_h1.push_back(er.v_h1 / er.v_h1_norm);
    r.p_l2.push_back(er.p_l2 / er.p_l2_norm);
    print0("  viscosity field, k=2 NS %2dx%-2d: rel errors v L2 %.3e, v H1 %.3e, p L2 %.3e\n", n, n,
           r.v_l2.back(), r.v_h1.back(), r.p_l2.back());
  }
  expect_rates(r, 2, "viscosity field");
}

// --- Time: generalized-alpha
// ------------------------------------------------------------------------------------

TEST(DivConformingFluid, TimeIntegrationIsSecondOrder) {
  // The Taylor-Green vortex (2 pi-periodic square, Navier-Stokes, nu = 1: fast decay), k = 2 on 16 x 16, to
  // T = 0.2 with dt = 0.04, 0.02, 0.01, rho_inf = 0.5, from the divergence-free projections of v and dv/dt.
  // The rate is measured on the same mesh from the differences of successive solutions (u_dt - u_dt/2 over
  // u_dt/2 - u_dt/4), which the spatial error does not enter: 2 within 0.1. (Against the exact solution the
  // spatial error, ~1e-5 here, would hide the time error of the smallest step.)
  const double nu = 1.0, two_pi = 2 * kPi, T = 0.2;
  const auto v = [&](const Vec3& x, double t) {
    const double F = std::exp(-2 * nu * t);
    return Vec3(std::sin(x[0]) * std::cos(x[1]) * F, -std::cos(x[0]) * std::sin(x[1]) * F, 0);
  };
  const DivConformingSpace sp(2, 2, {16, 16, 1}, Vec3(0, 0, 0), Vec3(two_pi, two_pi, 0), {true, true, false});
  std::vector<double> u[3];
  double e[3];
  const double dts[3] = {0.04, 0.02, 0.01};
  for (int i = 0; i < 3; ++i) {
    DcFluidOptions opt;
    opt.density = 1.0;
    opt.viscosity = nu;
    opt.dt = dts[i];
    DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
    fs.project_initial_state([&](const Vec3& x) { return v(x, 0); },
                             [&](const Vec3& x) { return Vec3(-2 * nu * v(x, 0)); });
    const int steps = static_cast<int>(std::lround(T / dts[i]));
    for (int s = 0; s < steps; ++s) ASSERT_TRUE(fs.step().converged) << "dt " << dts[i] << " step " << s;
    for (double r : fs.divergence_history()) EXPECT_LE(r, 1e-9);
    const auto er =
        fs.errors([&](const Vec3& x) { return v(x, fs.time()); },
                  [](const Vec3&) { return Mat3(Mat3::Zero()); }, [](const Vec3&) { return 0.0; });
    e[i] = er.v_l2 / er.v_l2_norm;
    u[i].assign(fs.state().begin(), fs.state().begin() + sp.n_velocity());
  }
  auto distance = [](const std::vector<double>& a, const std::vector<double>& b) {
    double s = 0;
    for (size_t i = 0; i < a.size(); ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
    return std::sqrt(s);
  };
  const double d01 = distance(u[0], u[1]), d12 = distance(u[1], u[2]);
  const double rate = std::log2(d01 / d12);
  print0(
      "  Taylor-Green k=2 16x16, dt = 0.04, 0.02, 0.01: rel L2 errors %.3e %.3e %.3e; successive "
      "differences %.3e %.3e, rate %.2f\n",
      e[0], e[1], e[2], d01, d12, rate);
  EXPECT_NEAR(rate, 2.0, 0.1);
}

// --- 3D
// ----------------------------------------------------------------------------------------------------------

namespace {

/// f(x) g(y) h(z) with each factor a sine or cosine of its own wave number.
struct TrigProduct {
  double amp;
  std::array<bool, 3> cosine;
  std::array<double, 3> wave;
  double factor(int d, double x, int derivative) const {
    const double a = wave[d] * x;
    if (derivative == 0) return cosine[d] ? std::cos(a) : std::sin(a);
    return cosine[d] ? -wave[d] * std::sin(a) : wave[d] * std::cos(a);
  }
  double value(const Vec3& x) const {
    return amp * factor(0, x[0], 0) * factor(1, x[1], 0) * factor(2, x[2], 0);
  }
  Vec3 grad(const Vec3& x) const {
    Vec3 g;
    for (int j = 0; j < 3; ++j) {
      g[j] = amp;
      for (int d = 0; d < 3; ++d) g[j] *= factor(d, x[d], d == j ? 1 : 0);
    }
    return g;
  }
};

/// The unit box, periodic in x, walls at y = 0, 1 and z = 0, 1: v = curl(psi e_z) + curl(a e_x) with
/// psi = sin(2 pi x) sin(pi y) cos(pi z), a = cos(2 pi x) sin(pi y) sin(pi z):
///   v = pi (sin 2 pi x cos pi y cos pi z, -cos 2 pi x sin pi y cos pi z, -cos 2 pi x cos pi y sin pi z),
/// divergence-free, v.n = 0 on the walls (tangential wall velocity varies), -lap v = 6 pi^2 v;
/// p = P sin(2 pi x) cos(pi y) cos(pi z); Stokes with rho = nu = 1.
struct Manufactured3d {
  double P = 100.0;
  std::array<TrigProduct, 3> v_comp{TrigProduct{kPi, {false, true, true}, {2 * kPi, kPi, kPi}},
                                    TrigProduct{-kPi, {true, false, true}, {2 * kPi, kPi, kPi}},
                                    TrigProduct{-kPi, {true, true, false}, {2 * kPi, kPi, kPi}}};
  TrigProduct p_fn() const { return TrigProduct{P, {false, true, true}, {2 * kPi, kPi, kPi}}; }
  Vec3 v(const Vec3& x) const { return Vec3(v_comp[0].value(x), v_comp[1].value(x), v_comp[2].value(x)); }
  Mat3 grad(const Vec3& x) const {
    Mat3 m;
    for (int i = 0; i < 3; ++i) m.row(i) = v_comp[i].grad(x).transpose();
    return m;
  }
  Vec3 force(const Vec3& x) const { return 6 * kPi * kPi * v(x) + p_fn().grad(x); }
};

}  // namespace

TEST(DivConformingFluid, ManufacturedStokes3dConvergesAtTheOptimalRates) {
  // k = 2 on 6^3, 8^3, 10^3 elements (small meshes: the 3D path is the 2D one, dimension-generic).
  const Manufactured3d m;
  const int meshes[3] = {6, 8, 10};
  Rates r;
  for (int n : meshes) {
    const DivConformingSpace sp(3, 2, {n, n, n}, Vec3(0, 0, 0), Vec3(1, 1, 1), {true, false, false});
    DcFluidOptions opt;
    opt.density = 1.0;
    opt.viscosity = 1.0;
    opt.stokes = true;
    opt.body_force_field = [&](const Vec3& x, double) { return m.force(x); };
    opt.wall_velocity_field = [&](const Vec3& x, double) { return m.v(x); };
    DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
    ASSERT_TRUE(fs.solve_steady().converged) << "n=" << n;
    EXPECT_LE(fs.divergence_ratio(), 1e-9) << "n=" << n;
    const TrigProduct pf = m.p_fn();
    const auto er = fs.errors([&](const Vec3& x) { return m.v(x); }, [&](const Vec3& x) { return m.grad(x); },
                              [&](const Vec3& x) { return pf.value(x); });
    r.v_l2.push_back(er.v_l2 / er.v_l2_norm);
    r.v_h1.push_back(er.v_h1 / er.v_h1_norm);
    r.p_l2.push_back(er.p_l2 / er.p_l2_norm);
    print0("  3D k=2 Stokes %2d^3: rel errors v L2 %.3e, v H1 %.3e, p L2 %.3e; div ratio %.1e\n", n,
           r.v_l2.back(), r.v_h1.back(), r.p_l2.back(), fs.divergence_ratio());
  }
  double rate[3][3];  // [pair][v L2, v H1, p L2]
  for (int i = 1; i < 3; ++i) {
    const double h = std::log(static_cast<double>(meshes[i]) / meshes[i - 1]);
    rate[i][0] = std::log(r.v_l2[i - 1] / r.v_l2[i]) / h;
    rate[i][1] = std::log(r.v_h1[i - 1] / r.v_h1[i]) / h;
    rate[i][2] = std::log(r.p_l2[i - 1] / r.p_l2[i]) / h;
    print0("  3D k=2 rates (%d -> %d): v L2 %.2f, v H1 %.2f, p L2 %.2f\n", meshes[i - 1], meshes[i],
           rate[i][0], rate[i][1], rate[i][2]);
  }
  // These meshes are pre-asymptotic: the rates come down to the optimal ones from above (observed 3.39, 2.21,
  // 3.37 from 6^3 to 8^3, then 3.24, 2.13, 3.23 to 10^3; on 4^3, 8^3, 12^3, which took twice the time, 3.58,
  // 2.34, 3.55 then 3.21, 2.11, 3.20). Asserted: at least optimal within 0.1, and at most 0.3 above (a wrong
  // term lowers a rate; the 0.1-margin acceptance is the 2D tests' above).
  const double optimal[3] = {3, 2, 3};
  for (int c = 0; c < 3; ++c) {
    EXPECT_GE(rate[2][c], optimal[c] - 0.1) << "3D rate " << c;
    EXPECT_LE(rate[2][c], optimal[c] + 0.3) << "3D rate " << c;
  }
}
