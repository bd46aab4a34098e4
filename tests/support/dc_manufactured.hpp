#pragma once
// The divergence-conforming solver's manufactured steady flow in the unit channel, shared by its convergence
// test (tests/convergence/test_div_conforming_convergence.cpp) and the mapped-space test
// (tests/unit/fluid/test_dc_mapped_fluid.cpp).
#include <cmath>
#include <numbers>

#include "geometry/patch.hpp"

namespace cellfsi::test_support {

using geometry::Mat3;
using geometry::Vec3;

/// On the unit channel (periodic x, walls y = 0, 1): psi = sin(2 pi x) sin(pi y), v = (psi_y, -psi_x), so
/// div v = 0, v.n = 0 on the walls and the tangential wall velocity varies along them (Nitsche with a wall
/// velocity field); p = P sin(2 pi x) cos(pi y). rho = nu = 1; f = 5 pi^2 nu v + c (v.grad)v + grad p.
/// The pressure's amplitude P: the velocity does not depend on it (pressure robustness), and P = 100 makes
/// the pressure's own approximation error, of order k + 1, dominate its error from the first mesh on (with P
/// = 1 a part of order k + 2 driven by the velocity is as large on these meshes: rates 4.1, 3.8, 3.5 for k =
/// 2).
struct Manufactured {
  double nu = 1.0;
  double P = 100.0;
  Vec3 v(const Vec3& x) const {
    return Vec3(
        std::numbers::pi * std::sin(2 * std::numbers::pi * x[0]) * std::cos(std::numbers::pi * x[1]),
        -2 * std::numbers::pi * std::cos(2 * std::numbers::pi * x[0]) * std::sin(std::numbers::pi * x[1]), 0);
  }
  Mat3 grad(const Vec3& x) const {
    const double s2 = std::sin(2 * std::numbers::pi * x[0]), c2 = std::cos(2 * std::numbers::pi * x[0]);
    const double s1 = std::sin(std::numbers::pi * x[1]), c1 = std::cos(std::numbers::pi * x[1]);
    Mat3 m = Mat3::Zero();
    m(0, 0) = 2 * std::numbers::pi * std::numbers::pi * c2 * c1;
    m(0, 1) = -std::numbers::pi * std::numbers::pi * s2 * s1;
    m(1, 0) = 4 * std::numbers::pi * std::numbers::pi * s2 * s1;
    m(1, 1) = -2 * std::numbers::pi * std::numbers::pi * c2 * c1;
    return m;
  }
  double p(const Vec3& x) const {
    return P * std::sin(2 * std::numbers::pi * x[0]) * std::cos(std::numbers::pi * x[1]);
  }
  Vec3 force(const Vec3& x, double convection) const {
    const Vec3 vv = v(x);
    const Mat3 g = grad(x);
    const Vec3 grad_p(
        P * 2 * std::numbers::pi * std::cos(2 * std::numbers::pi * x[0]) * std::cos(std::numbers::pi * x[1]),
        -P * std::numbers::pi * std::sin(2 * std::numbers::pi * x[0]) * std::sin(std::numbers::pi * x[1]), 0);
    return 5 * std::numbers::pi * std::numbers::pi * nu * vv + convection * (g * vv) + grad_p;
  }
};

}  // namespace cellfsi::test_support
