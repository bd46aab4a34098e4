// VMS pointwise kernels: the residual against a literal transcription of the formulas of vms_kernel.hpp, the
// tangent against finite differences of the residual, closed-form special cases, and invariants.
//
// Inputs are random but scaled like the application (lengths ~1e-5 cm so gradients ~1e5, velocities ~0.1
// cm/s, nu = 0.0117 cm^2/s, dt = 5e-4 s, s in [1, 1e3]). There the convective terms are ~1e-5 of the viscous
// ones, so every check is also run on a "balanced" scaling (unit lengths, velocities, dt; nu = 0.1) where the
// Galerkin, cross, SUPG, Reynolds-stress, PSPG and LSIC terms are all of order one and an error in any of
// them shows.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "fluid/vms_kernel.hpp"
#include "vms_test_cases.hpp"

using namespace cellfsi::fluid;
using namespace vms_test;

namespace {

// Column k of the Jacobian of R(U) by central differences, stored like the tangent (row-major).
// order 4: the five-point stencil is exact (up to round-off) for polynomials of degree <= 4 in the perturbed
// unknown. With tau frozen, r_M is quadratic in each unknown and (a . grad N_A) v'_i quartic, so the step can
// be as large as the unknown itself and round-off stays ~1e-14 of the entries. order 2 with a small step is
// used where tau varies (the residual is then not a polynomial).
template <class F>
std::vector<double> fd_jacobian(const Case& c, F&& res, int order, double rel_step) {
  const int m = c.size();
  std::vector<double> J(m * m);
  for (int k = 0; k < m; ++k) {
    const double h = rel_step * c.unknown_scale(k);
    auto at = [&](double t) {
      std::vector<double> u = c.U;
      u[k] += t * h;
      return res(u);
    };
    const std::vector<double> p1 = at(1), m1 = at(-1);
    std::vector<double> p2, m2;
    if (order == 4) p2 = at(2), m2 = at(-2);
    for (int r = 0; r < m; ++r) {
      J[r * m + k] =
          order == 4 ? (8 * (p1[r] - m1[r]) - (p2[r] - m2[r])) / (12 * h) : (p1[r] - m1[r]) / (2 * h);
    }
  }
  return J;
}

// Entries fall into four classes (momentum|continuity rows) x (velocity|pressure columns) whose sizes differ
// by up to ~1e8 at physical scales, so each class is compared on its own scale.
struct Comparison {
  double worst = 0;                   // max over entries of |K - J| / max(|J|, floor * max |J| of the class)
  std::array<double, 4> class_fro{};  // ||K - J||_F / ||J||_F per class
};

int entry_class(const Case& c, int r, int k) {
  return 2 * (r % c.nc() == c.prm.dim) + (k % c.nc() == c.prm.dim);
}

Comparison compare(const Case& c, const std::vector<double>& K, const std::vector<double>& J, double floor) {
  const int m = c.size();
  std::array<double, 4> jmax{}, diff2{}, j2{};
  for (int r = 0; r < m; ++r)
    for (int k = 0; k < m; ++k) {
      const int cl = entry_class(c, r, k);
      jmax[cl] = std::max(jmax[cl], std::abs(J[r * m + k]));
      diff2[cl] += std::pow(K[r * m + k] - J[r * m + k], 2);
      j2[cl] += std::pow(J[r * m + k], 2);
    }
  Comparison out;
  for (int r = 0; r < m; ++r)
    for (int k = 0; k < m; ++k) {
      const int cl = entry_class(c, r, k);
      const double err = std::abs(K[r * m + k] - J[r * m + k]);
      // A class that is identically zero in J must be identically zero in K.
      const double e =
          jmax[cl] > 0 ? err / std::max(std::abs(J[r * m + k]), floor * jmax[cl]) : (err > 0 ? 1e300 : 0);
      out.worst = std::max(out.worst, e);
    }
  for (int cl = 0; cl < 4; ++cl) out.class_fro[cl] = j2[cl] > 0 ? std::sqrt(diff2[cl] / j2[cl]) : 0;
  return out;
}

double max_abs(const std::vector<double>& x) {
  double m = 0;
  for (double v : x) m = std::max(m, std::abs(v));
  return m;
}

std::string label(const Case& c) {
  return std::string(c.sc.name) + " " + std::to_string(c.prm.dim) + "D " + (c.prm.stokes ? "Stokes" : "NS") +
         " n=" + std::to_string(c.n);
}

struct Config {
  int dim, n;
  bool stokes;
  const Scales* sc;
};
std::vector<Config> all_configs() {
  std::vector<Config> out;
  for (const Scales* sc : {&kPhysical, &kBalanced})
    for (bool stokes : {false, true}) {
      out.push_back({2, 9, stokes, sc});
      out.push_back({3, 27, stokes, sc});
    }
  return out;
}

// Tolerances (see the report in each test's output).
constexpr double kFdTol = 1e-7;    // tangent vs finite differences, per entry
constexpr double kFdFloor = 1e-6;  // entries below this fraction of their class maximum compared absolutely

// The header's formulas transcribed term by term, with no algebraic rearrangement.
std::vector<double> reference_residual(const Case& c, const PointFields& f, const Stabilization& tau) {
  const VmsParameters& prm = c.prm;
  const int d = prm.dim, nc = d + 1;
  const double conv = prm.stokes ? 0.0 : 1.0;
  double r_m[3] = {}, v_f[3] = {}, div = 0;
  for (int i = 0; i < d; ++i) {
    double v_grad_v = 0;
    for (int j = 0; j < d; ++j) v_grad_v += f.v[j] * f.dv[i][j];
    r_m[i] = f.vdot[i] + conv * v_grad_v + f.dp[i] - prm.nu * f.lap_v[i] - prm.g[i];
    for (int j = 0; j < d; ++j) r_m[i] -= f.dnu[j] * (f.dv[i][j] + f.dv[j][i]);  // a viscosity field
    v_f[i] = -tau.tau_m * r_m[i];
    div += f.dv[i][i];
  }
  const double p_f = -tau.tau_c * div;
  std::vector<double> R(c.size(), 0.0);
  for (int A = 0; A < c.n; ++A) {
    const double NA = c.N[A];
    const double* dNA = &c.dN[A * 3];
    for (int i = 0; i < d; ++i) {
      double v_grad_v = 0, vf_grad_v = 0, visc = 0, adv_dNA = 0;
      for (int j = 0; j < d; ++j) {
        v_grad_v += f.v[j] * f.dv[i][j];
        vf_grad_v += v_f[j] * f.dv[i][j];
        visc += dNA[j] * (f.dv[i][j] + f.dv[j][i]);
        adv_dNA += (f.v[j] + v_f[j]) * dNA[j];
      }
      const double galerkin = NA * (f.vdot[i] + conv * v_grad_v - prm.g[i]) + prm.nu * visc - dNA[i] * f.p;
      const double cross = conv * NA * vf_grad_v;
      const double supg_reynolds = -conv * adv_dNA * v_f[i];
      const double lsic = -dNA[i] * p_f;
      R[A * nc + i] = c.weight * (galerkin + cross + supg_reynolds + lsic);
    }
    double pspg = 0;
    for (int j = 0; j < d; ++j) pspg += dNA[j] * v_f[j];
    R[A * nc + d] = c.weight * (NA * div - pspg);
  }
  return R;
}

std::vector<double> reference_immersed(const Case& c, const PointFields& f, const ImmersedPoint& ip) {
  const int d = c.prm.dim, nc = d + 1;
  std::vector<double> R(c.size(), 0.0);
  for (int A = 0; A < c.n; ++A)
    for (int i = 0; i < d; ++i) {
      double v_grad_v = 0, visc = 0, stress = 0;
      for (int j = 0; j < d; ++j) {
        v_grad_v += f.v[j] * f.dv[i][j];
        visc += c.dN[A * 3 + j] * (f.dv[i][j] + f.dv[j][i]);
        stress += c.dN[A * 3 + j] * ip.stress[i][j];
      }
      if (c.prm.stokes) v_grad_v = 0;
      R[A * nc + i] = ip.weight * (-ip.beta * c.N[A] * (f.vdot[i] + v_grad_v - c.prm.g[i]) - c.prm.nu * visc +
                                   stress - c.N[A] * ip.force[i]);
    }
  return R;
}

ImmersedPoint make_immersed_point(const Case& c, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(-1, 1);
  ImmersedPoint ip;
  ip.weight = c.weight * (1.5 + 0.5 * uni(rng));
  ip.beta = 1 - 1.1;  // rho_2 / rho_1 = 1.1: a cell slightly denser than plasma
  // Stress scale ~ nu |grad v| so that it competes with the viscous term.
  const double scale = c.prm.nu * c.sc.velocity / c.sc.length;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j <= i; ++j) ip.stress[i][j] = ip.stress[j][i] = scale * uni(rng);
  // An external load (the stretching test's bead) on the same scale as the stress's divergence.
  for (int i = 0; i < c.prm.dim; ++i) ip.force[i] = scale / c.sc.length * uni(rng);
  return ip;
}

}  // namespace

