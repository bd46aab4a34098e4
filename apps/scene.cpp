#include "apps/scene.hpp"

#include <petscsys.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>

#include "common/option_table.hpp"
#include "common/petsc_error.hpp"
#include "coupling/placement.hpp"
#include "fluid/fluid_output.hpp"
#include "geometry/measures.hpp"

namespace cellfsi::app {

using geometry::Vec3;

geometry::Patch build_domain(const SceneSettings& s) {
  if (s.domain == "rectangle")
    return geometry::rectangle(s.size[0], s.size[1], s.elements[0], s.elements[1], s.degree,
                               {s.periodic[0], s.periodic[1]}, s.origin);
  if (s.domain == "box")
    return geometry::box(s.size[0], s.size[1], s.size[2], s.elements[0], s.elements[1], s.elements[2],
                         s.degree, {s.periodic[0], s.periodic[1], s.periodic[2]}, s.origin);
  return geometry::narrowing_channel(s.channel, s.elements[0], s.elements[1], s.degree);
}

namespace {

/// The smallest Eulerian element extent of the scene's (uniform or channel) mesh.
double fluid_element_size(const SceneSettings& s) {
  if (s.domain == "narrowing")
    return std::min({s.channel.length / s.elements[0], s.channel.throat_height / s.elements[1]});
  double h = 1e300;
  for (int d = 0; d < s.dim; ++d) h = std::min(h, s.size[d] / s.elements[d]);
  return h;
}

geometry::Patch make_body(const SceneSettings& s, const BodySettings& b, const std::array<int, 3>& n) {
  Vec3 c = b.center;
  if (!std::isfinite(c[0])) {
    Vec3 lo, hi;
    build_domain(s).bounding_box(lo, hi);
    c = 0.5 * (lo + hi);
  }
  const double angle = b.angle_deg * std::numbers::pi / 180;
  const std::vector<double>& a = b.semi_axes;
  if (b.shape == "hollow_ellipse")
    return geometry::hollow_ellipse(a[0], a[1], b.thickness, n[1], b.degree, c, angle);
  if (b.shape == "ellipse") return geometry::bulky_ellipse(a[0], a[1], n[0], n[1], b.degree, c, angle);
  if (b.shape == "rbc")
    return geometry::biconcave_rbc(b.thickness, n[1], b.degree, c, angle,
                                   b.area > 0 ? b.area : geometry::kRbcArea2d);
  // 3D: built axis-aligned at c, then turned about c.
  const geometry::Mat3 A = Eigen::AngleAxisd(angle, b.axis).toRotationMatrix();
  if (b.shape == "hollow_ellipsoid")
    return geometry::transformed(
        geometry::hollow_ellipsoid(a[0], a[1], a[2], b.thickness, n[1], n[2], b.degree, c), A, c - A * c);
  return geometry::transformed(geometry::solid_ellipsoid(a[0], a[1], a[2], n[0], n[1], n[2], b.degree, c), A,
                               c - A * c);
}

}  // namespace

std::array<int, 3> body_element_counts(const SceneSettings& s, const BodySettings& b) {
  // Automatic counts: elements slightly smaller (0.9) than the smallest fluid element (paper Sec. 3.4),
  // scaled from a trial mesh (element size ~ 1 / count).
  const double target = 0.9 * std::min(1.0, s.max_mesh_ratio) * fluid_element_size(s);
  std::array<int, 3> n = b.elements;
  const int D = s.dim;
  const int mult = 4;  // elements around: every builder needs a multiple of 4
  if (b.membrane()) n[0] = 1;
  std::array<int, 3> trial{b.membrane() ? 1 : 2, 16, 16};
  if (D == 3) trial[1] = 8;
  bool any_auto = false;
  for (int d = 0; d < D; ++d) any_auto = any_auto || n[d] == 0;
  if (!any_auto) return n;
  // The trial's element sizes do not depend on where it is: drawn at the origin, not at the domain's centre
  // (which would build the fluid patch).
  BodySettings at_origin = b;
  if (!std::isfinite(at_origin.center[0])) at_origin.center = Vec3::Zero();
  const geometry::Patch t = make_body(s, at_origin, trial);
  for (int d = 0; d < D; ++d) {
    if (n[d] != 0) continue;
    // Largest extent along direction d of the trial mesh (measured as the Remark 3 check measures it).
    double ext = 0;
    for (int e = 0; e < t.n_elements(); ++e) ext = std::max(ext, geometry::element_extents(t, e)[d]);
    // Capped where int ends (a throat far narrower than the cell asks for billions): the memory check
    // refuses such a count with its estimate.
    const double m = std::min(std::max(d == 0 ? 2.0 : 4.0, std::ceil(trial[d] * ext / target)), 1e9);
    const int step = d == 0 ? 1 : (D == 3 && d == 1 ? 2 : mult);
    n[d] = (static_cast<int>(m) + step - 1) / step * step;
  }
  return n;
}

geometry::Patch build_body_patch(const SceneSettings& s, const BodySettings& b) {
  return make_body(s, b, body_element_counts(s, b));
}

std::vector<std::unique_ptr<solid::NurbsSolid>> build_bodies(const SceneSettings& s) {
  std::vector<std::unique_ptr<solid::NurbsSolid>> out;
  for (const BodySettings& b : s.bodies)
    out.push_back(std::make_unique<solid::NurbsSolid>(
        b.name, build_body_patch(s, b), std::make_shared<solid::DeviatoricNeoHookean>(b.shear_modulus),
        b.density));
  return out;
}

void check_bodies(const SceneSettings& s, const geometry::Patch& domain) {
  if (s.bodies.empty()) return;
  // The cheap checks of every body (its centre, its mesh against the fluid's) come before the costly ones
  // (its points located in the fluid mesh, the overlaps): a mesh the ratio refuses must not first be
  // located point by point.
  std::vector<coupling::BodyPlacement> placed;
  Vec3 lo, hi;
  domain.bounding_box(lo, hi);
  for (const BodySettings& b : s.bodies) {
    // A periodic direction wraps every point into the domain (the locator finds their images), but the body
    // is drawn where its centre is: the centre itself must lie inside.
    for (int d = 0; d < s.dim && std::isfinite(b.center[0]); ++d)
      if (s.periodic[d] && !(b.center[d] >= lo[d] && b.center[d] < hi[d])) {
        std::ostringstream v, w;
        for (int e = 0; e < s.dim; ++e) v << (e ? "," : "") << b.center[e];
        w << "a centre inside the domain, " << lo[d] << " <= "
          << "xyz"[d] << " < " << hi[d] << " cm in the periodic direction "
          << "xyz"[d];
        bad_option("solid_" + b.name + "_center", v.str(), w.str());
      }
    coupling::BodyPlacement pl{b.name, build_body_patch(s, b), b.membrane()};
    const coupling::Resolution r = coupling::resolution(domain, pl);
    if (r.ratio() > s.max_mesh_ratio) {
      std::ostringstream os;
      os << "Lagrangian elements no larger than " << s.max_mesh_ratio
         << " x the fluid's (paper Remark 3): body '" << b.name << "' has elements of " << r.solid_element
         << " cm, the fluid " << r.fluid_element
         << " cm; use more body elements (0: automatic) or -coupling_max_mesh_ratio";
      std::ostringstream v;
      for (int d = 0; d < s.dim; ++d) v << (d ? "," : "") << pl.patch.n_elements(d);
      bad_option("solid_" + b.name + "_elements", v.str(), os.str());
    }
    // The cell must span the fluid mesh: its smallest semi-axis at least one fluid element.
    if (!b.semi_axes.empty()) {
      const double amin = *std::min_element(b.semi_axes.begin(), b.semi_axes.end());
      if (amin < r.fluid_element) {
        std::ostringstream v, w;
        for (int d = 0; d < s.dim; ++d) v << (d ? "," : "") << s.elements[d];
        w << "a fluid mesh with elements no larger than the smallest semi-axis of body '" << b.name << "' ("
          << amin << " cm; now " << r.fluid_element << " cm)";
        bad_option("fluid_elements", v.str(), w.str());
      }
    }
    placed.push_back(std::move(pl));
  }
  const coupling::Locator locator(domain);
  for (const coupling::BodyPlacement& pl : placed) coupling::check_inside(locator, pl);
  coupling::check_no_overlap(placed);
}

Scene::Scene(MPI_Comm comm, const SceneSettings& settings) : s_(settings) {
  const int D = s_.dim;
  profile_from_ = average_from();
  patch_ = build_domain(s_);
  for (int d = D - 1; d >= 0 && wall_dir_ < 0; --d)
    if (!patch_.knots(d).periodic()) wall_dir_ = d;

  fluid::FluidOptions fo;
  fo.dt = s_.dt;
  fo.set_from_options(D);
  Vec3 lo, hi;
  patch_.bounding_box(lo, hi);
  if (s_.flow == "shear") {
    if (wall_dir_ <= 0)
      throw std::invalid_argument("option -flow = shear needs a wall direction other than x");
    // Walls move at -+ gammadot H / 2 along x, so a centred cell stays put (docs/design.md §3).
    const double H = s_.size[wall_dir_];
    fo.wall_velocity[wall_dir_][0] = Vec3(-s_.shear_rate * H / 2, 0, 0);
    fo.wall_velocity[wall_dir_][1] = Vec3(s_.shear_rate * H / 2, 0, 0);
  }
  fluid_ = std::make_unique<fluid::FluidSolver>(comm, patch_, fo);
  const double mid = s_.flow == "shear" ? s_.origin[wall_dir_] + s_.size[wall_dir_] / 2 : 0.0;
  const int wd = wall_dir_;
  const double rate = s_.shear_rate;
  const bool shear = s_.flow == "shear";
  // Initial state: the undisturbed flow for shear, rest otherwise.
  if (shear) undisturbed_ = [=](const Vec3& x) { return Vec3(rate * (x[wd] - mid), 0, 0); };
  fluid_->set_initial_velocity(shear ? undisturbed_ : [](const Vec3&) { return Vec3(Vec3::Zero()); });
}

void Scene::attach_bodies(std::vector<solid::SolidSolver*> bodies) {
  if (coupler_) throw std::logic_error("Scene::attach_bodies called twice");
  bodies_ = std::move(bodies);
  if (bodies_.empty()) return;
  coupler_ = std::make_unique<coupling::FsiCoupler>(*fluid_, bodies_, s_.coupling);
  coupler_->initialize();
  const int plane = wall_dir_ > 0 ? wall_dir_ : 1;
  for (solid::SolidSolver* b : bodies_) {
    trackers_.emplace_back(b->reference_patch(), b->is_membrane(), plane);
    trackers_.back().record(fluid_->time(), b->current_patch());
  }
  suspension_on_ =
      s_.flow == "poiseuille" && s_.domain == "rectangle" && s_.dim == 2 && wall_dir_ == 1 &&
      std::any_of(bodies_.begin(), bodies_.end(), [](const auto* b) { return b->is_membrane(); });
  if (suspension_on_) record_suspension();
}

void Scene::record_suspension() {
  solid::SuspensionRecord r;
  r.time = fluid_->time();
  const fluid::SectionData sec = fluid::section(*fluid_, 0.5, 65);
  r.mean_velocity = sec.flow_rate / sec.area;
  const double y0 = s_.origin[1], y1 = s_.origin[1] + s_.size[1];
  r.gap_low = r.gap_high = s_.size[1];
  for (const solid::SolidSolver* b : bodies_) {
    if (!b->is_membrane()) continue;
    const geometry::Patch p = b->current_patch();
    const geometry::MembraneShape m = geometry::membrane_shape(p, 0);
    r.cell_area += m.enclosed;
    r.cell_x.push_back(m.moments.centroid[0]);
    // The membrane's extent across the channel: both faces sampled around.
    const geometry::KnotVector &k0 = p.knots(0), &k1 = p.knots(1);
    for (double xi0 : {k0.a(), k0.b()})
      for (int i = 0; i < 256; ++i) {
        const double y = p.point({xi0, k1.a() + (k1.b() - k1.a()) * i / 256, 0})[1];
        r.gap_low = std::min(r.gap_low, y - y0);
        r.gap_high = std::min(r.gap_high, y1 - y);
      }
  }
  suspension_.push_back(std::move(r));
}

void Scene::accumulate_profile() {
  if (s_.flow == "shear") return;
  const fluid::SectionData sec = fluid::section(*fluid_, 0.5, 65);
  flow_rates_.emplace_back(fluid_->time(), sec.flow_rate);
  if (fluid_->time() < average_from() || profile_from_ != average_from()) return;
  if (profile_count_ == 0) {
    profile_sum_ = sec;
  } else {
    for (std::size_t i = 0; i < sec.velocity.size(); ++i) profile_sum_.velocity[i] += sec.velocity[i];
    profile_sum_.flow_rate += sec.flow_rate;
  }
  ++profile_count_;
}

fluid::SectionData Scene::mean_profile() const {
  fluid::SectionData m = profile_sum_;
  if (profile_count_ == 0 || profile_from_ != average_from()) return {};
  for (auto& v : m.velocity) v /= profile_count_;
  m.flow_rate /= profile_count_;
  return m;
}

std::vector<double> Scene::metric_state() const {
  // [profile_count, n_points, (x y z vx vy vz) per point, flow_rate, area,
  //  n_records, per record: time mean_velocity cell_area gap_low gap_high n_cells cell_x...]
  std::vector<double> out{profile_from_, static_cast<double>(profile_count_),
                          static_cast<double>(profile_sum_.points.size())};
  for (std::size_t i = 0; i < profile_sum_.points.size(); ++i)
    for (const geometry::Vec3* v : {&profile_sum_.points[i], &profile_sum_.velocity[i]})
      out.insert(out.end(), v->data(), v->data() + 3);
  out.insert(out.end(), {profile_sum_.flow_rate, profile_sum_.area, static_cast<double>(suspension_.size())});
  for (const solid::SuspensionRecord& r : suspension_) {
    out.insert(out.end(), {r.time, r.mean_velocity, r.cell_area, r.gap_low, r.gap_high,
                           static_cast<double>(r.cell_x.size())});
    out.insert(out.end(), r.cell_x.begin(), r.cell_x.end());
  }
  out.push_back(static_cast<double>(flow_rates_.size()));
  for (const auto& [t, q] : flow_rates_) out.insert(out.end(), {t, q});
  return out;
}

void Scene::restore_metric_state(const std::vector<double>& state) {
  std::size_t k = 0;
  auto next = [&]() {
    if (k >= state.size())
      throw std::invalid_argument("option -restart: the checkpoint's scene records are damaged");
    return state[k++];
  };
  // The window the profile was summed over: a restart that moves it (-final_time, -metrics_average_from) has
  // no average over the new one (the steps before the restart are gone), so profile_mean.csv is not written.
  profile_from_ = next();
  profile_count_ = static_cast<int>(next());
  fluid::SectionData p;
  const auto n = static_cast<std::size_t>(next());
  for (std::size_t i = 0; i < n; ++i) {
    geometry::Vec3 x, v;
    for (int c = 0; c < 3; ++c) x[c] = next();
    for (int c = 0; c < 3; ++c) v[c] = next();
    p.points.push_back(x);
    p.velocity.push_back(v);
  }
  p.flow_rate = next();
  p.area = next();
  profile_sum_ = std::move(p);
  std::vector<solid::SuspensionRecord> recs(static_cast<std::size_t>(next()));
  for (solid::SuspensionRecord& r : recs) {
    r.time = next(), r.mean_velocity = next(), r.cell_area = next(), r.gap_low = next(), r.gap_high = next();
    r.cell_x.resize(static_cast<std::size_t>(next()));
    for (double& x : r.cell_x) x = next();
  }
  suspension_ = std::move(recs);
  std::vector<std::pair<double, double>> rates(static_cast<std::size_t>(next()));
  for (auto& [t, q] : rates) t = next(), q = next();
  flow_rates_ = std::move(rates);
}

std::vector<std::vector<double>> Scene::body_states() const {
  std::vector<std::vector<double>> out;
  for (const solid::SolidSolver* b : bodies_) out.push_back(b->state());
  return out;
}

std::vector<std::vector<double>> Scene::tracker_states() const {
  std::vector<std::vector<double>> out;
  for (const solid::BodyTracker& t : trackers_) out.push_back(t.state());
  return out;
}

void Scene::restore(Vec U, Vec Udot, int steps, const std::vector<std::vector<double>>& bodies,
                    const std::vector<std::vector<double>>& trackers) {
  if (bodies.size() != bodies_.size() || trackers.size() != bodies_.size())
    throw std::invalid_argument("option -restart is invalid here: the checkpoint has " +
                                std::to_string(bodies.size()) + " bodies, the scene " +
                                std::to_string(bodies_.size()));
  fluid_->restore(U, Udot, steps);
  for (size_t b = 0; b < bodies_.size(); ++b) {
    try {
      bodies_[b]->set_state(bodies[b]);
      trackers_[b].restore(trackers[b]);
    } catch (const std::exception& e) {
      // Also a remote body's refusal, which arrives as a runtime error: the checkpoint is bad input.
      throw std::invalid_argument(std::string("option -restart is invalid here: ") + e.what());
    }
  }
  if (coupler_) coupler_->restart();
}

SceneStep Scene::step() {
  SceneStep r;
  if (!coupler_) {
    const fluid::StepStats st = fluid_->step();
    r.iterations = st.newton_iterations, r.linear_iterations = st.linear_iterations;
    r.converged = st.converged, r.reason = st.reason;
    if (r.converged) accumulate_profile();
    return r;
  }
  const coupling::CouplerStats st = coupler_->step();
  r.iterations = st.iterations, r.linear_iterations = st.linear_iterations;
  r.factorizations = st.factorizations;
  r.converged = st.converged, r.reason = st.reason;
  if (st.converged) {
    for (size_t b = 0; b < bodies_.size(); ++b)
      trackers_[b].record(fluid_->time(), bodies_[b]->current_patch());
    if (suspension_on_) record_suspension();
    accumulate_profile();
  }
  return r;
}

std::vector<std::pair<std::string, double>> Scene::summary_metrics() {
  std::vector<std::pair<std::string, double>> m;
  for (const auto& kv : last_) {
    bool body = false;
    for (const solid::SolidSolver* b : bodies_) body = body || kv.first.rfind(b->name() + "_", 0) == 0;
    if (!body) m.push_back(kv);
  }
  const double from = average_from();
  if (suspension_on_) {
    // The suspension's rheology over the window (paper Sec. 4.3).
    const fluid::FluidOptions& fo = fluid_->options();
    const double H = s_.size[1], plasma_mean = fo.body_force[0] * H * H / (12 * fo.viscosity);
    const solid::SuspensionRheology r =
        solid::suspension_rheology(suspension_, s_.size[0] * s_.size[1], plasma_mean, from);
    if (r.records >= 2) {
      m.emplace_back("H_t", r.tube_hematocrit);
      m.emplace_back("H_d", r.discharge_hematocrit);
      m.emplace_back("zeta", r.fahraeus);
      m.emplace_back("eta", r.relative_viscosity);
      m.emplace_back("h_cf", r.cell_free_layer);
      m.emplace_back("v_cells", r.cell_velocity);
      m.emplace_back("v_mean", r.mean_velocity);
    }
    m.emplace_back("rheology_records", r.records);
  }
  if (!flow_rates_.empty()) {
    // The flow rate through mid-length once the flow has developed from rest (after 5 viscous times H^2 / nu
    // across the channel; the impulsive start overshoots in the first step): its largest and smallest value
    // and when (a cell in a narrowing slows the flow, paper Sec. 4.4).
    const fluid::FluidOptions& fo = fluid_->options();
    const double H = s_.size[wall_dir_ >= 0 ? wall_dir_ : s_.dim - 1];
    const double developed = flow_rates_.front().first + 5 * H * H * fo.density / fo.viscosity;
    auto first = flow_rates_.begin();
    while (first != flow_rates_.end() && first->first < developed) ++first;
    if (first != flow_rates_.end()) {
      auto by_rate = [](const auto& a, const auto& b) { return a.second < b.second; };
      const auto low = std::min_element(first, flow_rates_.end(), by_rate);
      const auto high = std::max_element(first, flow_rates_.end(), by_rate);
      m.emplace_back("flow_rate_max", high->second);
      m.emplace_back("flow_rate_max_time", high->first);
      m.emplace_back("flow_rate_min", low->second);
      m.emplace_back("flow_rate_min_time", low->first);
    }
  }
  // The paper's dimensionless numbers (Sec. 3.1-3.2) from the scene: the shear rate of a shear flow, the
  // half-width across the walls.
  solid::FlowScales flow;
  flow.viscosity = fluid_->options().viscosity;
  flow.density = fluid_->options().density;
  if (s_.flow == "shear") flow.shear_rate = s_.shear_rate;
  if (wall_dir_ >= 0) flow.half_width = 0.5 * s_.size[wall_dir_];
  for (size_t b = 0; b < bodies_.size(); ++b) {
    const std::string& name = bodies_[b]->name();
    for (const auto& [k, v] : trackers_[b].summary(from)) m.emplace_back(name + "_" + k, v);
    for (const auto& [k, v] : shape_symmetry(b)) m.emplace_back(name + "_" + k, v);
    if (s_.flow == "poiseuille" && wall_dir_ >= 0) {
      // Lateral migration across the channel (paper Sec. 4.2): offsets from the centre line, and when the
      // offset first fell to a tenth of its start.
      const solid::Migration mg = solid::lateral_migration(trackers_[b].centroid_track(), wall_dir_,
                                                           s_.origin[wall_dir_] + 0.5 * s_.size[wall_dir_]);
      m.emplace_back(name + "_lateral_offset_start", mg.offset_start);
      m.emplace_back(name + "_lateral_offset_final", mg.offset_final);
      m.emplace_back(name + "_time_to_centreline", mg.time_to_centreline);
    }
    if (s_.domain == "narrowing") {
      // Passage through the throat (paper Sec. 4.4): when the centroid crossed its start and its end.
      const double x_in = s_.channel.throat_center - s_.channel.throat_length / 2,
                   x_out = s_.channel.throat_center + s_.channel.throat_length / 2;
      double t_in = std::numeric_limits<double>::quiet_NaN(), t_out = t_in;
      for (const auto& [t, c] : trackers_[b].centroid_track()) {
        if (std::isnan(t_in) && c[0] >= x_in) t_in = t;
        if (std::isnan(t_out) && c[0] >= x_out) t_out = t;
      }
      m.emplace_back(name + "_throat_entry_time", t_in);
      m.emplace_back(name + "_throat_exit_time", t_out);
      m.emplace_back(name + "_throat_transit_time", t_out - t_in);
    }
    const geometry::Patch reference = bodies_[b]->reference_patch();
    const BodySettings& bs = body_settings(name);
    for (const auto& [k, v] : solid::dimensionless_numbers(reference, bodies_[b]->is_membrane(), bs.thickness,
                                                           bs.shear_modulus, flow))
      m.emplace_back(name + "_" + k, v);
    if (!bodies_[b]->is_membrane()) {
      // phi: against the membrane whose enclosed region holds this body's centroid (the nearest such).
      const geometry::Vec3 c = geometry::patch_moments(reference).centroid;
      for (const solid::SolidSolver* o : bodies_) {
        if (!o->is_membrane()) continue;
        const geometry::Patch mem = o->reference_patch();
        const geometry::MembraneShape ms = geometry::membrane_shape(mem, 0);
        if ((ms.moments.centroid - c).norm() < ms.effective_radius) {
          m.emplace_back(name + "_phi", solid::filling_fraction(reference, mem));
          break;
        }
      }
    }
    // The Lagrangian mesh actually used (automatic counts are chosen from the fluid mesh).
    for (int d = 0; d < reference.param_dim(); ++d)
      m.emplace_back(name + "_elements_" + std::to_string(d), reference.n_elements(d));
    const coupling::Resolution r = coupling::resolution(patch_, {name, reference, bodies_[b]->is_membrane()});
    m.emplace_back(name + "_mesh_ratio", r.ratio());
  }
  return m;
}

double Scene::average_from() const {
  return s_.metrics_average_from >= 0 ? s_.metrics_average_from : 0.5 * s_.final_time;
}

const BodySettings& Scene::body_settings(const std::string& name) const {
  for (const BodySettings& b : s_.bodies)
    if (b.name == name) return b;
  throw std::logic_error("no settings for body '" + name + "'");
}

std::vector<std::pair<std::string, std::string>> Scene::summary_text() const {
  std::vector<std::pair<std::string, std::string>> t;
  for (size_t b = 0; b < bodies_.size(); ++b)
    t.emplace_back(bodies_[b]->name() + "_regime", trackers_[b].regime(average_from()));
  return t;
}

std::vector<std::pair<std::string, double>> Scene::metrics() {
  last_ = flow_metrics();
  for (size_t b = 0; b < bodies_.size(); ++b) {
    for (const auto& [k, v] : trackers_[b].metrics()) last_.emplace_back(bodies_[b]->name() + "_" + k, v);
    for (const auto& [k, v] : shape_symmetry(b)) last_.emplace_back(bodies_[b]->name() + "_" + k, v);
  }
  return last_;
}

std::vector<std::pair<std::string, double>> Scene::shape_symmetry(std::size_t b) const {
  // A membrane in a 2D channel: its mid-line's mirror asymmetry about the line along the flow through its
  // centroid, and about the line across (solid::mirror_asymmetry): an inclined ellipse has both, a parachute
  // only the second, a cell aligned and symmetric neither (paper Sec. 4.2).
  if (s_.flow != "poiseuille" || s_.dim != 2 || !bodies_[b]->is_membrane()) return {};
  const geometry::Patch p = bodies_[b]->current_patch();
  const geometry::Vec3 c = geometry::membrane_shape(p, 0).moments.centroid;
  const geometry::KnotVector &k0 = p.knots(0), &k1 = p.knots(1);
  std::vector<geometry::Vec3> mid;
  for (int i = 0; i < 256; ++i)
    mid.push_back(p.point({0.5 * (k0.a() + k0.b()), k1.a() + (k1.b() - k1.a()) * i / 256, 0}));
  return {{"asymmetry_flow_axis", solid::mirror_asymmetry(mid, c, 0)},
          {"asymmetry_front_back", solid::mirror_asymmetry(mid, c, 1)}};
}

std::vector<std::pair<std::string, double>> Scene::flow_metrics() {
  std::vector<std::pair<std::string, double>> m;
  const fluid::FluidOptions& fo = fluid_->options();
  if (s_.flow == "poiseuille" || s_.flow == "rest") {
    const fluid::SectionData sec = fluid::section(*fluid_, 0.5, 65);
    m.emplace_back("flow_rate", sec.flow_rate);
    m.emplace_back("mean_velocity", sec.flow_rate / sec.area);
    double umax = 0;
    for (const Vec3& v : sec.velocity) umax = std::max(umax, v[0]);
    m.emplace_back("max_velocity", umax);
    if (s_.domain == "rectangle" && s_.flow == "poiseuille" && wall_dir_ == 1) {
      // Plane Poiseuille: u_max = f H^2 / (8 mu), mean f H^2 / (12 mu) (f a force per volume).
      const double H = s_.size[1], f = fo.body_force[0];
      const double exact = f * H * H / (8 * fo.viscosity), plasma_mean = f * H * H / (12 * fo.viscosity);
      if (bodies_.empty()) {
        m.emplace_back("max_velocity_exact", exact);
        m.emplace_back("max_velocity_rel_error", std::abs(umax - exact) / std::abs(exact));
        m.emplace_back("mean_velocity_rel_error",
                       std::abs(sec.flow_rate / sec.area - plasma_mean) / std::abs(2 * exact / 3));
      } else {
        // With cells the difference from the plasma flow is their effect, not an error: v_m / v_P = 1 / eta.
        m.emplace_back("plasma_mean_velocity", plasma_mean);
        m.emplace_back("mean_velocity_ratio", sec.flow_rate / sec.area / plasma_mean);
      }
      if (suspension_on_ && !suspension_.empty()) {
        const solid::SuspensionRecord& r = suspension_.back();
        m.emplace_back("tube_hematocrit", r.cell_area / (s_.size[0] * s_.size[1]));
        m.emplace_back("cell_free_layer", 0.5 * (r.gap_low + r.gap_high));
      }
    }
  } else {
    // Shear: the velocity against the linear profile at points across the gap, relative to the wall speed.
    std::vector<Vec3> pts;
    const double H = s_.size[wall_dir_];
    for (int k = 0; k < 17; ++k) {
      Vec3 x = s_.origin;
      for (int d = 0; d < s_.dim; ++d) x[d] += 0.37 * s_.size[d];
      x[wall_dir_] = s_.origin[wall_dir_] + H * (k + 0.5) / 17;
      pts.push_back(x);
    }
    const auto samp = fluid_->sample(pts);
    double err = 0;
    const double mid = s_.origin[wall_dir_] + H / 2;
    for (size_t i = 0; i < pts.size(); ++i)
      err = std::max(err, (samp[i].v - Vec3(s_.shear_rate * (pts[i][wall_dir_] - mid), 0, 0)).norm());
    m.emplace_back("shear_profile_rel_error", err / std::abs(s_.shear_rate * H / 2));
  }
  return m;
}

}  // namespace cellfsi::app
