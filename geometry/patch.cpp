#include "geometry/patch.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "geometry/basis.hpp"

namespace cellfsi::geometry {

Patch::Patch(std::vector<KnotVector> knots, int physical_dim, std::vector<Vec3> control_points,
             std::vector<double> weights, std::array<Vec3, 3> shifts)
    : knots_(std::move(knots)),
      physical_dim_(physical_dim),
      control_points_(std::move(control_points)),
      weights_(std::move(weights)),
      shifts_(shifts) {
  if (param_dim() < 1 || param_dim() > 3)
    throw std::invalid_argument("Patch: parametric dimension must be 1, 2 or 3, got " +
                                std::to_string(param_dim()));
  if (physical_dim_ < 2 || physical_dim_ > 3)
    throw std::invalid_argument("Patch: physical dimension must be 2 or 3, got " +
                                std::to_string(physical_dim_));
  if (param_dim() > physical_dim_)
    throw std::invalid_argument("Patch: parametric dimension exceeds physical dimension");
  int n = 1;
  for (const auto& kv : knots_) n *= kv.n_basis();
  if (static_cast<int>(control_points_.size()) != n || static_cast<int>(weights_.size()) != n)
    throw std::invalid_argument("Patch: expected " + std::to_string(n) + " control points and weights, got " +
                                std::to_string(control_points_.size()) + " and " +
                                std::to_string(weights_.size()));
  for (double w : weights_)
    if (!(w > 0)) throw std::invalid_argument("Patch: weights must be positive");
  for (int d = param_dim(); d < 3; ++d) shifts_[d].setZero();
  for (int d = 0; d < param_dim(); ++d)
    if (!knots_[d].periodic()) shifts_[d].setZero();
  detect_closed();
}

void Patch::detect_closed() {
  Vec3 lo, hi;
  bounding_box(lo, hi);
  const double tol = 1e-12 * std::max((hi - lo).norm(), 1e-300);
  for (int d = 0; d < param_dim(); ++d) {
    if (knots_[d].periodic()) {
      closed_[d] = true;
      continue;
    }
    const int n = n_control(d);
    bool same = n > 1;
    for (int idx = 0; idx < n_control() && same; ++idx) {
      Index3 m = control_multi_index(idx);
      if (m[d] != 0) continue;
      Index3 m2 = m;
      m2[d] = n - 1;
      const int idx2 = control_index(m2[0], m2[1], m2[2]);
      same = (control_points_[idx] - control_points_[idx2]).norm() <= tol &&
             std::abs(weights_[idx] - weights_[idx2]) <= 1e-12 * weights_[idx];
    }
    closed_[d] = same;
  }
}

bool Patch::rational() const {
  for (double w : weights_)
    if (w != weights_[0]) return true;
  return false;
}

Index3 Patch::control_multi_index(int idx) const {
  const int n0 = n_control(0), n1 = n_control(1);
  return {idx % n0, (idx / n0) % n1, idx / (n0 * n1)};
}

Index3 Patch::element_multi_index(int e) const {
  const int n0 = n_elements(0), n1 = n_elements(1);
  return {e % n0, (e / n0) % n1, e / (n0 * n1)};
}

void Patch::element_bounds(const Index3& e, Param& lo, Param& hi) const {
  lo = {0, 0, 0};
  hi = {0, 0, 0};
  for (int d = 0; d < param_dim(); ++d) {
    lo[d] = knots_[d].element_begin(e[d]);
    hi[d] = knots_[d].element_end(e[d]);
  }
}

Index3 Patch::find_element(const Param& xi) const {
  Index3 e{0, 0, 0};
  for (int d = 0; d < param_dim(); ++d) e[d] = knots_[d].find_element(xi[d]);
  return e;
}

void Patch::basis(const Param& xi_in, int n_deriv, BasisValues& out, const Index3* element) const {
  if (n_deriv < 0 || n_deriv > 2) throw std::invalid_argument("Patch::basis: n_deriv must be 0, 1 or 2");
  const int P = param_dim();
  // Per-direction univariate values; the wrap of a periodic coordinate becomes a physical offset.
  constexpr int M = kMaxDegree + 1;
  double ders[3][(kMaxDeriv + 1) * M];
  int first[3] = {0, 0, 0}, np[3] = {1, 1, 1};
  double wraps[3] = {0, 0, 0};
  for (int d = 0; d < P; ++d) {
    const KnotVector& kv = knots_[d];
    double u = xi_in[d];
    if (kv.periodic()) {
      const double un = kv.normalize(u);
      wraps[d] = std::round((u - un) / kv.period());
      u = un;
    } else {
      u = kv.normalize(u);
    }
    int span = element ? kv.element_span((*element)[d]) : kv.find_span(u);
    if (element && kv.periodic()) {
      // Keep u inside the requested element even if it sits on the wrap point.
      if (u < kv.knot(span) - 0.5 * kv.period()) u += kv.period(), wraps[d] -= 1;
    }
    out.span[d] = span;
    bspline_basis(kv, span, u, n_deriv, ders[d]);
    first[d] = span - kv.degree();
    np[d] = kv.degree() + 1;
  }
  for (int d = P; d < 3; ++d) {
    ders[d][0] = 1.0;
    ders[d][1] = ders[d][2] = 0.0;
    out.span[d] = 0;
  }

  const int n = np[0] * np[1] * np[2];
  out.n = n;
  out.n_deriv = n_deriv;
  out.index.resize(n);
  out.offset.resize(n);
  out.value.resize(n);
  out.d1.resize(3 * n);
  out.d2.resize(9 * n);

  // Tensor products of the weighted B-splines, and the weight function W with its derivatives.
  double W = 0, dW[3] = {0, 0, 0}, d2W[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  int k = 0;
  for (int c = 0; c < np[2]; ++c)
    for (int b = 0; b < np[1]; ++b)
      for (int a = 0; a < np[0]; ++a, ++k) {
        const int loc[3] = {a, b, c};
        int gidx[3] = {0, 0, 0};
        Vec3 off = Vec3::Zero();
        for (int d = 0; d < P; ++d) {
          const int j = first[d] + loc[d];
          gidx[d] = knots_[d].fold(j);
          const double wc = knots_[d].wrap_count(j) + wraps[d];
          if (wc != 0) off += wc * shifts_[d];
        }
        const int idx = control_index(gidx[0], gidx[1], gidx[2]);
        out.index[k] = idx;
        out.offset[k] = off;
        const double w = weights_[idx];
        // value and derivatives of the tensor-product B-spline (non-rational), times w
        double v[3], d1v[3], d2v[3];
        for (int d = 0; d < 3; ++d) {
          const int pp = (d < P) ? np[d] : 1;
          v[d] = ders[d][loc[d]];
          d1v[d] = (n_deriv >= 1 && d < P) ? ders[d][pp + loc[d]] : 0.0;
          d2v[d] = (n_deriv >= 2 && d < P) ? ders[d][2 * pp + loc[d]] : 0.0;
        }
        const double N = v[0] * v[1] * v[2];
        out.value[k] = w * N;
        W += w * N;
        if (n_deriv >= 1) {
          const double g[3] = {d1v[0] * v[1] * v[2], v[0] * d1v[1] * v[2], v[0] * v[1] * d1v[2]};
          for (int q = 0; q < 3; ++q) {
            out.d1[3 * k + q] = w * g[q];
            dW[q] += w * g[q];
          }
        }
        if (n_deriv >= 2) {
          double h[3][3];
          h[0][0] = d2v[0] * v[1] * v[2];
          h[1][1] = v[0] * d2v[1] * v[2];
          h[2][2] = v[0] * v[1] * d2v[2];
          h[0][1] = h[1][0] = d1v[0] * d1v[1] * v[2];
          h[0][2] = h[2][0] = d1v[0] * v[1] * d1v[2];
          h[1][2] = h[2][1] = v[0] * d1v[1] * d1v[2];
          for (int q = 0; q < 3; ++q)
            for (int r = 0; r < 3; ++r) {
              out.d2[9 * k + 3 * q + r] = w * h[q][r];
              d2W[q][r] += w * h[q][r];
            }
        }
      }

  // Rationalise: R = wN / W; dR_a = (wN_a - R W_a) / W;
  // d2R_ab = (wN_ab - dR_a W_b - dR_b W_a - R W_ab) / W.
  const double invW = 1.0 / W;
  for (int k2 = 0; k2 < n; ++k2) {
    const double R = out.value[k2] * invW;
    out.value[k2] = R;
    if (n_deriv >= 1) {
      double dR[3];
      for (int q = 0; q < 3; ++q) dR[q] = (out.d1[3 * k2 + q] - R * dW[q]) * invW;
      if (n_deriv >= 2)
        for (int q = 0; q < 3; ++q)
          for (int r = 0; r < 3; ++r)
            out.d2[9 * k2 + 3 * q + r] =
                (out.d2[9 * k2 + 3 * q + r] - dR[q] * dW[r] - dR[r] * dW[q] - R * d2W[q][r]) * invW;
      for (int q = 0; q < 3; ++q) out.d1[3 * k2 + q] = dR[q];
    }
  }
}

void Patch::map(const BasisValues& bv, MapValues& out) const {
  out.x.setZero();
  out.dx.setZero();
  for (auto& m : out.d2x) m.setZero();
  const Vec3 X0 = control_points_[bv.index[0]] + bv.offset[0];
  for (int k = 0; k < bv.n; ++k) {
    const Vec3 X = control_points_[bv.index[k]] + bv.offset[k] - X0;
    out.x += bv.value[k] * X;
    if (bv.n_deriv >= 1)
      for (int a = 0; a < 3; ++a) out.dx.col(a) += bv.d1[3 * k + a] * X;
    if (bv.n_deriv >= 2)
      for (int i = 0; i < 3; ++i)
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) out.d2x[i](a, b) += bv.d2[9 * k + 3 * a + b] * X[i];
  }
  out.x += X0;
}

Vec3 Patch::map_minus(const BasisValues& bv, const Vec3& y) const {
  const Vec3 X0 = control_points_[bv.index[0]] + bv.offset[0];
  Vec3 r = X0 - y;
  for (int k = 0; k < bv.n; ++k) r += bv.value[k] * (control_points_[bv.index[k]] + bv.offset[k] - X0);
  return r;
}

Vec3 Patch::point(const Param& xi) const {
  BasisValues bv;
  basis(xi, 0, bv);
  MapValues mv;
  map(bv, mv);
  return mv.x;
}

MapValues Patch::evaluate(const Param& xi, int n_deriv) const {
  BasisValues bv;
  basis(xi, n_deriv, bv);
  MapValues mv;
  map(bv, mv);
  return mv;
}

void Patch::bounding_box(Vec3& lo, Vec3& hi) const {
  lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  hi = -lo;
  for (const auto& p : control_points_) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // In a periodic direction the map also uses the first p control layers shifted by one period.
  for (int d = 0; d < param_dim(); ++d) {
    if (!knots_[d].periodic() || shifts_[d].isZero()) continue;
    for (int idx = 0; idx < n_control(); ++idx)
      if (control_multi_index(idx)[d] < knots_[d].degree()) {
        lo = lo.cwiseMin(control_points_[idx] + shifts_[d]);
        hi = hi.cwiseMax(control_points_[idx] + shifts_[d]);
      }
  }
}

void Patch::element_bounding_box(const Index3& e, Vec3& lo, Vec3& hi) const {
  lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  hi = -lo;
  const int P = param_dim();
  int first[3] = {0, 0, 0}, np[3] = {1, 1, 1};
  for (int d = 0; d < P; ++d) {
    first[d] = knots_[d].element_span(e[d]) - knots_[d].degree();
    np[d] = knots_[d].degree() + 1;
  }
  for (int c = 0; c < np[2]; ++c)
    for (int b = 0; b < np[1]; ++b)
      for (int a = 0; a < np[0]; ++a) {
        const int loc[3] = {a, b, c};
        int g[3] = {0, 0, 0};
        Vec3 off = Vec3::Zero();
        for (int d = 0; d < P; ++d) {
          const int j = first[d] + loc[d];
          g[d] = knots_[d].fold(j);
          off += knots_[d].wrap_count(j) * shifts_[d];
        }
        const Vec3 X = control_points_[control_index(g[0], g[1], g[2])] + off;
        lo = lo.cwiseMin(X);
        hi = hi.cwiseMax(X);
      }
}

Patch transformed(const Patch& patch, const Mat3& A, const Vec3& t) {
  std::vector<Vec3> cps = patch.control_points();
  for (auto& p : cps) p = A * p + t;
  std::array<Vec3, 3> shifts = patch.shifts();
  for (auto& s : shifts) s = A * s;
  return Patch(patch.all_knots(), patch.physical_dim(), std::move(cps), patch.weights(), shifts);
}

bool translation_invariant(const Patch& patch, double tol) {
  const std::vector<Vec3>& P = patch.control_points();
  const std::vector<double>& w = patch.weights();
  double extent = 0;
  for (const Vec3& x : P) extent = std::max(extent, (x - P[0]).norm());
  const double eps = tol * std::max(extent, 1e-300);
  const int n0 = patch.n_control(0), n1 = patch.n_control(1), n2 = patch.n_control(2);
  for (int d = 0; d < patch.param_dim(); ++d) {
    if (!patch.knots(d).periodic()) continue;
    // (Breakpoints, not multiplicities, are compared: periodic knot vectors are only built uniform with
    // simple knots, KnotVector::periodic_uniform.)
    const std::vector<double> b = patch.knots(d).breakpoints();
    for (std::size_t k = 2; k < b.size(); ++k)
      if (std::abs((b[k] - b[k - 1]) - (b[1] - b[0])) > tol * std::abs(b.back() - b.front())) return false;
    const int n = patch.n_control(d);
    const int stride = d == 0 ? 1 : d == 1 ? n0 : n0 * n1;
    const Vec3 step = P[stride] - P[0];
    for (int i = 0; i < n0 * n1 * n2; ++i) {
      const int id = (i / stride) % n;
      const int next = id + 1 < n ? i + stride : i - id * stride;  // wraps onto the first layer
      const Vec3 to_next = P[next] + (id + 1 < n ? Vec3::Zero() : patch.shifts()[d]) - P[i];
      if ((to_next - step).norm() > eps || std::abs(w[next] - w[i]) > tol * std::abs(w[i])) return false;
    }
  }
  return true;
}

void Patch::element_controls(const int first[3], Vec3* X, double* W) const {
  const int P = param_dim();
  int np[3] = {1, 1, 1};
  for (int d = 0; d < P; ++d) np[d] = degree(d) + 1;
  int k = 0;
  for (int c = 0; c < np[2]; ++c)
    for (int b = 0; b < np[1]; ++b)
      for (int a = 0; a < np[0]; ++a, ++k) {
        const int loc[3] = {a, b, c};
        int g[3] = {0, 0, 0};
        Vec3 off = Vec3::Zero();
        for (int d = 0; d < P; ++d) {
          const int j = first[d] + loc[d];
          g[d] = knots_[d].fold(j);
          if (const int w = knots_[d].wrap_count(j)) off += w * shifts_[d];
        }
        const int idx = control_index(g[0], g[1], g[2]);
        X[k] = control_points_[idx] + off;
        W[k] = weights_[idx];
      }
}

std::optional<AffineMap> affine_map(const Patch& patch, double tol) {
  const int P = patch.param_dim();
  const std::vector<Vec3>& X = patch.control_points();
  const std::vector<double>& w = patch.weights();
  for (double wi : w)
    if (std::abs(wi - w[0]) > tol * w[0]) return std::nullopt;
  Vec3 lo, hi;
  patch.bounding_box(lo, hi);
  const double eps = tol * std::max((hi - lo).norm(), 1e-300);
  // The map from the control points at the two ends of each direction's first row (x_d depends on xi_d only,
  // so any row serves; the rest are checked below).
  std::array<std::vector<double>, 3> tau;
  AffineMap m;
  m.offset = X[0];
  for (int d = 0; d < P; ++d) {
    tau[d] = patch.knots(d).greville_unwrapped();
    const int n = patch.n_control(d);
    if (patch.degree(d) < 1 || n < 2 || tau[d][n - 1] == tau[d][0]) return std::nullopt;
    Index3 last{0, 0, 0};
    last[d] = n - 1;
    m.scale[d] =
        (X[patch.control_index(last[0], last[1], last[2])][d] - X[0][d]) / (tau[d][n - 1] - tau[d][0]);
    m.offset[d] = X[0][d] - m.scale[d] * tau[d][0];
    if (std::abs(m.scale[d]) * (tau[d][n - 1] - tau[d][0]) <= eps) return std::nullopt;  // degenerate
    // A periodic direction continues the map: unwrapped control point j + n is X_j + shift.
    if (patch.knots(d).periodic()) {
      Vec3 s = Vec3::Zero();
      s[d] = m.scale[d] * patch.knots(d).period();
      if ((patch.shift(d) - s).norm() > eps) return std::nullopt;
    }
  }
  for (int i = 0; i < patch.n_control(); ++i) {
    const Index3 c = patch.control_multi_index(i);
    Param g{0, 0, 0};
    for (int d = 0; d < P; ++d) g[d] = tau[d][c[d]];
    if ((X[i] - m.point(g)).norm() > eps) return std::nullopt;
  }
  // The control points settle it (sum_j tau_j N_j(u) = u); evaluating the patch once inside every element
  // guards the reasoning (periodic wrap, knot multiplicities) with the code that the solvers use.
  for (int e = 0; e < patch.n_elements(); ++e) {
    Param a, b, xi{0, 0, 0};
    patch.element_bounds(patch.element_multi_index(e), a, b);
    for (int d = 0; d < P; ++d) xi[d] = a[d] + (0.29 + 0.1 * d) * (b[d] - a[d]);
    if ((patch.point(xi) - m.point(xi)).norm() > eps) return std::nullopt;
  }
  return m;
}

Vec3 nearest_image(const Patch& patch, Vec3 r) {
  for (int d = 0; d < patch.param_dim(); ++d) {
    const Vec3& s = patch.shift(d);
    if (!patch.knots(d).periodic() || s.isZero()) continue;
    r -= std::round(r.dot(s) / s.squaredNorm()) * s;
  }
  return r;
}

std::vector<Vec3> neighbour_image_shifts(const Patch& patch) {
  std::vector<Vec3> shifts{Vec3::Zero()};
  for (int d = 0; d < patch.param_dim(); ++d) {
    const Vec3& s = patch.shift(d);
    if (!patch.knots(d).periodic() || s.isZero()) continue;
    const size_t n = shifts.size();
    for (size_t k = 0; k < n; ++k) shifts.push_back(shifts[k] + s), shifts.push_back(shifts[k] - s);
  }
  return shifts;
}

}  // namespace cellfsi::geometry
