#pragma once
// The viscosity inside closed membranes (issue 27; docs/fluid.md, "The viscosity field"): each membrane body
// may enclose a fluid (a cytosol) of its own viscosity mu_in. The fluid's viscosity field then has the
// control values
//   mu_A = mu_out + sum_b (mu_in,b - mu_out) I_b(X_A),
// with X_A the fluid's control points (its Greville points on the builders' affine meshes) and I_b the
// indicator of the inside of membrane b's mid-surface. nu^h = sum_A (mu_A / rho_1) N_A then changes from
// mu_out to mu_in over p elements of the fluid mesh across the mid-surface (measured in
// tests/unit/coupling/test_inner_viscosity.cpp). Within the membrane's own thickness the fluid viscosity does
// not act: the immersed terms remove the same local nu^h that the fluid's integral adds there (fluid/
// vms_kernel.hpp), so the wall carries its material's stress only, whichever viscosity the field has there.
// Plain functions of patches and points: no PETSc.
#include <string>
#include <vector>

#include "geometry/patch.hpp"

namespace cellfsi::coupling {

/// Whether each point lies inside the closed mid-surface (xi_0 halfway through the wall) of a membrane patch
/// (direction 0 through the wall; directions 1 (and 2) around it): the winding number of the mid-line sampled
/// as a polygon (2D) or the generalized winding number of the mid-surface sampled as triangles (3D), with
/// `samples` points per element and direction (0: 8 in 2D, 4 in 3D, where the work is points x triangles:
/// with 8, the 3D compound capsule at 16^3 spent 0.35 s per step on it, 4 quarter that; the chord error of 4
/// samples on a quadratic element spanning 13 degrees is 4e-4 of the radius). Points near the mid-surface
/// (within that chord error) may fall on either side.
std::vector<char> inside_membrane(const geometry::Patch& membrane, const std::vector<geometry::Vec3>& points,
                                  int samples = 0);
/// The same for a membrane made of parts (patches each open and together closed, oriented alike: a membrane's
/// faces, geometry::biconcave_rbc_3d_faces): the parts' windings added.
std::vector<char> inside_membrane(const std::vector<geometry::Patch>& parts,
                                  const std::vector<geometry::Vec3>& points, int samples = 0);

/// One membrane with an inner viscosity.
struct InnerViscosity {
  const geometry::Patch* membrane = nullptr;  // its current configuration
  double viscosity = 0;                       // mu_in [g/(cm s)]
  const std::vector<geometry::Patch>* parts = nullptr;  // or, a membrane made of patches, its parts
};

/// The control values mu_A of the fluid's viscosity field (size: fluid.n_control(), by natural index):
/// mu_out, and mu_in of the membrane whose inside holds the control point (membranes do not overlap).
std::vector<double> viscosity_values(const geometry::Patch& fluid, const std::vector<InnerViscosity>& inner,
                                     double mu_out);

/// Throws std::invalid_argument unless mu_in > 0 (and finite) and the body is a membrane (a bulky body has no
/// inside that holds fluid). `body` names it in the message.
void check_inner_viscosity(const std::string& body, bool membrane, double mu_in);

}  // namespace cellfsi::coupling
