// FluidSolver against analytic flows: plane Couette and Poiseuille (exact in the discrete space), start-up
// Poiseuille against its series solution; the assembled tangent against finite differences; immersed points;
// the same problem on 1 and 2 ranks; what it answers through fluid::ImmersedFluid (state, regions, layout).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <vector>

#include "common/petsc_error.hpp"
#include "fluid/fluid_solver.hpp"
#include "geometry/builders.hpp"
#include "geometry/element_region.hpp"
#include "geometry/quadrature.hpp"

using namespace cellfsi;
using fluid::FluidOptions;
using fluid::FluidSolver;
using geometry::Vec3;

namespace {

/// Sets PETSc options for the duration of a test (tight solves for exactness checks).
class ScopedOptions {
 public:
  explicit ScopedOptions(std::initializer_list<std::pair<const char*, const char*>> kv) {
    for (auto& [k, v] : kv) {
      PetscOptionsSetValue(nullptr, k, v);
      names_.push_back(k);
    }
  }
  ~ScopedOptions() {
    for (auto* k : names_) PetscOptionsClearValue(nullptr, k);
  }

 private:
  std::vector<const char*> names_;
};

const std::initializer_list<std::pair<const char*, const char*>> kTight = {{"-fluid_snes_rtol", "1e-14"},
                                                                           {"-fluid_snes_atol", "1e-20"},
                                                                           {"-fluid_ksp_rtol", "1e-14"},
                                                                           {"-fluid_ksp_atol", "1e-22"},
                                                                           {"-fluid_snes_max_it", "20"}};

std::vector<Vec3> sample_points(double lx, double ly, double y0 = 0.0) {
  std::vector<Vec3> pts;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 7; ++j) pts.emplace_back(lx * (i + 0.31) / 5, y0 + ly * (j + 0.5) / 7, 0);
  return pts;
}

/// Five immersed points spread over the box [0, lx] x [-ly/2, ly/2] (a few elements, the periodic seam), with
/// a shear stress and the given stiffness viscosity.
std::vector<fluid::ImmersedPointData> five_immersed_points(double lx, double ly, double stiffness_viscosity) {
  std::vector<fluid::ImmersedPointData> pts;
  for (int i = 0; i < 5; ++i) {
    fluid::ImmersedPointData d;
    d.x = Vec3(lx * (0.05 + 0.2 * i), ly * (0.1 * i - 0.25), 0);
    d.data.weight = 1e-9;
    d.data.beta = -0.07;
    d.data.stress[0][1] = d.data.stress[1][0] = 3.0;
    d.data.stiffness_viscosity = stiffness_viscosity;
    pts.push_back(d);
  }
  return pts;
}

/// Plasma between walls y = a and y = b moving at -speed and +speed along x.
FluidOptions moving_walls(double speed) {
  FluidOptions opt;
  opt.wall_velocity[1][0] = Vec3(-speed, 0, 0);
  opt.wall_velocity[1][1] = Vec3(speed, 0, 0);
  return opt;
}

}  // namespace

TEST(FluidSolver, PlaneCouetteFromRestIsExact) {
  // Shear box of the paper (Sec. 3.3), coarse: walls at +-gammadot H / 2 reach the linear profile exactly
  // (it is in the discrete space); the start-up transient is damped by generalized-alpha (rho_inf = 0.5).
  const double lx = 0.0024, ly = 0.0012, shear = 70.0;
  for (bool stokes : {true, false})
    for (int p : {2, 3}) {
      ScopedOptions o(kTight);
      const geometry::Patch box = geometry::rectangle(lx, ly, 12, 6, p, {true, false}, Vec3(0, -ly / 2, 0));
      FluidOptions opt;
      opt.stokes = stokes;
      opt.wall_velocity[1][0] = Vec3(-shear * ly / 2, 0, 0);
      opt.wall_velocity[1][1] = Vec3(shear * ly / 2, 0, 0);
      FluidSolver fs(PETSC_COMM_WORLD, box, opt);
      fs.set_initial_velocity([](const Vec3&) { return Vec3::Zero(); });
      for (int s = 0; s < 60; ++s) ASSERT_TRUE(fs.step().converged);
      const auto samples = fs.sample(sample_points(lx, ly, -ly / 2));
      const double U = shear * ly / 2;
      for (size_t i = 0; i < samples.size(); ++i) {
        const Vec3 x = sample_points(lx, ly, -ly / 2)[i];
        ASSERT_TRUE(samples[i].found);
        EXPECT_NEAR(samples[i].v[0], shear * x[1], 1e-10 * U) << "stokes=" << stokes << " p=" << p;
        EXPECT_NEAR(samples[i].v[1], 0.0, 1e-10 * U);
        EXPECT_NEAR(samples[i].grad_v(0, 1), shear, 1e-9 * shear);
      }
    }
}

