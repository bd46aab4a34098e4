#pragma once
// The divergence-conforming B-spline spaces of Evans & Hughes (M3AS 2013; JCP 2013) on an axis-aligned box.
//
// Degrees: k (k' in the papers and in issue 44) is the degree of the pressure. Per direction d there are two
// knot vectors on the same breakpoints, in physical coordinates (the box's map is affine and axis-aligned, so
// the parametric and physical coordinates differ only by that map and the knot vectors are written in x):
//   high(d): degree k + 1, continuity C^k      (open: end knots repeated k + 2 times; periodic: periodic)
//   low(d):  degree k,     continuity C^(k-1)  (the same breakpoints with one end knot fewer at each end)
// d/dx maps the span of high(d) onto the span of low(d) (Piegl & Tiller Eq. (2.9); for periodic vectors onto
// its zero-mean part). The spaces:
//   velocity component i: high along x_i, low along the other directions;
//   pressure:             low along every direction.
// Hence div v_h = sum_i d v_i / d x_i lies in the pressure space for every v_h, with coefficients given by
// the difference matrices of divergence() (the de Rham property of the pair; no quadrature involved).
//
// Numbering of the unknowns: velocity component 0, then 1 (then 2), then pressure; within each, the folded
// basis indices lexicographically with direction 0 fastest (as geometry::Patch numbers control points).
#include <array>
#include <memory>
#include <vector>

#include "fluid/div_conforming/dc_piola.hpp"
#include "geometry/knot_vector.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::fluid::dc {

using geometry::Index3;
using geometry::KnotVector;
using geometry::Vec3;

/// Values and first derivatives of one field component's nonzero basis functions at a set of points of one
/// element (tensor products of univariate B-splines, physical derivatives).
struct ComponentBasis {
  int n = 0;                  // number of nonzero functions, prod (degree_d + 1)
  std::vector<int> index;     // global unknown index of each function (component offset included)
  std::vector<double> value;  // value[q * n + a]
  std::vector<double> grad;   // grad[(q * n + a) * 3 + j] = d N_a / d x_j at point q
};

/// The element's basis at its points: components 0..dim-1 are the velocity, component dim the pressure.
/// On a mapped space (DivConformingSpace::mapped) comp holds the parametric basis (derivatives in xi), piola
/// the map at each point, x the physical points and weight the parametric weight times J (a face's measure is
/// weight |G^T n^|, n^ its parametric normal); interpolate() returns the physical fields. On a box piola is
/// empty.
struct ElementBasis {
  int n_points = 0;
  std::vector<Vec3> x;         // physical points
  std::vector<double> weight;  // quadrature weight (physical measure; face weights for face rules)
  std::array<ComponentBasis, 4> comp;
  std::vector<PiolaPoint> piola;
};

/// Tensor rule of an element or of a face of it: per direction a list of points and weights. A face rule has
/// one point of weight 1 in the face's normal direction.
struct TensorRule {
  std::array<std::vector<double>, 3> points;
  std::array<std::vector<double>, 3> weights;
};