TEST(VmsKernel, ResidualMatchesTheHeaderFormulasTermByTerm) {
  unsigned seed = 1;
  for (const Config& cf : all_configs()) {
    const Case c = make_case(cf.dim, cf.n, cf.stokes, *cf.sc, seed++);
    const PointFields f = c.fields();
    const Stabilization tau = vms_stabilization(c.prm, f);
    const std::vector<double> R = residual(c, c.U, nullptr), ref = reference_residual(c, f, tau);
    // Each row class (momentum, continuity) on its own scale.
    const int nc = c.nc();
    double worst = 0;
    for (int cls = 0; cls < 2; ++cls) {
      double scale = 0;
      for (int r = 0; r < c.size(); ++r)
        if ((r % nc == c.prm.dim) == cls) scale = std::max(scale, std::abs(ref[r]));
      for (int r = 0; r < c.size(); ++r)
        if ((r % nc == c.prm.dim) == cls) worst = std::max(worst, std::abs(R[r] - ref[r]) / scale);
    }
    std::printf("  residual vs transcription, %-28s: %.2e (tol %.0e)\n", label(c).c_str(), worst, kRefTol);
    EXPECT_LT(worst, kRefTol) << label(c);
  }
}

TEST(VmsKernel, TangentMatchesFiniteDifferencesWithTauFrozen) {
  unsigned seed = 100;
  for (const Config& cf : all_configs()) {
    const Case c = make_case(cf.dim, cf.n, cf.stokes, *cf.sc, seed++);
    const Stabilization frozen = vms_stabilization(c.prm, c.fields());
    const auto J = fd_jacobian(
        c, [&](const std::vector<double>& u) { return residual(c, u, &frozen); }, 4, 1.0);
    const Comparison cmp = compare(c, tangent(c), J, kFdFloor);
    std::printf("  tangent vs FD (tau frozen), %-28s: worst entry %.2e (tol %.0e)\n", label(c).c_str(),
                cmp.worst, kFdTol);
    EXPECT_LT(cmp.worst, kFdTol) << label(c);
  }
}