TEST(FluidSolver, PoiseuilleDrivenByBodyForceIsExact) {
  // Channel of paper Sec. 4.1 (0.003 x 0.001 cm), f = 1666.66 dyn/cm^3 as a force per volume: the steady
  // profile is the parabola with u_max = f H^2 / (8 mu), in the discrete space for p >= 2.
  const double lx = 0.003, H = 0.001, f = 1666.66, mu = 0.012;
  const double umax = f * H * H / (8 * mu);
  for (int p : {2, 3}) {
    ScopedOptions o(kTight);
    const geometry::Patch ch = geometry::rectangle(lx, H, 8, 8, p, {true, false});
    FluidOptions opt;
    opt.body_force = Vec3(f, 0, 0);
    FluidSolver fs(PETSC_COMM_WORLD, ch, opt);
    fs.set_initial_velocity([](const Vec3&) { return Vec3::Zero(); });
    for (int s = 0; s < 60; ++s) ASSERT_TRUE(fs.step().converged);
    const auto pts = sample_points(lx, H);
    const auto samples = fs.sample(pts);
    for (size_t i = 0; i < samples.size(); ++i) {
      const double y = pts[i][1];
      EXPECT_NEAR(samples[i].v[0], 4 * umax * y * (H - y) / (H * H), 1e-8 * umax) << "p=" << p;
      EXPECT_NEAR(samples[i].v[1], 0.0, 1e-8 * umax);
    }
    const auto centre = fs.sample({Vec3(0.3 * lx, H / 2, 0)});
    EXPECT_NEAR(centre[0].v[0], umax, 1e-8 * umax);
  }
}

TEST(FluidSolver, PressureNullSpaceAndPinnedPressureGiveTheSameState) {
  // A channel driven along and across the walls (f_y balanced by a pressure gradient), started from a
  // disturbed flow: with the constant pressure as MatNullSpace (the default) and with one pinned pressure
  // control value, 5 steps give the same velocity, and the same pressure (both put the first control value
  // at 0).
  const double lx = 0.003, H = 0.001;
  std::vector<double> state[2];
  for (int pin = 0; pin < 2; ++pin) {
    ScopedOptions o(kTight);
    const geometry::Patch ch = geometry::rectangle(lx, H, 8, 6, 2, {true, false});
    FluidOptions opt;
    opt.body_force = Vec3(1666.66, 500.0, 0);
    opt.pressure_null_space = pin == 0;
    FluidSolver fs(PETSC_COMM_WORLD, ch, opt);
    fs.set_initial_velocity([&](const Vec3& x) {
      return Vec3(0.01 * std::sin(2 * std::numbers::pi * x[0] / lx) * std::sin(std::numbers::pi * x[1] / H),
                  0, 0);
    });
    for (int s = 0; s < 5; ++s) ASSERT_TRUE(fs.step().converged);
    state[pin] = fs.gather_to_zero(fs.solution());
  }
  ASSERT_EQ(state[0].size(), state[1].size());
  double dv = 0, dp = 0, vmax = 0, pmax = 0;
  for (size_t i = 0; i < state[0].size(); ++i) {
    const bool pressure = i % 3 == 2;
    (pressure ? dp : dv) = std::max(pressure ? dp : dv, std::abs(state[0][i] - state[1][i]));
    (pressure ? pmax : vmax) = std::max(pressure ? pmax : vmax, std::abs(state[1][i]));
  }
  std::printf("  null space vs pin: velocity %.2e of %.2e, pressure %.2e of %.2e\n", dv, vmax, dp, pmax);
  EXPECT_GT(pmax, 0.1) << "the pressure balances f_y: it is not zero";
  EXPECT_LT(dv, 1e-10 * vmax);
  EXPECT_LT(dp, 1e-9 * pmax);
  EXPECT_EQ(state[0][2], 0.0) << "the null-space run's pressure is shifted to the pin's gauge";
}

