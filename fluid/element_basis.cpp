#include "fluid/element_basis.hpp"

#include <cmath>

#include "geometry/basis.hpp"
#include "geometry/quadrature.hpp"

namespace cellfsi::fluid {

using geometry::Index3;
using geometry::Vec3;

ElementBasis::ElementBasis(const geometry::Patch& patch, Index3 n_gauss)
    : patch_(patch), dim_(patch.param_dim()) {
  rational_ = patch.rational();
  for (int d = 0; d < dim_; ++d) {
    const geometry::KnotVector& kv = patch.knots(d);
    const int p = kv.degree();
    np_[d] = p + 1;
    nq_[d] = n_gauss[d] > 0 ? n_gauss[d] : p + 1;
    const geometry::GaussRule& g = geometry::gauss_legendre(nq_[d]);
    const int ne = kv.n_elements();
    table_[d].assign(static_cast<size_t>(ne) * nq_[d] * 3 * np_[d], 0.0);
    gauss_w_[d].assign(static_cast<size_t>(ne) * nq_[d], 0.0);
    parent_scale_[d].assign(ne, 0.0);
    std::vector<double> ders(3 * np_[d]);
    for (int e = 0; e < ne; ++e) {
      const double a = kv.element_begin(e), b = kv.element_end(e), half = 0.5 * (b - a);
      parent_scale_[d][e] = 1.0 / half;
      for (int q = 0; q < nq_[d]; ++q) {
        const double u = a + half * (g.points[q] + 1.0);
        geometry::bspline_basis(kv, kv.element_span(e), u, std::min(2, p), ders.data());
        for (int k = 0; k < 3; ++k)
          for (int i = 0; i < np_[d]; ++i)
            table_[d][((static_cast<size_t>(e) * nq_[d] + q) * 3 + k) * np_[d] + i] =
                k <= p ? ders[k * np_[d] + i] : 0;
        gauss_w_[d][static_cast<size_t>(e) * nq_[d] + q] = half * g.weights[q];
      }
    }
  }
  // Axis-affine: non-rational and X = origin + sum_d L_d tau_d(i_d) e_d at every control point (Greville
  // identity), so dx/dxi = diag(L_d) everywhere.
  axis_affine_ = !rational_;
  if (axis_affine_) {
    Vec3 lo, hi;
    patch.bounding_box(lo, hi);
    const double tol = 1e-13 * (hi - lo).norm();
    std::vector<double> tau[3];
    double L[3] = {0, 0, 0};
    for (int d = 0; d < dim_; ++d) {
      tau[d] = patch.knots(d).greville_unwrapped();
      const int n = patch.n_control(d);
      geometry::Index3 a{0, 0, 0}, b{0, 0, 0};
      b[d] = n - 1;
      const Vec3 Xa = patch.control_points()[patch.control_index(a[0], a[1], a[2])];
      const Vec3 Xb = patch.control_points()[patch.control_index(b[0], b[1], b[2])];
      L[d] = (Xb[d] - Xa[d]) / (tau[d][n - 1] - tau[d][0]);
    }
    const Vec3 X0 = patch.control_points()[0];
    for (int idx = 0; idx < patch.n_control() && axis_affine_; ++idx) {
      const geometry::Index3 m = patch.control_multi_index(idx);
      Vec3 x = X0;
      for (int d = 0; d < dim_; ++d) x[d] += L[d] * (tau[d][m[d]] - tau[d][0]);
      axis_affine_ = (patch.control_points()[idx] - x).norm() <= tol;
    }
    for (int d = 0; d < dim_ && axis_affine_; ++d)
      if (patch.knots(d).periodic())
        axis_affine_ = (patch.shift(d) - Vec3::Unit(d) * L[d] * patch.knots(d).period()).norm() <= tol;
  }
  if (axis_affine_) {
    for (int d = 0; d < 3; ++d) {
      const int ne = d < dim_ ? patch.knots(d).n_elements() : 1;
      class_[d].assign(ne, 0);
      if (d >= dim_) continue;
      const size_t stride = static_cast<size_t>(nq_[d]) * 3 * np_[d];
      std::vector<int> reps;  // representative element of each class
      for (int e = 0; e < ne; ++e) {
        int c = -1;
        for (size_t r = 0; r < reps.size() && c < 0; ++r) {
          bool same = parent_scale_[d][e] == parent_scale_[d][reps[r]];
          for (size_t i = 0; i < stride && same; ++i)
            same = std::abs(table_[d][e * stride + i] - table_[d][reps[r] * stride + i]) <= 1e-15;
          if (same) c = static_cast<int>(r);
        }
        if (c < 0) {
          c = static_cast<int>(reps.size());
          reps.push_back(e);
        }
        class_[d][e] = c;
      }
      n_classes_[d] = static_cast<int>(reps.size());
    }
    cache_.resize(static_cast<size_t>(n_classes_[0]) * n_classes_[1] * n_classes_[2]);
    cached_.assign(cache_.size(), 0);
  }
}

const ElementValues& ElementBasis::evaluate(const Index3& e, ElementValues& scratch, int first[3]) const {
  for (int d = 0; d < 3; ++d) first[d] = d < dim_ ? patch_.knots(d).element_span(e[d]) - patch_.degree(d) : 0;
  if (!axis_affine_) {
    compute(e, scratch);
    return scratch;
  }
  const int key = class_[0][e[0]] + n_classes_[0] * (class_[1][e[1]] + n_classes_[1] * class_[2][e[2]]);
  if (!cached_[key]) {
    compute(e, cache_[key]);
    cached_[key] = 1;
  }
  return cache_[key];
}

void ElementBasis::compute(const Index3& e, ElementValues& out) const {
  const int D = dim_;
  const int n = np_[0] * np_[1] * np_[2];
  const int nq = nq_[0] * nq_[1] * nq_[2];
  out.n = n;
  out.nq = nq;
  out.N.resize(static_cast<size_t>(nq) * n);
  out.dN.resize(static_cast<size_t>(nq) * n * 3);
  out.lapN.resize(static_cast<size_t>(nq) * n);
  out.weight.resize(nq);
  out.G.resize(nq);

  // The element's control points (unwrapped: periodic offsets applied) and weights.
  int first[3] = {0, 0, 0};
  for (int d = 0; d < D; ++d) first[d] = patch_.knots(d).element_span(e[d]) - patch_.degree(d);
  for (int d = 0; d < 3; ++d) out.first[d] = first[d];
  constexpr int kMaxFunctions =
      (geometry::kMaxDegree + 1) * (geometry::kMaxDegree + 1) * (geometry::kMaxDegree + 1);
  Vec3 X[kMaxFunctions];
  double Wc[kMaxFunctions];
  patch_.element_controls(first, X, Wc);
  const Vec3 X0 = X[0];
  for (int k = 0; k < n; ++k) X[k] -= X0;  // relative coordinates: derivatives are unchanged, digits are kept

  // Parametric -> parent scale per direction (for G).
  double ps[3] = {1, 1, 1};
  for (int d = 0; d < D; ++d) ps[d] = parent_scale_[d][e[d]];

  // Up to (kMaxDegree + 1)^3 functions; second derivatives stored as xx, yy, zz, xy, xz, yz.
  constexpr int kMaxN = (geometry::kMaxDegree + 1) * (geometry::kMaxDegree + 1) * (geometry::kMaxDegree + 1);
  double R[kMaxN], dR[kMaxN][3], d2R[kMaxN][6];
  double jinv_diag[3] = {1, 1, 1};  // d xi_d / d x_d (constant on an axis-affine patch)
  int qi = 0;
  for (int q2 = 0; q2 < nq_[2]; ++q2)
    for (int q1 = 0; q1 < nq_[1]; ++q1)
      for (int q0 = 0; q0 < nq_[0]; ++q0, ++qi) {
        const int qd[3] = {q0, q1, q2};
        const double* T[3];
        static const double one[9] = {1, 0, 0, 1, 0, 0, 1, 0, 0};
        double wq = 1.0;
        for (int d = 0; d < 3; ++d) {
          if (d < D) {
            T[d] = &table_[d][((static_cast<size_t>(e[d]) * nq_[d] + qd[d]) * 3) * np_[d]];
            wq *= gauss_w_[d][static_cast<size_t>(e[d]) * nq_[d] + qd[d]];
          } else {
            T[d] = one;
          }
        }
        // Tensor products: value, first and second parametric derivatives.
        int k = 0;
        for (int c = 0; c < np_[2]; ++c)
          for (int b = 0; b < np_[1]; ++b)
            for (int a = 0; a < np_[0]; ++a, ++k) {
              const double v0 = T[0][a], v1 = T[1][b], v2 = T[2][c];
              const double g0 = T[0][np_[0] + a], g1 = T[1][np_[1] + b], g2 = D == 3 ? T[2][np_[2] + c] : 0.0;
              const double h0 = T[0][2 * np_[0] + a], h1 = T[1][2 * np_[1] + b],
                           h2 = D == 3 ? T[2][2 * np_[2] + c] : 0.0;
              R[k] = v0 * v1 * v2;
              dR[k][0] = g0 * v1 * v2;
              dR[k][1] = v0 * g1 * v2;
              dR[k][2] = v0 * v1 * g2;
              d2R[k][0] = h0 * v1 * v2;
              d2R[k][1] = v0 * h1 * v2;
              d2R[k][2] = v0 * v1 * h2;
              d2R[k][3] = g0 * g1 * v2;
              d2R[k][4] = g0 * v1 * g2;
              d2R[k][5] = v0 * g1 * g2;
            }
        if (rational_) {
          double W = 0, dW[3] = {0, 0, 0}, d2W[6] = {0, 0, 0, 0, 0, 0};
          for (int i = 0; i < n; ++i) {
            R[i] *= Wc[i];
            W += R[i];
            for (int a = 0; a < 3; ++a) dR[i][a] *= Wc[i], dW[a] += dR[i][a];
            for (int a = 0; a < 6; ++a) d2R[i][a] *= Wc[i], d2W[a] += d2R[i][a];
          }
          const double iW = 1.0 / W;
          static const int pa[6] = {0, 1, 2, 0, 0, 1}, pb[6] = {0, 1, 2, 1, 2, 2};
          for (int i = 0; i < n; ++i) {
            const double r = R[i] * iW;
            double g[3];
            for (int a = 0; a < 3; ++a) g[a] = (dR[i][a] - r * dW[a]) * iW;
            for (int s = 0; s < 6; ++s)
              d2R[i][s] = (d2R[i][s] - g[pa[s]] * dW[pb[s]] - g[pb[s]] * dW[pa[s]] - r * d2W[s]) * iW;
            R[i] = r;
            for (int a = 0; a < 3; ++a) dR[i][a] = g[a];
          }
        }
        // Map derivatives: J(i, a) = d x_i / d xi_a, H[i][s] = d2 x_i / d xi_a d xi_b.
        double J[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}, H[3][6] = {};
        bool curved = false;
        for (int i = 0; i < n; ++i)
          for (int c = 0; c < D; ++c) {
            const double x = X[i][c];
            for (int a = 0; a < D; ++a) J[c][a] += dR[i][a] * x;
            for (int s = 0; s < 6; ++s) H[c][s] += d2R[i][s] * x;
          }
        // Inverse Jacobian (Ji[a][j] = d xi_a / d x_j) and determinant.
        double Ji[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, det;
        if (D == 2) {
          det = J[0][0] * J[1][1] - J[0][1] * J[1][0];
          Ji[0][0] = J[1][1] / det, Ji[0][1] = -J[0][1] / det;
          Ji[1][0] = -J[1][0] / det, Ji[1][1] = J[0][0] / det;
        } else {
          const double c00 = J[1][1] * J[2][2] - J[1][2] * J[2][1],
                       c01 = J[1][2] * J[2][0] - J[1][0] * J[2][2],
                       c02 = J[1][0] * J[2][1] - J[1][1] * J[2][0];
          det = J[0][0] * c00 + J[0][1] * c01 + J[0][2] * c02;
          Ji[0][0] = c00 / det;
          Ji[1][0] = c01 / det;
          Ji[2][0] = c02 / det;
          Ji[0][1] = (J[0][2] * J[2][1] - J[0][1] * J[2][2]) / det;
          Ji[1][1] = (J[0][0] * J[2][2] - J[0][2] * J[2][0]) / det;
          Ji[2][1] = (J[0][1] * J[2][0] - J[0][0] * J[2][1]) / det;
          Ji[0][2] = (J[0][1] * J[1][2] - J[0][2] * J[1][1]) / det;
          Ji[1][2] = (J[0][2] * J[1][0] - J[0][0] * J[1][2]) / det;
          Ji[2][2] = (J[0][0] * J[1][1] - J[0][1] * J[1][0]) / det;
        }
        for (int c = 0; c < D && !curved; ++c)
          for (int s = 0; s < 6; ++s) curved = curved || std::abs(H[c][s]) > 1e-13 * std::abs(J[c][c]);
        if (qi == 0)
          for (int d = 0; d < D; ++d) jinv_diag[d] = Ji[d][d];
        out.weight[qi] = wq * std::abs(det);
        auto& G = out.G[qi];
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            double s = 0;
            if (i < D && j < D)
              for (int a = 0; a < D; ++a) s += ps[a] * ps[a] * Ji[a][i] * Ji[a][j];
            G[i][j] = s;
          }
        // Physical derivatives; the Laplacian is tr(Ji^T (H_xi - sum_m dN/dx_m H_m) Ji).
        static const int sidx[3][3] = {{0, 3, 4}, {3, 1, 5}, {4, 5, 2}};
        double JJ[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};  // Ji Ji^T
        for (int a = 0; a < D; ++a)
          for (int b = 0; b < D; ++b)
            for (int j = 0; j < D; ++j) JJ[a][b] += Ji[a][j] * Ji[b][j];
        double* No = &out.N[static_cast<size_t>(qi) * n];
        double* dNo = &out.dN[static_cast<size_t>(qi) * n * 3];
        double* lo = &out.lapN[static_cast<size_t>(qi) * n];
        for (int i = 0; i < n; ++i) {
          No[i] = R[i];
          double g[3] = {0, 0, 0};
          for (int j = 0; j < D; ++j)
            for (int a = 0; a < D; ++a) g[j] += dR[i][a] * Ji[a][j];
          dNo[3 * i] = g[0], dNo[3 * i + 1] = g[1], dNo[3 * i + 2] = g[2];
          double lap = 0;
          for (int a = 0; a < D; ++a)
            for (int b = 0; b < D; ++b) {
              double h = d2R[i][sidx[a][b]];
              if (curved)
                for (int m = 0; m < D; ++m) h -= g[m] * H[m][sidx[a][b]];
              lap += h * JJ[a][b];
            }
          lo[i] = lap;
        }
      }

  // Univariate factors (see ElementValues::tensor): the tables' values and derivatives, the latter scaled to
  // physical coordinates, which on an axis-affine patch is a per-direction constant.
  out.tensor = axis_affine_;
  if (!axis_affine_) return;
  for (int d = 0; d < 3; ++d) {
    out.np[d] = np_[d];
    out.nq1[d] = nq_[d];
    out.factor_value[d].assign(static_cast<size_t>(nq_[d]) * np_[d], d < D ? 0.0 : 1.0);
    out.factor_deriv[d].assign(static_cast<size_t>(nq_[d]) * np_[d], 0.0);
    if (d >= D) continue;
    for (int q = 0; q < nq_[d]; ++q)
      for (int a = 0; a < np_[d]; ++a) {
        const double* T = &table_[d][((static_cast<size_t>(e[d]) * nq_[d] + q) * 3) * np_[d]];
        out.factor_value[d][static_cast<size_t>(q) * np_[d] + a] = T[a];
        out.factor_deriv[d][static_cast<size_t>(q) * np_[d] + a] = T[np_[d] + a] * jinv_diag[d];
      }
  }
}

}  // namespace cellfsi::fluid
