#pragma once
// Univariate B-spline basis functions and their derivatives (Cox-de Boor; Piegl & Tiller, The NURBS Book,
// A2.3).
#include "geometry/knot_vector.hpp"

namespace cellfsi::geometry {

/// Largest polynomial degree the fixed-size work arrays of the kernel support.
inline constexpr int kMaxDegree = 8;
/// Largest derivative order computed by the kernel.
inline constexpr int kMaxDeriv = 2;

/// Values and derivatives up to order n_deriv (<= kMaxDeriv... any n_deriv <= p is meaningful) of the p + 1
/// B-spline functions nonzero on `span`, at u. Output ders[k * (p + 1) + j] is the k-th derivative of
/// unwrapped function span - p + j. `ders` must hold (n_deriv + 1) * (p + 1) doubles.
void bspline_basis(const KnotVector& kv, int span, double u, int n_deriv, double* ders);

}  // namespace cellfsi::geometry
