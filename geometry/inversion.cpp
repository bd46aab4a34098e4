#include "geometry/inversion.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace cellfsi::geometry {

namespace {
// Fixed-capacity (no heap) small vectors and matrices for the per-point Newton iteration.
using VecP = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 3, 1>;
using MatP = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3>;
}  // namespace

PointInverter::PointInverter(const Patch& patch, InversionOptions options)
    : patch_(patch), options_(options) {
  if (patch.param_dim() != patch.physical_dim())
    throw std::invalid_argument("PointInverter: inversion needs parametric dimension == physical dimension");
  Vec3 lo, hi;
  patch.bounding_box(lo, hi);
  scale_ = (hi - lo).norm();
  centre_ = 0.5 * (lo + hi);
  element_centres_.resize(patch.n_elements());
  BasisValues bv;
  MapValues mv;
  for (int e = 0; e < patch.n_elements(); ++e) {
    const Index3 m = patch.element_multi_index(e);
    Param a, b, c{0, 0, 0};
    patch.element_bounds(m, a, b);
    for (int d = 0; d < patch.param_dim(); ++d) c[d] = 0.5 * (a[d] + b[d]);
    patch.basis(c, 0, bv, &m);
    patch.map(bv, mv);
    element_centres_[e] = mv.x;
  }
}

namespace {
/// The periodic image of y nearest to `near`: in a direction periodic with shift s, y and y + k s are one
/// point.
Vec3 nearest_image(const Patch& patch, const Vec3& y, const Vec3& near) {
  Vec3 z = y;
  for (int d = 0; d < patch.param_dim(); ++d) {
    const Vec3& s = patch.shift(d);
    const double s2 = s.squaredNorm();
    if (!patch.knots(d).periodic() || s2 == 0) continue;
    z -= std::round((z - near).dot(s) / s2) * s;
  }
  return z;
}
}  // namespace

InversionResult PointInverter::invert(const Vec3& x_in) const {
  const Vec3 x = nearest_image(patch_, x_in, centre_);
  int best = 0;
  double best_d = std::numeric_limits<double>::infinity();
  for (int e = 0; e < static_cast<int>(element_centres_.size()); ++e) {
    const double d = (element_centres_[e] - x).squaredNorm();
    if (d < best_d) best_d = d, best = e;
  }
  const Index3 m = patch_.element_multi_index(best);
  Param a, b, c{0, 0, 0};
  patch_.element_bounds(m, a, b);
  for (int d = 0; d < patch_.param_dim(); ++d) c[d] = 0.5 * (a[d] + b[d]);
  InversionResult r = invert(x, m, c);
  return r;
}

InversionResult PointInverter::invert(const Vec3& x_in, const Index3& element, const Param& xi_guess) const {
  const int P = patch_.param_dim();
  const double tol = options_.residual_tolerance * scale_;
  InversionResult res;
  Index3 e = element;
  for (int d = 0; d < P; ++d)
    if (e[d] < 0 || e[d] >= patch_.n_elements(d))
      throw std::invalid_argument("PointInverter: element out of range");
  Param lo, hi, xi = xi_guess;
  patch_.element_bounds(e, lo, hi);
  for (int d = 0; d < P; ++d) {
    if (patch_.knots(d).periodic()) xi[d] = patch_.knots(d).normalize(xi[d]);
    xi[d] = std::clamp(xi[d], lo[d], hi[d]);
  }

  BasisValues bv;
  MapValues mv;
  // Work with the periodic image of the target nearest to the starting point.
  patch_.basis(xi, 0, bv, &e);
  Vec3 x = nearest_image(patch_, x_in, patch_.map_minus(bv, Vec3::Zero()));
  bool fixed[3] = {false, false, false};  // directions held on the patch boundary
  int stall = 0;
  for (int it = 0; it < options_.max_iterations; ++it) {
    patch_.basis(xi, 1, bv, &e);
    patch_.map(bv, mv);
    const VecP r = patch_.map_minus(bv, x).head(P);
    if (r.norm() <= tol) break;
    res.iterations = it + 1;
    const MatP J = mv.dx.topLeftCorner(P, P);
    // A direction held on the patch boundary is released when the full Newton step points back inside.
    const VecP full = J.colPivHouseholderQr().solve(-r);
    for (int d = 0; d < P; ++d)
      if (fixed[d] && ((xi[d] <= lo[d] && full[d] > 0) || (xi[d] >= hi[d] && full[d] < 0))) fixed[d] = false;
    // Step in the free directions: Newton if all are free, least squares (Gauss-Newton) otherwise.
    int free_dirs[3], n_free = 0;
    for (int d = 0; d < P; ++d)
      if (!fixed[d]) free_dirs[n_free++] = d;
    VecP step = VecP::Zero(P);
    if (n_free == P) {
      step = full;
    } else if (n_free > 0) {
      MatP Jf(P, n_free);
      for (int k = 0; k < n_free; ++k) Jf.col(k) = J.col(free_dirs[k]);
      const VecP s = Jf.colPivHouseholderQr().solve(-r);
      for (int k = 0; k < n_free; ++k) step[free_dirs[k]] = s[k];
    }
    // Apply the step. Leaving the element moves to the neighbour (at most one element per direction and
    // iteration, wrapping around closed directions) and clamps to it; at the patch boundary the direction is
    // clamped, and held once it is pushed outward from the boundary itself.
    double moved = 0;
    for (int d = 0; d < P; ++d) {
      if (fixed[d]) continue;
      const KnotVector& kv = patch_.knots(d);
      const double h = hi[d] - lo[d];
      double target = xi[d] + step[d], unwrap = 0;
      if (target < lo[d] || target > hi[d]) {
        const int dir = target < lo[d] ? -1 : +1;
        int ne = e[d] + dir;
        bool exists = ne >= 0 && ne < kv.n_elements();
        if (!exists && patch_.closed(d)) {
          ne = (ne + kv.n_elements()) % kv.n_elements();
          unwrap = -dir * kv.period();
          exists = true;
        }
        if (exists) {
          e[d] = ne;
          patch_.element_bounds(e, lo, hi);
          target = std::clamp(target + unwrap, lo[d], hi[d]);
          // Crossing the wrap moves xi by a period: the map moves by the period shift, so must the target.
          if (unwrap != 0) x += (unwrap / kv.period()) * patch_.shift(d);
          ++res.elements_visited;
        } else {
          const double face = dir < 0 ? lo[d] : hi[d];
          if (xi[d] == face) fixed[d] = true;
          target = face;
        }
      }
      moved = std::max(moved, std::abs(target - unwrap - xi[d]) / h);
      xi[d] = target;
    }
    bool held = false;
    for (int d = 0; d < P; ++d) held = held || fixed[d];
    if (!held && moved <= options_.step_tolerance) break;  // converged (the error left is ~ moved^2)
    if (moved < 1e-15) {
      if (++stall >= 2) break;  // stationary on the boundary: the nearest boundary point found (outside)
    } else {
      stall = 0;
    }
  }
  res.element = e;
  res.xi = xi;
  patch_.basis(xi, 0, bv, &e);
  patch_.map(bv, mv);
  res.distance = patch_.map_minus(bv, x).head(P).norm();
  res.inside = res.distance <= options_.inside_tolerance * scale_;
  return res;
}

}  // namespace cellfsi::geometry