// A viscosity that varies in space (vms_kernel.hpp): the point's own nu in prm.nu and grad nu in f.dnu, of
// the size a viscosity ratio of 5 across one element gives (|grad nu| ~ 4 nu / element size). The residual's
// -grad nu . (grad v + grad v^T) enters r_M and so v'; its tangent is checked against finite differences, and
// the term must be visible to that check.
Case with_viscosity_gradient(Case c, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(-1, 1);
  for (int j = 0; j < 3; ++j) c.offset.dnu[j] = 4 * c.prm.nu / c.sc.length * uni(rng);
  return c;
}

TEST(VmsKernel, ViscosityGradientResidualMatchesTheHeaderFormulas) {
  unsigned seed = 60;
  for (const Config& cf : all_configs()) {
    const Case c = with_viscosity_gradient(make_case(cf.dim, cf.n, cf.stokes, *cf.sc, seed), seed);
    ++seed;
    const PointFields f = c.fields();
    ASSERT_TRUE(f.has_dnu());
    const std::vector<double> R = residual(c, c.U, nullptr),
                              ref = reference_residual(c, f, vms_stabilization(c.prm, f));
    double worst = 0, scale = 0;
    for (int r = 0; r < c.size(); ++r) scale = std::max(scale, std::abs(ref[r]));
    for (int r = 0; r < c.size(); ++r)
      if (r % c.nc() == c.prm.dim) worst = std::max(worst, std::abs(R[r] - ref[r]) / scale);
    EXPECT_LT(worst, kRefTol) << label(c);
  }
}

TEST(VmsKernel, ViscosityGradientTangentMatchesFiniteDifferences) {
  unsigned seed = 170;
  for (const Config& cf : all_configs()) {
    const Case c = with_viscosity_gradient(make_case(cf.dim, cf.n, cf.stokes, *cf.sc, seed), seed);
    ++seed;
    const Stabilization frozen = vms_stabilization(c.prm, c.fields());
    const auto J = fd_jacobian(
        c, [&](const std::vector<double>& u) { return residual(c, u, &frozen); }, 4, 1.0);
    const std::vector<double> K = tangent(c);
    const Comparison cmp = compare(c, K, J, kFdFloor);
    // Not blind: the same tangent without grad nu differs from it by far more than the tolerance.
    Case uniform = c;
    uniform.offset.dnu = {};
    const Comparison off = compare(c, tangent(uniform), K, 0.0);
    const double seen = *std::max_element(off.class_fro.begin(), off.class_fro.end());
    std::printf(
        "  tangent vs FD with grad nu, %-28s: worst entry %.2e (tol %.0e); grad nu changes K by %.1e\n",
        label(c).c_str(), cmp.worst, kFdTol, seen);
    EXPECT_LT(cmp.worst, kFdTol) << label(c);
    EXPECT_GT(seen, 1e3 * kFdTol) << label(c);
  }
}

