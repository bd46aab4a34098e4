#include "coupling/inner_viscosity.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace cellfsi::coupling {

using geometry::Vec3;

namespace {

/// Sample parameters along direction d of a patch: m per element, uniform in the parameter; a periodic
/// direction's last segment closes on the first sample, an open direction's samples include both ends.
std::vector<double> samples_along(const geometry::Patch& p, int d, int per_element, bool& periodic) {
  const geometry::KnotVector& k = p.knots(d);
  periodic = k.periodic();
  const int m = std::max(1, k.n_elements() * per_element);
  std::vector<double> t;
  for (int i = 0; i < m + (periodic ? 0 : 1); ++i) t.push_back(k.a() + (k.b() - k.a()) * i / m);
  return t;
}

// Winding number of a closed polygon about x (2D, in the xy plane); of an open one (a part of a closed
// curve), its share.
double winding_2d(const std::vector<Vec3>& poly, const Vec3& x, bool closed = true) {
  double angle = 0;
  for (std::size_t i = 0; i + (closed ? 0 : 1) < poly.size(); ++i) {
    const Vec3 a = poly[i] - x, b = poly[(i + 1) % poly.size()] - x;
    angle += std::atan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1]);
  }
  return angle / (2 * std::numbers::pi);
}

// Solid angle of triangle (a, b, c) seen from x, over 4 pi (Van Oosterom and Strackee 1983).
double triangle_winding(const Vec3& a0, const Vec3& b0, const Vec3& c0, const Vec3& x) {
  const Vec3 a = a0 - x, b = b0 - x, c = c0 - x;
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double num = a.dot(b.cross(c));
  const double den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
  return 2 * std::atan2(num, den) / (4 * std::numbers::pi);
}

}  // namespace

namespace {

/// A membrane's mid-curve or mid-surface sampled for the winding number: a polygon (2D) or a grid of
/// quadrilaterals (3D), with its box.
struct SampledMidSurface {
  int P = 0;
  std::vector<Vec3> grid;  // 2D: the polygon's vertices; 3D: n1 x n2 points, direction 1 fastest
  int n1 = 0, n2 = 0;
  bool closed1 = false, closed2 = false;  // the polygon's, or a direction's, last segment closes on the first
  Vec3 lo, hi;

  SampledMidSurface(const geometry::Patch& membrane, int samples) : P(membrane.param_dim()) {
    if (P != 2 && P != 3) throw std::invalid_argument("inside_membrane: a 2D or 3D membrane patch");
    const geometry::KnotVector& k0 = membrane.knots(0);
    const double mid = 0.5 * (k0.a() + k0.b());
    if (samples <= 0) samples = P == 2 ? 8 : 4;
    const std::vector<double> t1 = samples_along(membrane, 1, samples, closed1);
    const std::vector<double> t2 =
        P == 3 ? samples_along(membrane, 2, samples, closed2) : std::vector<double>{0.0};
    n1 = static_cast<int>(t1.size()), n2 = static_cast<int>(t2.size());
    // 2D: a periodic curve's samples close on the first; an open one's last sample is dropped where the
    // curve is closed (its ends meet), kept where it is a part.
    if (P == 2 && !closed1 && membrane.closed(1)) n1 -= 1, closed1 = true;
    for (int j = 0; j < n2; ++j)
      for (int i = 0; i < n1; ++i) grid.push_back(membrane.point({mid, t1[i], t2[j]}));
    lo = hi = grid[0];
    for (const Vec3& q : grid) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
  }

  double winding(const Vec3& x) const {
    if (P == 2) return winding_2d(grid, x, closed1);
    const int s1 = closed1 ? n1 : n1 - 1, s2 = closed2 ? n2 : n2 - 1;  // quads per direction
    double w = 0;
    for (int j = 0; j < s2; ++j)
      for (int i = 0; i < s1; ++i) {
        const Vec3& a = grid[i + n1 * j];
        const Vec3& b = grid[(i + 1) % n1 + n1 * j];
        const Vec3& c = grid[(i + 1) % n1 + n1 * ((j + 1) % n2)];
        const Vec3& d = grid[i + n1 * ((j + 1) % n2)];
        w += triangle_winding(a, b, c, x) + triangle_winding(a, c, d, x);
      }
    return w;
  }
};

std::vector<char> inside_sampled(const std::vector<SampledMidSurface>& parts,
                                 const std::vector<Vec3>& points) {
  Vec3 lo = parts[0].lo, hi = parts[0].hi;
  for (const SampledMidSurface& s : parts) lo = lo.cwiseMin(s.lo), hi = hi.cwiseMax(s.hi);
  const int D = parts[0].P;
  std::vector<char> inside(points.size(), 0);
  for (std::size_t p = 0; p < points.size(); ++p) {
    const Vec3& x = points[p];
    if ((x.head(D).array() < lo.head(D).array()).any() || (x.head(D).array() > hi.head(D).array()).any())
      continue;
    double w = 0;
    for (const SampledMidSurface& s : parts) w += s.winding(x);
    inside[p] = std::abs(w) > 0.5;
  }
  return inside;
}

}  // namespace

std::vector<char> inside_membrane(const geometry::Patch& membrane, const std::vector<Vec3>& points,
                                  int samples) {
  return inside_sampled({SampledMidSurface(membrane, samples)}, points);
}

std::vector<char> inside_membrane(const std::vector<geometry::Patch>& parts, const std::vector<Vec3>& points,
                                  int samples) {
  if (parts.empty()) throw std::invalid_argument("inside_membrane: no parts");
  std::vector<SampledMidSurface> sampled;
  for (const geometry::Patch& p : parts) sampled.emplace_back(p, samples);
  return inside_sampled(sampled, points);
}

std::vector<double> viscosity_values(const geometry::Patch& fluid, const std::vector<InnerViscosity>& inner,
                                     double mu_out) {
  std::vector<double> mu(fluid.n_control(), mu_out);
  for (const InnerViscosity& b : inner) {
    const std::vector<char> in = b.parts ? inside_membrane(*b.parts, fluid.control_points())
                                         : inside_membrane(*b.membrane, fluid.control_points());
    for (std::size_t k = 0; k < mu.size(); ++k)
      if (in[k]) mu[k] = b.viscosity;
  }
  return mu;
}

void check_inner_viscosity(const std::string& body, bool membrane, double mu_in) {
  if (!(mu_in > 0 && std::isfinite(mu_in)))
    throw std::invalid_argument("body '" + body + "': the inner viscosity must be > 0 [g/(cm s)]");
  if (!membrane)
    throw std::invalid_argument(
        "body '" + body +
        "': only a membrane (a hollow shape) encloses fluid; a bulky body has no inner "
        "viscosity");
}

}  // namespace cellfsi::coupling