class DivConformingSpace {
 public:
  /// The box [lo, hi] of dimension dim (2 or 3) with n_elements[d] equal elements per direction, pressure
  /// degree k (1 <= k <= geometry::kMaxDegree - 1); periodic[d] makes direction d periodic (needs
  /// n_elements[d] >= k + 1), otherwise its two ends are walls. Throws std::invalid_argument on bad input.
  DivConformingSpace(int dim, int k, const Index3& n_elements, const Vec3& lo, const Vec3& hi,
                     const std::array<bool, 3>& periodic);
  /// The same space on the box of an axis-aligned affine patch (geometry::affine_map; geometry::rectangle or
  /// geometry::box) with its elements and periodic directions; the patch's own degree plays no part.
  /// Throws std::invalid_argument for a patch that is not affine or whose periodic elements are not uniform.
  static DivConformingSpace from_patch(const geometry::Patch& patch, int k);
  /// The space on a curved patch through the contravariant Piola map (dc_piola.hpp; issue 45 part 2): the
  /// knot vectors on the patch's parametric box scaled per direction (from_patch_parameters; its elements,
  /// which must be uniform per direction; its periodic directions), the fields mapped at every point
  /// evaluate() forms. Its lo/hi/element_size, find_element/point_rule and divergence() (div_s: div_x v =
  /// div_s v^ / J) are in those coordinates s. Throws std::invalid_argument as from_patch; evaluate() throws
  /// it where the map folds (det F <= 0 at a point). DcFourierSolver refuses such a space.
  static DivConformingSpace mapped(std::shared_ptr<const geometry::Patch> patch, int k);
  bool is_mapped() const { return map_ != nullptr; }
  /// The geometry of a mapped space (null on a box).
  const geometry::Patch* patch() const { return map_.get(); }
  /// A mapped space's coordinates s (its knots, rules and points) are the patch's parameters xi scaled per
  /// direction, s_d = c_d xi_d (mapped() says why); c_d is 1 on a box.
  Vec3 from_patch_parameters(const geometry::Param& xi) const {
    return Vec3(xi[0] * param_scale_[0], xi[1] * param_scale_[1], xi[2] * param_scale_[2]);
  }
  geometry::Param to_patch(const Vec3& s) const {
    return {s[0] / param_scale_[0], s[1] / param_scale_[1], s[2] / param_scale_[2]};
  }

  int dim() const { return dim_; }
  int degree() const { return k_; }  // pressure degree k'
  bool periodic(int d) const { return periodic_[d]; }
  double lo(int d) const { return lo_[d]; }
  double hi(int d) const { return hi_[d]; }
  int n_elements(int d) const { return d < dim_ ? low_[d].n_elements() : 1; }
  int n_elements() const { return n_elements(0) * n_elements(1) * n_elements(2); }
  Index3 element_multi_index(int e) const;
  double element_size(int d) const { return (hi_[d] - lo_[d]) / n_elements(d); }

  const KnotVector& high(int d) const { return high_[d]; }
  const KnotVector& low(int d) const { return low_[d]; }
  /// The knot vector of component c (c < dim: velocity component; c == dim: pressure) along direction d.
  const KnotVector& knots(int c, int d) const { return (c == d) ? high_[d] : low_[d]; }

  /// Number of basis functions of component c along direction d (1 for d >= dim), and in total.
  int n_basis(int c, int d) const { return d < dim_ ? knots(c, d).n_basis() : 1; }
  int n_basis(int c) const { return n_basis(c, 0) * n_basis(c, 1) * n_basis(c, 2); }
  int offset(int c) const { return offset_[c]; }
  int n_velocity() const { return offset_[dim_]; }
  int n_pressure() const { return n_basis(dim_); }
  int n_dofs() const { return offset_[dim_] + n_pressure(); }
  /// Global index of the function (i0, i1, i2) (folded indices) of component c.
  int index(int c, const Index3& i) const {
    return offset_[c] + i[0] + n_basis(c, 0) * (i[1] + n_basis(c, 1) * i[2]);
  }
  Index3 multi_index(int c, int global) const;
  /// Replaces the coefficients U (natural numbering, n_dofs()) of each component by their mean over the
  /// periodic directions, line by line across: the field averaged along those directions (their functions
  /// are translates of one another on uniform elements, each of the same integral).
  void average_periodic(std::vector<double>& U) const;

  /// The unknowns fixed strongly: the normal velocity on every wall (component d at the first and last
  /// function along a non-periodic direction d, the only ones nonzero there).
  std::vector<int> wall_normal_dofs() const;

