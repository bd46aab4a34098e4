#include "solid/body_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "geometry/refine.hpp"

namespace cellfsi::solid {

using geometry::Param;
using geometry::Patch;
using geometry::Vec3;

namespace {

constexpr double kPi = std::numbers::pi;
// A shape whose second moments differ by less than this relative amount has no long axis.
constexpr double kRoundShape = 1e-6;

/// a wrapped into (-period/2, period/2].
double wrap(double a, double period) {
  a = std::fmod(a, period);
  if (a > period / 2) a -= period;
  if (a <= -period / 2) a += period;
  return a;
}

/// The metric of a membrane's mid-surface (directions 1, and 2 in 3D, of the patch): a_ab = dx/dxi_a . dx/dxi_b.
/// In 2D only entry (0, 0) is the curve's; the other diagonal entry is 1 so that the matrix inverts.
Eigen::Matrix2d surface_metric(const geometry::MapValues& m, int dim) {
  Eigen::Matrix2d g = Eigen::Matrix2d::Identity();
  const Vec3 a1 = m.dx.col(1);
  g(0, 0) = a1.squaredNorm();
  if (dim == 3) {
    const Vec3 a2 = m.dx.col(2);
    g(0, 1) = g(1, 0) = a1.dot(a2);
    g(1, 1) = a2.squaredNorm();
  }
  return g;
}

}  // namespace

BodyTracker::BodyTracker(const Patch& reference, bool membrane, int plane_dir, int n_material_points)
    : BodyTracker(std::vector<Patch>{reference}, membrane, plane_dir, n_material_points) {}

BodyTracker::BodyTracker(const std::vector<Patch>& parts, bool membrane, int plane_dir, int n_material_points)
    : membrane_(membrane),
      dim_(parts.empty() ? 0 : parts[0].physical_dim()),
      plane_dir_(plane_dir),
      n_parts_(static_cast<int>(parts.size())) {
  if (parts.empty()) throw std::invalid_argument("BodyTracker: no patch");
  for (const Patch& p : parts)
    if (p.param_dim() != dim_ || p.physical_dim() != dim_)
      throw std::invalid_argument("BodyTracker: the patch must fill its space");
  if (parts.size() > 1 && !membrane)
    throw std::invalid_argument("BodyTracker: only a membrane may have parts");
  if (plane_dir < 1 || plane_dir >= dim_)
    throw std::invalid_argument("BodyTracker: plane_dir must be 1.." + std::to_string(dim_ - 1));
  if (n_material_points < 4) throw std::invalid_argument("BodyTracker: at least 4 material points");
  const Patch& reference = parts[0];
  if (!membrane) {
    // Its inner face (direction 0's start) a point or a line, of no measure: the outer face bounds it.
    const geometry::KnotVector& k0 = reference.knots(0);
    face_bounds_ = geometry::patch_measure(geometry::isoparametric(reference, 0, k0.a())) <=
                   1e-12 * geometry::patch_measure(geometry::isoparametric(reference, 0, k0.b()));
  }
  geometry::RegionMoments region;
  measure(parts, {}, area0_, boundary0_, region);
  const geometry::PrincipalAxes ax = geometry::principal_axes(region, dim_);
  elongated_ = ax.values[0] > 1.01 * ax.values[dim_ - 1];
  // Material points: mid-thickness of a membrane, the outer face of a bulky body; a part's share of them.
  const int n_material = std::max(4, n_material_points / n_parts_);
  for (int k = 0; k < n_parts_; ++k) {
    const geometry::KnotVector& k0 = parts[k].knots(0);
    const double xi0 = membrane ? 0.5 * (k0.a() + k0.b()) : k0.b();
    const geometry::KnotVector& k1 = parts[k].knots(1);
    if (dim_ == 2) {
      for (int i = 0; i < n_material; ++i)
        material_xi_.push_back({xi0, k1.a() + (k1.b() - k1.a()) * i / n_material, 0});
    } else {
      const geometry::KnotVector& k2 = parts[k].knots(2);
      const int n1 = std::max(2, n_material / 2);
      for (int j = 0; j < n1; ++j)
        for (int i = 0; i < n_material; ++i)
          material_xi_.push_back({xi0, k1.a() + (k1.b() - k1.a()) * (j + 0.5) / n1,
                                  k2.a() + (k2.b() - k2.a()) * i / n_material});
    }
    material_part_.resize(material_xi_.size(), k);
  }
  for (std::size_t i = 0; i < material_xi_.size(); ++i) {
    const Vec3 y = parts[material_part_[i]].point(material_xi_[i]) - region.centroid;
    weights_.push_back(dim_ == 2 ? 1.0 : y[0] * y[0] + y[plane_dir_] * y[plane_dir_]);
  }
  if (membrane) {
    // 4 points per element in each direction along the mid-surface (at the element's quarter points'
    // midpoints), where the largest stretch is looked for.
    const int per = 4;
    for (int k = 0; k < n_parts_; ++k) {
      const geometry::KnotVector& k0 = parts[k].knots(0);
      const double xi0 = 0.5 * (k0.a() + k0.b());
      auto samples = [&](int dir) {
        std::vector<double> t;
        if (dir >= dim_) return std::vector<double>{0.0};
        const geometry::KnotVector& kv = parts[k].knots(dir);
        const int n = kv.n_elements() * per;
        for (int i = 0; i < n; ++i) t.push_back(kv.a() + (kv.b() - kv.a()) * (i + 0.5) / n);
        return t;
      };
      for (double t2 : samples(2))
        for (double t1 : samples(1)) stretch_xi_.push_back({xi0, t1, t2});
      stretch_part_.resize(stretch_xi_.size(), k);
    }
    for (std::size_t i = 0; i < stretch_xi_.size(); ++i)
      reference_metric_inverse_.push_back(
          surface_metric(parts[stretch_part_[i]].evaluate(stretch_xi_[i]), dim_).inverse());
  }
}

std::vector<std::pair<double, Vec3>> BodyTracker::centroid_track() const {
  std::vector<std::pair<double, Vec3>> out;
  for (const Sample& s : history_) out.emplace_back(s.time, s.centroid);
  return out;
}

Migration lateral_migration(const std::vector<std::pair<double, Vec3>>& track, int dir, double mid,
                            double fraction) {
  Migration m;
  if (track.empty()) return m;
  m.offset_start = track.front().second[dir] - mid;
  m.offset_final = track.back().second[dir] - mid;
  m.time_to_centreline = std::numeric_limits<double>::quiet_NaN();
  for (const auto& [t, c] : track)
    if (std::abs(c[dir] - mid) <= fraction * std::abs(m.offset_start)) {
      m.time_to_centreline = t - track.front().first;
      break;
    }
  return m;
}

LateralEquilibrium lateral_equilibrium(const std::vector<std::pair<double, Vec3>>& track, int dir, double mid,
                                       double tolerance, double window) {
  if (track.empty() || !(window > 0 && window <= 1))
    throw std::invalid_argument("lateral_equilibrium: a non-empty track and a window in (0, 1]");
  const double t0 = track.front().first, t1 = track.back().first, from = t1 - window * (t1 - t0);
  // The offset's mean and least-squares slope over the window.
  double n = 0, st = 0, sy = 0, stt = 0, sty = 0;
  for (const auto& [t, c] : track)
    if (t >= from) {
      const double y = c[dir] - mid, tau = t - from;
      n += 1, st += tau, sy += y, stt += tau * tau, sty += tau * y;
    }
  LateralEquilibrium e;
  e.offset = sy / n;
  const double var = n * stt - st * st;
  e.drift = var > 0 ? (n * sty - st * sy) / var : 0.0;
  // The last record outside the band, and the time of the record after it.
  e.settle_time = 0;
  for (std::size_t i = track.size(); i-- > 0;)
    if (std::abs(track[i].second[dir] - mid - e.offset) > tolerance) {
      e.settle_time =
          i + 1 < track.size() ? track[i + 1].first - t0 : std::numeric_limits<double>::quiet_NaN();
      break;
    }
  return e;
}

double mirror_asymmetry(const std::vector<Vec3>& curve, const Vec3& centre, int axis) {
  if (curve.size() < 3 || (axis != 0 && axis != 1))
    throw std::invalid_argument("mirror_asymmetry: at least 3 points, axis 0 or 1");
  const int across = 1 - axis;  // the coordinate that the mirror flips
  double dist = 0, radius = 0;
  for (const Vec3& p : curve) {
    Vec3 m = p;
    m[across] = 2 * centre[across] - p[across];
    double nearest = std::numeric_limits<double>::max();
    for (const Vec3& q : curve) nearest = std::min(nearest, (m - q).head<2>().squaredNorm());
    dist += std::sqrt(nearest);
    radius += (p - centre).head<2>().norm();
  }
  return radius > 0 ? dist / radius : 0.0;
}

std::vector<double> BodyTracker::state() const {
  // [n_angles, angles..., n_records, per record: time r_a r_p axis anisotropy material cx cy cz stretch]
  std::vector<double> out{static_cast<double>(last_angles_.size())};
  out.insert(out.end(), last_angles_.begin(), last_angles_.end());
  out.push_back(static_cast<double>(history_.size()));
  for (const Sample& s : history_)
    out.insert(out.end(), {s.time, s.r_a, s.r_p, s.axis, s.anisotropy, s.material, s.centroid[0],
                           s.centroid[1], s.centroid[2], s.stretch});
  return out;
}

void BodyTracker::restore(const std::vector<double>& state) {
  auto bad = [] { return std::invalid_argument("BodyTracker::restore: the state does not fit this body"); };
  std::size_t k = 0;
  auto next = [&]() {
    if (k >= state.size()) throw bad();
    return state[k++];
  };
  const double n_angles = next();
  if (n_angles != static_cast<double>(material_xi_.size()) && n_angles != 0) throw bad();
  std::vector<double> angles;
  for (int i = 0; i < static_cast<int>(n_angles); ++i) angles.push_back(next());
  const double n_records = next();
  if (!(n_records >= 0)) throw bad();
  // 10 numbers per record; 9 in checkpoints written before the stretch was kept (it restarts from 0 there).
  const auto n = static_cast<std::size_t>(n_records);
  const std::size_t per_record = state.size() == k + 10 * n ? 10 : state.size() == k + 9 * n ? 9 : 0;
  if (per_record == 0) throw bad();
  std::vector<Sample> history(n);
  for (Sample& s : history) {
    s.time = next(), s.r_a = next(), s.r_p = next(), s.axis = next(), s.anisotropy = next();
    s.material = next();
    for (int c = 0; c < 3; ++c) s.centroid[c] = next();
    if (per_record == 10) s.stretch = next();
  }
  last_angles_ = std::move(angles);
  history_ = std::move(history);
}

void BodyTracker::measure(const std::vector<Patch>& parts, const MetricShare& share, double& area,
                          double& boundary, geometry::RegionMoments& region) const {
  if (static_cast<int>(parts.size()) != n_parts_)
    throw std::invalid_argument("BodyTracker: " + std::to_string(parts.size()) + " patches for a body of " +
                                std::to_string(n_parts_));
  const Patch& p = parts[0];
  // A membrane: the band's own measure, the mid-surface's and the moments of the region it encloses
  // (geometry::membrane_shape's integrals); a bulky body: its outer face's measure and the moments of the
  // region that face encloses, which is the body.
  constexpr int kExtra = 2;
  double measures[2] = {0, 0};  // the body's own (a membrane's), the boundary's
  geometry::MomentSums sums;
  if (membrane_ && n_parts_ > 1) {
    std::vector<Patch> mids;
    for (const Patch& part : parts) {
      const geometry::KnotVector& kv = part.knots(0);
      mids.push_back(geometry::isoparametric(part, 0, 0.5 * (kv.a() + kv.b())));
      measures[0] += geometry::patch_measure(part, kExtra, share.elements);
      measures[1] += geometry::patch_measure(mids.back(), kExtra, share.elements);
    }
    sums = geometry::enclosed_moment_sums(mids, kExtra, share.elements);
  } else if (membrane_) {
    const geometry::KnotVector& kv = p.knots(0);
    const Patch mid = geometry::isoparametric(p, 0, 0.5 * (kv.a() + kv.b()));
    measures[0] = geometry::patch_measure(p, kExtra, share.elements);
    measures[1] = geometry::patch_measure(mid, kExtra, share.elements);
    sums = geometry::enclosed_moment_sums(mid, kExtra, share.elements);
  } else {
    // Where its outer face bounds it (direction 0 runs from a degenerate centre, as the scenes' bulky shapes'
    // do): the moments by the divergence theorem over the face, as a membrane's, where its volume's integrals
    // took 7168 elements at 125 points for the paper's 3D nucleus (0.21 s of a 64^3 step's 0.32 s of metrics,
    // on every rank) against the face's 1024 at 25. Otherwise (a hollow body) its volume's.
    const Patch face = geometry::isoparametric(p, 0, p.knots(0).b());
    measures[1] = geometry::patch_measure(face, kExtra, share.elements);
    sums = face_bounds_ ? geometry::enclosed_moment_sums(face, kExtra, share.elements)
                        : geometry::patch_moment_sums(p, kExtra, share.elements);
  }
  if (share.sum) {
    double v[15] = {measures[0], measures[1], sums.m0, sums.m1[0], sums.m1[1], sums.m1[2]};
    for (int i = 0; i < 9; ++i) v[6 + i] = sums.m2(i / 3, i % 3);
    share.sum(v, 15);
    measures[0] = v[0], measures[1] = v[1], sums.m0 = v[2];
    for (int i = 0; i < 3; ++i) sums.m1[i] = v[3 + i];
    for (int i = 0; i < 9; ++i) sums.m2(i / 3, i % 3) = v[6 + i];
  }
  region = geometry::finish(sums);
  area = membrane_ ? measures[0] : region.measure;
  boundary = measures[1];
}

double BodyTracker::largest_stretch(const std::vector<Patch>& parts_list, const MetricShare& share) const {
  // The squared principal stretches are the eigenvalues of G^{-1} g (G, g: the reference and current
  // metrics), which are those of the symmetric G^{-1/2} g G^{-1/2}; the larger of a 2 x 2 pair in closed form.
  double largest = 0;
  // (The share was checked by measure(), which record() calls first.)
  const std::vector<Patch>& parts_of = parts_list;
  const std::size_t n = stretch_xi_.size(), parts = share.elements.parts, part = share.elements.part;
  if (share.elements.operations)
    *share.elements.operations += static_cast<double>(n * (part + 1) / parts - n * part / parts) *
                                  (geometry::point_operations(parts_of[0]) + 20.0);
  for (std::size_t i = n * part / parts; i < n * (part + 1) / parts; ++i) {
    const Eigen::Matrix2d m = reference_metric_inverse_[i] *
                              surface_metric(parts_of[stretch_part_[i]].evaluate(stretch_xi_[i]), dim_);
    double l2 = m(0, 0);
    if (dim_ == 3) {
      const double tr = m.trace(), det = m.determinant();
      l2 = 0.5 * tr + std::sqrt(std::max(0.0, 0.25 * tr * tr - det));
    }
    largest = std::max(largest, std::sqrt(l2));
  }
  if (share.max) share.max(&largest, 1);
  return largest;
}

std::vector<double> BodyTracker::material_angles(const std::vector<Patch>& parts,
                                                 const Vec3& centroid) const {
  std::vector<double> a;
  a.reserve(material_xi_.size());
  for (std::size_t i = 0; i < material_xi_.size(); ++i) {
    const Vec3 y = parts[material_part_[i]].point(material_xi_[i]) - centroid;
    a.push_back(std::atan2(y[plane_dir_], y[0]));
  }
  return a;
}

void BodyTracker::record(double time, const Patch& current, const MetricShare& share) {
  record(time, std::vector<Patch>{current}, share);
}

void BodyTracker::record(double time, const std::vector<Patch>& current, const MetricShare& share) {
  if (!history_.empty() && !(time > history_.back().time))
    throw std::invalid_argument("BodyTracker::record: times must increase");
  double area = 0, boundary = 0;
  geometry::RegionMoments region;
  measure(current, share, area, boundary, region);
  Sample s;
  s.time = time;
  s.r_a = (area - area0_) / area0_;
  s.r_p = (boundary - boundary0_) / boundary0_;
  s.centroid = region.centroid;
  const geometry::PrincipalAxes ax = geometry::principal_axes(region, dim_);
  double axis = std::atan2(ax.axes(plane_dir_, 0), ax.axes(0, 0));
  // The second moments in the shear plane: the whole in 2D, the (x, plane_dir) block in 3D. Their principal
  // values give the deformation index (descending: l0 >= l1).
  geometry::RegionMoments in_plane;
  const int ix[2] = {0, plane_dir_};
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) in_plane.second_moment(r, c) = region.second_moment(ix[r], ix[c]);
  const Vec3 l = geometry::principal_axes(in_plane, 2).values;
  const double long_side = std::sqrt(std::max(l[0], 0.0)), short_side = std::sqrt(std::max(l[1], 0.0));
  deformation_index_ = long_side > 0 ? (long_side - short_side) / (long_side + short_side) : 0.0;
  if (dim_ == 3) {
    // The long axis in the shear plane, of that block: an oblate body (an RBC) has two equal largest moments,
    // and its 3D long axis may be any direction in its disc, out of the plane.
    axis = geometry::long_axis_angle(in_plane);
    // The short axis (an RBC's axis of symmetry) against the vorticity direction, the axis normal to the
    // shear plane: 0 when the body rolls about it, 90 deg when the short axis lies in the shear plane.
    const int vorticity = 3 - plane_dir_;
    short_axis_to_vorticity_ = std::acos(std::min(1.0, std::abs(ax.axes(vorticity, 2)))) * 180 / kPi;
  }
  s.anisotropy = ax.values[dim_ - 1] > 0 ? ax.values[0] / ax.values[dim_ - 1] - 1 : 0.0;
  if (membrane_) s.stretch = largest_stretch(current, share);
  std::vector<double> angles = material_angles(current, region.centroid);
  if (history_.empty()) {
    s.axis = wrap(axis, kPi);
  } else {
    const Sample& prev = history_.back();
    s.axis = prev.axis + wrap(axis - prev.axis, kPi);  // the axis has no sign: unwrap modulo pi
    for (size_t i = 0; i < angles.size(); ++i)
      angles[i] = last_angles_[i] + wrap(angles[i] - last_angles_[i], 2 * kPi);
  }
  double wsum = 0, msum = 0;
  for (size_t i = 0; i < angles.size(); ++i) wsum += weights_[i], msum += weights_[i] * angles[i];
  s.material = msum / wsum;
  last_angles_ = std::move(angles);
  history_.push_back(s);
}

