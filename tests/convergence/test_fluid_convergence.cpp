// Convergence of the fluid solver on the Taylor-Green vortex, an exact Navier-Stokes solution on the 2
// pi-periodic square: v = (sin x cos y, -cos x sin y) e^{-2 nu t}, p = (cos 2x + cos 2y) e^{-4 nu t} / 4.
// Space: velocity L2 error rate within 0.2 of the optimal p + 1 for p = 2, 3 over three meshes.
// Time: second order (generalized-alpha, rho_inf = 0.5) on a fine mesh.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "fluid/fluid_solver.hpp"
#include "geometry/builders.hpp"

using namespace cellfsi;
using geometry::Vec3;

namespace {

constexpr double kTwoPi = 2 * std::numbers::pi;

struct TaylorGreen {
  double nu;
  Vec3 v(const Vec3& x, double t) const {
    const double F = std::exp(-2 * nu * t);
    return Vec3(std::sin(x[0]) * std::cos(x[1]) * F, -std::cos(x[0]) * std::sin(x[1]) * F, 0);
  }
  Vec3 vdot(const Vec3& x, double t) const { return -2 * nu * v(x, t); }
};

/// Relative L2 velocity error at time T on n x n elements of degree p with time step dt.
double tg_error(int n, int p, double nu, double dt, double T) {
  const geometry::Patch box = geometry::rectangle(kTwoPi, kTwoPi, n, n, p, {true, true});
  fluid::FluidOptions opt;
  opt.density = 1.0;
  opt.viscosity = nu;  // mu = nu rho
  opt.dt = dt;
  fluid::FluidSolver fs(PETSC_COMM_WORLD, box, opt);
  const TaylorGreen tg{nu};
  fs.project_initial_state([&](const Vec3& x) { return tg.v(x, 0); },
                           [&](const Vec3& x) { return tg.vdot(x, 0); });
  const int steps = static_cast<int>(std::lround(T / dt));
  for (int s = 0; s < steps; ++s) {
    const fluid::StepStats st = fs.step();
    if (!st.converged) ADD_FAILURE() << "step " << s << " did not converge: " << st.reason;
  }
  const auto e = fs.velocity_l2_error([&](const Vec3& x) { return tg.v(x, fs.time()); });
  return e.error / e.norm;
}

class TightSolves : public ::testing::Test {
 protected:
  void SetUp() override {
    for (auto [k, v] : {std::pair{"-fluid_snes_rtol", "1e-12"},
                        {"-fluid_snes_atol", "1e-16"},
                        {"-fluid_ksp_rtol", "1e-13"},
                        {"-fluid_snes_max_it", "30"}})
      PetscOptionsSetValue(nullptr, k, v);
  }
  void TearDown() override {
    for (auto k : {"-fluid_snes_rtol", "-fluid_snes_atol", "-fluid_ksp_rtol", "-fluid_snes_max_it"})
      PetscOptionsClearValue(nullptr, k);
  }
};

}  // namespace

TEST_F(TightSolves, SpatialRateIsOptimalForQuadraticsAndCubics) {
  // nu = 0.1, T = 0.05 with dt = 0.005: the time error (~1e-9) stays far below the spatial errors measured.
  for (int p : {2, 3}) {
    const int meshes[3] = {8, 16, 32};
    double e[3];
    for (int i = 0; i < 3; ++i) e[i] = tg_error(meshes[i], p, 0.1, 0.005, 0.05);
    const double r1 = std::log2(e[0] / e[1]), r2 = std::log2(e[1] / e[2]);
    std::printf("  Taylor-Green p=%d: rel L2 errors %.3e %.3e %.3e, rates %.2f %.2f (optimal %d)\n", p, e[0],
                e[1], e[2], r1, r2, p + 1);
    EXPECT_NEAR(r2, p + 1, 0.2) << "p=" << p;
  }
}

TEST_F(TightSolves, TimeIntegrationIsSecondOrder) {
  // nu = 1 (fast decay), cubic 32 x 32 mesh: spatial error ~1e-6, time errors 1e-4..1e-3.
  const double e1 = tg_error(32, 3, 1.0, 0.04, 0.2), e2 = tg_error(32, 3, 1.0, 0.02, 0.2),
               e3 = tg_error(32, 3, 1.0, 0.01, 0.2);
  const double r1 = std::log2(e1 / e2), r2 = std::log2(e2 / e3);
  std::printf("  Taylor-Green dt = 0.04, 0.02, 0.01: rel L2 errors %.3e %.3e %.3e, rates %.2f %.2f\n", e1, e2,
              e3, r1, r2);
  EXPECT_NEAR(r2, 2.0, 0.2);
}
