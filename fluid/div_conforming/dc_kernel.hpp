#pragma once
// Pointwise kernels of the Galerkin Navier-Stokes formulation on the divergence-conforming space: plain
// functions of plain data at one point (no mesh, no PETSc), as fluid/vms_kernel.hpp for the VMS one.
//
// Kinematic pressure p (pressure / rho), kinematic viscosity nu = mu / rho, body force per unit mass g, as
// the VMS solver. The weak form, for test functions w (velocity) and q (pressure), is written as
//   R_w = int  w . r0 + grad w : r1     (r1[i][j] multiplies d w_i / d x_j)
//   R_q = int  q rq
// Interior points (dc_interior_residual, dc_interior_tangent):
//   r0 = a + c (v . grad) v - g,   r1 = 2 nu eps(v) - p I,   rq = div v
// with a the acceleration (vdot at t_{n+alpha_m}; v itself for an L2 projection, nu = 0 and c = 0 there) and
// c = 1 for Navier-Stokes, 0 for Stokes. No stabilisation: the pair is inf-sup stable and, div v_h being 0
// pointwise and v.n = 0 on walls, the convective form (w, (v.grad)v) is energy-conserving (skew-symmetric).
// Wall points (dc_nitsche_residual, dc_nitsche_tangent; symmetric Nitsche), outward normal n, wall velocity
// v_w, penalty beta:
//   r0 = -2 nu eps(v) n + beta (v - v_w),   r1[i][j] = -nu ((v - v_w)_i n_j + (v - v_w)_j n_i),   rq = 0
// i.e. - int w . (2 nu eps(v) n) - int (2 nu eps(w) n) . (v - v_w) + int beta w . (v - v_w). The pressure's
// wall terms -int p w.n and int q n.(v - v_w) vanish: the normal velocity is imposed strongly (w.n = 0 and
// (v - v_w).n = 0 on walls).
//
// Tangents are the derivatives of r0, r1, rq with respect to the fields v, grad v, a and p at the point; the
// caller multiplies by d(field)/d(unknown) (the generalized-alpha factors).
#include <array>

#include "fluid/immersed_point.hpp"

namespace cellfsi::fluid::dc {

using PointVec = std::array<double, 3>;
using PointMat = std::array<std::array<double, 3>, 3>;

/// Fields at a point.
struct PointState {
  PointVec v{};   // velocity
  PointMat dv{};  // dv[i][j] = d v_i / d x_j
  PointVec a{};   // acceleration
  double p = 0;   // kinematic pressure
};

struct InteriorParameters {
  int dim = 2;
  double nu = 0;          // kinematic viscosity [cm^2/s]
  double convection = 1;  // 1: Navier-Stokes, 0: Stokes
  PointVec g{};           // body force per unit mass at the point [cm/s^2]
};

struct NitscheParameters {
  int dim = 2;
  double nu = 0;
  double beta = 0;    // penalty [cm/s]: C_pen nu (k + 1)^2 / h
  PointVec n{};       // outward unit normal
  PointVec v_wall{};  // wall velocity at the point
};

struct PointResidual {
  PointVec r0{};
  PointMat r1{};
  double rq = 0;
};

/// Derivatives of PointResidual with respect to the fields.
struct PointTangent {
  PointMat dr0_dv{};                                 // [i][k]
  std::array<PointMat, 3> dr0_ddv{};                 // [i][k][l] = d r0_i / d (d_l v_k)
  PointMat dr0_da{};                                 // [i][k]
  std::array<PointMat, 3> dr1_dv{};                  // [i][j][k]
  std::array<std::array<PointMat, 3>, 3> dr1_ddv{};  // [i][j][k][l]
  PointMat dr1_dp{};                                 // [i][j]
  PointMat drq_ddv{};                                // [k][l]
};

/// An immersed solid's quadrature point (paper Eq. (10), the same terms as fluid/vms_kernel.hpp's
/// immersed_residual, written in this file's r0 / r1 form and per unit weight; the caller multiplies by the
/// point's reference weight):
///   r0 = -beta (a + c (v.grad)v - g) - force,   r1 = stress - nu (grad v + grad v^T),   rq = 0
/// (nu the local fluid viscosity the solid replaces; c = prm.convection). The tangent holds the stress fixed
/// but adds the solid's stiffness seen over one step, as the VMS one: the isotropic nu_s of
/// ImmersedPoint::stiffness_viscosity, or with stiffness_time > 0 the consistent
///   d r1_ij / d(d_l v_k) += stiffness_time (stress_il delta_jk + delta_ik stress_lj + c_ijkl).
struct ImmersedParameters {
  int dim = 2;
  double nu = 0;          // the fluid's kinematic viscosity at the point
  double convection = 1;  // 1: Navier-Stokes, 0: Stokes
  PointVec g{};           // body force per unit mass
};
PointResidual dc_immersed_residual(const PointState& s, const ImmersedParameters& prm, const ImmersedPoint& ip);
PointTangent dc_immersed_tangent(const PointState& s, const ImmersedParameters& prm, const ImmersedPoint& ip);

PointResidual dc_interior_residual(const PointState& s, const InteriorParameters& prm);
PointTangent dc_interior_tangent(const PointState& s, const InteriorParameters& prm);
PointResidual dc_nitsche_residual(const PointState& s, const NitscheParameters& prm);
PointTangent dc_nitsche_tangent(const NitscheParameters& prm);  // linear: independent of the state

}  // namespace cellfsi::fluid::dc