std::vector<Metric> BodyTracker::metrics() const {
  if (history_.empty()) throw std::logic_error("BodyTracker::metrics before the first record");
  const Sample& s = history_.back();
  double w_mat = 0, w_axis = 0;
  if (history_.size() > 1) {
    const Sample& p = history_[history_.size() - 2];
    const double dt = s.time - p.time;
    w_mat = -(s.material - p.material) / (2 * kPi * dt);
    w_axis = -(s.axis - p.axis) / (2 * kPi * dt);
  }
  std::vector<Metric> m{{"r_A", s.r_a}, {"r_P", s.r_p}};
  for (int d = 0; d < dim_; ++d) m.emplace_back(std::string("centroid_") + "xyz"[d], s.centroid[d]);
  // Every record has the same names (metrics.csv columns): NaN while a round body's shape has no axis yet.
  m.emplace_back("theta_deg", elongated_ || s.anisotropy > kRoundShape
                                  ? wrap(s.axis, kPi) * 180 / kPi
                                  : std::numeric_limits<double>::quiet_NaN());
  m.emplace_back("deformation_index", deformation_index_);
  if (dim_ == 3) m.emplace_back("short_axis_to_vorticity_deg", short_axis_to_vorticity_);
  if (membrane_) {
    m.emplace_back("omega_tt", w_mat);
    if (elongated_) m.emplace_back("omega_tu", w_axis);
  } else {
    m.emplace_back("omega_tu", elongated_ ? w_axis : w_mat);
    if (elongated_) m.emplace_back("omega_material", w_mat);
  }
  return m;
}