TEST(FluidSolver, StartUpPoiseuilleFollowsTheSeriesSolution) {
  // From rest: u(y, t) = u_s(y) - sum_{k odd} 4 f H^2 / (mu pi^3 k^3) sin(k pi y / H) exp(-k^2 pi^2 nu t /
  // H^2).
  ScopedOptions o(kTight);
  const double lx = 0.003, H = 0.001, f = 1666.66, mu = 0.012, rho = 1.025, nu = mu / rho;
  const double pi = std::numbers::pi, T = H * H / (pi * pi * nu);  // slowest decay time, 8.6e-6 s
  const geometry::Patch ch = geometry::rectangle(lx, H, 4, 32, 3, {true, false});
  FluidOptions opt;
  opt.body_force = Vec3(f, 0, 0);
  opt.stokes = true;
  opt.dt = T / 100;
  FluidSolver fs(PETSC_COMM_WORLD, ch, opt);
  fs.set_initial_velocity([](const Vec3&) { return Vec3::Zero(); });
  auto exact = [&](double y, double t) {
    double u = f / (2 * mu) * y * (H - y);
    for (int k = 1; k < 400; k += 2)
      u -= 4 * f * H * H / (mu * std::pow(pi, 3) * k * k * k) * std::sin(k * pi * y / H) *
           std::exp(-k * k * pi * pi * nu * t / (H * H));
    return u;
  };
  auto exact_rate = [&](double y, double t) {
    double r = 0;
    for (int k = 1; k < 400; k += 2)
      r += 4 * f * H * H / (mu * std::pow(pi, 3) * k * k * k) * std::sin(k * pi * y / H) *
           (k * k * pi * pi * nu / (H * H)) * std::exp(-k * k * pi * pi * nu * t / (H * H));
    return r;
  };
  const double umax = f * H * H / (8 * mu);
  for (int checkpoint : {50, 100, 200}) {
    while (fs.steps_taken() < checkpoint) ASSERT_TRUE(fs.step().converged);
    for (double y : {0.1 * H, 0.3 * H, 0.5 * H}) {
      const auto s = fs.sample({Vec3(0.5 * lx, y, 0)});
      // Tolerance: O(dt^2) time error plus the start from a zero (not consistent) velocity rate.
      EXPECT_NEAR(s[0].v[0], exact(y, fs.time()), 2e-3 * umax) << "t=" << fs.time() << " y=" << y;
      // The sampled time derivative (what the solid's kinematic update will use) follows d u / d t.
      const double rate = exact_rate(y, fs.time()), rate0 = exact_rate(0.5 * H, 0.5 * T);
      EXPECT_NEAR(s[0].vdot[0], rate, 2e-2 * rate0) << "t=" << fs.time() << " y=" << y;
    }
  }
}

namespace {
/// Max |J - J_fd| / max |J| of the assembled tangent against central differences of the assembled residual.
double jacobian_deviation(FluidSolver& fs, double amplitude) {
  Vec U, F0, F1, dU;
  CELLFSI_PETSC(VecDuplicate(fs.solution(), &U));
  CELLFSI_PETSC(VecCopy(fs.solution(), U));
  // A non-trivial state: random perturbation of the current one (deterministic seed).
  PetscRandom rnd;
  CELLFSI_PETSC(PetscRandomCreate(PETSC_COMM_WORLD, &rnd));
  CELLFSI_PETSC(PetscRandomSetSeed(rnd, 42));
  CELLFSI_PETSC(PetscRandomSeed(rnd));
  CELLFSI_PETSC(VecDuplicate(U, &dU));
  CELLFSI_PETSC(VecSetRandom(dU, rnd));
  CELLFSI_PETSC(VecAXPY(U, amplitude, dU));
  CELLFSI_PETSC(PetscRandomDestroy(&rnd));
  Mat J;
  CELLFSI_PETSC(DMCreateMatrix(fs.dm(), &J));
  fs.evaluate_jacobian(U, J);
  fs.evaluate_jacobian(
      U, J);  // a second assembly into the same matrix must work (Dirichlet rows keep their pattern)
  CELLFSI_PETSC(VecDuplicate(U, &F0));
  CELLFSI_PETSC(VecDuplicate(U, &F1));
  PetscInt n = 0;
  CELLFSI_PETSC(VecGetSize(U, &n));
  double max_j = 0, max_diff = 0;
  for (PetscInt col = 0; col < n; ++col) {
    const double h = 1e-7 * amplitude;
    CELLFSI_PETSC(VecSetValue(U, col, h, ADD_VALUES));
    CELLFSI_PETSC(VecAssemblyBegin(U));
    CELLFSI_PETSC(VecAssemblyEnd(U));
    fs.evaluate_residual(U, F1);
    CELLFSI_PETSC(VecSetValue(U, col, -2 * h, ADD_VALUES));
    CELLFSI_PETSC(VecAssemblyBegin(U));
    CELLFSI_PETSC(VecAssemblyEnd(U));
    fs.evaluate_residual(U, F0);
    CELLFSI_PETSC(VecSetValue(U, col, h, ADD_VALUES));
    CELLFSI_PETSC(VecAssemblyBegin(U));
    CELLFSI_PETSC(VecAssemblyEnd(U));
    CELLFSI_PETSC(VecAXPY(F1, -1.0, F0));
    CELLFSI_PETSC(VecScale(F1, 1.0 / (2 * h)));
    // Compare column col.
    Vec Jc;
    CELLFSI_PETSC(VecDuplicate(U, &Jc));
    CELLFSI_PETSC(MatGetColumnVector(J, Jc, col));
    double nj = 0;
    CELLFSI_PETSC(VecNorm(Jc, NORM_INFINITY, &nj));
    CELLFSI_PETSC(VecAXPY(Jc, -1.0, F1));
    double nd = 0;
    CELLFSI_PETSC(VecNorm(Jc, NORM_INFINITY, &nd));
    max_j = std::max(max_j, nj);
    max_diff = std::max(max_diff, nd);
    CELLFSI_PETSC(VecDestroy(&Jc));
  }
  CELLFSI_PETSC(MatDestroy(&J));
  CELLFSI_PETSC(VecDestroy(&U));
  CELLFSI_PETSC(VecDestroy(&dU));
  CELLFSI_PETSC(VecDestroy(&F0));
  CELLFSI_PETSC(VecDestroy(&F1));
  return max_diff / max_j;
}
}  // namespace