  /// n_gauss-point Gauss rule per direction on element e.
  TensorRule element_rule(const Index3& e, int n_gauss) const;
  /// Rule on the face of element e at side `side` (0: x_d = lo, 1: x_d = hi) of direction d.
  TensorRule face_rule(const Index3& e, int d, int side, int n_gauss) const;
  /// The element containing x (per direction: wrapped into the period if periodic, clamped to the box
  /// otherwise) and the one-point rule at x in it (periodic coordinates wrapped). x: physical on a box, the
  /// space's coordinates s on a mapped space.
  Index3 find_element(const Vec3& x) const;
  TensorRule point_rule(const Vec3& x) const;
  /// The basis of every component at the points of `rule` in element e. with_indices false keeps out's
  /// function indices: the caller's last call was on the same element (the immersed points of one element).
  void evaluate(const Index3& e, const TensorRule& rule, ElementBasis& out, bool with_indices = true) const;
  /// The p + 1 functions of space s (0: low, 1: high) along direction d < dim() that are nonzero on element e
  /// of that direction: value[j] and physical derivative deriv[j] at x (a point of the element; beyond it,
  /// the element's polynomials continued). From each element's power-basis coefficients about its midpoint,
  /// set once at construction from the Cox-de Boor recursion (geometry::bspline_basis): at a point, Horner's
  /// rule without divisions. (The recursion at the immersed points, through point_factors and evaluate, was
  /// 5.6 % of a 64^3 coupled step with a 1 x 96 x 160 membrane; perf, by caller.)
  void univariate(int s, int d, int e, double x, double* value, double* deriv) const {
    const int p = k_ + s, n = p + 1;
    const double* c = &poly_[s][d][static_cast<size_t>(e) * n * n];
    const double t = (x - mid_[d][e]) * inv_h_[d][e];
    for (int j = 0; j < n; ++j, c += n) {
      double v = c[p], dv = 0.0;
      for (int m = p - 1; m >= 0; --m) dv = dv * t + v, v = v * t + c[m];
      value[j] = v, deriv[j] = dv * inv_h_[d][e];
    }
  }
  /// The fields at the points of eb from a coefficient array over all unknowns: velocity (dim) and its
  /// gradient grad[i][j] = d v_i / d x_j, and pressure.
  struct PointValues {
    std::array<double, 3> v{};
    std::array<std::array<double, 3>, 3> grad{};
    double p = 0;
  };
  static PointValues interpolate(const ElementBasis& eb, int q, int dim, const double* coeffs);
  /// The velocity alone at point q (no gradient, no pressure): interpolate's v, in a fifth of its work.
  static std::array<double, 3> interpolate_velocity(const ElementBasis& eb, int q, int dim,
                                                    const double* coeffs);

  /// The divergence as a map of coefficients: (D u)[pressure index] such that div v_h = sum_A (D u)_A q_A for
  /// the velocity with coefficients u (size n_velocity(); result size n_pressure()). Exact, from the
  /// derivative formula of B-splines.
  std::vector<double> divergence(const std::vector<double>& u) const;

 private:
  int dim_ = 2, k_ = 2;
  std::array<bool, 3> periodic_{false, false, false};
  std::array<double, 3> lo_{0, 0, 0}, hi_{0, 0, 0};
  std::array<KnotVector, 3> high_, low_;
  std::array<int, 4> offset_{0, 0, 0, 0};
  // univariate()'s tables: per space and direction, poly_[s][d][(e (p + 1) + j) (p + 1) + m] the coefficient
  // of t^m of function j on element e, t = (x - mid_[d][e]) inv_h_[d][e] (the spaces share their elements).
  std::array<std::array<std::vector<double>, 3>, 2> poly_;
  std::array<std::vector<double>, 3> mid_, inv_h_;
  std::shared_ptr<const geometry::Patch> map_;  // (mapped(): the geometry; null on a box)
  Vec3 param_scale_ = Vec3::Ones();             // c_d (from_patch_parameters)
};

}  // namespace cellfsi::fluid::dc