std::vector<const BodyTracker::Sample*> BodyTracker::window(double average_from) const {
  std::vector<const Sample*> win;
  for (const Sample& s : history_)
    if (s.time >= average_from) win.push_back(&s);
  return win;
}

std::string BodyTracker::regime(double average_from) const {
  const std::vector<const Sample*> win = window(average_from);
  if (win.size() < 2) return "undetermined";
  std::vector<double> axis, material;
  for (const Sample* s : win) axis.push_back(s->axis), material.push_back(s->material);
  return motion_regime(!elongated_, membrane_, axis, material);
}

std::vector<Metric> BodyTracker::summary(double average_from) const {
  if (history_.empty()) throw std::logic_error("BodyTracker::summary before the first record");
  const std::vector<const Sample*> win = window(average_from);
  double max_ra = 0, max_rp = 0;
  for (const Sample& s : history_)
    max_ra = std::max(max_ra, std::abs(s.r_a)), max_rp = std::max(max_rp, std::abs(s.r_p));
  // The most deformed record: the largest anisotropy of the shape (largest / smallest second moment - 1),
  // when and where (the CTC's nucleus deforms most as it leaves the narrowing, paper Sec. 4.4).
  const Sample* peak = &history_.front();
  for (const Sample& s : history_)
    if (s.anisotropy > peak->anisotropy) peak = &s;
  std::vector<Metric> m{{"r_A", history_.back().r_a},
                        {"r_P", history_.back().r_p},
                        {"max_abs_r_A", max_ra},
                        {"max_abs_r_P", max_rp},
                        {"max_anisotropy", peak->anisotropy},
                        {"max_anisotropy_time", peak->time},
                        {"max_anisotropy_x", peak->centroid[0]}};
  if (membrane_) {
    double stretch = 0;
    for (const Sample& s : history_) stretch = std::max(stretch, s.stretch);
    m.emplace_back("max_stretch", stretch);
  }
  if (win.size() < 2) return m;  // no window to average over (a run of one step)
  const Sample& a = *win.front();
  const Sample& b = *win.back();
  const double T = b.time - a.time;
  const bool has_axis = elongated_ || std::all_of(win.begin(), win.end(), [](const Sample* s) {
                          return s->anisotropy > kRoundShape;
                        });
  if (has_axis) {
    double mean = 0, lo = win.front()->axis, hi = lo;
    // Trapezoidal time average (steps may differ in length).
    for (size_t i = 1; i < win.size(); ++i)
      mean += 0.5 * (win[i]->axis + win[i - 1]->axis) * (win[i]->time - win[i - 1]->time);
    for (const Sample* s : win) lo = std::min(lo, s->axis), hi = std::max(hi, s->axis);
    mean /= T;
    // The mean is shifted by the same multiple of pi as the unwrapped axis; report it in (-90, 90].
    m.emplace_back("theta_deg", wrap(mean, kPi) * 180 / kPi);
    m.emplace_back("theta_oscillation_deg", 0.5 * (hi - lo) * 180 / kPi);
  }
  const double w_mat = -(b.material - a.material) / (2 * kPi * T);
  std::vector<double> times, axis;
  for (const Sample* s : win) times.push_back(s->time), axis.push_back(s->axis);
  int half_turns = 0;
  const double w_axis = tumbling_frequency(times, axis, &half_turns);
  if (membrane_)
    m.emplace_back("omega_tt", w_mat);
  else if (!elongated_)
    m.emplace_back("omega_tu", w_mat);
  if (elongated_) {
    m.emplace_back("omega_tu", w_axis);
    m.emplace_back("omega_tu_half_turns", half_turns);
    if (!membrane_) m.emplace_back("omega_material", w_mat);
  }
  m.emplace_back("average_from", a.time);
  m.emplace_back("average_to", b.time);
  return m;
}