// p = 4 in 3D has 125 basis functions, more than the tangent handles in one pass over its column table.
TEST(VmsKernel, TangentWithManyBasisFunctionsMatchesFiniteDifferences) {
  for (bool stokes : {false, true}) {
    const Case c = make_case(3, 125, stokes, kBalanced, 150 + stokes);
    const Stabilization frozen = vms_stabilization(c.prm, c.fields());
    const auto J = fd_jacobian(
        c, [&](const std::vector<double>& u) { return residual(c, u, &frozen); }, 4, 1.0);
    const Comparison cmp = compare(c, tangent(c), J, kFdFloor);
    std::printf("  tangent vs FD (tau frozen), %-28s: worst entry %.2e (tol %.0e)\n", label(c).c_str(),
                cmp.worst, kFdTol);
    EXPECT_LT(cmp.worst, kFdTol) << label(c);
  }
}

// Guards the test above against being blind: on the balanced scaling the convective terms (cross, SUPG,
// Reynolds stress) change every class of the tangent by far more than the FD tolerance.
TEST(VmsKernel, ConvectiveTermsAreVisibleToTheFiniteDifferenceTest) {
  for (int dim : {2, 3}) {
    const Case ns = make_case(dim, dim == 2 ? 9 : 27, false, kBalanced, 7);
    Case st = ns;
    st.prm.stokes = true;
    const Comparison cmp = compare(ns, tangent(st), tangent(ns), 0.0);
    for (int cl = 0; cl < 4; ++cl) {
      std::printf("  %dD balanced: ||K_NS - K_Stokes|| / ||K_NS|| in class %d = %.2e\n", dim, cl,
                  cmp.class_fro[cl]);
      EXPECT_GT(cmp.class_fro[cl], 1e3 * kFdTol) << "class " << cl;
    }
  }
}

TEST(VmsKernel, StokesTangentIsTheExactJacobian) {
  // In Stokes mode tau_M and tau_C do not depend on the unknowns, so no freezing is needed; the residual is
  // then linear in U and the FD step can be large.
  unsigned seed = 200;
  for (const Scales* sc : {&kPhysical, &kBalanced})
    for (int dim : {2, 3}) {
      const Case c = make_case(dim, dim == 2 ? 9 : 27, true, *sc, seed++);
      const auto J = fd_jacobian(
          c, [&](const std::vector<double>& u) { return residual(c, u, nullptr); }, 4, 1.0);
      const Comparison cmp = compare(c, tangent(c), J, kFdFloor);
      std::printf("  Stokes tangent vs FD (tau live), %-28s: worst entry %.2e (tol %.0e)\n", label(c).c_str(),
                  cmp.worst, kFdTol);
      EXPECT_LT(cmp.worst, kFdTol) << label(c);
    }
}

// The Navier-Stokes tangent omits d tau_M / d v (through v.G v). How much that matters, measured against the
// Jacobian of the live-tau residual (second-order FD, step 1e-5 of each unknown's scale, FD error ~1e-9).
TEST(VmsKernel, NavierStokesTangentDeviationFromTheTrueJacobianIsDocumented) {
  constexpr double kBound = 0.5;  // per-class ||K - J||_F / ||J||_F
  unsigned seed = 300;
  for (const Scales* sc : {&kPhysical, &kBalanced})
    for (int dim : {2, 3}) {
      const Case c = make_case(dim, dim == 2 ? 9 : 27, false, *sc, seed++);
      const auto K = tangent(c);
      const auto J = fd_jacobian(
          c, [&](const std::vector<double>& u) { return residual(c, u, nullptr); }, 2, 1e-5);
      // The FD error itself, from the same stencil on the frozen residual (where K is exact).
      const Stabilization frozen = vms_stabilization(c.prm, c.fields());
      const auto Jf = fd_jacobian(
          c, [&](const std::vector<double>& u) { return residual(c, u, &frozen); }, 2, 1e-5);
      const Comparison dev = compare(c, K, J, 0.0), fd_err = compare(c, K, Jf, 0.0);
      const double worst = *std::max_element(dev.class_fro.begin(), dev.class_fro.end());
      const double noise = *std::max_element(fd_err.class_fro.begin(), fd_err.class_fro.end());
      // The share of v.G v in tau_M^-2 is what the tangent leaves out.
      const PointFields f = c.fields();
      double v_G_v = 0;
      for (int i = 0; i < dim; ++i)
        for (int j = 0; j < dim; ++j) v_G_v += f.v[i] * f.G[i][j] * f.v[j];
      const double share = f.s * v_G_v * frozen.tau_m * frozen.tau_m;
      std::printf(
          "  NS tangent vs true Jacobian, %-28s: per class ||K-J||/||J|| = %.2e %.2e %.2e %.2e "
          "(FD noise %.1e, bound %.1f; v.G v share of tau_M^-2 %.1e)\n",
          label(c).c_str(), dev.class_fro[0], dev.class_fro[1], dev.class_fro[2], dev.class_fro[3], noise,
          kBound, share);
      EXPECT_LT(worst, kBound) << label(c);
      // Only on the balanced scaling is v.G v a sizeable part of tau_M^-2; at physical scales it is ~1e-12 of
      // it (viscous-dominated), so the deviation drowns in the FD noise there.
      if (sc == &kBalanced) {
        EXPECT_GT(worst, 100 * noise) << label(c);
      }
    }
}

