#include "geometry/basis.hpp"

#include <stdexcept>

namespace cellfsi::geometry {

void bspline_basis(const KnotVector& kv, int span, double u, int n_deriv, double* ders) {
  const int p = kv.degree();
  if (p > kMaxDegree) throw std::invalid_argument("bspline_basis: degree exceeds kMaxDegree");
  const auto& U = kv.knots();
  constexpr int M = kMaxDegree + 1;
  double ndu[M][M], left[M], right[M], a[2][M];

  ndu[0][0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - U[span + 1 - j];
    right[j] = U[span + j] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      ndu[j][r] = right[r + 1] + left[j - r];  // lower triangle: knot differences
      const double temp = ndu[r][j - 1] / ndu[j][r];
      ndu[r][j] = saved + right[r + 1] * temp;  // upper triangle: basis values
      saved = left[j - r] * temp;
    }
    ndu[j][j] = saved;
  }
  for (int j = 0; j <= p; ++j) ders[j] = ndu[j][p];

  for (int k = 1; k <= n_deriv; ++k)
    for (int j = 0; j <= p; ++j) ders[k * (p + 1) + j] = 0.0;
  if (n_deriv == 0) return;

  for (int r = 0; r <= p; ++r) {
    int s1 = 0, s2 = 1;
    a[0][0] = 1.0;
    for (int k = 1; k <= n_deriv && k <= p; ++k) {
      double d = 0.0;
      const int rk = r - k, pk = p - k;
      if (r >= k) {
        a[s2][0] = a[s1][0] / ndu[pk + 1][rk];
        d = a[s2][0] * ndu[rk][pk];
      }
      const int j1 = (rk >= -1) ? 1 : -rk;
      const int j2 = (r - 1 <= pk) ? k - 1 : p - r;
      for (int j = j1; j <= j2; ++j) {
        a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j];
        d += a[s2][j] * ndu[rk + j][pk];
      }
      if (r <= pk) {
        a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
        d += a[s2][k] * ndu[r][pk];
      }
      ders[k * (p + 1) + r] = d;
      std::swap(s1, s2);
    }
  }
  double factor = p;
  for (int k = 1; k <= n_deriv && k <= p; ++k) {
    for (int j = 0; j <= p; ++j) ders[k * (p + 1) + j] *= factor;
    factor *= (p - k);
  }
}

}  // namespace cellfsi::geometry
