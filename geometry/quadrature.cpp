#include "geometry/quadrature.hpp"

#include <cmath>
#include <map>
#include <mutex>
#include <numbers>
#include <stdexcept>
#include <string>

namespace cellfsi::geometry {

namespace {
GaussRule compute_gauss(int n) {
  // Roots of the Legendre polynomial by Newton from Chebyshev-like initial guesses.
  GaussRule r;
  r.points.resize(n);
  r.weights.resize(n);
  for (int i = 0; i < (n + 1) / 2; ++i) {
    double x = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    double dp = 0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = x;
      for (int k = 2; k <= n; ++k) {
        const double pk = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = pk;
      }
      if (n == 1) p0 = 1.0, p1 = x;
      dp = n * (x * p1 - p0) / (x * x - 1.0);
      const double dx = p1 / dp;
      x -= dx;
      if (std::abs(dx) < 1e-16) break;
    }
    // recompute derivative at the converged root
    double p0 = 1.0, p1 = x;
    for (int k = 2; k <= n; ++k) {
      const double pk = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
      p0 = p1;
      p1 = pk;
    }
    dp = (n == 1) ? 1.0 : n * (x * p1 - p0) / (x * x - 1.0);
    const double w = 2.0 / ((1.0 - x * x) * dp * dp);
    r.points[i] = -x;
    r.points[n - 1 - i] = x;
    r.weights[i] = r.weights[n - 1 - i] = w;
  }
  if (n % 2 == 1) r.points[n / 2] = 0.0;
  return r;
}
}  // namespace

const GaussRule& gauss_legendre(int n) {
  if (n < 1 || n > 64)
    throw std::invalid_argument("gauss_legendre: n must be in [1, 64], got " + std::to_string(n));
  static std::map<int, GaussRule> cache;
  static std::mutex mutex;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find(n);
  if (it == cache.end()) it = cache.emplace(n, compute_gauss(n)).first;
  return it->second;
}

void element_quadrature(const Patch& patch, const Index3& e, const Index3& n_gauss,
                        std::vector<QuadraturePoint>& out) {
  const int P = patch.param_dim();
  Param lo, hi;
  patch.element_bounds(e, lo, hi);
  const GaussRule* rules[3] = {nullptr, nullptr, nullptr};
  int n[3] = {1, 1, 1};
  for (int d = 0; d < P; ++d) {
    rules[d] = &gauss_legendre(n_gauss[d]);
    n[d] = n_gauss[d];
  }
  out.clear();
  out.reserve(n[0] * n[1] * n[2]);
  for (int c = 0; c < n[2]; ++c)
    for (int b = 0; b < n[1]; ++b)
      for (int a = 0; a < n[0]; ++a) {
        const int loc[3] = {a, b, c};
        QuadraturePoint q;
        q.weight = 1.0;
        for (int d = 0; d < P; ++d) {
          const double half = 0.5 * (hi[d] - lo[d]);
          q.xi[d] = lo[d] + half * (rules[d]->points[loc[d]] + 1.0);
          q.weight *= half * rules[d]->weights[loc[d]];
        }
        out.push_back(q);
      }
}

Index3 default_gauss(const Patch& patch, int extra) {
  Index3 n{1, 1, 1};
  for (int d = 0; d < patch.param_dim(); ++d) n[d] = patch.degree(d) + 1 + extra;
  return n;
}

}  // namespace cellfsi::geometry