TEST(VmsKernel, ImmersedTangentMatchesFiniteDifferences) {
  unsigned seed = 400;
  for (const Config& cf : all_configs()) {
    const Case c = make_case(cf.dim, cf.n, cf.stokes, *cf.sc, seed);
    const ImmersedPoint ip = make_immersed_point(c, seed++);
    auto res = [&](const std::vector<double>& u) {
      std::vector<double> R(c.size(), 0.0);
      immersed_residual(c.prm, c.basis(), c.fields(u), ip, R.data());
      return R;
    };
    std::vector<double> K(c.size() * c.size(), 0.0);
    immersed_tangent(c.prm, c.basis(), c.fields(), c.ts, ip, K.data());
    const Comparison cmp = compare(c, K, fd_jacobian(c, res, 4, 1.0), kFdFloor);
    std::printf("  immersed tangent vs FD, %-28s: worst entry %.2e (tol %.0e)\n", label(c).c_str(), cmp.worst,
                kFdTol);
    EXPECT_LT(cmp.worst, kFdTol) << label(c);

    // Residual against the transcription of Eq. (10) as the header writes it.
    const std::vector<double> R = res(c.U), ref = reference_immersed(c, c.fields(), ip);
    double worst = 0;
    for (int r = 0; r < c.size(); ++r) worst = std::max(worst, std::abs(R[r] - ref[r]) / max_abs(ref));
    EXPECT_LT(worst, kRefTol) << label(c);
  }
}

TEST(VmsKernel, ConsistentSolidStiffnessIsTheDerivativeOfTheStressTerm) {
  // -coupling_solid_tangent consistent: the point's stress moves with the velocity as the solid does over a
  // step, stress(U + dU) = stress + L stress + stress L^T + c : sym(L), L = stiffness_time grad dv (c: a
  // random symmetric Voigt tensor). The tangent must be the residual's derivative with that stress, to the
  // finite differences' accuracy; and it must differ from the isotropic one.
  unsigned seed = 700;
  for (const Config& cf : all_configs()) {
    const Case c = make_case(cf.dim, cf.n, cf.stokes, *cf.sc, seed);
    ImmersedPoint ip = make_immersed_point(c, seed);
    std::mt19937 rng(seed++);
    std::uniform_real_distribution<double> uni(-1, 1);
    ip.stiffness_time = 0.7 * c.prm.dt;
    ip.stiffness_viscosity = 3 * c.prm.nu;  // unused where stiffness_time > 0
    const double modulus = c.prm.nu / ip.stiffness_time;  // the solid's term competes with the viscous one
    double C[6][6];
    for (int r = 0; r < 6; ++r)
      for (int q = 0; q <= r; ++q) C[r][q] = C[q][r] = modulus * (uni(rng) + (r == q ? 3.0 : 0.0));
    for (int r = 0, t = 0; r < 6; ++r)
      for (int q = r; q < 6; ++q, ++t) ip.stiffness[t] = C[r][q];
    const PointFields f0 = c.fields();
    const int dim = c.prm.dim;
    auto res = [&](const std::vector<double>& u) {
      const PointFields f = c.fields(u);
      double L[3][3] = {};
      for (int i = 0; i < dim; ++i)
        for (int j = 0; j < dim; ++j) L[i][j] = ip.stiffness_time * (f.dv[i][j] - f0.dv[i][j]);
      const double D[6] = {L[0][0],           L[1][1],           L[2][2],
                           L[1][2] + L[2][1], L[0][2] + L[2][0], L[0][1] + L[1][0]};
      double S[6] = {};
      for (int r = 0; r < 6; ++r)
        for (int q = 0; q < 6; ++q) S[r] += C[r][q] * D[q];
      const int pair[6][2] = {{0, 0}, {1, 1}, {2, 2}, {1, 2}, {0, 2}, {0, 1}};
      ImmersedPoint q = ip;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          for (int m = 0; m < 3; ++m) q.stress[i][j] += L[i][m] * ip.stress[m][j] + ip.stress[i][m] * L[j][m];
      for (int r = 0; r < 6; ++r) {
        q.stress[pair[r][0]][pair[r][1]] += S[r];
        if (pair[r][0] != pair[r][1]) q.stress[pair[r][1]][pair[r][0]] += S[r];
      }
      std::vector<double> R(c.size(), 0.0);
      immersed_residual(c.prm, c.basis(), f, q, R.data());
      return R;
    };
    std::vector<double> K(c.size() * c.size(), 0.0), Kiso(c.size() * c.size(), 0.0);
    immersed_tangent(c.prm, c.basis(), c.fields(), c.ts, ip, K.data());
    const Comparison cmp = compare(c, K, fd_jacobian(c, res, 4, 1.0), kFdFloor);
    std::printf("  consistent solid stiffness vs FD, %-28s: worst entry %.2e (tol %.0e)\n", label(c).c_str(),
                cmp.worst, kFdTol);
    EXPECT_LT(cmp.worst, kFdTol) << label(c);
    ImmersedPoint iso = ip;
    iso.stiffness_time = 0;
    immersed_tangent(c.prm, c.basis(), c.fields(), c.ts, iso, Kiso.data());
    EXPECT_GT(compare(c, K, Kiso, kFdFloor).worst, 100 * kFdTol) << label(c);
  }
}