std::string motion_regime(bool round, bool membrane, const std::vector<double>& axis,
                          const std::vector<double>& material, double swing_deg) {
  if (axis.size() < 2 || axis.size() != material.size())
    throw std::invalid_argument("motion_regime: at least two records of axis and material angles");
  const double turned = std::abs(axis.back() - axis.front()),
               moved = std::abs(material.back() - material.front());
  // A round body's axis says nothing (a circle squeezed through a narrowing swaps its long axis without
  // turning): its material decides.
  if (round) return moved < kPi / 2 ? "steady" : membrane ? "tank-treading" : "tumbling";
  // Net passages of the axis through the vertical (pi/2 + k pi): the change of the side it is on, between the
  // first and the last record at least 1 deg clear of a vertical (a body started with its axis across the
  // flow, at 90 deg exactly, has not passed it by turning away; a flip back and forth nets nothing).
  const double clear = kPi / 180;
  long first_side = 0, last_side = 0;
  bool any_clear = false;
  for (const double a : axis) {
    const double k = std::floor((a - kPi / 2) / kPi);  // the vertical below a is pi/2 + k pi
    const double from_vertical = std::min(a - (kPi / 2 + k * kPi), kPi / 2 + (k + 1) * kPi - a);
    if (from_vertical < clear) continue;
    last_side = std::lround(k);
    if (!any_clear) first_side = last_side, any_clear = true;
  }
  const bool passed_vertical = any_clear && last_side != first_side;
  if (turned >= kPi * (1 - 1e-12) || passed_vertical || (turned >= kPi / 4 && turned >= 0.5 * moved))
    return "tumbling";
  if (moved < kPi / 2) return "steady";
  const auto [lo, hi] = std::minmax_element(axis.begin(), axis.end());
  return 0.5 * (*hi - *lo) * 180 / kPi >= swing_deg ? "swinging" : "tank-treading";
}

