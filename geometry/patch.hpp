#pragma once
// Tensor-product NURBS patches of parametric dimension 1-3 in physical dimension 2-3.
//
// Control points are stored lexicographically with parametric direction 0 fastest (the ordering of a
// PETSc DMDA), always as 3-vectors (z = 0 for physical dimension 2). In a periodic direction the patch
// stores the n_basis() folded control points plus a physical "period shift" vector: unwrapped control
// point j is P_{j mod n} + (j div n) * shift. The shift is zero for a closed curve and (L, 0, 0) for a
// channel periodic in x, so fields are periodic while the map need not be.
#include <array>
#include <optional>
#include <vector>

#include <Eigen/Dense>

#include "geometry/knot_vector.hpp"

namespace cellfsi::geometry {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Index3 = std::array<int, 3>;
using Param = std::array<double, 3>;  // parametric coordinates (unused trailing entries are 0)

/// The nonzero rational basis functions of a patch at one parametric point, with derivatives with respect
/// to the parametric coordinates. Reused across evaluations to avoid allocation.
struct BasisValues {
  int n = 0;                  // number of nonzero functions, prod (p_d + 1)
  int n_deriv = 0;            // derivative order available
  Index3 span{0, 0, 0};       // span index per direction
  std::vector<int> index;     // folded control-point (= field) index of each function
  std::vector<Vec3> offset;   // physical offset of the unwrapped control point (periodic shifts)
  std::vector<double> value;  // R_k
  std::vector<double> d1;     // d1[k * 3 + a] = dR_k / dxi_a
  std::vector<double> d2;     // d2[k * 9 + a * 3 + b] = d2R_k / dxi_a dxi_b
};

/// Geometric map and its parametric derivatives at one point.
struct MapValues {
  Vec3 x = Vec3::Zero();
  Mat3 dx = Mat3::Zero();  // dx(i, a) = d x_i / d xi_a (columns beyond param_dim are 0)
  std::array<Mat3, 3> d2x{Mat3::Zero(), Mat3::Zero(), Mat3::Zero()};  // d2x[i](a, b)
};

class Patch {
 public:
  Patch() = default;
  /// knots.size() is the parametric dimension; control_points.size() == weights.size() == prod n_basis(d).
  /// shifts[d] is the period shift of direction d (ignored unless that direction is periodic).
  Patch(std::vector<KnotVector> knots, int physical_dim, std::vector<Vec3> control_points,
        std::vector<double> weights, std::array<Vec3, 3> shifts = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()});

  int param_dim() const { return static_cast<int>(knots_.size()); }
  int physical_dim() const { return physical_dim_; }
  const KnotVector& knots(int dir) const { return knots_[dir]; }
  const std::vector<KnotVector>& all_knots() const { return knots_; }
  int degree(int dir) const { return knots_[dir].degree(); }
  int n_control(int dir) const { return dir < param_dim() ? knots_[dir].n_basis() : 1; }
  int n_control() const { return static_cast<int>(control_points_.size()); }
  int n_elements(int dir) const { return dir < param_dim() ? knots_[dir].n_elements() : 1; }
  int n_elements() const { return n_elements(0) * n_elements(1) * n_elements(2); }
  int control_index(int i0, int i1 = 0, int i2 = 0) const {
    return i0 + n_control(0) * (i1 + n_control(1) * i2);
  }
  Index3 control_multi_index(int idx) const;

  const std::vector<Vec3>& control_points() const { return control_points_; }
  std::vector<Vec3>& control_points() { return control_points_; }
  const std::vector<double>& weights() const { return weights_; }
  std::vector<double>& weights() { return weights_; }
  const Vec3& shift(int dir) const { return shifts_[dir]; }
  const std::array<Vec3, 3>& shifts() const { return shifts_; }
  /// The control points (unwrapped: periodic offsets applied) and weights of the (p+1)^d functions whose
  /// first unwrapped indices per direction are `first` (an element's: span - degree), in basis order
  /// (direction 0 fastest). X and W hold at least that many entries.
  void element_controls(const int first[3], Vec3* X, double* W) const;
  bool rational() const;

  /// True if direction dir wraps around: periodic, or open with coinciding first and last control layers
  /// (a closed curve/surface; the layers are C0-joined and a field must identify them).
  bool closed(int dir) const { return closed_[dir]; }