TEST(VmsKernel, ImmersedTermsLeaveContinuityRowsAndPressureColumnsUntouched) {
  for (int dim : {2, 3}) {
    const Case c = make_case(dim, dim == 2 ? 9 : 27, false, kPhysical, 500 + dim);
    const ImmersedPoint ip = make_immersed_point(c, 9);
    const int m = c.size(), nc = c.nc();
    // Sentinel values everywhere: the continuity entries must come back bit for bit.
    std::vector<double> R(m), K(m * m);
    for (int r = 0; r < m; ++r) R[r] = 1.0 + r;
    for (int r = 0; r < m * m; ++r) K[r] = 0.5 + r;
    const std::vector<double> R0 = R, K0 = K;
    immersed_residual(c.prm, c.basis(), c.fields(), ip, R.data());
    immersed_tangent(c.prm, c.basis(), c.fields(), c.ts, ip, K.data());
    int momentum_changed = 0;
    for (int r = 0; r < m; ++r) {
      if (r % nc == dim)
        EXPECT_EQ(R[r], R0[r]) << "continuity row " << r;
      else
        momentum_changed += R[r] != R0[r];
      for (int k = 0; k < m; ++k)
        if (r % nc == dim || k % nc == dim) {
          EXPECT_EQ(K[r * m + k], K0[r * m + k]) << r << "," << k;
        }
    }
    EXPECT_EQ(momentum_changed, c.n * dim);
  }
}

// Largest |got - expected| / scale over a test, checked once and printed so the margin to the tolerance
// shows.
struct WorstError {
  const char* what;
  double tol;
  double value = 0;
  void add(double got, double expected, double scale) {
    value = std::max(value, scale > 0 ? std::abs(got - expected) / scale : std::abs(got - expected) * 1e300);
  }
  void check() const {
    std::printf("  %-58s: worst %.2e (tol %.0e)\n", what, value, tol);
    EXPECT_LE(value, tol) << what;
  }
};

// (a) Only p, and vdot = g so that r_M = 0 exactly: R^M_{A,i} = -weight dN_A,i p, R^C_A = 0 (bit for bit).
TEST(VmsKernel, PressureOnlyGivesTheGradientOfTheTestFunction) {
  WorstError err{"pressure only: R^M = -w dN_A,i p, relative", 1e-15};
  for (bool stokes : {false, true})
    for (int dim : {2, 3}) {
      Case c = make_case(dim, dim == 2 ? 9 : 27, stokes, kPhysical, 600 + dim);
      PointFields f{};
      f.G = c.offset.G;
      f.s = c.offset.s;
      f.p = 37.5;
      for (int i = 0; i < 3; ++i) f.vdot[i] = c.prm.g[i];
      std::vector<double> R(c.size(), 0.0);
      vms_residual(c.prm, c.basis(), f, c.weight, R.data());
      const int nc = c.nc();
      for (int A = 0; A < c.n; ++A) {
        for (int i = 0; i < dim; ++i) {
          const double expected = -c.dN[A * 3 + i] * f.p * c.weight;
          err.add(R[A * nc + i], expected, std::abs(expected));
        }
        EXPECT_EQ(R[A * nc + dim], 0.0) << "A=" << A;  // v' = 0 and div v = 0 exactly
      }
    }
  err.check();
}