double tumbling_frequency(const std::vector<double>& times, const std::vector<double>& axis,
                          int* half_turns) {
  if (times.size() < 2 || times.size() != axis.size())
    throw std::invalid_argument("tumbling_frequency: at least two records of times and angles");
  const double a0 = axis.front();
  const double total = axis.back() - a0;
  const int n = static_cast<int>(std::floor(std::abs(total) / kPi + 1e-12));
  if (half_turns) *half_turns = n;
  if (n == 0) return -total / (2 * kPi * (times.back() - times.front()));
  // The first time the axis has turned by n pi (linear between records).
  const double target = (total > 0 ? 1 : -1) * n * kPi;
  for (size_t i = 1; i < axis.size(); ++i) {
    const double d0 = axis[i - 1] - a0, d1 = axis[i] - a0;
    if ((d1 - target) * (target > 0 ? 1 : -1) >= 0) {
      const double f = d1 != d0 ? (target - d0) / (d1 - d0) : 1.0;
      const double t = times[i - 1] + f * (times[i] - times[i - 1]);
      return -target / (2 * kPi * (t - times.front()));
    }
  }
  return -total / (2 * kPi * (times.back() - times.front()));  // not reached: the last record has turned n pi
}

namespace {

/// Delta and R0, and the flow's numbers from R0.
std::vector<Metric> numbers_from(double delta, double r0, bool membrane, double thickness,
                                 double shear_modulus, const FlowScales& flow) {
  std::vector<Metric> m{{"Delta", delta}, {"R0", r0}};
  if (flow.half_width > 0) m.emplace_back("chi", r0 / flow.half_width);
  if (flow.shear_rate > 0 && flow.viscosity > 0) {
    m.emplace_back("Re", flow.density * flow.shear_rate * r0 * r0 / flow.viscosity);
    if (shear_modulus > 0)
      m.emplace_back("Ca", membrane ? flow.viscosity * flow.shear_rate * r0 / (thickness * shear_modulus)
                                    : flow.viscosity * flow.shear_rate / shear_modulus);
  }
  return m;
}

}  // namespace

