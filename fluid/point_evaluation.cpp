// See point_evaluation.hpp.
#include "fluid/point_evaluation.hpp"

#include <algorithm>
#include <cmath>

#include "geometry/basis.hpp"

namespace cellfsi::fluid {

using geometry::BasisValues;
using geometry::MapValues;

namespace {

/// physical_point on an axis-aligned affine patch: x_d = offset_d + scale_d xi_d, so
/// N_k = prod_d B_{a_d}(xi_d), d N_k / d x_j = B'_{a_j} / scale_j times the other factors, and G is
/// diagonal. Non-rational (affine_map requires equal weights, and equal weights cancel).
void physical_point_affine(const geometry::Patch& patch, const geometry::AffineMap& map, const Index3& e,
                           const Param& xi, int order, PhysicalPoint& out) {
  const int D = patch.param_dim();
  constexpr int M = geometry::kMaxDegree + 1;
  double f[3][3 * M];  // f[d][k M + a]: k-th derivative in x_d of univariate function a of direction d
  int np[3] = {1, 1, 1}, fold[3][M] = {{0}, {0}, {0}};
  double ders[3 * M];
  const int n_deriv = std::min(order, 2);
  for (int d = 0; d < 3; ++d) {
    if (d >= D) {
      f[d][0] = 1.0;
      f[d][M] = f[d][2 * M] = 0.0;
      out.first[d] = 0;
      continue;
    }
    const geometry::KnotVector& kv = patch.knots(d);
    const int p = kv.degree(), span = kv.element_span(e[d]);
    // u inside the requested element, as Patch::basis takes it (a periodic coordinate wrapped).
    double u = kv.normalize(xi[d]);
    if (kv.periodic() && u < kv.knot(span) - 0.5 * kv.period()) u += kv.period();
    const int nd = std::min(n_deriv, p);
    geometry::bspline_basis(kv, span, u, nd, ders);
    np[d] = p + 1;
    out.first[d] = span - p;
    const double inv = 1.0 / map.scale[d];
    for (int a = 0; a < np[d]; ++a) {
      f[d][a] = ders[a];
      f[d][M + a] = nd >= 1 ? ders[np[d] + a] * inv : 0.0;
      f[d][2 * M + a] = nd >= 2 ? ders[2 * np[d] + a] * inv * inv : 0.0;
      fold[d][a] = kv.fold(out.first[d] + a);
    }
  }
  const int n = np[0] * np[1] * np[2];
  out.n = n;
  out.x = map.point(xi);
  out.detJ = 1.0;
  for (int d = 0; d < D; ++d) out.detJ *= std::abs(map.scale[d]);
  out.index.resize(n);
  out.N.resize(n);
  out.dN.resize(3 * n);
  out.lapN.resize(order >= 2 ? n : 0);
  int k = 0;
  for (int c = 0; c < np[2]; ++c)
    for (int b = 0; b < np[1]; ++b)
      for (int a = 0; a < np[0]; ++a, ++k) {
        const double v0 = f[0][a], v1 = f[1][b], v2 = f[2][c];
        out.index[k] = patch.control_index(fold[0][a], fold[1][b], fold[2][c]);
        out.N[k] = v0 * v1 * v2;
        out.dN[3 * k] = f[0][M + a] * v1 * v2;
        out.dN[3 * k + 1] = v0 * f[1][M + b] * v2;
        out.dN[3 * k + 2] = v0 * v1 * f[2][M + c];
        if (order >= 2)
          out.lapN[k] = f[0][2 * M + a] * v1 * v2 + v0 * f[1][2 * M + b] * v2 + v0 * v1 * f[2][2 * M + c];
      }
  if (order < 2) return;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out.G[i][j] = 0.0;
  for (int a = 0; a < D; ++a) {
    const double h = patch.knots(a).element_end(e[a]) - patch.knots(a).element_begin(e[a]);
    const double s = 2.0 / (h * map.scale[a]);
    out.G[a][a] = s * s;
  }
}

}  // namespace

void physical_point(const geometry::Patch& patch, const Index3& e, const Param& xi, int order,
                    BasisValues& bv, MapValues& mv, PhysicalPoint& out, const geometry::AffineMap* affine) {
  if (affine) return physical_point_affine(patch, *affine, e, xi, order, out);
  const int D = patch.param_dim();
  patch.basis(xi, order, bv, &e);
  patch.map(bv, mv);
  out.x = mv.x;
  first_functions(patch, bv, out.first);
  out.index = bv.index;
  const Mat3 J = mv.dx;
  Mat3 Jinv = Mat3::Identity();
  Jinv.topLeftCorner(D, D) = J.topLeftCorner(D, D).inverse();  // Jinv(a, j) = d xi_a / d x_j
  out.detJ = std::abs(J.topLeftCorner(D, D).determinant());
  out.n = bv.n;
  out.N.resize(bv.n);
  out.dN.resize(3 * bv.n);
  out.lapN.resize(order >= 2 ? bv.n : 0);
  bool flat = true;  // the map's second derivatives vanish
  for (int i = 0; i < D && flat; ++i) flat = mv.d2x[i].topLeftCorner(D, D).isZero(0.0);
  for (int k = 0; k < bv.n; ++k) {
    out.N[k] = bv.value[k];
    double g[3] = {0, 0, 0};
    for (int j = 0; j < D; ++j)
      for (int a = 0; a < D; ++a) g[j] += bv.d1[3 * k + a] * Jinv(a, j);
    for (int j = 0; j < 3; ++j) out.dN[3 * k + j] = g[j];
    if (order < 2) continue;
    // Hessian in x: Jinv^T (H_xi - sum_m dN/dx_m d2x_m/dxi2) Jinv; only its trace is needed.
    Mat3 H = Mat3::Zero();
    for (int a = 0; a < D; ++a)
      for (int b = 0; b < D; ++b) {
        double h = bv.d2[9 * k + 3 * a + b];
        if (!flat)
          for (int m = 0; m < D; ++m) h -= g[m] * mv.d2x[m](a, b);
        H(a, b) = h;
      }
    double lap = 0;
    for (int i = 0; i < D; ++i)
      for (int a = 0; a < D; ++a)
        for (int b = 0; b < D; ++b) lap += Jinv(a, i) * H(a, b) * Jinv(b, i);
    out.lapN[k] = lap;
  }
  if (order < 2) return;
  // G with parent coordinates in [-1, 1]: d xi_parent / d x = (2 / h_a) d xi / d x.
  double scale[3] = {1, 1, 1};
  for (int a = 0; a < D; ++a) {
    const double h = patch.knots(a).element_end(e[a]) - patch.knots(a).element_begin(e[a]);
    scale[a] = 2.0 / h;
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double s = 0;
      if (i < D && j < D)
        for (int a = 0; a < D; ++a) s += scale[a] * scale[a] * Jinv(a, i) * Jinv(a, j);
      out.G[i][j] = s;
    }
}

Index3 element_of(const geometry::Patch& patch, const Param& xi) {
  Index3 e{0, 0, 0};
  for (int d = 0; d < patch.param_dim(); ++d) {
    const geometry::KnotVector& kv = patch.knots(d);
    // The end of a periodic interval stays in the last element (find_element would wrap it to the first).
    e[d] = xi[d] >= kv.b() ? kv.n_elements() - 1 : kv.find_element(xi[d]);
  }
  return e;
}

}  // namespace cellfsi::fluid