// (b) Only grad p (v = vdot = g = p = 0): v' = -tau_M dp, so R^C_A = weight tau_M dN_A . dp; the momentum
// rows hold only the Reynolds stress -(v'.grad N_A) v'_i = -tau_M^2 (dp . dN_A) dp_i (nothing in Stokes
// mode).
TEST(VmsKernel, PressureGradientOnlyGivesThePspgTerm) {
  WorstError err{"grad p only: PSPG and Reynolds stress, rel. to terms", 1e-14};
  const Stabilization frozen{0.3, 7.0};
  for (bool stokes : {false, true})
    for (int dim : {2, 3}) {
      Case c = make_case(dim, dim == 2 ? 9 : 27, stokes, kBalanced, 610 + dim);
      c.prm.g = {};
      PointFields f{};
      f.G = c.offset.G;
      f.s = c.offset.s;
      f.dp = {1.5, -0.75, 2.25};
      std::vector<double> R(c.size(), 0.0);
      vms_residual(c.prm, c.basis(), f, c.weight, R.data(), &frozen);
      const int nc = c.nc();
      for (int A = 0; A < c.n; ++A) {
        // Relative to the size of the terms of dN_A . dp, which may nearly cancel.
        double dN_dp = 0, dN_dp_terms = 0;
        for (int j = 0; j < dim; ++j) {
          dN_dp += c.dN[A * 3 + j] * f.dp[j];
          dN_dp_terms += std::abs(c.dN[A * 3 + j] * f.dp[j]);
        }
        const double pspg = c.weight * frozen.tau_m * dN_dp;
        err.add(R[A * nc + dim], pspg, c.weight * frozen.tau_m * dN_dp_terms);
        for (int i = 0; i < dim; ++i) {
          const double reynolds = -c.weight * frozen.tau_m * frozen.tau_m * dN_dp * f.dp[i];
          if (stokes)
            EXPECT_EQ(R[A * nc + i], 0.0) << "A=" << A << " i=" << i;
          else
            err.add(R[A * nc + i], reynolds,
                    c.weight * frozen.tau_m * frozen.tau_m * dN_dp_terms * std::abs(f.dp[i]));
        }
      }
    }
  err.check();
}

// (c) tau_M and tau_C against Eqs. (16)-(17) with G = a I.
TEST(VmsKernel, StabilizationMatchesClosedForm) {
  WorstError err{"tau_M, tau_C vs closed form, relative", 1e-14};
  // Hand-made numbers: G = I (2D), v = (1, 1), dt = 1, nu = 1/6, C_I = 36, s = 2:
  // tau_M = (2 (4 + 2 + 36 / 36 * 2))^-1/2 = 1/4, tau_C = 1 / (tau_M tr G) = 2; Stokes: tau_M = 12^-1/2.
  VmsParameters prm;
  prm.dim = 2;
  prm.dt = 1;
  prm.nu = 1.0 / 6.0;
  PointFields f;
  f.G = {{{1, 0, 1e6}, {0, 1, -1e6}, {1e6, -1e6, 1e9}}};  // third row and column must be ignored in 2D
  f.v = {1, 1, 1e3};
  f.s = 2;
  Stabilization t = vms_stabilization(prm, f);
  err.add(t.tau_m, 0.25, 0.25);
  err.add(t.tau_c, 2.0, 2.0);
  prm.stokes = true;
  t = vms_stabilization(prm, f);
  err.add(t.tau_m, 1 / std::sqrt(12.0), 1 / std::sqrt(12.0));
  err.add(t.tau_c, std::sqrt(12.0) / 2, std::sqrt(12.0) / 2);

  // Physical scales, G = a I: G:G = d a^2, v.G v = a |v|^2, tr G = d a.
  for (int dim : {2, 3})
    for (bool stokes : {false, true}) {
      prm = VmsParameters{};
      prm.dim = dim;
      prm.dt = 5e-4;
      prm.nu = 0.0117;
      prm.stokes = stokes;
      const double a = 4e10;
      f = PointFields{};
      for (int i = 0; i < dim; ++i) f.G[i][i] = a;
      f.v = {0.03, -0.05, dim == 3 ? 0.02 : 0.0};
      f.s = 250;
      const double v2 = f.v[0] * f.v[0] + f.v[1] * f.v[1] + f.v[2] * f.v[2];
      const double tau_m = 1 / std::sqrt(f.s * (4 / (prm.dt * prm.dt) + (stokes ? 0 : a * v2) +
                                                36 * prm.nu * prm.nu * dim * a * a));
      const double tau_c = 1 / (tau_m * dim * a);
      t = vms_stabilization(prm, f);
      err.add(t.tau_m, tau_m, tau_m);
      err.add(t.tau_c, tau_c, tau_c);
    }
  err.check();
}

