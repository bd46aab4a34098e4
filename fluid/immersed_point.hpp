#pragma once
// One quadrature point of an immersed solid (paper Eq. (10)) as the coupling layer hands it to any fluid
// discretisation (fluid/immersed_fluid.hpp): plain data, no mesh, no PETSc.
#include <array>

namespace cellfsi::fluid {

/// One quadrature point of an immersed solid (paper Eq. (10)), in the data the coupling layer provides.
struct ImmersedPoint {
  double weight = 0;                              // quadrature weight in the reference configuration
  std::array<std::array<double, 3>, 3> stress{};  // (1/rho_1) F S F^T, symmetric
  double beta = 0;                                // density factor 1 - rho_2 / rho_1
  /// Tangent only: the solid's stiffness seen by the fluid velocity over one step, as an equivalent kinematic
  /// viscosity nu_s (the stress increment from the displacement the kinematic equation gives for a velocity
  /// increment: for shear modulus G, nu_s = G gamma dt alpha_f / (alpha_m rho_1)). Without it the
  /// block-iterative loop diverges for any realistic stiffness; the residual, and so the solution, does not
  /// depend on it.
  double stiffness_viscosity = 0;
  /// Tangent only, in place of stiffness_viscosity where stiffness_time > 0: the solid's consistent stiffness
  /// (-coupling_solid_tangent consistent). A velocity increment dv moves the solid by stiffness_time dv
  /// (gamma dt alpha_f / alpha_m), which changes the stress term d_j N_A stress_ij by L stress + stress L^T +
  /// c : sym(L), L = stiffness_time grad dv (the test function held). `stiffness` is that c / rho_1 in Voigt
  /// form (solid::Material::spatial_tangent), its upper triangle row by row (11, 22, 33, 23, 13, 12).
  double stiffness_time = 0;
  std::array<double, 21> stiffness{};
  /// An external force on the solid (an optical tweezers' bead): (1/rho_1) times its density per unit
  /// reference volume [cm/s^2], weighed like the other terms (solid/external_load.hpp). Zero: no load.
  std::array<double, 3> force{};
  /// Tangent only, with a SolidLinearization (ImmersedFluid::set_solid_linearization): the point's body
  /// functions are entries [solid_begin, solid_end) of its tables; -1: none (the consistent tangent above).
  int solid_begin = -1, solid_end = -1;
};

}  // namespace cellfsi::fluid