std::vector<Metric> dimensionless_numbers(const Patch& reference, bool membrane, double thickness,
                                          double shear_modulus, const FlowScales& flow) {
  const int dim = reference.physical_dim();
  double delta = 0, r0 = 0;
  if (membrane) {
    const geometry::MembraneShape s = geometry::membrane_shape(reference, 0);
    delta = s.swelling, r0 = s.effective_radius;
  } else {
    const double boundary =
        geometry::patch_measure(geometry::isoparametric(reference, 0, reference.knots(0).b()));
    delta = geometry::swelling_degree(geometry::patch_measure(reference), boundary, dim);
    r0 = geometry::effective_radius(boundary, dim);
  }
  return numbers_from(delta, r0, membrane, thickness, shear_modulus, flow);
}

double filling_fraction(const Patch& inclusion, const Patch& membrane) {
  return geometry::patch_measure(inclusion) / geometry::membrane_shape(membrane, 0).enclosed;
}

std::vector<Metric> dimensionless_numbers(const std::vector<Patch>& reference, bool membrane,
                                          double thickness, double shear_modulus, const FlowScales& flow) {
  if (reference.size() == 1)
    return dimensionless_numbers(reference[0], membrane, thickness, shear_modulus, flow);
  if (!membrane) throw std::invalid_argument("dimensionless_numbers: only a membrane may have parts");
  const geometry::MembraneShape s = geometry::membrane_shape(reference, 0);
  return numbers_from(s.swelling, s.effective_radius, true, thickness, shear_modulus, flow);
}

double filling_fraction(const Patch& inclusion, const std::vector<Patch>& membrane) {
  if (membrane.size() == 1) return filling_fraction(inclusion, membrane[0]);
  return geometry::patch_measure(inclusion) / geometry::membrane_shape(membrane, 0).enclosed;
}

}  // namespace cellfsi::solid