TEST(FluidSolver, AssembledTangentMatchesFiniteDifferences) {
  const geometry::Patch ch = geometry::narrowing_channel(geometry::NarrowingChannel{}, 6, 3, 2);
  FluidOptions opt;
  opt.stokes = true;
  opt.body_force = Vec3(1666.66, 0, 0);
  FluidSolver stokes(PETSC_COMM_WORLD, ch, opt);
  stokes.set_initial_velocity([](const Vec3& x) { return Vec3(0.01 + 3 * x[1], 5 * x[0], 0); });
  // Stokes part: the tangent is the exact Jacobian (curved geometry, walls, pressure pin included).
  EXPECT_LT(jacobian_deviation(stokes, 0.01), 1e-6);
  opt.stokes = false;
  FluidSolver ns(PETSC_COMM_WORLD, ch, opt);
  ns.set_initial_velocity([](const Vec3& x) { return Vec3(0.01 + 3 * x[1], 5 * x[0], 0); });
  // Navier-Stokes: exact but for the derivative of tau_M in v (documented approximation): at these Reynolds
  // numbers tau_M is dominated by 4/dt^2 and the viscous term, so the deviation is small.
  const double dev = jacobian_deviation(ns, 0.01);
  std::printf("  Navier-Stokes tangent: max |J - J_fd| / max |J| = %.3e\n", dev);
  EXPECT_LT(dev, 1e-3);
}

// A viscosity field (FluidSolver::set_viscosity): its tangent, where it varies (each point's own nu and grad
// nu), is the Jacobian of its residual; in Stokes mode exactly, as without a field.
TEST(FluidSolver, AssembledTangentWithAViscosityFieldMatchesFiniteDifferences) {
  const geometry::Patch ch = geometry::narrowing_channel(geometry::NarrowingChannel{}, 6, 3, 2);
  FluidOptions opt;
  opt.body_force = Vec3(1666.66, 0, 0);
  for (bool stokes : {true, false}) {
    opt.stokes = stokes;
    FluidSolver fs(PETSC_COMM_WORLD, ch, opt);
    fs.set_initial_velocity([](const Vec3& x) { return Vec3(0.01 + 3 * x[1], 5 * x[0], 0); });
    // A ratio of 5 across the channel, smooth in x and y.
    fs.project_viscosity([&](const Vec3& x) {
      return opt.viscosity * (3 + 2 * std::sin(2000 * x[1]) * std::cos(1000 * x[0]));
    });
    const double dev = jacobian_deviation(fs, 0.01);
    std::printf("  %s tangent with a viscosity field: max |J - J_fd| / max |J| = %.3e\n",
                stokes ? "Stokes" : "Navier-Stokes", dev);
    EXPECT_LT(dev, stokes ? 1e-6 : 1e-3);
  }
}

namespace {
/// Residual and Jacobian of the solver's current state, perturbed, with a few immersed points.
struct Assembled {
  std::vector<double> F;
  Mat J = nullptr;
  ~Assembled() { MatDestroy(&J); }
};
void assemble_state(FluidSolver& fs, Assembled& out) {
  Vec U, F;
  CELLFSI_PETSC(VecDuplicate(fs.solution(), &U));
  CELLFSI_PETSC(VecCopy(fs.solution(), U));
  CELLFSI_PETSC(VecShift(U, 1e-4));
  CELLFSI_PETSC(VecDuplicate(U, &F));
  fs.evaluate_residual(U, F);
  out.F = fs.gather_to_zero(F);
  CELLFSI_PETSC(MatDuplicate(fs.jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, &out.J));
  fs.evaluate_jacobian(U, out.J);
  CELLFSI_PETSC(VecDestroy(&U));
  CELLFSI_PETSC(VecDestroy(&F));
}
/// |A - B|_F (0: bit for bit).
double matrix_difference(Mat A, Mat B) {
  Mat D;
  CELLFSI_PETSC(MatDuplicate(A, MAT_COPY_VALUES, &D));
  CELLFSI_PETSC(MatAXPY(D, -1.0, B, SAME_NONZERO_PATTERN));
  PetscReal n = 0;
  CELLFSI_PETSC(MatNorm(D, NORM_FROBENIUS, &n));
  CELLFSI_PETSC(MatDestroy(&D));
  return n;
}
}  // namespace

