#include "geometry/projection.hpp"

#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Sparse>

#include "geometry/basis.hpp"
#include "geometry/quadrature.hpp"

namespace cellfsi::geometry {

Eigen::MatrixXd l2_project(const KnotVector& kv, int n_comp, const VectorFunction& f, int n_gauss) {
  const int p = kv.degree();
  const int n = kv.n_basis();
  if (n_gauss <= 0) n_gauss = p + 2;
  const GaussRule& g = gauss_legendre(n_gauss);
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, n_comp);
  double N[(kMaxDeriv + 1) * (kMaxDegree + 1)];
  for (int e = 0; e < kv.n_elements(); ++e) {
    const double lo = kv.element_begin(e), hi = kv.element_end(e), half = 0.5 * (hi - lo);
    const int span = kv.element_span(e);
    for (int q = 0; q < n_gauss; ++q) {
      const double u = lo + half * (g.points[q] + 1.0), w = half * g.weights[q];
      bspline_basis(kv, span, u, 0, N);
      const Eigen::VectorXd fu = f(u);
      if (fu.size() != n_comp)
        throw std::invalid_argument("l2_project: function returned wrong number of components");
      for (int i = 0; i <= p; ++i) {
        const int I = kv.fold(span - p + i);
        rhs.row(I) += w * N[i] * fu.transpose();
        for (int j = 0; j <= p; ++j) trip.emplace_back(I, kv.fold(span - p + j), w * N[i] * N[j]);
      }
    }
  }
  Eigen::SparseMatrix<double> M(n, n);
  M.setFromTriplets(trip.begin(), trip.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(M);
  if (solver.info() != Eigen::Success)
    throw std::runtime_error("l2_project: mass matrix factorisation failed");
  Eigen::MatrixXd c = solver.solve(rhs);
  // One step of iterative refinement keeps the projection exact to round-off for moderately
  // ill-conditioned (high degree, graded) mass matrices.
  c += solver.solve(rhs - M * c);
  return c;
}

namespace {
/// Collocation at the Greville abscissae; when `ends` is given, the rows of the second and the second-to-last
/// abscissae prescribe the first derivative at the two ends instead (ends->first, ends->second).
Eigen::MatrixXd collocate(const KnotVector& kv, int n_comp, const VectorFunction& f,
                          const std::pair<Eigen::VectorXd, Eigen::VectorXd>* ends, const char* who) {
  const int p = kv.degree();
  const int n = kv.n_basis();
  const std::vector<double> tau = kv.greville();
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::MatrixXd rhs(n, n_comp);
  double N[(kMaxDeriv + 1) * (kMaxDegree + 1)];
  for (int i = 0; i < n; ++i) {
    const bool slope = ends && (i == 1 || i == n - 2);
    const double u = slope ? (i == 1 ? kv.knots().front() : kv.knots().back()) : tau[i];
    const int span = kv.find_span(u);
    bspline_basis(kv, span, u, slope ? 1 : 0, N);
    for (int j = 0; j <= p; ++j) trip.emplace_back(i, kv.fold(span - p + j), N[(slope ? p + 1 : 0) + j]);
    const Eigen::VectorXd fu = slope ? (i == 1 ? ends->first : ends->second) : f(u);
    if (fu.size() != n_comp) throw std::invalid_argument(std::string(who) + ": wrong number of components");
    rhs.row(i) = fu.transpose();
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(trip.begin(), trip.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> solver;
  solver.compute(A);
  if (solver.info() != Eigen::Success)
    throw std::runtime_error(std::string(who) + ": collocation matrix is singular");
  return solver.solve(rhs);
}
}  // namespace

Eigen::MatrixXd greville_interpolate(const KnotVector& kv, int n_comp, const VectorFunction& f) {
  return collocate(kv, n_comp, f, nullptr, "greville_interpolate");
}

Eigen::MatrixXd greville_interpolate_clamped(const KnotVector& kv, int n_comp, const VectorFunction& f,
                                             const Eigen::VectorXd& slope_start,
                                             const Eigen::VectorXd& slope_end) {
  if (kv.periodic() || kv.n_basis() < 4)
    throw std::invalid_argument(
        "greville_interpolate_clamped: needs an open knot vector with >= 4 functions, got " +
        std::to_string(kv.n_basis()) + (kv.periodic() ? " (periodic)" : ""));
  const std::pair<Eigen::VectorXd, Eigen::VectorXd> ends{slope_start, slope_end};
  return collocate(kv, n_comp, f, &ends, "greville_interpolate_clamped");
}

Eigen::VectorXd evaluate_spline(const KnotVector& kv, const Eigen::MatrixXd& c, double u, int n_deriv) {
  const int p = kv.degree();
  double N[(kMaxDeriv + 1) * (kMaxDegree + 1)];
  const int span = kv.find_span(u);
  bspline_basis(kv, span, kv.normalize(u), n_deriv, N);
  Eigen::VectorXd v = Eigen::VectorXd::Zero(c.cols());
  for (int j = 0; j <= p; ++j) v += N[n_deriv * (p + 1) + j] * c.row(kv.fold(span - p + j)).transpose();
  return v;
}

}  // namespace cellfsi::geometry
