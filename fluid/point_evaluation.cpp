// See point_evaluation.hpp.
#include "fluid/point_evaluation.hpp"

#include <cmath>

namespace cellfsi::fluid {

using geometry::BasisValues;
using geometry::MapValues;

void physical_point(const geometry::Patch& patch, const Index3& e, const Param& xi, int order,
                    BasisValues& bv, MapValues& mv, PhysicalPoint& out) {
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
  bool affine = true;
  for (int i = 0; i < D && affine; ++i) affine = mv.d2x[i].topLeftCorner(D, D).isZero(0.0);
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
        if (!affine)
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
