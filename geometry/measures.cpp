#include "geometry/measures.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>

#include "geometry/basis.hpp"
#include "geometry/quadrature.hpp"
#include "geometry/refine.hpp"

namespace cellfsi::geometry {

namespace {

/// Calls f(x, dx, weight) at every quadrature point of the patch (weight = parametric weight), in
/// element_quadrature's points. Per element the univariate B-splines at its Gauss points are evaluated once
/// per direction, and each point forms their tensor products (times the weights, for a rational patch) and
/// the map: the values of Patch::basis and Patch::map without their per-point span search, folding and
/// allocation (the bodies' metrics integrate every body at every step).
template <class F>
void for_each_point(const Patch& patch, int extra_gauss, const ElementShare& share, F&& f) {
  const int P = patch.param_dim();
  const Index3 ng = default_gauss(patch, extra_gauss);
  constexpr int M = kMaxDegree + 1, kMaxN = M * M * M;
  int np[3] = {1, 1, 1}, nq[3] = {1, 1, 1};
  const GaussRule* rule[3] = {nullptr, nullptr, nullptr};
  for (int d = 0; d < P; ++d) {
    np[d] = patch.degree(d) + 1;
    nq[d] = ng[d];
    rule[d] = &gauss_legendre(nq[d]);
  }
  const int n = np[0] * np[1] * np[2];
  // table[d][(q * 2 + k) * np + a]: k-th derivative of function a of direction d at Gauss point q.
  std::vector<double> table[3], wq[3];
  for (int d = 0; d < 3; ++d) {
    table[d].assign(static_cast<size_t>(nq[d]) * 2 * np[d], 0.0);
    wq[d].assign(nq[d], 1.0);
    if (d >= P) table[d][0] = 1.0;  // a direction the patch lacks: one function, value 1
  }
  const bool rational = patch.rational();
  Vec3 X[kMaxN];
  double Wc[kMaxN], R[kMaxN], dR[kMaxN][3], ders[2 * M];
  if (share.parts < 1 || share.part < 0 || share.part >= share.parts)
    throw std::invalid_argument("ElementShare: part " + std::to_string(share.part) + " of " +
                                std::to_string(share.parts));
  const std::int64_t n_elements = patch.n_elements();
  const int e_begin = static_cast<int>(n_elements * share.part / share.parts);
  const int e_end = static_cast<int>(n_elements * (share.part + 1) / share.parts);
  if (share.operations)
    *share.operations += point_operations(patch) * (e_end - e_begin) * nq[0] * nq[1] * nq[2];
  for (int e = e_begin; e < e_end; ++e) {
    const Index3 m = patch.element_multi_index(e);
    Param lo, hi;
    patch.element_bounds(m, lo, hi);
    int first[3] = {0, 0, 0};
    for (int d = 0; d < P; ++d) {
      const KnotVector& kv = patch.knots(d);
      const int span = kv.element_span(m[d]);
      first[d] = span - kv.degree();
      const double half = 0.5 * (hi[d] - lo[d]);
      for (int q = 0; q < nq[d]; ++q) {
        bspline_basis(kv, span, lo[d] + half * (rule[d]->points[q] + 1.0), std::min(1, kv.degree()), ders);
        for (int a = 0; a < np[d]; ++a) {
          table[d][(q * 2) * np[d] + a] = ders[a];
          table[d][(q * 2 + 1) * np[d] + a] = kv.degree() >= 1 ? ders[np[d] + a] : 0.0;
        }
        wq[d][q] = half * rule[d]->weights[q];
      }
    }
    // The element's control points, relative to the first (Patch::map's digits).
    patch.element_controls(first, X, Wc);
    const Vec3 X0 = X[0];
    for (int i = 0; i < n; ++i) X[i] -= X0;
    for (int q2 = 0; q2 < nq[2]; ++q2)
      for (int q1 = 0; q1 < nq[1]; ++q1)
        for (int q0 = 0; q0 < nq[0]; ++q0) {
          const double* T0 = &table[0][q0 * 2 * np[0]];
          const double* T1 = &table[1][q1 * 2 * np[1]];
          const double* T2 = &table[2][q2 * 2 * np[2]];
          double W = 0, dW[3] = {0, 0, 0};
          int i = 0;
          for (int c = 0; c < np[2]; ++c)
            for (int b = 0; b < np[1]; ++b)
              for (int a = 0; a < np[0]; ++a, ++i) {
                const double v0 = T0[a], v1 = T1[b], v2 = T2[c];
                const double w = rational ? Wc[i] : 1.0;
                R[i] = w * v0 * v1 * v2;
                dR[i][0] = w * T0[np[0] + a] * v1 * v2;
                dR[i][1] = w * v0 * T1[np[1] + b] * v2;
                dR[i][2] = w * v0 * v1 * T2[np[2] + c];
                W += R[i];
                for (int j = 0; j < 3; ++j) dW[j] += dR[i][j];
              }
          Vec3 x = Vec3::Zero();
          Mat3 dx = Mat3::Zero();
          const double iW = 1.0 / W;
          for (i = 0; i < n; ++i) {
            const double r = R[i] * iW;
            x += r * X[i];
            for (int a = 0; a < P; ++a) dx.col(a) += (dR[i][a] - r * dW[a]) * iW * X[i];
          }
          f(Vec3(X0 + x), dx, wq[0][q0] * wq[1][q1] * wq[2][q2]);
        }
  }
}

}  // namespace

double point_operations(const Patch& patch) {
  int n = 1;
  for (int d = 0; d < patch.param_dim(); ++d) n *= patch.degree(d) + 1;
  // Per function: its value and derivatives (about 20), the point (6) and each column of the Jacobian (9).
  return n * (26.0 + 9.0 * patch.param_dim());
}

namespace {

/// Reference point to integrate about (reduces cancellation for small bodies far from the origin).
Vec3 reference_point(const Patch& patch) {
  Vec3 lo, hi;
  patch.bounding_box(lo, hi);
  return 0.5 * (lo + hi);
}

}  // namespace

RegionMoments finish(const MomentSums& sums) {
  RegionMoments r;
  const double s = sums.m0 < 0 ? -1.0 : 1.0;  // orientation of the boundary
  r.measure = s * sums.m0;
  const Vec3 c = s * sums.m1 / r.measure;  // centroid relative to ref
  r.centroid = sums.ref + c;
  r.second_moment = s * sums.m2 - r.measure * c * c.transpose();
  return r;
}

std::array<double, 3> element_extents(const Patch& p, int e) {
  Param lo, hi;
  p.element_bounds(p.element_multi_index(e), lo, hi);
  const int P = p.param_dim();
  std::array<double, 3> out{0.0, 0.0, 0.0};
  for (int d = 0; d < P; ++d) {
    for (int c = 0; c < (1 << P); ++c) {
      if (c & (1 << d)) continue;
      Param x0, x1;
      for (int k = 0; k < 3; ++k) x0[k] = x1[k] = k < P ? ((c >> k) & 1 ? hi[k] : lo[k]) : 0.0;
      x1[d] = hi[d];
      x0[d] = lo[d];
      out[d] = std::max(out[d], (p.point(x1) - p.point(x0)).norm());
    }
  }
  return out;
}

double smallest_element_extent(const Patch& patch) {
  double smallest = 1e300;
  if (const std::optional<AffineMap> map = affine_map(patch)) {
    for (int d = 0; d < patch.param_dim(); ++d) {
      const KnotVector& kv = patch.knots(d);
      for (int e = 0; e < kv.n_elements(); ++e)
        smallest = std::min(smallest, std::abs(map->scale[d]) * (kv.element_end(e) - kv.element_begin(e)));
    }
    return smallest;
  }
  for (int e = 0; e < patch.n_elements(); ++e) {
    const std::array<double, 3> ext = element_extents(patch, e);
    for (int d = 0; d < patch.param_dim(); ++d) smallest = std::min(smallest, ext[d]);
  }
  return smallest;
}

double patch_measure(const Patch& patch, int extra_gauss, const ElementShare& share) {
  const int P = patch.param_dim();
  double total = 0;
  // sqrt(det(J^T J)) of the P tangent columns J, with fixed sizes (a dynamic matrix per point was a heap
  // allocation per point: the bodies' metrics evaluate this at every step).
  for_each_point(patch, extra_gauss, share, [&](const Vec3&, const Mat3& dx, double w) {
    const Mat3 G = dx.transpose() * dx;
    const double det = P == 1 ? G(0, 0) : P == 2 ? G.topLeftCorner<2, 2>().determinant() : G.determinant();
    total += w * std::sqrt(std::abs(det));
  });
  return total;
}

RegionMoments patch_moments(const Patch& patch, int extra_gauss) {
  return finish(patch_moment_sums(patch, extra_gauss));
}

MomentSums patch_moment_sums(const Patch& patch, int extra_gauss, const ElementShare& share) {
  const int P = patch.param_dim(), D = patch.physical_dim();
  if (P != D) throw std::invalid_argument("patch_moments: needs parametric dimension == physical dimension");
  const Vec3 ref = reference_point(patch);
  double M0 = 0;
  Vec3 M1 = Vec3::Zero();
  Mat3 M2 = Mat3::Zero();
  for_each_point(patch, extra_gauss, share, [&](const Vec3& x, const Mat3& dx, double w) {
    const double detJ = std::abs(dx.topLeftCorner(D, D).determinant());
    const Vec3 y = x - ref;
    M0 += w * detJ;
    M1 += w * detJ * y;
    M2 += w * detJ * y * y.transpose();
  });
  return {M0, M1, M2, ref};
}

RegionMoments enclosed_moments(const Patch& boundary, int extra_gauss) {
  return finish(enclosed_moment_sums(boundary, extra_gauss));
}

namespace {

/// enclosed_moment_sums about ref, of a closed boundary or of one part of one.
MomentSums enclosed_sums_about(const Patch& boundary, int extra_gauss, const ElementShare& share,
                               const Vec3& ref, bool whole) {
  const int P = boundary.param_dim(), D = boundary.physical_dim();
  if (P != D - 1) throw std::invalid_argument("enclosed_moments: needs a curve in 2D or a surface in 3D");
  for (int d = 0; d < P && whole; ++d)
    if (D == 2 && !boundary.closed(d))
      throw std::invalid_argument("enclosed_moments: the boundary curve is not closed");
  double M0 = 0;
  Vec3 M1 = Vec3::Zero();
  Mat3 M2 = Mat3::Zero();
  if (D == 2) {
    // Green: int_A f dA = oint F . n ds with n ds = (y', -x') du for a counter-clockwise curve.
    for_each_point(boundary, extra_gauss, share, [&](const Vec3& xx, const Mat3& dx, double w) {
      const double x = xx[0] - ref[0], y = xx[1] - ref[1], xp = dx(0, 0), yp = dx(1, 0);
      M0 += w * 0.5 * (x * yp - y * xp);
      M1[0] += w * 0.5 * x * x * yp;
      M1[1] += -w * 0.5 * y * y * xp;
      M2(0, 0) += w * x * x * x / 3.0 * yp;
      M2(1, 1) += -w * y * y * y / 3.0 * xp;
      M2(0, 1) += w * 0.5 * x * x * y * yp;
    });
    M2(1, 0) = M2(0, 1);
  } else {
    // Divergence theorem with n dA = (S_u x S_v) du dv.
    for_each_point(boundary, extra_gauss, share, [&](const Vec3& xx, const Mat3& dx, double w) {
      const Vec3 x = xx - ref;
      const Vec3 n = dx.col(0).cross(dx.col(1));
      M0 += w * x.dot(n) / 3.0;
      for (int i = 0; i < 3; ++i) M1[i] += w * 0.5 * x[i] * x[i] * n[i];
      for (int i = 0; i < 3; ++i) {
        M2(i, i) += w * x[i] * x[i] * x[i] / 3.0 * n[i];
        for (int j = i + 1; j < 3; ++j) {
          const int k = 3 - i - j;  // the third index: d/dx_k (x_i x_j x_k) = x_i x_j
          M2(i, j) += w * x[i] * x[j] * x[k] * n[k];
        }
      }
    });
    for (int i = 0; i < 3; ++i)
      for (int j = i + 1; j < 3; ++j) M2(j, i) = M2(i, j);
  }
  return {M0, M1, M2, ref};
}

}  // namespace

MomentSums enclosed_moment_sums(const Patch& boundary, int extra_gauss, const ElementShare& share) {
  return enclosed_sums_about(boundary, extra_gauss, share, reference_point(boundary), true);
}

MomentSums enclosed_moment_sums(const std::vector<Patch>& parts, int extra_gauss, const ElementShare& share) {
  if (parts.empty()) throw std::invalid_argument("enclosed_moments: no parts");
  Vec3 lo, hi;
  parts[0].bounding_box(lo, hi);
  for (const Patch& p : parts) {
    Vec3 a, b;
    p.bounding_box(a, b);
    lo = lo.cwiseMin(a), hi = hi.cwiseMax(b);
  }
  MomentSums sums{0, Vec3::Zero(), Mat3::Zero(), 0.5 * (lo + hi)};
  for (const Patch& p : parts) {
    const MomentSums s = enclosed_sums_about(p, extra_gauss, share, sums.ref, false);
    sums.m0 += s.m0, sums.m1 += s.m1, sums.m2 += s.m2;
  }
  return sums;
}

PrincipalAxes principal_axes(const RegionMoments& moments, int dim) {
  PrincipalAxes pa;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(moments.second_moment.topLeftCorner(dim, dim));
  // Eigen sorts ascending; we want descending (long axis first).
  for (int k = 0; k < dim; ++k) {
    pa.values[k] = es.eigenvalues()[dim - 1 - k];
    pa.axes.col(k).setZero();
    pa.axes.col(k).head(dim) = es.eigenvectors().col(dim - 1 - k);
  }
  return pa;
}

double long_axis_angle(const RegionMoments& moments) {
  const PrincipalAxes pa = principal_axes(moments, 2);
  double angle = std::atan2(pa.axes(1, 0), pa.axes(0, 0));
  if (angle <= -std::numbers::pi / 2) angle += std::numbers::pi;
  if (angle > std::numbers::pi / 2) angle -= std::numbers::pi;
  return angle;
}

double swelling_degree(double enclosed, double boundary, int dim) {
  if (dim == 2) return 4.0 * std::numbers::pi * enclosed / (boundary * boundary);
  return 6.0 * std::sqrt(std::numbers::pi) * enclosed / std::pow(boundary, 1.5);
}

double effective_radius(double boundary, int dim) {
  if (dim == 2) return boundary / (2.0 * std::numbers::pi);
  return std::sqrt(boundary / (4.0 * std::numbers::pi));
}

MembraneShape membrane_shape(const std::vector<Patch>& parts, int thickness_dir, int extra_gauss) {
  std::vector<Patch> mids;
  MembraneShape s;
  for (const Patch& part : parts) {
    const KnotVector& kv = part.knots(thickness_dir);
    mids.push_back(isoparametric(part, thickness_dir, 0.5 * (kv.a() + kv.b())));
    s.boundary += patch_measure(mids.back(), extra_gauss);
  }
  const int D = parts.at(0).physical_dim();
  s.moments = finish(enclosed_moment_sums(mids, extra_gauss));
  s.enclosed = s.moments.measure;
  s.swelling = swelling_degree(s.enclosed, s.boundary, D);
  s.effective_radius = effective_radius(s.boundary, D);
  return s;
}

MembraneShape membrane_shape(const Patch& membrane, int thickness_dir, int extra_gauss) {
  const KnotVector& kv = membrane.knots(thickness_dir);
  const Patch mid = isoparametric(membrane, thickness_dir, 0.5 * (kv.a() + kv.b()));
  const int D = membrane.physical_dim();
  MembraneShape s;
  s.moments = enclosed_moments(mid, extra_gauss);
  s.enclosed = s.moments.measure;
  s.boundary = patch_measure(mid, extra_gauss);
  s.swelling = swelling_degree(s.enclosed, s.boundary, D);
  s.effective_radius = effective_radius(s.boundary, D);
  return s;
}

}  // namespace cellfsi::geometry
