#include "fluid/div_conforming/dc_kernel.hpp"

namespace cellfsi::fluid::dc {

PointResidual dc_interior_residual(const PointState& s, const InteriorParameters& prm) {
  const int D = prm.dim;
  PointResidual r;
  for (int i = 0; i < D; ++i) {
    double conv = 0;
    for (int l = 0; l < D; ++l) conv += s.v[l] * s.dv[i][l];
    r.r0[i] = s.a[i] + prm.convection * conv - prm.g[i];
    for (int j = 0; j < D; ++j) r.r1[i][j] = prm.nu * (s.dv[i][j] + s.dv[j][i]) - (i == j ? s.p : 0.0);
    r.rq += s.dv[i][i];
  }
  return r;
}

PointTangent dc_interior_tangent(const PointState& s, const InteriorParameters& prm) {
  const int D = prm.dim;
  PointTangent t;
  for (int i = 0; i < D; ++i) {
    t.dr0_da[i][i] = 1.0;
    for (int k = 0; k < D; ++k) {
      t.dr0_dv[i][k] = prm.convection * s.dv[i][k];  // d/dv_k of v_l d_l v_i
      t.dr0_ddv[i][i][k] = prm.convection * s.v[k];  // d/d(d_k v_i)
    }
    for (int j = 0; j < D; ++j) {
      t.dr1_ddv[i][j][i][j] += prm.nu;
      t.dr1_ddv[i][j][j][i] += prm.nu;
    }
    t.dr1_dp[i][i] = -1.0;
    t.drq_ddv[i][i] = 1.0;
  }
  return t;
}

PointResidual dc_nitsche_residual(const PointState& s, const NitscheParameters& prm) {
  const int D = prm.dim;
  PointResidual r;
  PointVec jump{};
  for (int i = 0; i < D; ++i) jump[i] = s.v[i] - prm.v_wall[i];
  for (int i = 0; i < D; ++i) {
    double traction = 0;  // (2 eps(v) n)_i
    for (int l = 0; l < D; ++l) traction += (s.dv[i][l] + s.dv[l][i]) * prm.n[l];
    r.r0[i] = -prm.nu * traction + prm.beta * jump[i];
    for (int j = 0; j < D; ++j) r.r1[i][j] = -prm.nu * (jump[i] * prm.n[j] + jump[j] * prm.n[i]);
  }
  return r;
}

PointTangent dc_nitsche_tangent(const NitscheParameters& prm) {
  const int D = prm.dim;
  PointTangent t;
  for (int i = 0; i < D; ++i) {
    t.dr0_dv[i][i] = prm.beta;
    for (int l = 0; l < D; ++l) {
      t.dr0_ddv[i][i][l] -= prm.nu * prm.n[l];  // d_l v_i n_l
      t.dr0_ddv[i][l][i] -= prm.nu * prm.n[l];  // d_i v_l n_l
    }
    for (int j = 0; j < D; ++j) {
      t.dr1_dv[i][j][i] -= prm.nu * prm.n[j];
      t.dr1_dv[i][j][j] -= prm.nu * prm.n[i];
    }
  }
  return t;
}

PointResidual dc_immersed_residual(const PointState& s, const ImmersedParameters& prm, const ImmersedPoint& ip) {
  const int D = prm.dim;
  PointResidual r;
  for (int i = 0; i < D; ++i) {
    double conv = 0;
    for (int l = 0; l < D; ++l) conv += s.v[l] * s.dv[i][l];
    r.r0[i] = -ip.beta * (s.a[i] + prm.convection * conv - prm.g[i]) - ip.force[i];
    for (int j = 0; j < D; ++j) r.r1[i][j] = ip.stress[i][j] - prm.nu * (s.dv[i][j] + s.dv[j][i]);
  }
  return r;
}

PointTangent dc_immersed_tangent(const PointState& s, const ImmersedParameters& prm, const ImmersedPoint& ip) {
  // Voigt index of (i, j) in ImmersedPoint::stiffness' order (11, 22, 33, 23, 13, 12).
  static constexpr int voigt[3][3] = {{0, 5, 4}, {5, 1, 3}, {4, 3, 2}};
  const int D = prm.dim;
  const bool consistent = ip.stiffness_time > 0;
  const double nu = prm.nu - (consistent ? 0.0 : ip.stiffness_viscosity);
  double c[6][6] = {};
  if (consistent)
    for (int r = 0, t = 0; r < 6; ++r)
      for (int q = r; q < 6; ++q, ++t) c[r][q] = c[q][r] = ip.stiffness[t];
  PointTangent t;
  for (int i = 0; i < D; ++i) {
    t.dr0_da[i][i] = -ip.beta;
    for (int k = 0; k < D; ++k) {
      t.dr0_dv[i][k] = -ip.beta * prm.convection * s.dv[i][k];
      t.dr0_ddv[i][i][k] += -ip.beta * prm.convection * s.v[k];
    }
    for (int j = 0; j < D; ++j) {
      t.dr1_ddv[i][j][i][j] -= nu;
      t.dr1_ddv[i][j][j][i] -= nu;
      if (!consistent) continue;
      for (int k = 0; k < D; ++k)
        for (int l = 0; l < D; ++l) {
          double x = c[voigt[i][j]][voigt[k][l]];
          if (j == k) x += ip.stress[i][l];
          if (i == k) x += ip.stress[l][j];
          t.dr1_ddv[i][j][k][l] += ip.stiffness_time * x;
        }
    }
  }
  return t;
}

}  // namespace cellfsi::fluid::dc