  /// Element multi-index <-> linear index (direction 0 fastest).
  Index3 element_multi_index(int e) const;
  int element_index(const Index3& e) const { return e[0] + n_elements(0) * (e[1] + n_elements(1) * e[2]); }
  /// Parametric box of an element.
  void element_bounds(const Index3& e, Param& lo, Param& hi) const;
  /// Element containing xi (wrapped/clamped per direction).
  Index3 find_element(const Param& xi) const;

  /// Rational basis at xi (periodic coordinates may lie outside [a, b): the shift is applied).
  /// If `element` is given, xi is evaluated with that element's span (needed on element boundaries).
  void basis(const Param& xi, int n_deriv, BasisValues& out, const Index3* element = nullptr) const;
  /// Map and derivatives from basis values. Sums are taken relative to the first control point of the
  /// support, so a thin body far from the origin keeps its digits (x = X_0 + sum R_k (X_k - X_0); sum dR_k =
  /// 0).
  void map(const BasisValues& bv, MapValues& out) const;
  /// x(xi) - y, computed as (X_0 - y) + sum R_k (X_k - X_0): accurate to round-off of the element's size
  /// rather than of |x| (the residual of point inversion).
  Vec3 map_minus(const BasisValues& bv, const Vec3& y) const;
  /// Convenience: physical point at xi.
  Vec3 point(const Param& xi) const;
  /// Convenience: map and derivatives at xi.
  MapValues evaluate(const Param& xi, int n_deriv = 1) const;

  /// Axis-aligned bounding box of the control points (contains the patch, convex hull property).
  void bounding_box(Vec3& lo, Vec3& hi) const;
  /// Bounding box of the control points that influence element e (contains the element).
  void element_bounding_box(const Index3& e, Vec3& lo, Vec3& hi) const;

 private:
  void detect_closed();
  std::vector<KnotVector> knots_;
  int physical_dim_ = 2;
  std::vector<Vec3> control_points_;
  std::vector<double> weights_;
  std::array<Vec3, 3> shifts_{Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  std::array<bool, 3> closed_{false, false, false};
};

/// Returns the patch with every control point mapped by x -> A x + t (exact for NURBS: affine invariance).
Patch transformed(const Patch& patch, const Mat3& A, const Vec3& t);

/// Whether the patch is the same under a shift by one element along every periodic direction: uniform
/// knots there and control points that move by one constant vector per step (weights unchanged), so that any
/// operator assembled on it from a flow that is uniform along those directions is translation-invariant (the
/// paper's boxes; not the narrowing channel). tol: relative to the patch's extent.
bool translation_invariant(const Patch& patch, double tol = 1e-12);

/// An axis-aligned affine map of the parameter box: x_d = offset_d + scale_d xi_d for the parametric
/// directions d < param_dim, x_d = offset_d (scale_d = 0) for the others. Its inverse is closed-form: no
/// Newton iteration.
struct AffineMap {
  Vec3 offset = Vec3::Zero();
  Vec3 scale = Vec3::Zero();
  Vec3 point(const Param& xi) const { return offset + scale.cwiseProduct(Vec3(xi[0], xi[1], xi[2])); }
};

/// The patch's map if it is axis-aligned affine (the paper's boxes and straight channels:
/// geometry::rectangle, geometry::box), else nullopt (the narrowing channel, any curved, rotated, sheared or
/// rational patch). Affine means: equal weights (the map is then the B-spline one), every control point at
/// offset + scale .* (its Greville abscissae) (the coefficients of the identity map, unique by linear
/// independence), each periodic direction's shift equal to scale_d times its period along axis d, and, as a
/// check of all that, the patch's own evaluation at a point inside every element equal to the map. tol:
/// relative to the patch's extent.
std::optional<AffineMap> affine_map(const Patch& patch, double tol = 1e-12);

/// r moved by whole periods of the patch's periodic directions to the image nearest the origin (applied to a
/// separation x - y: its shortest periodic form; to x - centre: x's image in the period around centre).
Vec3 nearest_image(const Patch& patch, Vec3 r);
/// The shifts that bring a periodic patch's neighbouring images next to it: 0 and every sum of -1, 0 or +1
/// times each periodic direction's shift (3^k of them for k periodic directions).
std::vector<Vec3> neighbour_image_shifts(const Patch& patch);

}  // namespace cellfsi::geometry