// Where the field's control values over an element are all equal, the element is assembled as with a uniform
// viscosity of that value, on the same fast paths: a field equal to the fluid's viscosity everywhere changes
// no bit of the residual or the Jacobian (immersed points included), nor does a field of another constant
// against a fluid of that viscosity; the bulk operator (bulk_jacobian) ignores the field.
TEST(FluidSolver, UniformViscosityFieldChangesNoBit) {
  const double lx = 0.0024, ly = 0.0012, shear = 70.0;
  const geometry::Patch box = geometry::rectangle(lx, ly, 12, 6, 3, {true, false}, Vec3(0, -ly / 2, 0));
  FluidOptions opt = moving_walls(shear * ly / 2);
  const std::vector<fluid::ImmersedPointData> pts = five_immersed_points(lx, ly, 0.0);
  auto make = [&](const FluidOptions& o) {
    auto fs = std::make_unique<FluidSolver>(PETSC_COMM_WORLD, box, o);
    fs->set_initial_velocity(
        [&](const Vec3& x) { return Vec3(shear * x[1], 1e-3 * std::sin(9 * x[0] / lx), 0); });
    fs->set_immersed_points(pts);
    return fs;
  };
  for (double mu : {opt.viscosity, 5 * opt.viscosity}) {
    FluidOptions o = opt;
    o.viscosity = mu;
    auto plain = make(o), with_field = make(opt);
    with_field->set_viscosity([&](int) { return mu; });
    Assembled a, b;
    assemble_state(*plain, a);
    assemble_state(*with_field, b);
    EXPECT_EQ(a.F, b.F) << "mu " << mu;
    EXPECT_EQ(matrix_difference(a.J, b.J), 0.0) << "mu " << mu;
  }
  // The bulk operator of a solver with a varying field is that of the fluid's uniform viscosity.
  auto plain = make(opt), with_field = make(opt);
  with_field->set_viscosity([&](int k) { return opt.viscosity * (1 + (k % 7 == 0 ? 4 : 0)); });
  Mat Jp, Jf;
  CELLFSI_PETSC(MatDuplicate(plain->jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, &Jp));
  CELLFSI_PETSC(MatDuplicate(plain->jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, &Jf));
  plain->bulk_jacobian(plain->solution(), Jp);
  with_field->bulk_jacobian(with_field->solution(), Jf);
  EXPECT_EQ(matrix_difference(Jp, Jf), 0.0);
  EXPECT_TRUE(with_field->has_viscosity_field());  // restored after the bulk assembly
  // ... and the field changes the Jacobian itself.
  plain->evaluate_jacobian(plain->solution(), Jp);
  with_field->evaluate_jacobian(with_field->solution(), Jf);
  EXPECT_GT(matrix_difference(Jp, Jf), 0.0);
  CELLFSI_PETSC(MatDestroy(&Jp));
  CELLFSI_PETSC(MatDestroy(&Jf));
}

TEST(FluidSolver, JacobianPartsAddUpToTheJacobian) {
  // The band solver's split (jacobian_part): the elements of a mask with every immersed point, and the other
  // elements, add up to the whole tangent, including the wall (Dirichlet) rows, the pinned pressure and the
  // periodic seam, which the mask below all touches.
  const double lx = 0.0024, ly = 0.0012, shear = 70.0;
  const geometry::Patch box = geometry::rectangle(lx, ly, 12, 6, 3, {true, false}, Vec3(0, -ly / 2, 0));
  const FluidOptions opt = moving_walls(shear * ly / 2);
  FluidSolver fs(PETSC_COMM_WORLD, box, opt);
  fs.set_initial_velocity(
      [&](const Vec3& x) { return Vec3(shear * x[1], 1e-3 * std::sin(9 * x[0] / lx), 0); });
  const std::vector<fluid::ImmersedPointData> pts = five_immersed_points(lx, ly, 0.5);
  fs.set_immersed_points(pts);
  std::vector<char> mask(box.n_elements(), 0);
  for (int e = 0; e < box.n_elements(); ++e) {
    const geometry::Index3 m = box.element_multi_index(e);
    mask[e] = m[0] <= 1 || m[0] == 11 || m[1] == 0;
  }
  Mat J, Jf, Jb;
  CELLFSI_PETSC(MatDuplicate(fs.jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, &J));
  CELLFSI_PETSC(MatDuplicate(J, MAT_DO_NOT_COPY_VALUES, &Jf));
  CELLFSI_PETSC(MatDuplicate(J, MAT_DO_NOT_COPY_VALUES, &Jb));
  fs.evaluate_jacobian(fs.solution(), J);
  fs.jacobian_part(fs.solution(), Jf, mask, false);
  fs.jacobian_part(fs.solution(), Jb, mask, true);
  PetscReal nj = 0, nb = 0, nf = 0, nd = 0;
  CELLFSI_PETSC(MatNorm(J, NORM_FROBENIUS, &nj));
  CELLFSI_PETSC(MatNorm(Jb, NORM_FROBENIUS, &nb));
  CELLFSI_PETSC(MatNorm(Jf, NORM_FROBENIUS, &nf));
  CELLFSI_PETSC(MatAXPY(Jf, 1.0, Jb, SAME_NONZERO_PATTERN));
  CELLFSI_PETSC(MatAXPY(Jf, -1.0, J, SAME_NONZERO_PATTERN));
  CELLFSI_PETSC(MatNorm(Jf, NORM_FROBENIUS, &nd));
  // (The wall rows' unit diagonal dominates |J|: the difference is measured against the band part, the
  // smaller.)
  EXPECT_GT(nb, 0.0);
  EXPECT_GT(nf, nb);
  EXPECT_LT(nd, 1e-13 * nb) << "|J_fixed + J_band - J| / |J_band| = " << nd / nb;
  // The fixed part plus the band part added in place (jacobian_add_part) is the Jacobian too.
  fs.jacobian_part(fs.solution(), Jf, mask, false);
  fs.jacobian_add_part(fs.solution(), Jf, mask);
  CELLFSI_PETSC(MatAXPY(Jf, -1.0, J, SAME_NONZERO_PATTERN));
  CELLFSI_PETSC(MatNorm(Jf, NORM_FROBENIUS, &nd));
  EXPECT_LT(nd, 1e-13 * nb) << "|J_fixed (+)= J_band - J| / |J_band| = " << nd / nb;
  // A mask of the wrong size is refused.
  EXPECT_THROW(fs.jacobian_part(fs.solution(), Jb, std::vector<char>(3, 0), true), std::invalid_argument);
  CELLFSI_PETSC(MatDestroy(&J));
  CELLFSI_PETSC(MatDestroy(&Jf));
  CELLFSI_PETSC(MatDestroy(&Jb));
}

