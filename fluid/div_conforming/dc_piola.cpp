#include "fluid/div_conforming/dc_piola.hpp"

#include <stdexcept>
#include <string>

namespace cellfsi::fluid::dc {

using geometry::Mat3;

PiolaPoint piola_point(const geometry::MapValues& m, int dim) {
  if (dim != 2 && dim != 3) throw std::invalid_argument("piola_point: dim must be 2 or 3");
  PiolaPoint pt;
  pt.dim = dim;
  Mat3 F = Mat3::Identity();
  F.topLeftCorner(dim, dim) = m.dx.topLeftCorner(dim, dim);
  pt.J = F.determinant();
  if (!(pt.J > 0))
    throw std::invalid_argument("piola_point: the map's Jacobian determinant is " + std::to_string(pt.J) +
                                " at x = (" + std::to_string(m.x[0]) + ", " + std::to_string(m.x[1]) + ", " +
                                std::to_string(m.x[2]) + "); a contravariant Piola map needs det F > 0");
  pt.G = F.inverse();
  pt.P = F / pt.J;
  // dF[b](i, c) = d F_ic / d xi_b = d2x_i / dxi_c dxi_b (zero beyond dim).
  std::array<Mat3, 3> dF{Mat3::Zero(), Mat3::Zero(), Mat3::Zero()};
  for (int b = 0; b < dim; ++b)
    for (int i = 0; i < dim; ++i)
      for (int c = 0; c < dim; ++c) dF[b](i, c) = m.d2x[i](c, b);
  std::array<Mat3, 3> dP_dxi;  // d P / d xi_b
  for (int b = 0; b < 3; ++b) {
    const double dJ = pt.J * (pt.G * dF[b]).trace();  // Jacobi's formula
    dP_dxi[b] = dF[b] / pt.J - pt.P * (dJ / pt.J);
  }
  for (int j = 0; j < 3; ++j) {
    pt.dP[j] = Mat3::Zero();
    for (int b = 0; b < 3; ++b) pt.dP[j] += dP_dxi[b] * pt.G(b, j);
  }
  return pt;
}

void piola_values(const PiolaPoint& pt, const double* v_hat, const double (*grad_hat)[3], double* v,
                  double (*grad)[3]) {
  const int D = pt.dim;
  // d v^_c / d x_j = grad_hat[c][a] G_aj.
  double gx[3][3] = {};
  for (int c = 0; c < D; ++c)
    for (int j = 0; j < D; ++j)
      for (int a = 0; a < D; ++a) gx[c][j] += grad_hat[c][a] * pt.G(a, j);
  for (int i = 0; i < 3; ++i) {
    v[i] = 0;
    for (int j = 0; j < 3; ++j) grad[i][j] = 0;
  }
  for (int i = 0; i < D; ++i)
    for (int c = 0; c < D; ++c) {
      v[i] += pt.P(i, c) * v_hat[c];
      for (int j = 0; j < D; ++j) grad[i][j] += pt.dP[j](i, c) * v_hat[c] + pt.P(i, c) * gx[c][j];
    }
}

void piola_test(const PiolaPoint& pt, const double* r0, const double (*r1)[3], double* r0_hat,
                double (*r1_hat)[3]) {
  const int D = pt.dim;
  for (int c = 0; c < 3; ++c) {
    r0_hat[c] = 0;
    for (int a = 0; a < 3; ++a) r1_hat[c][a] = 0;
  }
  for (int c = 0; c < D; ++c) {
    double s[3] = {0, 0, 0};  // s[j] = sum_i r1_ij P_ic: the factor of d v^_c / d x_j
    for (int i = 0; i < D; ++i) {
      r0_hat[c] += r0[i] * pt.P(i, c);
      for (int j = 0; j < D; ++j) {
        r0_hat[c] += r1[i][j] * pt.dP[j](i, c);
        s[j] += r1[i][j] * pt.P(i, c);
      }
    }
    for (int a = 0; a < D; ++a)
      for (int j = 0; j < D; ++j) r1_hat[c][a] += s[j] * pt.G(a, j);
  }
}

}  // namespace cellfsi::fluid::dc
