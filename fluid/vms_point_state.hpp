#pragma once
// What the pointwise VMS kernels (vms_kernel.cpp) and the element tangent (vms_element_tangent.cpp) share:
// the quantities of one point that every basis function uses. Internal to fluid/.
#include <array>

#include "fluid/vms_kernel.hpp"

namespace cellfsi::fluid::detail {

using Vec3 = std::array<double, 3>;
using Mat3 = std::array<Vec3, 3>;

// Quantities of one point that every basis function shares.
struct PointState {
  double tau_m = 0, tau_c = 0;
  Vec3 v_fine{};   // v' = -tau_M r_M
  Vec3 a{};        // v + v': the advecting velocity of the SUPG and Reynolds-stress terms
  double r_c = 0;  // div v
};

inline PointState point_state(const VmsParameters& prm, const PointFields& f, const Stabilization& tau) {
  const int d = prm.dim;
  PointState st;
  st.tau_m = tau.tau_m;
  st.tau_c = tau.tau_c;
  const bool dnu = f.has_dnu();
  for (int i = 0; i < d; ++i) {
    double r_m = f.vdot[i] + f.dp[i] - prm.nu * f.lap_v[i] - prm.g[i];
    if (!prm.stokes)
      for (int j = 0; j < d; ++j) r_m += f.v[j] * f.dv[i][j];
    if (dnu)  // a viscosity field: -grad nu . (grad v + grad v^T) of -div(2 nu eps(v)) (vms_kernel.hpp)
      for (int j = 0; j < d; ++j) r_m -= f.dnu[j] * (f.dv[i][j] + f.dv[j][i]);
    st.v_fine[i] = -tau.tau_m * r_m;
    st.a[i] = f.v[i] + st.v_fine[i];
    st.r_c += f.dv[i][i];
  }
  return st;
}

}  // namespace cellfsi::fluid::detail
