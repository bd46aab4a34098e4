#pragma once
// Sum factorisation of the divergence-conforming bases over blocks of elements
// (fluid/div_conforming/dc_space.hpp).
//
// Every component of the space is a tensor product: at a tensor rule's point q = (q0, q1, q2), function
// a = (j0, j1, j2) of component c has the value B0[q0][j0] B1[q1][j1] B2[q2][j2], the factor of direction d
// taken from the high space where d == c, the low one otherwise (every direction for the pressure). A field's
// value and gradient at all points of an element are then three contractions, one direction at a time,
// instead of one product with the n_q x n_a matrix of the whole basis: for a velocity component of the 3D
// space at k' = 2 (4 x 3 x 3 functions, the fluid's 4 x 4 x 4 Gauss points) 1488 multiply-adds for the value
// and the gradient against 64 x 36 x 4 = 9216. The transposed contractions test point values against the
// functions, at the same cost.
//
// The kernels work on a block of m elements that share their factors (the fluid's basis classes: elements
// away from the walls, the same offset from a wall), stored with the element fastest, x[k * m + e], so that
// every inner loop runs over the block's elements.
#include <array>
#include <vector>

#include "fluid/div_conforming/dc_space.hpp"
#include "geometry/basis.hpp"

namespace cellfsi::fluid::dc {

/// One component's univariate factors on one element at a tensor rule's points: per direction d, n[d]
/// functions and nq[d] points, value[d][q * n[d] + j] and its derivative deriv[d][...] (physical). Directions
/// beyond the space's dimension have one function of value 1 at one point (derivative 0).
struct ComponentFactors {
  std::array<int, 3> n{1, 1, 1}, nq{1, 1, 1};
  std::array<std::vector<double>, 3> value, deriv;
  int n_functions() const { return n[0] * n[1] * n[2]; }
  int n_points() const { return nq[0] * nq[1] * nq[2]; }
};

/// The most points per direction a rule may have (the contractions' terms are counted at compile time).
inline constexpr int kMaxRulePoints = 10;

/// The factors of component c (c < dim: velocity, c == dim: pressure) of `space` on element e at the points
/// of `rule` (the factors evaluate() multiplies). Throws std::invalid_argument for a rule of more than
/// kMaxRulePoints points in a direction.
ComponentFactors component_factors(const DivConformingSpace& space, int c, const Index3& e,
                                   const TensorRule& rule);

/// The field with coefficients u[a * m + e] (a: the component's functions, direction 0 fastest) at the points
/// of the m elements: value[q * m + e] (where value is not null) and, where grad is not null, grad[j][q * m +
/// e] = d/dx_j for j < 3 (directions beyond the space's dimension give 0). scratch: kept by the caller (no
/// allocation once sized).
void sum_factorized_values(const ComponentFactors& f, int m, const double* u, double* value,
                           const std::array<double*, 3>* grad, std::vector<double>& scratch);

/// The transpose: out[a * m + e] = sum_q (r_value[q m + e] N_a(x_q) + sum_j r_grad[j][q m + e]
/// dN_a/dx_j(x_q)). r_grad may be null (values only); out is overwritten.
void sum_factorized_test(const ComponentFactors& f, int m, const double* r_value,
                         const std::array<const double*, 3>* r_grad, double* out,
                         std::vector<double>& scratch);

/// The same at one point of an element (the immersed points): per space s (0: low, 1: high) and direction d,
/// the n[s][d] nonzero functions' values and derivatives at x[d] (directions beyond the space's dimension:
/// one function of value 1, derivative 0).
struct PointFactors {
  static constexpr int kMax = geometry::kMaxDegree + 2;
  int n[2][3] = {{1, 1, 1}, {1, 1, 1}};
  double value[2][3][kMax] = {}, deriv[2][3][kMax] = {};
};
void point_factors(const DivConformingSpace& space, const Index3& e, const Vec3& x, PointFactors& out);

/// Component c's field at the point from its coefficients u[a] on the element (direction 0 fastest): the
/// value, and its gradient into grad[0..2] where grad is not null. (The immersed points' residual through the
/// whole basis at each point took 0.15 s of each residual at 64^3 on two ranks, 0.09 s this way.)
double point_value(const PointFactors& f, int c, const double* u, double* grad);

/// Adds r_value N_a(x) + sum_j r_grad[j] dN_a/dx_j(x) to out[a] for component c's functions on the element;
/// r_grad: three values (0 beyond the space's dimension), not null.
void point_test(const PointFactors& f, int c, double r_value, const double* r_grad, double* out);

}  // namespace cellfsi::fluid::dc
