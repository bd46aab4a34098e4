#pragma once
// Generalized-alpha for first-order systems (Jansen, Whiting & Hulbert 2000; docs/design.md §3), written
// once: the parameters from the spectral radius at infinity, the rate update, and the intermediate levels at
// which the fluid's residual is evaluated (velocity at t_{n+alpha_f}, its rate at t_{n+alpha_m}).
// Used by the fluid (fluid/fluid_solver.cpp) and the solids (solid::TimeParameters).
#include <stdexcept>

namespace cellfsi {

struct GeneralizedAlpha {
  double alpha_m = 0, alpha_f = 0, gamma = 0, dt = 0;

  /// Second-order accurate and unconditionally stable for rho_inf in [0, 1]. Throws std::invalid_argument
  /// for rho_inf outside [0, 1] or dt <= 0.
  static GeneralizedAlpha from_rho_inf(double rho_inf, double dt) {
    if (!(rho_inf >= 0 && rho_inf <= 1)) throw std::invalid_argument("rho_inf must be in [0, 1]");
    if (!(dt > 0)) throw std::invalid_argument("dt must be > 0");
    GeneralizedAlpha a;
    a.alpha_m = (3.0 - rho_inf) / (2.0 * (1.0 + rho_inf));
    a.alpha_f = 1.0 / (1.0 + rho_inf);
    a.gamma = 0.5 + a.alpha_m - a.alpha_f;
    a.dt = dt;
    return a;
  }

  /// The rate at t_{n+1} of one unknown from its value at t_{n+1} (x1) and its value and rate at t_n:
  /// xdot_{n+1} = (x_{n+1} - x_n) / (gamma dt) - (1 - gamma) / gamma xdot_n.
  double rate(double x1, double x0, double xdot0) const {
    return (x1 - x0) / (gamma * dt) - (1.0 - gamma) / gamma * xdot0;
  }
  /// The value at t_{n+alpha_f}.
  double value_alpha_f(double x1, double x0) const { return x0 + alpha_f * (x1 - x0); }
  /// The rate at t_{n+alpha_m}.
  double rate_alpha_m(double x1, double x0, double xdot0) const {
    return xdot0 + alpha_m * (rate(x1, x0, xdot0) - xdot0);
  }
  /// d(rate at t_{n+alpha_m}) / d x_{n+1}.
  double rate_alpha_m_scale() const { return alpha_m / (gamma * dt); }
};

}  // namespace cellfsi
