#pragma once
// Measures of patches and of the regions that closed membranes enclose: length/area/volume, perimeter or
// surface area, centroid, second moments and principal axes (for the inclination angle), swelling degree
// Delta and effective radius R_0 (paper Sec. 3.1). Integrals use Gauss rules on the patch's elements;
// rational maps are not integrated exactly, so accuracy improves with refinement and `extra_gauss`.
#include <array>
#include <vector>

#include "geometry/patch.hpp"

namespace cellfsi::geometry {

/// Zeroth, first and (central) second moments of a region.
struct RegionMoments {
  double measure = 0;  // area in 2D, volume in 3D
  Vec3 centroid = Vec3::Zero();
  Mat3 second_moment = Mat3::Zero();  // integral of (x - c)(x - c)^T over the region
};

/// A contiguous share of a patch's elements (by linear element index), part `part` of `parts`: the integrals
/// below over a share are partial sums, to be added over all parts (the bodies' metrics split among ranks).
struct ElementShare {
  int part = 0;
  int parts = 1;
  /// If given, the integrals add to it the operations of their points on this share (an estimate from the
  /// basis's size: -log_view's counts, by which a strong-scaling model sees that the share divides).
  double* operations = nullptr;
};
/// An estimate of the operations at one quadrature point of a patch: its basis functions' tensor products
/// and derivatives, the map and its Jacobian.
double point_operations(const Patch& patch);

/// Raw moments about a reference point (the patch's bounding-box centre, the same for every share): M0 =
/// int 1, M1 = int (x - ref), M2 = int (x - ref)(x - ref)^T (signed by the orientation for a boundary's).
/// Sums over shares add entry by entry; finish() turns the whole into RegionMoments.
struct MomentSums {
  double m0 = 0;
  Vec3 m1 = Vec3::Zero();
  Mat3 m2 = Mat3::Zero();
  Vec3 ref = Vec3::Zero();
};
RegionMoments finish(const MomentSums& sums);

/// Extent of element e of a patch along each parametric direction d: the largest distance between two of its
/// corners that differ only in d (entry d < param_dim; the others are zero).
std::array<double, 3> element_extents(const Patch& patch, int e);
/// The smallest element_extents over all elements and parametric directions. On an axis-aligned affine patch
/// (affine_map: the paper's boxes) it is closed-form: the shortest knot span times the map's scale; otherwise
/// every element's edges are evaluated (12 per element in 3D).
double smallest_element_extent(const Patch& patch);

/// Length, area or volume of the patch itself (its parametric dimension decides which); over a share of its
/// elements, that share's part.
double patch_measure(const Patch& patch, int extra_gauss = 2, const ElementShare& share = {});

/// Moments of the region a patch covers (parametric dimension == physical dimension), e.g. a nucleus or the
/// membrane band itself; patch_moment_sums: a share's raw sums.
RegionMoments patch_moments(const Patch& patch, int extra_gauss = 2);
MomentSums patch_moment_sums(const Patch& patch, int extra_gauss = 2, const ElementShare& share = {});

/// Moments of the region enclosed by a closed boundary: a closed curve in 2D (Green's theorem) or a closed
/// surface in 3D (divergence theorem). Orientation does not matter. enclosed_moment_sums: a share's raw sums.
RegionMoments enclosed_moments(const Patch& boundary, int extra_gauss = 2);
MomentSums enclosed_moment_sums(const Patch& boundary, int extra_gauss = 2, const ElementShare& share = {});
/// The same for a boundary made of parts, each open and all of them together closed and oriented alike (a
/// membrane's faces, geometry::biconcave_rbc_3d_faces' mid-surfaces): the parts' sums taken about one
/// reference point, their common bounding box's centre (Green's and the divergence theorem's integrals add
/// over the parts only about one point). A share: that share of each part's elements.
MomentSums enclosed_moment_sums(const std::vector<Patch>& parts, int extra_gauss = 2,
                                const ElementShare& share = {});

/// Principal axes of a region: eigenvalues of the central second moment in descending order and the matching
/// unit eigenvectors as columns. The first axis is the long axis (least moment of inertia).
struct PrincipalAxes {
  Vec3 values = Vec3::Zero();
  Mat3 axes = Mat3::Identity();
};
PrincipalAxes principal_axes(const RegionMoments& moments, int dim);

/// 2D: angle of the long axis with the +x direction, in (-pi/2, pi/2].
double long_axis_angle(const RegionMoments& moments);

/// Swelling degree: 2D 4 pi A / P^2; 3D 6 sqrt(pi) V / S^(3/2).
double swelling_degree(double enclosed, double boundary, int dim);
/// Effective radius: 2D P / (2 pi); 3D sqrt(S / (4 pi)).
double effective_radius(double boundary, int dim);

/// Shape measures of a membrane patch (one parametric direction through the thickness), taken on its
/// mid-surface (the isoparametric sub-patch at mid-thickness).
struct MembraneShape {
  double enclosed = 0;          // area (2D) / volume (3D) enclosed by the mid-surface
  double boundary = 0;          // perimeter (2D) / surface area (3D) of the mid-surface
  double swelling = 0;          // Delta_m
  double effective_radius = 0;  // R_0
  RegionMoments moments;        // of the enclosed region
};
MembraneShape membrane_shape(const Patch& membrane, int thickness_dir = 0, int extra_gauss = 2);
/// The same for a membrane made of parts (each a patch with the thickness along thickness_dir, together
/// closed).
MembraneShape membrane_shape(const std::vector<Patch>& parts, int thickness_dir = 0, int extra_gauss = 2);

}  // namespace cellfsi::geometry
