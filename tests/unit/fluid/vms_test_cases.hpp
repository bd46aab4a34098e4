#pragma once
// The random, application-scaled point data that the VMS kernel tests share (test_vms_kernel.cpp: pointwise
// kernels; test_vms_element_tangent.cpp: the element tangent).
#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "fluid/vms_kernel.hpp"

namespace vms_test {

using namespace cellfsi::fluid;

struct Scales {
  const char* name;
  double length;    // element size: dN ~ 1 / length, lapN ~ 1 / length^2, G ~ 1 / length^2
  double velocity;  // magnitude of the velocity unknowns and offsets
  double pressure;  // magnitude of the kinematic-pressure unknowns (~ nu velocity / length)
  double nu, dt, s_min, s_max, g;
};
constexpr Scales kPhysical{"physical", 1e-5, 0.1, 100.0, 0.0117, 5e-4, 1.0, 1e3, 1e3};
constexpr Scales kBalanced{"balanced", 1.0, 1.0, 1.0, 0.1, 1.0, 1.0, 2.0, 1.0};

// Generalized-alpha with rho_inf = 0.5 (docs/design.md §3): d v_{n+alpha_f} / d v_{n+1} = alpha_f,
// d vdot_{n+alpha_m} / d v_{n+1} = alpha_m / (gamma dt).
inline TangentScales generalized_alpha_scales(double dt) {
  const double rho_inf = 0.5;
  const double alpha_m = (3 - rho_inf) / (2 * (1 + rho_inf)), alpha_f = 1 / (1 + rho_inf);
  const double gamma = 0.5 + alpha_m - alpha_f;
  return {alpha_f, alpha_m / (gamma * dt), 1.0};
}

// One quadrature point: basis values, nodal unknowns U at t_{n+1}, and the parts of the fields that do not
// depend on U (the offsets stand for the contributions of t_n to the alpha-level fields).
struct Case {
  VmsParameters prm;
  TangentScales ts;
  Scales sc;
  int n = 0;
  std::vector<double> N, dN, lapN, U;
  PointFields offset;  // v, dv, lap_v, vdot, p, dp offsets; G and s
  double weight = 0;

  int nc() const { return prm.dim + 1; }
  int size() const { return n * nc(); }
  PointBasis basis() const { return {n, N.data(), dN.data(), lapN.data()}; }

  // The fields as the assembly evaluates them: v = velocity sum_B N_B V_B + c0, and so on.
  PointFields fields(const std::vector<double>& u) const {
    PointFields f = offset;
    const int d = prm.dim;
    for (int B = 0; B < n; ++B) {
      for (int i = 0; i < d; ++i) {
        const double V = u[B * nc() + i];
        f.v[i] += ts.velocity * N[B] * V;
        f.lap_v[i] += ts.velocity * lapN[B] * V;
        f.vdot[i] += ts.velocity_rate * N[B] * V;
        for (int j = 0; j < 3; ++j) f.dv[i][j] += ts.velocity * dN[B * 3 + j] * V;
      }
      const double P = u[B * nc() + d];
      f.p += ts.pressure * N[B] * P;
      for (int j = 0; j < 3; ++j) f.dp[j] += ts.pressure * dN[B * 3 + j] * P;
    }
    return f;
  }
  PointFields fields() const { return fields(U); }

  // Typical size of unknown k: the finite-difference steps are taken relative to it.
  double unknown_scale(int k) const { return k % nc() == prm.dim ? sc.pressure : sc.velocity; }
};

// In 2D the third components of every input (dN[., 2], v[2], G[2][.], ...) are filled with garbage on
// purpose: the kernels must use only the leading dim x dim block.
inline Case make_case(int dim, int n, bool stokes, const Scales& sc, unsigned seed) {
  std::mt19937 rng(seed);
  auto uni = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  Case c;
  c.sc = sc;
  c.n = n;
  c.prm.dim = dim;
  c.prm.nu = sc.nu * uni(0.9, 1.1);
  c.prm.dt = sc.dt * uni(0.9, 1.1);
  c.prm.stokes = stokes;
  for (double& gi : c.prm.g) gi = sc.g * uni(-1, 1);
  c.ts = generalized_alpha_scales(c.prm.dt);
  const double L = sc.length;
  for (int A = 0; A < n; ++A) {
    c.N.push_back(uni(0, 1));
    for (int j = 0; j < 3; ++j) c.dN.push_back(uni(-1, 1) / L);
    c.lapN.push_back(uni(-1, 1) / (L * L));
    for (int i = 0; i < dim; ++i) c.U.push_back(sc.velocity * uni(-1, 1));
    c.U.push_back(sc.pressure * uni(-1, 1));
  }
  PointFields& f = c.offset;
  const double V = sc.velocity;
  for (int i = 0; i < 3; ++i) {
    f.v[i] = 0.5 * V * uni(-1, 1);
    f.lap_v[i] = 0.5 * V / (L * L) * uni(-1, 1);
    f.vdot[i] = 0.5 * c.ts.velocity_rate * V * uni(-1, 1);
    f.dp[i] = 0.5 * sc.pressure / L * uni(-1, 1);
    for (int j = 0; j < 3; ++j) f.dv[i][j] = 0.5 * V / L * uni(-1, 1);
  }
  f.p = 0.5 * sc.pressure * uni(-1, 1);
  // G = Q^T Q with Q = dxi/dx ~ (2 / element size) (I + perturbation): symmetric positive definite.
  std::array<std::array<double, 3>, 3> Q{};
  for (int i = 0; i < dim; ++i)
    for (int j = 0; j < dim; ++j) Q[i][j] = 2 / L * ((i == j ? 1.0 : 0.0) + 0.3 * uni(-1, 1));
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      for (int k = 0; k < dim; ++k) f.G[i][j] += Q[k][i] * Q[k][j];
      if (i >= dim || j >= dim) f.G[i][j] = 1e3 * uni(-1, 1) / (L * L);
    }
  f.s = std::exp(uni(std::log(sc.s_min), std::log(sc.s_max)));
  c.weight = std::pow(L, dim) * uni(0.5, 2);
  return c;
}

inline std::vector<double> residual(const Case& c, const std::vector<double>& u,
                                    const Stabilization* frozen) {
  std::vector<double> R(c.size(), 0.0);
  vms_residual(c.prm, c.basis(), c.fields(u), c.weight, R.data(), frozen);
  return R;
}

inline std::vector<double> tangent(const Case& c) {
  std::vector<double> K(c.size() * c.size(), 0.0);
  vms_tangent(c.prm, c.basis(), c.fields(), c.ts, c.weight, K.data());
  return K;
}

constexpr double kRefTol = 1e-12;  // kernel vs literal transcription of the formulas

}  // namespace vms_test
