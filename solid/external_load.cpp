#include "solid/external_load.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

namespace cellfsi::solid {

using geometry::Vec3;

std::vector<Vec3> load_densities(const std::vector<Vec3>& X, const std::vector<double>& w,
                                 const std::vector<PatchLoad>& loads) {
  if (X.size() != w.size()) throw std::invalid_argument("load_densities: one weight per point");
  std::vector<Vec3> f(X.size(), Vec3::Zero());
  std::vector<int> owner(X.size(), -1);
  for (std::size_t l = 0; l < loads.size(); ++l) {
    const PatchLoad& load = loads[l];
    double volume = 0;
    std::vector<std::size_t> in;
    for (std::size_t q = 0; q < X.size(); ++q)
      if ((X[q] - load.center).norm() <= load.radius) {
        if (owner[q] >= 0)
          throw std::invalid_argument("load_densities: patches " + std::to_string(owner[q]) + " and " +
                                      std::to_string(l) + " overlap (contact radius " +
                                      std::to_string(load.radius) + " cm)");
        owner[q] = static_cast<int>(l);
        in.push_back(q);
        volume += w[q];
      }
    if (!(volume > 0))
      throw std::invalid_argument("load_densities: patch " + std::to_string(l) +
                                  " holds no material point (contact radius " + std::to_string(load.radius) +
                                  " cm is smaller than the spacing of the body's quadrature points)");
    for (std::size_t q : in) f[q] = load.force / volume;
  }
  return f;
}

std::vector<Vec3> mid_surface_points(const geometry::Patch& p, int n1, int n2) {
  const geometry::KnotVector& k0 = p.knots(0);
  const double xi0 = 0.5 * (k0.a() + k0.b());
  const geometry::KnotVector& k1 = p.knots(1);
  const bool has2 = p.param_dim() == 3;
  const int m2 = has2 ? n2 : 1;
  std::vector<Vec3> out;
  out.reserve(static_cast<std::size_t>(n1) * m2);
  for (int j = 0; j < m2; ++j) {
    double xi2 = 0;
    if (has2) xi2 = p.knots(2).a() + (p.knots(2).b() - p.knots(2).a()) * j / (n2 - 1);
    for (int i = 0; i < n1; ++i)
      out.push_back(p.point({xi0, k1.a() + (k1.b() - k1.a()) * i / (n1 - 1), xi2}));
  }
  return out;
}

std::array<Vec3, 2> membrane_ends(const geometry::Patch& membrane, const Vec3& axis) {
  return membrane_ends(mid_surface_points(membrane), axis);
}

std::array<Vec3, 2> membrane_ends(const std::vector<Vec3>& pts, const Vec3& axis) {
  if (pts.empty()) throw std::invalid_argument("membrane_ends: no points");
  auto along = [&](const Vec3& a, const Vec3& b) { return a.dot(axis) < b.dot(axis); };
  return {*std::min_element(pts.begin(), pts.end(), along), *std::max_element(pts.begin(), pts.end(), along)};
}

geometry::Vec3 mid_surface_extent(const geometry::Patch& membrane, int n1, int n2) {
  const std::vector<geometry::Vec3> pts = mid_surface_points(membrane, n1, n2);
  geometry::Vec3 lo = pts.front(), hi = pts.front();
  for (const geometry::Vec3& x : pts) lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
  return hi - lo;
}

StretchDiameters stretch_diameters(const std::vector<Vec3>& points, const Vec3& axis) {
  StretchDiameters d;
  if (points.empty()) return d;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Vec3& x : points) lo = std::min(lo, x.dot(axis)), hi = std::max(hi, x.dot(axis));
  d.axial = hi - lo;
  // An orthonormal pair (e1, e2) normal to the axis; the widths along cos t e1 + sin t e2.
  const Vec3 e1 = axis.unitOrthogonal(), e2 = axis.cross(e1);
  constexpr int kDirections = 180;
  for (int k = 0; k < kDirections; ++k) {
    const double t = std::numbers::pi * k / kDirections;
    const Vec3 n = std::cos(t) * e1 + std::sin(t) * e2;
    double a = std::numeric_limits<double>::infinity(), b = -a;
    for (const Vec3& x : points) a = std::min(a, x.dot(n)), b = std::max(b, x.dot(n));
    d.transverse = std::max(d.transverse, b - a);
  }
  return d;
}

void EquilibriumMonitor::record(double time, const StretchDiameters& d) {
  records_.push_back({time, d});
  last_change_ = std::numeric_limits<double>::quiet_NaN();
  // The latest record at least a window before this one (a small slack for the round-off of k dt).
  const double before = time - window_ * (1 - 1e-9);
  const Record* past = nullptr;
  for (const Record& r : records_)
    if (r.time <= before) past = &r;
  if (!past) return;
  last_change_ = std::max(std::abs(d.axial - past->d.axial) / d.axial,
                          std::abs(d.transverse - past->d.transverse) / d.transverse);
  // The whole window after the ramp's end (its start record at or after not_before).
  if (reached_ < 0 && last_change_ <= tolerance_ && past->time >= not_before_ * (1 - 1e-9))
    reached_ = static_cast<int>(records_.size()) - 1;
}

double EquilibriumMonitor::time() const {
  return reached_ >= 0 ? records_[reached_].time : std::numeric_limits<double>::quiet_NaN();
}

std::vector<double> EquilibriumMonitor::state() const {
  // No NaN in the numbers (JSON has none): -1 for a change not yet measured.
  std::vector<double> s{static_cast<double>(reached_), std::isnan(last_change_) ? -1.0 : last_change_};
  for (const Record& r : records_) s.insert(s.end(), {r.time, r.d.axial, r.d.transverse});
  return s;
}

void EquilibriumMonitor::restore(const std::vector<double>& s) {
  if (s.size() < 2 || (s.size() - 2) % 3 != 0)
    throw std::invalid_argument("EquilibriumMonitor::restore: the state does not fit");
  records_.clear();
  for (std::size_t k = 2; k < s.size(); k += 3) records_.push_back({s[k], {s[k + 1], s[k + 2]}});
  reached_ = static_cast<int>(s[0]);
  last_change_ = s[1] < 0 ? std::numeric_limits<double>::quiet_NaN() : s[1];
  if (reached_ >= static_cast<int>(records_.size()))
    throw std::invalid_argument("EquilibriumMonitor::restore: the state does not fit");
}

}  // namespace cellfsi::solid
