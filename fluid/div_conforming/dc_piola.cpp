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

namespace cellfsi::fluid::dc {

PointState piola_state(const PiolaPoint& pt, const PointState& hat) {
  PointState s;
  double v[3], g[3][3], gh[3][3];
  for (int c = 0; c < 3; ++c)
    for (int a = 0; a < 3; ++a) gh[c][a] = hat.dv[c][a];
  piola_values(pt, hat.v.data(), gh, v, g);
  for (int i = 0; i < 3; ++i) {
    s.v[i] = v[i];
    for (int j = 0; j < 3; ++j) s.dv[i][j] = g[i][j];
    for (int c = 0; c < pt.dim; ++c) s.a[i] += i < pt.dim ? pt.P(i, c) * hat.a[c] : 0.0;
  }
  s.p = hat.p;
  return s;
}

PointResidual piola_residual(const PiolaPoint& pt, const PointResidual& r) {
  PointResidual h;
  double r1[3][3], r1h[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r1[i][j] = r.r1[i][j];
  piola_test(pt, r.r0.data(), r1, h.r0.data(), r1h);
  for (int c = 0; c < 3; ++c)
    for (int a = 0; a < 3; ++a) h.r1[c][a] = r1h[c][a];
  h.rq = r.rq;
  return h;
}

PointTangent piola_tangent(const PiolaPoint& pt, const PointTangent& t) {
  const int D = pt.dim;
  // The trial side first: the physical residual's derivatives with respect to the parametric fields,
  //   d r / d v^_m = dr/dv_k P_km + dr/d(d_l v_k) dP[l]_km,   d r / d(d_b v^_m) = dr/d(d_l v_k) P_km G_bl,
  //   d r0 / d a^_m = dr0/da_k P_km.
  // PG[k][l] for fixed (m, b): P_km G_bl.
  PointMat r0v{}, r0a{};                         // [i][m]
  std::array<PointMat, 3> r0g{}, r1v{};          // r0g[i][m][b]; r1v[i][j][m]
  std::array<std::array<PointMat, 3>, 3> r1g{};  // [i][j][m][b]
  PointMat qg{};                                 // [m][b]
  for (int m = 0; m < D; ++m) {
    for (int i = 0; i < D; ++i) {
      double sv = 0, sa = 0;
      for (int k = 0; k < D; ++k) {
        sv += t.dr0_dv[i][k] * pt.P(k, m);
        sa += t.dr0_da[i][k] * pt.P(k, m);
        for (int l = 0; l < D; ++l) sv += t.dr0_ddv[i][k][l] * pt.dP[l](k, m);
      }
      r0v[i][m] = sv, r0a[i][m] = sa;
      for (int j = 0; j < D; ++j) {
        double s1 = 0;
        for (int k = 0; k < D; ++k) {
          s1 += t.dr1_dv[i][j][k] * pt.P(k, m);
          for (int l = 0; l < D; ++l) s1 += t.dr1_ddv[i][j][k][l] * pt.dP[l](k, m);
        }
        r1v[i][j][m] = s1;
      }
    }
    for (int b = 0; b < D; ++b) {
      double PG[3][3] = {};
      for (int k = 0; k < D; ++k)
        for (int l = 0; l < D; ++l) PG[k][l] = pt.P(k, m) * pt.G(b, l);
      double sq = 0;
      for (int k = 0; k < D; ++k)
        for (int l = 0; l < D; ++l) sq += t.drq_ddv[k][l] * PG[k][l];
      qg[m][b] = sq;
      for (int i = 0; i < D; ++i) {
        double s0 = 0;
        for (int k = 0; k < D; ++k)
          for (int l = 0; l < D; ++l) s0 += t.dr0_ddv[i][k][l] * PG[k][l];
        r0g[i][m][b] = s0;
        for (int j = 0; j < D; ++j) {
          double s1 = 0;
          for (int k = 0; k < D; ++k)
            for (int l = 0; l < D; ++l) s1 += t.dr1_ddv[i][j][k][l] * PG[k][l];
          r1g[i][j][m][b] = s1;
        }
      }
    }
  }
  // Then the test side: r0^_c = P_ic r0_i + dP[j]_ic r1_ij, r1^_ca = P_ic G_aj r1_ij.
  PointTangent h;
  for (int c = 0; c < D; ++c) {
    for (int m = 0; m < D; ++m) {
      double sv = 0, sa = 0;
      for (int i = 0; i < D; ++i) {
        sv += pt.P(i, c) * r0v[i][m];
        sa += pt.P(i, c) * r0a[i][m];
        for (int j = 0; j < D; ++j) sv += pt.dP[j](i, c) * r1v[i][j][m];
      }
      h.dr0_dv[c][m] = sv, h.dr0_da[c][m] = sa;
      for (int b = 0; b < D; ++b) {
        double sg = 0;
        for (int i = 0; i < D; ++i) {
          sg += pt.P(i, c) * r0g[i][m][b];
          for (int j = 0; j < D; ++j) sg += pt.dP[j](i, c) * r1g[i][j][m][b];
        }
        h.dr0_ddv[c][m][b] = sg;
      }
    }
    for (int a = 0; a < D; ++a) {
      double PGca[3][3] = {};  // [i][j]: P_ic G_aj
      for (int i = 0; i < D; ++i)
        for (int j = 0; j < D; ++j) PGca[i][j] = pt.P(i, c) * pt.G(a, j);
      double sp = 0;
      for (int i = 0; i < D; ++i)
        for (int j = 0; j < D; ++j) sp += PGca[i][j] * t.dr1_dp[i][j];
      h.dr1_dp[c][a] = sp;
      for (int m = 0; m < D; ++m) {
        double sv = 0;
        for (int i = 0; i < D; ++i)
          for (int j = 0; j < D; ++j) sv += PGca[i][j] * r1v[i][j][m];
        h.dr1_dv[c][a][m] = sv;
        for (int b = 0; b < D; ++b) {
          double sg = 0;
          for (int i = 0; i < D; ++i)
            for (int j = 0; j < D; ++j) sg += PGca[i][j] * r1g[i][j][m][b];
          h.dr1_ddv[c][a][m][b] = sg;
        }
      }
    }
  }
  h.drq_ddv = qg;
  return h;
}

}  // namespace cellfsi::fluid::dc
