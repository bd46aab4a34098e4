#pragma once
// Physical basis functions at the quadrature points of one element, fast: the univariate B-spline values and
// derivatives at the Gauss points are tabulated once per element and direction (the mesh is a tensor
// product), and each quadrature point only forms tensor products, the geometric map from the element's
// control points, and explicit 2x2 / 3x3 inverses. Rational patches are handled (the weight function is
// formed the same way).
#include <array>
#include <vector>

#include "geometry/patch.hpp"

namespace cellfsi::fluid {

/// Values of the n basis functions of an element at its nq quadrature points, in physical coordinates.
struct ElementValues {
  int n = 0, nq = 0;
  geometry::Index3 first{0, 0, 0};                      // unwrapped index of the first function per direction
  std::vector<double> N;                                // N[q * n + k]
  std::vector<double> dN;                               // dN[(q * n + k) * 3 + j] = d N_k / d x_j
  std::vector<double> lapN;                             // lapN[q * n + k]
  std::vector<double> weight;                           // Gauss weight times |det dx/dxi| at q
  std::vector<std::array<std::array<double, 3>, 3>> G;  // tau_M's metric at q (parent coordinates)
  // Axis-affine patches only (tensor true): the basis is a product of univariate factors in physical
  // coordinates too. With k = a_0 + np_0 (a_1 + np_1 a_2) and q = q_0 + nq_0 (q_1 + nq_1 q_2),
  // N[q n + k] = prod_d factor_value[d][q_d np_d + a_d], and dN[(q n + k) 3 + j] is that product with
  // factor_deriv[j] (d / dx_j) in place of factor_value[j] (equal to round-off).
  bool tensor = false;
  int np[3] = {1, 1, 1}, nq1[3] = {1, 1, 1};  // functions and points per direction
  std::vector<double> factor_value[3], factor_deriv[3];
};

class ElementBasis {
 public:
  /// n_gauss points per direction (degree + 1 by default).
  explicit ElementBasis(const geometry::Patch& patch, geometry::Index3 n_gauss = {0, 0, 0});
  /// The element's values. On an axis-affine patch (x_d an affine function of xi_d alone: the builders'
  /// rectangle and box) they depend only on each direction's element class (elements whose univariate tables
  /// agree), so they are computed once per class combination and served from a cache (at most (2p+1)^d
  /// entries). Returns the values: a reference to the cache, or to `scratch` filled for this element. `first`
  /// is the element's first unwrapped function index per direction.
  const ElementValues& evaluate(const geometry::Index3& e, ElementValues& scratch, int first[3]) const;
  bool axis_affine() const { return axis_affine_; }
  int n_points() const { return nq_[0] * nq_[1] * nq_[2]; }

 private:
  const geometry::Patch& patch_;
  int dim_ = 2;
  int np_[3] = {1, 1, 1};  // functions per direction (degree + 1)
  int nq_[3] = {1, 1, 1};  // Gauss points per direction
  bool rational_ = false;
  // table_[d][((e * nq + q) * 3 + k) * np + a]: k-th derivative (k <= 2) of univariate function a of element
  // e in direction d at Gauss point q; gauss_w_[d][e * nq + q]: Gauss weight times the element's parametric
  // half-length.
  std::vector<double> table_[3], gauss_w_[3];
  std::vector<double> parent_scale_[3];  // 2 / (element parametric length), per element and direction
  bool axis_affine_ = false;
  std::vector<int> class_[3];  // element class per direction (axis-affine patches)
  int n_classes_[3] = {1, 1, 1};
  mutable std::vector<ElementValues> cache_;  // by class combination
  mutable std::vector<char> cached_;
  void compute(const geometry::Index3& e, ElementValues& out) const;
};

}  // namespace cellfsi::fluid