TEST(FluidSolver, ImmersedPointsWithTheFluidStressLeaveTheResidualUnchanged) {
  // Immersed points at every Eulerian quadrature point with beta = 0 and stress (1/rho) F S F^T = 2 nu sym
  // grad v (here constant: a Couette state) cancel exactly: Eq. (10) replaces the fluid stress by the
  // solid's.
  const double lx = 0.0024, ly = 0.0012, shear = 70.0;
  const geometry::Patch box = geometry::rectangle(lx, ly, 6, 4, 2, {true, false}, Vec3(0, -ly / 2, 0));
  const FluidOptions opt = moving_walls(shear * ly / 2);
  FluidSolver fs(PETSC_COMM_WORLD, box, opt);
  fs.set_initial_velocity([&](const Vec3& x) { return Vec3(shear * x[1], 0, 0); });
  Vec F0, F1;
  CELLFSI_PETSC(VecDuplicate(fs.solution(), &F0));
  CELLFSI_PETSC(VecDuplicate(fs.solution(), &F1));
  // A non-zero residual to compare against: perturb the state so the residual is not trivially zero.
  Vec U;
  CELLFSI_PETSC(VecDuplicate(fs.solution(), &U));
  CELLFSI_PETSC(VecCopy(fs.solution(), U));
  CELLFSI_PETSC(VecShift(U, 1e-4));
  fs.evaluate_residual(U, F0);
  const double nu = opt.viscosity / opt.density;
  std::vector<fluid::ImmersedPointData> pts;
  std::vector<geometry::QuadraturePoint> qp;
  for (int e = 0; e < box.n_elements(); ++e) {
    const geometry::Index3 m = box.element_multi_index(e);
    geometry::element_quadrature(box, m, geometry::default_gauss(box), qp);
    for (const auto& q : qp) {
      fluid::ImmersedPointData d;
      d.x = box.point(q.xi);
      d.data.weight = q.weight * lx * ly;  // affine map: det J = lx ly
      d.data.beta = 0.0;
      d.data.stress[0][1] = d.data.stress[1][0] = nu * shear;  // 2 nu sym grad v of the perturbed state
      pts.push_back(d);
    }
  }
  fs.set_immersed_points(pts);
  fs.evaluate_residual(U, F1);
  double n0 = 0, nd = 0;
  CELLFSI_PETSC(VecNorm(F0, NORM_INFINITY, &n0));
  CELLFSI_PETSC(VecAXPY(F1, -1.0, F0));
  CELLFSI_PETSC(VecNorm(F1, NORM_INFINITY, &nd));
  EXPECT_GT(n0, 0.0);
  EXPECT_LT(nd, 1e-10 * n0 + 1e-16);
  // A point outside the domain is an error naming the point.
  EXPECT_THROW(fs.set_immersed_points({fluid::ImmersedPointData{Vec3(0.001, 0.0009, 0), {}}}),
               std::runtime_error);
  CELLFSI_PETSC(VecDestroy(&U));
  CELLFSI_PETSC(VecDestroy(&F0));
  CELLFSI_PETSC(VecDestroy(&F1));
}

