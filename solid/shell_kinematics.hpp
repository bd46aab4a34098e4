#pragma once
// The kinematics of a thin shell described by its mid-surface alone (Kirchhoff-Love), for a membrane whose
// thickness is not an unknown. The one-element-thick solid shell (NurbsSolid) carries its thickness in
// control points through it, which follow the fluid at three or four collocation points across 0.32 um; at a
// red cell's dimple that representation folds (docs/validation.md, "A red blood cell in 3D"). Here the
// shell's points follow from the mid-surface: a point at height zeta above it lies along the normal, at the
// distance the thickness has shrunk or grown to, so the shell cannot fold through its thickness while the
// mid-surface's curvature radius stays above the half thickness.
//
//   reference X(theta, zeta) = X(theta) + zeta N(theta),
//   current   x(theta, zeta) = x(theta) + zeta lambda3(theta) n(theta),  lambda3 = |A1 x A2| / |a1 x a2|,
//
// with A_a = dX / dtheta_a, a_a = dx / dtheta_a, N and n the unit normals. lambda3 is the thickness stretch
// of an incompressible shell (the mid-surface's area stretch times lambda3 is 1: det F = 1 at zeta = 0). F is
// the 3D deformation gradient at (theta, zeta), g_i (x) G^i, which the 3D laws take as they take a solid
// shell's (solid/material.hpp); its variation through the thickness is what bends the shell. The second
// derivatives of the mid-surface enter through the normal's and lambda3's derivatives.
#include "geometry/patch.hpp"
#include "solid/material.hpp"
#include "solid/solid_solver.hpp"

namespace cellfsi::solid {

/// A point of the shell at height zeta above the mid-surface.
struct ShellPoint {
  Vec3 x = Vec3::Zero();          // its current position
  Mat3 F = Mat3::Identity();      // the deformation gradient dx / dX
  double ref_jacobian = 0;        // det [G_1 G_2 N]: dV = ref_jacobian dtheta_1 dtheta_2 dzeta
  Mat3 frame = Mat3::Identity();  // the reference frame T1, T2, N (columns; T1 along A_1): a surface law's
  double thickness_stretch = 1;   // lambda3 (at the mid-surface point)
};

/// The shell's point at height zeta [cm] from the reference and current mid-surface's map values at the same
/// parametric point (a surface patch: parametric dimension 2 in 3D, evaluated with second derivatives).
/// Throws std::invalid_argument for a degenerate mid-surface (A_1 x A_2 or a_1 x a_2 zero) and for a zeta
/// that inverts the reference shell there (det [G_1 G_2 N] <= 0: zeta beyond a curvature radius).
ShellPoint shell_point(const geometry::MapValues& ref, const geometry::MapValues& cur, double zeta);

/// The current covariant basis at height zeta is g0 + zeta g1 (columns g_1, g_2, g_3): g0 = [a_1, a_2,
/// lambda3 n], g1 = [d (lambda3 n) / dtheta_1, d (lambda3 n) / dtheta_2, 0]; F = (g0 + zeta g1) G^-1. Their
/// derivatives in the current mid-surface's 15 derivatives m = (a_1, a_2, a_11, a_12, a_22), 3 components
/// each, are what a shell's internal force needs (its energy's gradient in the control points, by the chain
/// rule through the basis functions' derivatives): rows are g's entries column by column.
struct ShellBasisDerivative {
  Mat3 g0, g1;
  Eigen::Matrix<double, 9, 15> d_g0, d_g1;
};
/// The same arguments and refusals as shell_point (a degenerate mid-surface).
ShellBasisDerivative shell_basis_derivative(const geometry::MapValues& ref, const geometry::MapValues& cur);

}  // namespace cellfsi::solid
