#pragma once
// Step 3 of the paper's solid (Sec. 2.3): the control variables from values at the collocation points,
// c = R^{-1} v, where R_{pk} = R_k(xi_p) is the patch's rational basis at its Greville points.
//
// For a NURBS patch R = D^{-1} (A_2 (x) A_1 (x) A_0) W, with A_d the univariate B-spline collocation matrix
// of direction d (m_d x m_d, a closed direction's last function folded onto its first), W the control
// weights (diagonal) and D the weight function at the points (diagonal). So
//   c = W^{-1} (A_2^{-1} (x) A_1^{-1} (x) A_0^{-1}) D v,
// applied one direction at a time: the sparse LU of each banded A_d (cyclic in a closed direction) solved
// for all the lines of the patch along d at once, O(n p) per column, instead of the triangular solves of a
// sparse LU of the n x n matrix (a 3D membrane's 44 892 unknowns: 6.2 M entries in its COLAMD-ordered
// factors). The split needs one weight per unknown: where a closed direction's folded layers carry
// different weights, R is not of this form and the solver falls back to a sparse LU of R itself.
#include <array>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <Eigen/Sparse>

#include "geometry/patch.hpp"

namespace cellfsi::solid {

class CollocationSolver {
 public:
  /// The patch's collocation points are its Greville points per direction; a closed direction with an open
  /// knot vector (a membrane's seam: first and last control layers coincide) has its last control layer
  /// folded onto the first, as one unknown, and its duplicate last point dropped, so that R is square. Points
  /// and unknowns are numbered a + m_0 (b + m_1 c). R is assembled from Patch::basis; the
  /// direction-by-direction form is used only if it reproduces R's products to round-off. Throws
  /// std::runtime_error if R is singular.
  explicit CollocationSolver(const geometry::Patch& patch);

  /// Points (and unknowns) in direction d (1 beyond the patch's parametric dimension).
  int n_points(int d) const { return m_[d]; }
  /// Whether direction d's last control layer is folded onto its first.
  bool folded(int d) const { return fold_[d]; }
  /// The points' abscissae in direction d.
  const std::vector<double>& abscissae(int d) const { return tau_[d]; }
  /// The unknown of the patch's control point k.
  int unknown(int k) const { return unknown_[k]; }

  /// R (points x unknowns): values at the points from control variables, R c.
  const Eigen::SparseMatrix<double>& matrix() const { return matrix_; }

  /// c with R c = v, column by column (v: n x k).
  Eigen::MatrixXd solve(const Eigen::MatrixXd& values) const;
  /// An estimate of solve()'s operations for `columns` right-hand sides (-log_view's counts).
  double solve_operations(int columns) const;
  /// Whether solve() goes direction by direction (else: the sparse LU of R).
  bool by_direction() const { return by_direction_; }
  /// Why the sparse LU is used (empty when by_direction()).
  const std::string& fallback_reason() const { return fallback_reason_; }

 private:
  /// X := (M_2 (x) M_1 (x) M_0) X, column by column, where op(d, Y) sets Y := M_d Y for an m_d x k matrix Y
  /// (Y's columns: the lines of the patch along direction d).
  template <class Op>
  void apply(Eigen::MatrixXd& x, const Op& op) const;
  std::array<int, 3> m_{1, 1, 1};
  std::array<bool, 3> fold_{false, false, false};
  std::array<std::vector<double>, 3> tau_{{{0.0}, {0.0}, {0.0}}};
  std::vector<int> unknown_;
  Eigen::SparseMatrix<double> matrix_;
  bool by_direction_ = false;
  std::string fallback_reason_;
  std::array<Eigen::SparseMatrix<double>, 3> univariate_;  // A_d
  /// Each direction's inverse, dense (m_d <= a few hundred): solve() multiplies by it, a matrix product over
  /// all the lines at once (a sparse LU's substitutions go column by column: 1.6 times the time of the
  /// kinematic update's step 3 for the 64^3 compound capsule's bodies, 10 500 and 11 628 points).
  std::array<Eigen::MatrixXd, 3> univariate_inverse_;
  Eigen::VectorXd point_weight_;    // D: the weight function at each point
  Eigen::VectorXd inverse_weight_;  // W^{-1}: one per unknown
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu_;
};

}  // namespace cellfsi::solid
