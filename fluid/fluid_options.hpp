#pragma once
// The fluid's physical and numerical settings (prefix fluid_), shared by every discretisation behind
// fluid::ImmersedFluid. Read and checked in fluid_options.cpp (the option table -help lists).
#include <array>
#include <string>

#include "geometry/patch.hpp"

namespace cellfsi::fluid {

using geometry::Vec3;

/// The fluid's own linear solver (the paper's: GMRES, restricted additive Schwarz, LU subdomain solves, here by
/// MUMPS), stated once: fluid_solver.cpp sets them as defaults under -fluid_, and a coupled run's PETSc PC starts
/// from them under -coupling_ (coupling/solver_policy.hpp).
struct KrylovDefaults {
  static constexpr double rtol = 1e-5;
  static constexpr int asm_overlap = 4;  // (PETSc's: 1) measured: fluid_solver.cpp
  static constexpr const char* sub_pc_type = "lu";
  static constexpr const char* sub_solver = "mumps";
};

/// Physical and numerical settings; the defaults are the paper's plasma (CGS).
struct FluidOptions {
  double density = 1.025;    // rho_1 [g/cm^3]
  double viscosity = 0.012;  // mu [g/(cm s)]
  Vec3 body_force =
      Vec3::Zero();      // f [dyn/cm^3], a force per unit volume (g = f / rho_1), docs/design.md section 3
  bool stokes = false;   // drop convection
  double rho_inf = 0.5;  // generalized-alpha spectral radius at infinity, in [0, 1]
  double dt = 5e-4;      // time step [s]
  double c_i = 36.0;     // C_I of tau_M (the VMS discretisation's; others ignore it)
  /// The discretisation (create_fluid): "equal_order" (the paper's VMS on the patch's own splines) or
  /// "div_conforming" (fluid/div_conforming/: Evans-Hughes divergence-conforming B-splines, Galerkin, no s_I).
  std::string space = "equal_order";
  int dc_degree = 2;       // div_conforming: the pressure degree k' (velocity component i: k' + 1 along x_i)
  double dc_penalty = 4.0;  // div_conforming: C_pen of the Nitsche penalty C_pen nu (k' + 1)^2 / h
  std::string jacobian_type = "baij";  // PETSc matrix type of the Jacobian: baij (node blocks) or aij
  bool pressure_null_space = true;  // the constant pressure as MatNullSpace (false: one control value pinned)
  /// Velocity of the wall at side s (0: xi = a, 1: xi = b) of non-periodic direction d. (Eigen vectors are
  /// not zeroed by value-initialisation, hence the explicit zeros.)
  std::array<std::array<Vec3, 2>, 3> wall_velocity{
      {{Vec3::Zero(), Vec3::Zero()}, {Vec3::Zero(), Vec3::Zero()}, {Vec3::Zero(), Vec3::Zero()}}};
  /// Reads -fluid_density, -fluid_viscosity, -fluid_body_force fx,fy[,fz], -fluid_stokes, -fluid_rho_inf,
  /// -fluid_c_i, -fluid_wall_velocity_{x,y,z}{0,1} vx,vy[,vz]. Throws std::invalid_argument on invalid
  /// values.
  void set_from_options(int dim);
  void validate() const;
};

}  // namespace cellfsi::fluid