TEST(FluidSolver, ImmersedForcesEnterTheMomentumRowsAsTheirTotal) {
  // An external force on a solid (solid/external_load.hpp: the stretching test's beads) is a load on the
  // momentum equation where the solid's points are. With sum_A N_A = 1 the momentum rows of the residual add
  // up to -sum_q w_q force_q per component (R = B - L), wherever the points lie in their elements; two
  // opposite patches add up to nothing. Fluid at rest, beta = 0, no stress: only the force is left.
  const double lx = 0.0024, ly = 0.0012;
  // Points within |y| < ly / 8, away from the walls' rows (the wall functions live in the outer elements).
  const geometry::Patch box = geometry::rectangle(lx, ly, 6, 4, 2, {true, false}, Vec3(0, -ly / 2, 0));
  FluidSolver fs(PETSC_COMM_WORLD, box, FluidOptions{});
  fs.set_initial_velocity([](const Vec3&) { return Vec3(Vec3::Zero()); });
  Vec U, F0, F1;
  CELLFSI_PETSC(VecDuplicate(fs.solution(), &U));
  CELLFSI_PETSC(VecCopy(fs.solution(), U));
  CELLFSI_PETSC(VecDuplicate(U, &F0));
  CELLFSI_PETSC(VecDuplicate(U, &F1));
  fs.evaluate_residual(U, F0);
  // The sums of the x and y momentum rows of F1 - F0 (one rank: the local array is the whole vector,
  // unknowns interleaved v_x, v_y, p per node).
  auto momentum_sums = [&]() {
    fs.evaluate_residual(U, F1);
    CELLFSI_PETSC(VecAXPY(F1, -1.0, F0));
    const PetscScalar* a = nullptr;
    PetscInt n = 0;
    CELLFSI_PETSC(VecGetLocalSize(F1, &n));
    CELLFSI_PETSC(VecGetArrayRead(F1, &a));
    Vec3 sum = Vec3::Zero();
    for (PetscInt i = 0; i < n; ++i)
      if (i % 3 < 2) sum[i % 3] += a[i];
    CELLFSI_PETSC(VecRestoreArrayRead(F1, &a));
    return sum;
  };
  auto patch = [&](double x0, double sign) {
    std::vector<fluid::ImmersedPointData> pts;
    for (int i = 0; i < 6; ++i) {
      fluid::ImmersedPointData d;
      d.x = Vec3(x0 + lx * 0.013 * i, ly * (0.02 * i - 0.06), 0);
      d.data.weight = 1e-9 * (1 + 0.3 * i);
      d.data.force = {sign * 2.0e3, sign * -0.5e3, 0.0};
      pts.push_back(d);
    }
    return pts;
  };
  std::vector<fluid::ImmersedPointData> one = patch(0.31 * lx, 1.0);
  Vec3 expected = Vec3::Zero();
  for (const auto& d : one) expected -= d.data.weight * Vec3(d.data.force[0], d.data.force[1], 0);
  fs.set_immersed_points(one);
  const Vec3 got = momentum_sums();
  std::printf("  one patch: momentum rows sum to (%.15g, %.15g), expected (%.15g, %.15g)\n", got[0], got[1],
              expected[0], expected[1]);
  EXPECT_NEAR(got[0], expected[0], 1e-12 * expected.norm());
  EXPECT_NEAR(got[1], expected[1], 1e-12 * expected.norm());
  std::vector<fluid::ImmersedPointData> both = one, other = patch(0.67 * lx, -1.0);
  both.insert(both.end(), other.begin(), other.end());
  fs.set_immersed_points(both);
  EXPECT_LT(momentum_sums().norm(), 1e-12 * expected.norm());
  CELLFSI_PETSC(VecDestroy(&U));
  CELLFSI_PETSC(VecDestroy(&F0));
  CELLFSI_PETSC(VecDestroy(&F1));
}

TEST(FluidParallel, SameProblemOnOneAndTwoRanksAgrees) {
  // A non-trivial Navier-Stokes shear flow (perturbed initial state) on PETSC_COMM_SELF and PETSC_COMM_WORLD;
  // when run on 2 ranks the two solutions must agree to 1e-10 (tight solves remove the preconditioner's
  // effect).
  ScopedOptions o(kTight);
  const double lx = 0.0024, ly = 0.0012, shear = 70.0;
  const geometry::Patch box = geometry::rectangle(lx, ly, 16, 8, 3, {true, false}, Vec3(0, -ly / 2, 0));
  FluidOptions opt;
  opt.wall_velocity[1][0] = Vec3(-shear * ly / 2, 0, 0);
  opt.wall_velocity[1][1] = Vec3(shear * ly / 2, 0, 0);
  auto v0 = [&](const Vec3& x) {
    const double k = 2 * std::numbers::pi / lx;
    return Vec3(shear * x[1] + 0.02 * std::sin(k * x[0]), 0.01 * std::cos(k * x[0]), 0);
  };
  std::vector<std::vector<double>> results;
  for (MPI_Comm comm : {PETSC_COMM_SELF, PETSC_COMM_WORLD}) {
    FluidSolver fs(comm, box, opt);
    fs.set_initial_velocity(v0);
    for (int s = 0; s < 3; ++s) ASSERT_TRUE(fs.step().converged);
    results.push_back(fs.gather_to_zero(fs.solution()));
  }
  PetscMPIInt rank = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  if (rank == 0) {
    ASSERT_EQ(results[0].size(), results[1].size());
    double scale = 0, diff = 0;
    for (size_t i = 0; i < results[0].size(); ++i) {
      scale = std::max(scale, std::abs(results[0][i]));
      diff = std::max(diff, std::abs(results[0][i] - results[1][i]));
    }
    EXPECT_LT(diff, 1e-10 * scale);
  }
}