// (d) Both kernels add weight times a weight-independent quantity.
TEST(VmsKernel, ResidualAndTangentAreLinearInTheWeightAndAccumulate) {
  WorstError scaled{"R, K at weight 3.7 vs 3.7 x weight 1, rel. to max", 1e-14};
  WorstError twice{"R, K added twice vs 2 x once, rel. to max", 1e-15};
  for (int dim : {2, 3}) {
    Case c = make_case(dim, dim == 2 ? 9 : 27, false, kBalanced, 700 + dim);
    const int m = c.size();
    c.weight = 1.0;
    const std::vector<double> R1 = residual(c, c.U, nullptr), K1 = tangent(c);
    c.weight = 3.7;
    const std::vector<double> R2 = residual(c, c.U, nullptr), K2 = tangent(c);
    for (int r = 0; r < m; ++r) scaled.add(R2[r], 3.7 * R1[r], max_abs(R2));
    for (int r = 0; r < m * m; ++r) scaled.add(K2[r], 3.7 * K1[r], max_abs(K2));
    // Adding into a filled buffer: twice the same contribution is twice it (to round-off, since one entry
    // receives several additions).
    std::vector<double> R(m, 0.0), K(m * m, 0.0);
    for (int rep = 0; rep < 2; ++rep) {
      vms_residual(c.prm, c.basis(), c.fields(), c.weight, R.data());
      vms_tangent(c.prm, c.basis(), c.fields(), c.ts, c.weight, K.data());
    }
    for (int r = 0; r < m; ++r) twice.add(R[r], 2 * R2[r], max_abs(R));
    for (int r = 0; r < m * m; ++r) twice.add(K[r], 2 * K2[r], max_abs(K));
  }
  scaled.check();
  twice.check();
}

// With a partition of unity (sum N = 1, sum dN = 0, sum lapN = 0) the PSPG terms cancel in the sum of the
// continuity rows, which is weight div v; the momentum rows sum to weight (vdot + ((v + v').grad) v - g).
TEST(VmsKernel, PartitionOfUnitySumsGiveTheStrongForm) {
  WorstError cont{"sum_A R^C_A vs w div v, relative", 1e-12};
  WorstError mom{"sum_A R^M_A,i vs strong form, rel. to sum_A |R^M_A,i|", 1e-12};
  for (const Scales* sc : {&kPhysical, &kBalanced})
    for (bool stokes : {false, true})
      for (int dim : {2, 3}) {
        Case c = make_case(dim, dim == 2 ? 9 : 27, stokes, *sc, 800 + dim);
        double sN = 0, slap = 0;
        std::array<double, 3> sdN{};
        for (int A = 0; A < c.n; ++A) {
          sN += c.N[A];
          slap += c.lapN[A];
          for (int j = 0; j < 3; ++j) sdN[j] += c.dN[A * 3 + j];
        }
        for (int A = 0; A < c.n; ++A) {
          c.N[A] /= sN;
          c.lapN[A] -= slap / c.n;
          for (int j = 0; j < 3; ++j) c.dN[A * 3 + j] -= sdN[j] / c.n;
        }
        const PointFields f = c.fields();
        const Stabilization tau = vms_stabilization(c.prm, f);
        const std::vector<double> R = residual(c, c.U, nullptr);
        const int nc = c.nc();
        double sum_c = 0;
        std::array<double, 3> sum_m{};
        for (int A = 0; A < c.n; ++A) {
          sum_c += R[A * nc + dim];
          for (int i = 0; i < dim; ++i) sum_m[i] += R[A * nc + i];
        }
        double div = 0;
        for (int i = 0; i < dim; ++i) div += f.dv[i][i];
        cont.add(sum_c, c.weight * div, std::abs(c.weight * div));

        std::array<double, 3> r_m{}, a{};
        for (int i = 0; i < dim; ++i) {
          r_m[i] = f.vdot[i] + f.dp[i] - c.prm.nu * f.lap_v[i] - c.prm.g[i];
          if (!stokes)
            for (int j = 0; j < dim; ++j) r_m[i] += f.v[j] * f.dv[i][j];
          a[i] = f.v[i] - tau.tau_m * r_m[i];
        }
        // The viscous, pressure and SUPG parts cancel only in the sum: round-off is relative to the terms.
        for (int i = 0; i < dim; ++i) {
          double expected = f.vdot[i] - c.prm.g[i], scale = 0;
          if (!stokes)
            for (int j = 0; j < dim; ++j) expected += a[j] * f.dv[i][j];
          for (int A = 0; A < c.n; ++A) scale += std::abs(R[A * nc + i]);
          mom.add(sum_m[i], c.weight * expected, scale);
        }
      }
  cont.check();
  mom.check();
}

// vms_tangent_element against vms_tangent summed over the points. Each point gets its own make_case data
// (basis values, fields, weight) under the parameters of the first, so the points differ as they do in an
// element. Compared block by block ((c, e): the n x n entries of row component c and column component e),
// relative to the block's largest entry: the blocks' scales differ by up to ~1e8 at physical scales.
