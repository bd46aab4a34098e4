#pragma once
// Shared helpers of the geometry tests: reference values computed independently of the kernel.
#include <cmath>
#include <numbers>
#include <random>

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

}  // namespace cellfsi::geometry::testing
