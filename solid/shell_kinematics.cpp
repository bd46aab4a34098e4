#include "solid/shell_kinematics.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include <unsupported/Eigen/AutoDiff>

namespace cellfsi::solid {

namespace {

/// A surface's tangents, unit normal, the area element |A_1 x A_2| and their derivatives along theta_b.
struct SurfaceFrame {
  Vec3 tangent[2];
  Vec3 normal;
  double area = 0;
  Vec3 d_normal[2];  // dN / dtheta_b
  double d_area[2];  // d |A_1 x A_2| / dtheta_b
};

SurfaceFrame surface_frame(const geometry::MapValues& m, const char* which) {
  SurfaceFrame s;
  Vec3 d_tangent[2][2];  // d_tangent[a][b] = d A_a / d theta_b
  for (int a = 0; a < 2; ++a) {
    s.tangent[a] = m.dx.col(a);
    for (int b = 0; b < 2; ++b) d_tangent[a][b] = Vec3(m.d2x[0](a, b), m.d2x[1](a, b), m.d2x[2](a, b));
  }
  const Vec3 c = s.tangent[0].cross(s.tangent[1]);
  s.area = c.norm();
  if (!(s.area > 0) || !std::isfinite(s.area))
    throw std::invalid_argument(std::string("shell_point: the ") + which +
                                " mid-surface is degenerate (A_1 x A_2 = 0) at this point");
  s.normal = c / s.area;
  for (int b = 0; b < 2; ++b) {
    const Vec3 dc = d_tangent[0][b].cross(s.tangent[1]) + s.tangent[0].cross(d_tangent[1][b]);
    s.d_area[b] = s.normal.dot(dc);
    s.d_normal[b] = (dc - s.normal * s.d_area[b]) / s.area;
  }
  return s;
}

/// The current covariant basis's two parts g0 and g1 (ShellBasisDerivative) from the current mid-surface's
/// derivatives m = (a_1, a_2, a_11, a_12, a_22) and the reference area element and its derivatives; T is
/// double or an automatic-differentiation scalar (for their derivatives in m). The caller has checked that
/// a_1 x a_2 is not zero.
template <class T>
void current_basis(const Eigen::Matrix<T, 3, 1> (&m)[5], double ref_area, const double (&ref_d_area)[2],
                   Eigen::Matrix<T, 3, 3>& g0, Eigen::Matrix<T, 3, 3>& g1) {
  using std::sqrt;
  using V = Eigen::Matrix<T, 3, 1>;
  const V d_tangent[2][2] = {{m[2], m[3]}, {m[3], m[4]}};  // d a_a / d theta_b
  const V c = m[0].cross(m[1]);
  const T area = sqrt(c.dot(c));
  const V n = c / area;
  const T lambda3 = ref_area / area;
  g0.col(0) = m[0];
  g0.col(1) = m[1];
  g0.col(2) = lambda3 * n;
  for (int b = 0; b < 2; ++b) {
    const V dc = d_tangent[0][b].cross(m[1]) + m[0].cross(d_tangent[1][b]);
    const T d_area = n.dot(dc);
    const V d_normal = (dc - n * d_area) / area;
    const T d_lambda3 = (ref_d_area[b] * area - ref_area * d_area) / (area * area);
    g1.col(b) = d_lambda3 * n + lambda3 * d_normal;
  }
  g1.col(2).setZero();
}

/// m of a mid-surface's map values (second derivatives needed).
void surface_derivatives(const geometry::MapValues& v, Vec3 (&m)[5]) {
  m[0] = v.dx.col(0);
  m[1] = v.dx.col(1);
  for (int i = 0; i < 3; ++i) m[2][i] = v.d2x[i](0, 0), m[3][i] = v.d2x[i](0, 1), m[4][i] = v.d2x[i](1, 1);
}

}  // namespace

ShellPoint shell_point(const geometry::MapValues& ref, const geometry::MapValues& cur, double zeta) {
  const SurfaceFrame R = surface_frame(ref, "reference");
  const SurfaceFrame C = surface_frame(cur, "current");  // (refuses a degenerate current mid-surface)
  Vec3 m[5];
  surface_derivatives(cur, m);
  Mat3 g0, g1;
  current_basis(m, R.area, R.d_area, g0, g1);
  ShellPoint p;
  p.thickness_stretch = R.area / C.area;
  p.x = cur.x + zeta * g0.col(2);
  Mat3 G;  // the reference covariant basis at height zeta: G_1, G_2, G_3
  for (int b = 0; b < 2; ++b) G.col(b) = R.tangent[b] + zeta * R.d_normal[b];
  G.col(2) = R.normal;
  p.ref_jacobian = G.determinant();
  if (!(p.ref_jacobian > 0))
    throw std::invalid_argument("shell_point: height " + std::to_string(zeta) +
                                " cm inverts the reference shell here (det [G_1 G_2 N] = " +
                                std::to_string(p.ref_jacobian) + "): beyond a curvature radius");
  p.F = (g0 + zeta * g1) * G.inverse();
  const Vec3 t1 = R.tangent[0].normalized();
  p.frame.col(0) = t1;
  p.frame.col(1) = R.normal.cross(t1);
  p.frame.col(2) = R.normal;
  return p;
}

ShellBasisDerivative shell_basis_derivative(const geometry::MapValues& ref, const geometry::MapValues& cur) {
  const SurfaceFrame R = surface_frame(ref, "reference");
  surface_frame(cur, "current");  // (its refusal of a degenerate mid-surface)
  using Derivatives = Eigen::Matrix<double, 15, 1>;
  using AD = Eigen::AutoDiffScalar<Derivatives>;
  Vec3 m[5];
  surface_derivatives(cur, m);
  Eigen::Matrix<AD, 3, 1> md[5];
  for (int k = 0; k < 5; ++k)
    for (int i = 0; i < 3; ++i) md[k][i] = AD(m[k][i], 15, 3 * k + i);
  Eigen::Matrix<AD, 3, 3> g0, g1;
  current_basis(md, R.area, R.d_area, g0, g1);
  ShellBasisDerivative d;
  for (int col = 0; col < 3; ++col)
    for (int i = 0; i < 3; ++i) {
      const int row = 3 * col + i;
      d.g0(i, col) = g0(i, col).value();
      d.g1(i, col) = g1(i, col).value();
      // (an entry that does not depend on m, g1's third column, holds zero derivatives: fixed-size)
      d.d_g0.row(row) = g0(i, col).derivatives().transpose();
      d.d_g1.row(row) = g1(i, col).derivatives().transpose();
    }
  return d;
}

}  // namespace cellfsi::solid
