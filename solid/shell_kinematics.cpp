#include "solid/shell_kinematics.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

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

}  // namespace

ShellPoint shell_point(const geometry::MapValues& ref, const geometry::MapValues& cur, double zeta) {
  const SurfaceFrame R = surface_frame(ref, "reference");
  const SurfaceFrame C = surface_frame(cur, "current");
  ShellPoint p;
  const double lambda3 = R.area / C.area;
  p.thickness_stretch = lambda3;
  p.x = cur.x + zeta * lambda3 * C.normal;
  Mat3 G, g;  // covariant bases at height zeta: columns G_1, G_2, G_3 (reference), g_1, g_2, g_3 (current)
  for (int b = 0; b < 2; ++b) {
    G.col(b) = R.tangent[b] + zeta * R.d_normal[b];
    const double d_lambda3 = (R.d_area[b] * C.area - R.area * C.d_area[b]) / (C.area * C.area);
    g.col(b) = C.tangent[b] + zeta * (d_lambda3 * C.normal + lambda3 * C.d_normal[b]);
  }
  G.col(2) = R.normal;
  g.col(2) = lambda3 * C.normal;
  p.ref_jacobian = G.determinant();
  if (!(p.ref_jacobian > 0))
    throw std::invalid_argument("shell_point: height " + std::to_string(zeta) +
                                " cm inverts the reference shell here (det [G_1 G_2 N] = " +
                                std::to_string(p.ref_jacobian) + "): beyond a curvature radius");
  p.F = g * G.inverse();
  const Vec3 t1 = R.tangent[0].normalized();
  p.frame.col(0) = t1;
  p.frame.col(1) = R.normal.cross(t1);
  p.frame.col(2) = R.normal;
  return p;
}

}  // namespace cellfsi::solid