// What the VMS solver answers through fluid::ImmersedFluid beyond the steps, on 1 and (as
// fluid_parallel_2ranks) 2 ranks: the state's bytes read back into another solver give the same state, and into
// a solver of another mesh are refused; an element region's unknowns are its nodes' blocks in the DMDA's
// numbering (checked through the natural ordering); each owned unknown's kind is its place in its node block.
TEST(FluidParallel, StateBytesRegionUnknownsAndKindsOnAnyRanks) {
  const geometry::Patch box = geometry::rectangle(0.0024, 0.0012, 8, 4, 2, {true, false});
  const geometry::Patch other = geometry::rectangle(0.0024, 0.0012, 10, 4, 2, {true, false});
  FluidOptions opt;
  FluidSolver fs(PETSC_COMM_WORLD, box, opt);
  fs.set_initial_velocity([](const Vec3& x) { return Vec3(70 * x[1], 10 * x[0] * x[1], 0); });
  PetscMPIInt rank = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  // The state, through a file as a checkpoint holds it (rank 0 writes the bytes).
  char path[64];
  int pid = static_cast<int>(getpid());
  MPI_Bcast(&pid, 1, MPI_INT, 0, PETSC_COMM_WORLD);
  std::snprintf(path, sizeof path, "/tmp/cellfsi_state_%d.petsc", pid);
  const std::string bytes = fs.state_bytes();
  if (rank == 0) {
    EXPECT_FALSE(bytes.empty());
    std::FILE* f = std::fopen(path, "wb");
    ASSERT_NE(f, nullptr);
    std::fwrite(bytes.data(), 1, bytes.size(), f);
    std::fclose(f);
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  auto load = [&](fluid::ImmersedFluid& into) {
    PetscViewer v = nullptr;
    CELLFSI_PETSC(PetscViewerBinaryOpen(PETSC_COMM_WORLD, path, FILE_MODE_READ, &v));
    const auto r = into.load_state(v, 3);
    PetscViewerDestroy(&v);
    return r;
  };
  FluidSolver same(PETSC_COMM_WORLD, box, opt), wrong(PETSC_COMM_WORLD, other, opt);
  EXPECT_EQ(load(same), fluid::ImmersedFluid::LoadedState::ok);
  EXPECT_EQ(load(wrong), fluid::ImmersedFluid::LoadedState::does_not_fit);
  EXPECT_EQ(wrong.steps_taken(), 0);
  MPI_Barrier(PETSC_COMM_WORLD);
  if (rank == 0) std::remove(path);
  EXPECT_EQ(same.steps_taken(), 3);
  EXPECT_EQ(same.time(), 3 * opt.dt);
  EXPECT_EQ(same.gather_to_zero(same.solution()), fs.gather_to_zero(fs.solution()));
  EXPECT_EQ(same.gather_to_zero(same.solution_rate()), fs.gather_to_zero(fs.solution_rate()));
  // A region: the elements around one function, grown by one. Its unknowns (every rank gets all of them) marked
  // in a vector, seen in the natural ordering: exactly the blocks of the functions on the region's elements.
  const std::vector<char> region =
      geometry::grow_elements(box, geometry::elements_supporting(box, {box.control_index(3, 2)}), 1);
  const std::vector<PetscInt> unknowns = fs.region_unknowns(region);
  EXPECT_TRUE(std::is_sorted(unknowns.begin(), unknowns.end()));
  Vec marks;
  CELLFSI_PETSC(VecDuplicate(fs.solution(), &marks));
  CELLFSI_PETSC(VecSet(marks, 0.0));
  if (rank == 0)
    for (PetscInt g : unknowns) CELLFSI_PETSC(VecSetValue(marks, g, 1.0, INSERT_VALUES));
  CELLFSI_PETSC(VecAssemblyBegin(marks));
  CELLFSI_PETSC(VecAssemblyEnd(marks));
  const std::vector<double> natural = fs.gather_to_zero(marks);
  CELLFSI_PETSC(VecDestroy(&marks));
  if (rank == 0) {
    std::vector<double> expected(natural.size(), 0.0);
    for (int n : geometry::functions_on_elements(box, region))
      for (int c = 0; c < 3; ++c) expected[3 * n + c] = 1.0;
    EXPECT_EQ(natural, expected);
    EXPECT_EQ(unknowns.size(), 3 * geometry::functions_on_elements(box, region).size());
  }
  const std::vector<int> kinds = fs.unknown_kinds();
  PetscInt n_local = 0;
  CELLFSI_PETSC(VecGetLocalSize(fs.solution(), &n_local));
  ASSERT_EQ(static_cast<PetscInt>(kinds.size()), n_local);
  for (PetscInt i = 0; i < n_local; ++i) EXPECT_EQ(kinds[i], i % 3);
  const std::optional<fluid::BlockLayout> layout = fs.block_layout();
  ASSERT_TRUE(layout.has_value());
  EXPECT_EQ(layout->dof, 3);
  EXPECT_EQ(layout->n[0], box.n_control(0));
  EXPECT_EQ(layout->n[1], box.n_control(1));
  EXPECT_TRUE(layout->periodic[0]);
  EXPECT_FALSE(layout->periodic[1]);
}
