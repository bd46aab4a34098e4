#include "geometry/refine.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "geometry/basis.hpp"
#include "geometry/projection.hpp"

namespace cellfsi::geometry {

namespace {

using Hom = Eigen::Vector4d;  // homogeneous control point (w x, w y, w z, w)

void require_open(const Patch& patch, int dir, const char* what) {
  if (dir < 0 || dir >= patch.param_dim())
    throw std::invalid_argument(std::string(what) + ": direction " + std::to_string(dir) + " is not in [0, " +
                                std::to_string(patch.param_dim() - 1) + "]");
  if (patch.knots(dir).periodic())
    throw std::invalid_argument(
        std::string(what) +
        ": periodic directions are built at their resolution by the builders, not refined");
}

/// Gathers the control net as fibers along dir: fibers[f][i] is the i-th homogeneous point of fiber f.
std::vector<std::vector<Hom>> gather_fibers(const Patch& patch, int dir, std::vector<Index3>& fiber_base) {
  const int n = patch.n_control(dir);
  std::vector<std::vector<Hom>> fibers;
  fiber_base.clear();
  for (int idx = 0; idx < patch.n_control(); ++idx) {
    Index3 m = patch.control_multi_index(idx);
    if (m[dir] != 0) continue;
    fiber_base.push_back(m);
    std::vector<Hom> fib(n);
    for (int i = 0; i < n; ++i) {
      Index3 mi = m;
      mi[dir] = i;
      const int k = patch.control_index(mi[0], mi[1], mi[2]);
      const double w = patch.weights()[k];
      fib[i] << w * patch.control_points()[k], w;
    }
    fibers.push_back(std::move(fib));
  }
  return fibers;
}

Patch scatter_fibers(const Patch& patch, int dir, const KnotVector& new_kv,
                     const std::vector<Index3>& fiber_base, const std::vector<std::vector<Hom>>& fibers) {
  std::vector<KnotVector> knots = patch.all_knots();
  knots[dir] = new_kv;
  int nc[3] = {1, 1, 1};
  for (int d = 0; d < patch.param_dim(); ++d) nc[d] = knots[d].n_basis();
  const int total = nc[0] * nc[1] * nc[2];
  std::vector<Vec3> cps(total);
  std::vector<double> ws(total);
  for (size_t f = 0; f < fibers.size(); ++f)
    for (int i = 0; i < nc[dir]; ++i) {
      Index3 m = fiber_base[f];
      m[dir] = i;
      const int k = m[0] + nc[0] * (m[1] + nc[1] * m[2]);
      const Hom& h = fibers[f][i];
      ws[k] = h[3];
      cps[k] = h.head<3>() / h[3];
    }
  return Patch(std::move(knots), patch.physical_dim(), std::move(cps), std::move(ws), patch.shifts());
}

int find_span_open(int n, int p, double u, const std::vector<double>& U) {
  if (u >= U[n + 1]) return n;
  int low = p, high = n + 1;
  int mid = (low + high) / 2;
  while (u < U[mid] || u >= U[mid + 1]) {
    if (u < U[mid])
      high = mid;
    else
      low = mid;
    mid = (low + high) / 2;
  }
  return mid;
}

}  // namespace

Patch insert_knots(const Patch& patch, int dir, const std::vector<double>& X) {
  require_open(patch, dir, "insert_knots");
  if (X.empty()) return patch;
  if (!std::is_sorted(X.begin(), X.end())) throw std::invalid_argument("insert_knots: knots must be sorted");
  const KnotVector& kv = patch.knots(dir);
  if (X.front() < kv.a() || X.back() > kv.b())
    throw std::invalid_argument("insert_knots: knots must lie in [a, b] of the direction");
  const int p = kv.degree();
  const std::vector<double>& U = kv.knots();
  const int n = kv.n_basis() - 1;
  const int m = n + p + 1;
  const int r = static_cast<int>(X.size()) - 1;
  const int a = find_span_open(n, p, X.front(), U);
  const int b = find_span_open(n, p, X.back(), U) + 1;
  std::vector<double> Ubar(m + r + 2);
  for (int j = 0; j <= a; ++j) Ubar[j] = U[j];
  for (int j = b + p; j <= m; ++j) Ubar[j + r + 1] = U[j];

  std::vector<Index3> base;
  auto fibers = gather_fibers(patch, dir, base);
  for (auto& Pw : fibers) {
    std::vector<Hom> Qw(n + r + 2);
    for (int j = 0; j <= a - p; ++j) Qw[j] = Pw[j];
    for (int j = b - 1; j <= n; ++j) Qw[j + r + 1] = Pw[j];
    std::vector<double> Ub = Ubar;
    int i = b + p - 1, k = b + p + r;
    for (int j = r; j >= 0; --j) {
      while (X[j] <= U[i] && i > a) {
        Qw[k - p - 1] = Pw[i - p - 1];
        Ub[k] = U[i];
        --k;
        --i;
      }
      Qw[k - p - 1] = Qw[k - p];
      for (int l = 1; l <= p; ++l) {
        const int ind = k - p + l;
        double alfa = Ub[k + l] - X[j];
        if (alfa == 0.0) {
          Qw[ind - 1] = Qw[ind];
        } else {
          alfa /= (Ub[k + l] - U[i - p + l]);
          Qw[ind - 1] = alfa * Qw[ind - 1] + (1.0 - alfa) * Qw[ind];
        }
      }
      Ub[k] = X[j];
      --k;
    }
    Pw = std::move(Qw);
    Ubar = Ub;
  }
  // Ubar of the last fiber holds the full new knot vector (identical for all fibers).
  if (fibers.empty()) throw std::logic_error("insert_knots: patch without control points");
  return scatter_fibers(patch, dir, KnotVector::open(p, Ubar), base, fibers);
}

Patch elevate_degree(const Patch& patch, int dir, int times) {
  require_open(patch, dir, "elevate_degree");
  if (times < 0) throw std::invalid_argument("elevate_degree: times must be >= 0");
  if (times == 0) return patch;
  const KnotVector& kv = patch.knots(dir);
  const int p = kv.degree(), q = p + times;
  if (q > kMaxDegree)
    throw std::invalid_argument("elevate_degree: degree " + std::to_string(q) +
                                " exceeds the supported maximum " + std::to_string(kMaxDegree));
  std::vector<double> U;
  for (double u : kv.breakpoints()) {
    const int mult = kv.multiplicity(u) + times;
    for (int k = 0; k < mult; ++k) U.push_back(u);
  }
  const KnotVector new_kv = KnotVector::open(q, U);

  std::vector<Index3> base;
  auto fibers = gather_fibers(patch, dir, base);
  const int n_fib = static_cast<int>(fibers.size());
  const int n_old = kv.n_basis();
  Eigen::MatrixXd old_coeffs(n_old, 4 * n_fib);
  for (int f = 0; f < n_fib; ++f)
    for (int i = 0; i < n_old; ++i) old_coeffs.block<1, 4>(i, 4 * f) = fibers[f][i].transpose();
  // All fibers are projected at once: one factorisation of the mass matrix.
  const Eigen::MatrixXd c = l2_project(
      new_kv, 4 * n_fib, [&](double u) { return evaluate_spline(kv, old_coeffs, u); }, q + 1);
  for (int f = 0; f < n_fib; ++f) {
    fibers[f].resize(new_kv.n_basis());
    for (int i = 0; i < new_kv.n_basis(); ++i) fibers[f][i] = c.block<1, 4>(i, 4 * f).transpose();
  }
  return scatter_fibers(patch, dir, new_kv, base, fibers);
}

Patch refine_uniform(const Patch& patch, int dir, int n_elements) {
  require_open(patch, dir, "refine_uniform");
  const KnotVector& kv = patch.knots(dir);
  const int n_now = kv.n_elements();
  if (n_elements < n_now || n_elements % n_now != 0)
    throw std::invalid_argument("refine_uniform: direction " + std::to_string(dir) + " has " +
                                std::to_string(n_now) + " elements; the requested count " +
                                std::to_string(n_elements) + " must be a positive multiple of it");
  const int k = n_elements / n_now;
  std::vector<double> X;
  for (int e = 0; e < n_now; ++e) {
    const double lo = kv.element_begin(e), hi = kv.element_end(e);
    for (int s = 1; s < k; ++s) X.push_back(lo + (hi - lo) * s / k);
  }
  return insert_knots(patch, dir, X);
}

Patch isoparametric(const Patch& patch, int dir, double value) {
  const int P = patch.param_dim();
  if (P < 2) throw std::invalid_argument("isoparametric: needs a patch of parametric dimension >= 2");
  if (dir < 0 || dir >= P) throw std::invalid_argument("isoparametric: direction out of range");
  const KnotVector& kv = patch.knots(dir);
  const int p = kv.degree();
  const double u = kv.normalize(value);
  const int span = kv.find_span(u);
  double N[(kMaxDeriv + 1) * (kMaxDegree + 1)];
  bspline_basis(kv, span, u, 0, N);

  std::vector<KnotVector> knots;
  std::array<Vec3, 3> shifts{Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  int other[2], n_other = 0;
  for (int d = 0; d < P; ++d)
    if (d != dir) {
      shifts[n_other] = patch.shift(d);
      other[n_other++] = d;
      knots.push_back(patch.knots(d));
    }
  const int n0 = patch.n_control(other[0]);
  const int n1 = (n_other > 1) ? patch.n_control(other[1]) : 1;
  std::vector<Vec3> cps(n0 * n1);
  std::vector<double> ws(n0 * n1);
  for (int j = 0; j < n1; ++j)
    for (int i = 0; i < n0; ++i) {
      Hom h = Hom::Zero();
      for (int l = 0; l <= p; ++l) {
        const int jj = span - p + l;
        Index3 m{0, 0, 0};
        m[other[0]] = i;
        if (n_other > 1) m[other[1]] = j;
        m[dir] = kv.fold(jj);
        const int k = patch.control_index(m[0], m[1], m[2]);
        const double w = patch.weights()[k];
        const Vec3 X = patch.control_points()[k] + kv.wrap_count(jj) * patch.shift(dir);
        h.head<3>() += N[l] * w * X;
        h[3] += N[l] * w;
      }
      ws[i + n0 * j] = h[3];
      cps[i + n0 * j] = h.head<3>() / h[3];
    }
  return Patch(std::move(knots), patch.physical_dim(), std::move(cps), std::move(ws), shifts);
}

}  // namespace cellfsi::geometry
