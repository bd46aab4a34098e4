#pragma once
// Shared helpers of the geometry tests: reference values computed independently of the kernel.
#include <cmath>
#include <numbers>
#include <random>
#include <tuple>
#include <utility>

namespace cellfsi::geometry::testing {

/// Complete elliptic integral of the second kind E(m), m = k^2, by the arithmetic-geometric mean (to
/// round-off).
inline double elliptic_e(double m) {
  double a = 1.0, b = std::sqrt(1.0 - m), c2sum = m / 2.0, pow2 = 0.5;
  for (int i = 0; i < 40 && std::abs(a - b) > 1e-17 * a; ++i) {
    const double an = 0.5 * (a + b), bn = std::sqrt(a * b), cn = 0.5 * (a - b);
    pow2 *= 2.0;
    c2sum += pow2 * cn * cn;
    a = an;
    b = bn;
  }
  return std::numbers::pi / (2.0 * a) * (1.0 - c2sum);
}

/// Perimeter of an ellipse with semi-axes a >= b: 4 a E(1 - b^2/a^2).
inline double ellipse_perimeter(double a, double b) {
  if (a < b) std::swap(a, b);
  return 4.0 * a * elliptic_e(1.0 - b * b / (a * a));
}

/// Surface area of a prolate spheroid with polar semi-axis a > equatorial b.
inline double prolate_area(double a, double b) {
  const double e = std::sqrt(1.0 - b * b / (a * a));
  return 2.0 * std::numbers::pi * b * b * (1.0 + a / (b * e) * std::asin(e));
}

inline double rel(double a, double b) { return std::abs(a - b) / std::abs(b); }

/// Integral of f over [a, b] by composite 20-point Gauss-Legendre on `pieces` equal parts, the nodes found by
/// Newton's method on the Legendre polynomial (independent of the kernel's rules): round-off accurate for
/// analytic integrands.
template <class F>
double gauss_integral(F f, double a, double b, int pieces = 64) {
  constexpr int n = 20;
  double x[n], w[n];
  for (int i = 0; i < n; ++i) {
    double z = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5)), dp = 1;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = z;  // P_0, P_1; then the recurrence up to P_n
      for (int k = 2; k <= n; ++k)
        std::tie(p0, p1) = std::pair(p1, ((2 * k - 1) * z * p1 - (k - 1) * p0) / k);
      dp = n * (z * p1 - p0) / (z * z - 1);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    x[i] = z, w[i] = 2 / ((1 - z * z) * dp * dp);
  }
  double sum = 0;
  const double h = (b - a) / pieces;
  for (int e = 0; e < pieces; ++e)
    for (int i = 0; i < n; ++i) sum += 0.5 * h * w[i] * f(a + h * (e + 0.5 * (x[i] + 1)));
  return sum;
}

}  // namespace cellfsi::geometry::testing
