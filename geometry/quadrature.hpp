#pragma once
// Gauss-Legendre rules and quadrature over the elements (non-empty knot spans) of a patch.
#include <vector>

#include "geometry/patch.hpp"

namespace cellfsi::geometry {

/// n-point Gauss-Legendre rule on [-1, 1] (exact for polynomials of degree 2n - 1).
struct GaussRule {
  std::vector<double> points;
  std::vector<double> weights;
};
const GaussRule& gauss_legendre(int n);  // cached; 1 <= n <= 64

/// A quadrature point of an element: parametric coordinates and the weight of the parametric measure
/// (Gauss weight times the element's parametric volume / 2^P). Physical measures multiply by |det J|.
struct QuadraturePoint {
  Param xi{0, 0, 0};
  double weight = 0;
};

/// Tensor Gauss rule with n_gauss[d] points per direction on element e of the patch.
void element_quadrature(const Patch& patch, const Index3& e, const Index3& n_gauss,
                        std::vector<QuadraturePoint>& out);

/// Default number of Gauss points for a direction: degree + 1 (exact for the mass matrix of a B-spline
/// space with affine geometry), plus `extra`.
Index3 default_gauss(const Patch& patch, int extra = 0);

}  // namespace cellfsi::geometry
