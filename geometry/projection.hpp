#pragma once
// Fitting functions of one variable into a univariate spline space: L2 projection (open or periodic
// vectors; exact, up to round-off, for functions in the space) and interpolation at Greville points (open
// vectors; reproduces the end values exactly).
#include <functional>
#include <vector>

#include <Eigen/Dense>

#include "geometry/knot_vector.hpp"

namespace cellfsi::geometry {

/// f(u) returns a vector of n_comp components. Returns coefficients as an n_basis x n_comp matrix.
using VectorFunction = std::function<Eigen::VectorXd(double)>;

/// L2 projection on [a, b] with `n_gauss` points per element (0: enough for degree-2p polynomials plus 2).
/// For periodic vectors the folded basis is used. Exact for f in the space (up to round-off).
Eigen::MatrixXd l2_project(const KnotVector& kv, int n_comp, const VectorFunction& f, int n_gauss = 0);

/// Interpolation at the Greville abscissae (open vectors; periodic vectors are folded and interpolated at
/// their periodic Greville points).
Eigen::MatrixXd greville_interpolate(const KnotVector& kv, int n_comp, const VectorFunction& f);

/// Interpolation at the Greville abscissae of an open vector with the first derivatives (with respect to
/// the knot parameter) prescribed at both ends, in place of the values at the second and the second-to-last
/// abscissae (e.g. a profile leaving an axis of revolution at a right angle). Needs >= 4 basis functions.
Eigen::MatrixXd greville_interpolate_clamped(const KnotVector& kv, int n_comp, const VectorFunction& f,
                                             const Eigen::VectorXd& slope_start,
                                             const Eigen::VectorXd& slope_end);

/// The (folded) spline with coefficients c evaluated at u (derivative order n_deriv <= 2).
Eigen::VectorXd evaluate_spline(const KnotVector& kv, const Eigen::MatrixXd& c, double u, int n_deriv = 0);

}  // namespace cellfsi::geometry
