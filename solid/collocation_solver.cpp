#include "solid/collocation_solver.hpp"

#include <cmath>
#include <random>
#include <stdexcept>

#include "geometry/basis.hpp"

namespace cellfsi::solid {

CollocationSolver::CollocationSolver(const geometry::Patch& patch) {
  for (int d = 0; d < patch.param_dim(); ++d) {
    fold_[d] = patch.closed(d) && !patch.knots(d).periodic();
    m_[d] = patch.n_control(d) - (fold_[d] ? 1 : 0);
    tau_[d] = patch.knots(d).greville();
    tau_[d].resize(m_[d]);
  }
  const std::array<int, 3>& m = m_;
  const std::array<bool, 3>& fold = fold_;
  const std::array<std::vector<double>, 3>& tau = tau_;
  const int n = m[0] * m[1] * m[2];
  unknown_.resize(patch.n_control());
  for (int k = 0; k < patch.n_control(); ++k) {
    geometry::Index3 i = patch.control_multi_index(k);
    for (int d = 0; d < 3; ++d)
      if (fold[d] && i[d] == patch.n_control(d) - 1) i[d] = 0;
    unknown_[k] = i[0] + m[0] * (i[1] + m[1] * i[2]);
  }
  // R, row by row from the patch's rational basis (a folded layer's functions add onto the first layer's).
  std::vector<Eigen::Triplet<double>> trip;
  geometry::BasisValues bv;
  int row = 0;
  for (int c = 0; c < m[2]; ++c)
    for (int b = 0; b < m[1]; ++b)
      for (int a = 0; a < m[0]; ++a, ++row) {
        patch.basis(geometry::Param{tau[0][a], tau[1][b], tau[2][c]}, 0, bv);
        for (int k = 0; k < bv.n; ++k)
          if (bv.value[k] != 0.0) trip.emplace_back(row, unknown_[bv.index[k]], bv.value[k]);
      }
  matrix_.resize(n, n);
  matrix_.setFromTriplets(trip.begin(), trip.end());
  const Eigen::SparseMatrix<double>& assembled = matrix_;

  // The univariate collocation matrices, as Patch::basis evaluates them (the span of find_span, functions
  // folded), a closed direction's last function added to its first.
  std::array<Eigen::MatrixXd, 3> A;
  for (int d = 0; d < 3; ++d) {
    A[d] = Eigen::MatrixXd::Identity(m[d], m[d]);
    if (d >= patch.param_dim()) continue;
    A[d].setZero();
    const geometry::KnotVector& kv = patch.knots(d);
    const int p = kv.degree();
    std::vector<double> value(p + 1);
    for (int a = 0; a < m[d]; ++a) {
      const double u = kv.normalize(tau[d][a]);
      const int span = kv.find_span(u);
      geometry::bspline_basis(kv, span, u, 0, value.data());
      for (int j = 0; j <= p; ++j) {
        int i = kv.fold(span - p + j);
        if (fold[d] && i == patch.n_control(d) - 1) i = 0;
        A[d](a, i) += value[j];
      }
    }
  }

  // One weight per unknown: a folded layer's weights must equal those of the layer it is folded onto.
  Eigen::VectorXd weight = Eigen::VectorXd::Constant(n, -1.0);
  for (int k = 0; k < patch.n_control(); ++k) {
    const int r = unknown_[k];
    const double w = patch.weights()[k];
    if (weight[r] < 0)
      weight[r] = w;
    else if (std::abs(weight[r] - w) > 1e-14 * std::abs(w))
      fallback_reason_ = "a closed direction's folded control layers carry different weights";
  }

  if (fallback_reason_.empty()) {
    for (int d = 0; d < 3; ++d) {
      univariate_[d] = A[d].sparseView();
      univariate_[d].makeCompressed();
      Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(univariate_[d]);
      if (lu.info() != Eigen::Success) {
        fallback_reason_ = "direction " + std::to_string(d) + "'s collocation matrix is singular";
        break;
      }
      const Eigen::MatrixXd identity = Eigen::MatrixXd::Identity(m_[d], m_[d]);
      univariate_inverse_[d] = lu.solve(identity);
    }
  }
  if (fallback_reason_.empty()) {
    const auto multiply = [this](int d, Eigen::MatrixXd& y) { y = univariate_[d] * y; };
    // D = the weight function at the points, (A_2 (x) A_1 (x) A_0) w.
    Eigen::MatrixXd W = weight;
    apply(W, multiply);
    point_weight_ = W.col(0);
    inverse_weight_ = weight.cwiseInverse();
    // The split must reproduce R: compare D^{-1} (x)A W c with R c for a random c. The two sums differ only
    // in their order: each entry of R is a product of three univariate values and two weights, so a few
    // units of round-off relative to |c|'s size (the basis is a partition of unity).
    std::mt19937 gen(7);
    std::uniform_real_distribution<double> dist(-1.0, 1.0);
    Eigen::MatrixXd c(n, 1);
    for (int k = 0; k < n; ++k) c(k, 0) = dist(gen);
    Eigen::MatrixXd split = weight.asDiagonal() * c;
    apply(split, multiply);
    split = point_weight_.cwiseInverse().asDiagonal() * split;
    const Eigen::VectorXd direct = assembled * c.col(0);
    if ((split.col(0) - direct).lpNorm<Eigen::Infinity>() > 1e-12)
      fallback_reason_ = "the patch's basis at its points is not the tensor product of its directions'";
  }
  by_direction_ = fallback_reason_.empty();
  if (!by_direction_) {
    lu_.compute(assembled);
    if (lu_.info() != Eigen::Success) throw std::runtime_error("the collocation matrix is singular");
  }
}

template <class Op>
void CollocationSolver::apply(Eigen::MatrixXd& x, const Op& op) const {
  const int m0 = m_[0], m1 = m_[1], m2 = m_[2];
  const Eigen::Index k = x.cols();
  if (m0 > 1) {  // the columns of x, m_0 rows at a time, are already direction 0's lines
    Eigen::MatrixXd y = Eigen::Map<Eigen::MatrixXd>(x.data(), m0, x.size() / m0);
    op(0, y);
    Eigen::Map<Eigen::MatrixXd>(x.data(), m0, x.size() / m0) = y;
  }
  Eigen::MatrixXd y;
  if (m1 > 1) {  // line (a, c) of column j: entries a + m_0 (b + m_1 c), b = 0..m_1-1
    y.resize(m1, m0 * m2 * k);
    for (Eigen::Index j = 0; j < k; ++j)
      for (int c = 0; c < m2; ++c)
        for (int b = 0; b < m1; ++b)
          for (int a = 0; a < m0; ++a) y(b, a + m0 * (c + m2 * j)) = x(a + m0 * (b + m1 * c), j);
    op(1, y);
    for (Eigen::Index j = 0; j < k; ++j)
      for (int c = 0; c < m2; ++c)
        for (int b = 0; b < m1; ++b)
          for (int a = 0; a < m0; ++a) x(a + m0 * (b + m1 * c), j) = y(b, a + m0 * (c + m2 * j));
  }
  if (m2 > 1) {  // line (a, b) of column j: a transpose of the column's m_0 m_1 x m_2 block
    const int s = m0 * m1;
    y.resize(m2, s * k);
    for (Eigen::Index j = 0; j < k; ++j)
      y.middleCols(s * j, s) = Eigen::Map<const Eigen::MatrixXd>(x.col(j).data(), s, m2).transpose();
    op(2, y);
    for (Eigen::Index j = 0; j < k; ++j)
      Eigen::Map<Eigen::MatrixXd>(x.col(j).data(), s, m2) = y.middleCols(s * j, s).transpose();
  }
}

double CollocationSolver::solve_operations(int columns) const {
  const double n = static_cast<double>(m_[0]) * m_[1] * m_[2];
  if (!by_direction_) {  // (the sparse LU's two substitutions)
    const double nnz = static_cast<double>(lu_.nnzL() + lu_.nnzU());
    return columns * 2.0 * nnz;
  }
  // Per column: the two weight scalings and, per direction d, a product by its m_d x m_d inverse on each
  // line.
  double per_column = 2.0 * n;
  for (int d = 0; d < 3; ++d)
    if (m_[d] > 1) per_column += 2.0 * n * m_[d];
  return columns * per_column;
}

Eigen::MatrixXd CollocationSolver::solve(const Eigen::MatrixXd& values) const {
  if (!by_direction_) return lu_.solve(values);
  Eigen::MatrixXd x = point_weight_.asDiagonal() * values;
  apply(x, [this](int d, Eigen::MatrixXd& y) { y = univariate_inverse_[d] * y; });
  return inverse_weight_.asDiagonal() * x;
}

}  // namespace cellfsi::solid
