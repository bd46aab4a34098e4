#pragma once
// Builders of the Eulerian domains and the cell patches of the paper, in CGS units (cm).
//
// Parametric directions of the cell patches:
//  - membranes (hollow ellipse, biconcave RBC in 2D and 3D, hollow ellipsoid): direction 0 runs through the
//    thickness (one element), the others around the membrane (closed: first and last control layers
//    coincide; in 3D direction 1 runs from pole to pole);
//  - bulky bodies (ellipse/disk, ellipsoid/sphere): direction 0 runs from the centre (a degenerate point)
//    to the boundary.
// Conics and quadrics are exact (rational quadratic NURBS, degree-elevated and refined exactly); every
// builder checks its arguments and throws std::invalid_argument naming the argument, its value and the valid
// range.
#include <array>
#include <vector>

#include "geometry/patch.hpp"

namespace cellfsi::geometry {

/// Rectangle [x0, x0 + lx] x [y0, y0 + ly], nx x ny elements of degree p and continuity p - 1; a periodic
/// direction gets a periodic knot vector and the period shift (lx, 0) or (0, ly).
Patch rectangle(double lx, double ly, int nx, int ny, int degree,
                std::array<bool, 2> periodic = {false, false}, const Vec3& origin = Vec3::Zero());

/// Box [x0, x0 + lx] x [y0, y0 + ly] x [z0, z0 + lz], likewise.
Patch box(double lx, double ly, double lz, int nx, int ny, int nz, int degree,
          std::array<bool, 3> periodic = {false, false, false}, const Vec3& origin = Vec3::Zero());

/// A 2D channel periodic in x with a smooth symmetric narrowing (docs/design.md §3). The walls are at
/// y = +-(height / 2 - offset(x)), offset(x) = (height - throat_height) / 2 * s(x), where s is 1 over the
/// throat, 0 far from it, and a C-infinity smooth step over the transitions. The channel spans [0, length] x
/// [-height / 2, height / 2].
struct NarrowingChannel {
  double length = 0.006;               // period in the flow direction
  double height = 0.002;               // channel height away from the narrowing
  double throat_height = 0.0008;       // narrower than a 0.001 cm CTC, so the cell must deform
  double throat_length = 0.001;        // length of the straight throat
  double transition_length = 0.001;    // length of each smooth transition
  double throat_center = 0.003;        // x of the throat's centre
  void validate() const;               // throws std::invalid_argument on an impossible parameter
  double wall_offset(double x) const;  // offset(x) above (exact profile; x taken modulo length)
};
/// The channel on nx x ny elements of degree p: x is exact (affine), the wall offset is the L2 projection of
/// the exact profile onto the periodic spline space in x (error O(h^(p+1)), measured in the tests).
Patch narrowing_channel(const NarrowingChannel& channel, int nx, int ny, int degree);

/// Hollow ellipse (capsule membrane) with mid-line semi-axes a (along the rotated x axis) and b, thickness h
/// (inner semi-axes a - h/2, b - h/2; outer a + h/2, b + h/2), 1 x n_angular elements of degree p >= 2,
/// centred at `center`, long axis rotated by `angle` radians from +x. Exact conics; n_angular a multiple
/// of 4.
Patch hollow_ellipse(double a, double b, double h, int n_angular, int degree,
                     const Vec3& center = Vec3::Zero(), double angle = 0.0);

/// Bulky ellipse (nucleus, or a disk when a == b) with n_radial x n_angular elements of degree p >= 2.
Patch bulky_ellipse(double a, double b, int n_radial, int n_angular, int degree,
                    const Vec3& center = Vec3::Zero(), double angle = 0.0);

/// Evans-Fung biconcave RBC profile (docs/design.md §3), unscaled, in cm: the cross-section curve
/// c(t) = (R0 cos t, 1/2 sin t (C0 + C2 cos^2 t + C4 cos^4 t)), t in [0, 2 pi): full thickness T(r) at r = R0
/// cos t.
struct EvansFung {
  double R0 = 3.91e-4, C0 = 0.81e-4, C2 = 7.83e-4, C4 = -4.39e-4;
  Vec3 point(double t) const;
  Vec3 tangent(double t) const;  // dc/dt
  double area() const;           // exact enclosed area: R0 pi (C0/2 + C2/8 + C4/16)
};
/// Target area of one 2D RBC (docs/design.md §3: 4 RBCs give H_t = 0.1716 in a 0.003 x 0.001 cm^2 channel).
inline constexpr double kRbcArea2d = 1.2868e-7;
/// Biconcave RBC membrane: the Evans-Fung mid-line interpolated at the Greville points of n_angular elements
/// of degree p (C^{p-1}), then scaled so it encloses `area`; thickness h about the mid-line along the exact
/// normal. Long axis (the disc's diameter) rotated by `angle` from +x.
Patch biconcave_rbc(double h, int n_angular, int degree, const Vec3& center = Vec3::Zero(),
                    double angle = 0.0, double area = kRbcArea2d, const EvansFung& shape = {});

/// Hollow ellipsoid (3D capsule membrane) with mid-surface semi-axes a, b, c along x, y, z, thickness h:
/// 1 x n_polar x n_azimuth elements of degree p >= 2 (polar axis z; n_polar a multiple of 2, n_azimuth of 4).
Patch hollow_ellipsoid(double a, double b, double c, double h, int n_polar, int n_azimuth, int degree,
                       const Vec3& center = Vec3::Zero());

/// 3D biconcave RBC membrane: the Evans-Fung cross-section (rho, z) = c(t), t in [-pi/2, pi/2] (x of
/// EvansFung::point is the distance from the axis), revolved exactly (rational quadratic arcs) about the z
/// axis through `center`, the disc's axis of symmetry. 1 x n_polar x n_azimuth elements of degree p >= 2
/// (n_polar even, n_azimuth a multiple of 4), poles on the axis as in hollow_ellipsoid. The profile
/// interpolates c at the Greville points of n_polar uniform elements in t, and c's end slopes (it leaves the
/// axis at a right angle: the surface is smooth at its poles); thickness h (< C0, the dimple's thickness)
/// about the mid-surface along the exact normal. Unscaled: mid-surface area about 135 um^2, volume about
/// 94 um^3 (docs/geometry.md).
Patch biconcave_rbc_3d(double h, int n_polar, int n_azimuth, int degree, const Vec3& center = Vec3::Zero(),
                       const EvansFung& shape = {});

/// The same membrane without poles: six patches, the faces of a cube projected onto the unit sphere
/// (equiangular: the face coordinates are tan(pi a / 4), a in [-1, 1]) and mapped onto the Evans-Fung
/// surface, (x, y, z) -> (R0 x, R0 y, z / 2 (C0 + C2 c2 + C4 c2^2)) with c2 = x^2 + y^2, the point of
/// latitude t on the sphere going to c(t) at the same angle about the axis. Each patch is 1 x n_face x n_face
/// elements of degree p >= 2: direction 0 through the thickness h (inner face first, as the other membranes),
/// directions 1 and 2 across the cube's face, right-handed with the outward normal; the two faces on the axis
/// (z) are centred on the dimples. Each layer interpolates X + (r - 1/2) h n (n the exact unit normal) at the
/// Greville points, so two patches that share a cube edge share its control points (to round-off: the
/// interpolant on a patch's boundary depends only on the data there). Order: +x, -x, +y, -y, +z, -z. Three
/// patches meet at each of the cube's eight corners; no element degenerates (at 8 elements a face their
/// mid-surface edges are 0.30-0.80 um long, where the polar shell's poles are edges of length 0).
std::vector<Patch> biconcave_rbc_3d_faces(double h, int n_face, int degree, const Vec3& center = Vec3::Zero(),
                                          const EvansFung& shape = {});

/// Solid ellipsoid (a sphere when a == b == c): n_radial x n_polar x n_azimuth elements of degree p >= 2.
Patch solid_ellipsoid(double a, double b, double c, int n_radial, int n_polar, int n_azimuth, int degree,
                      const Vec3& center = Vec3::Zero());

/// The surface of a solid shell's patch (parametric dimension 3, direction 0 through the thickness) at the
/// middle of direction 0's range, exactly: a surface patch (parametric dimension 2 in 3D) over directions 1
/// and 2, its control points and weights the combinations of the layers' in homogeneous coordinates. For the
/// builders' membranes, whose layers interpolate X + (r - 1/2) h n, the interpolant of X: a thin shell's
/// mid-surface.
Patch mid_surface(const Patch& shell);

}  // namespace cellfsi::geometry
