// The scene's post-processing: the metrics of every step, the summary's metrics and words (the paper's
// quantities: theta, omega, r_A, the flow and suspension metrics of the channels), the averaged profile, and
// their state in a checkpoint. The scene's assembly and its time step are in apps/scene.cpp.
#include <petscsys.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "apps/scene.hpp"
#include "common/petsc_error.hpp"
#include "coupling/inner_viscosity.hpp"
#include "coupling/placement.hpp"
#include "geometry/measures.hpp"

namespace cellfsi::app {

using geometry::Vec3;

namespace {

/// The plasma's mean velocity f H^2 / (12 mu) in a plane channel of height H driven by the body force along
/// x.
double plasma_mean_velocity(const fluid::FluidOptions& fo, double H) {
  return fo.body_force[0] * H * H / (12 * fo.viscosity);
}

/// Points on both faces of a 2D membrane (its inner and outer boundary curves), n around each (of each
/// patch).
std::vector<Vec3> membrane_face_points(const std::vector<geometry::Patch>& parts, int n) {
  std::vector<Vec3> out;
  for (const geometry::Patch& p : parts) {
    const geometry::KnotVector &k0 = p.knots(0), &k1 = p.knots(1);
    for (double xi0 : {k0.a(), k0.b()})
      for (int i = 0; i < n; ++i) out.push_back(p.point({xi0, k1.a() + (k1.b() - k1.a()) * i / n, 0}));
  }
  return out;
}

/// A membrane's shape measures, of its one patch or of its parts together.
geometry::MembraneShape shape_of(const std::vector<geometry::Patch>& parts) {
  return parts.size() == 1 ? geometry::membrane_shape(parts[0], 0) : geometry::membrane_shape(parts, 0);
}

/// A membrane's mid-surface sampled (solid::mid_surface_points), each patch's points in turn.
std::vector<Vec3> mid_points(const std::vector<geometry::Patch>& parts, int n1, int n2) {
  std::vector<Vec3> out;
  for (const geometry::Patch& p : parts) {
    const std::vector<Vec3> x = solid::mid_surface_points(p, n1, n2);
    out.insert(out.end(), x.begin(), x.end());
  }
  return out;
}

}  // namespace

void Scene::record_suspension() {
  solid::SuspensionRecord r;
  r.time = fluid_->time();
  const fluid::SectionData sec = fluid_->section(0.5, 65);
  r.mean_velocity = sec.flow_rate / sec.area;
  const double y0 = s_.origin[1], y1 = s_.origin[1] + s_.size[1];
  r.gap_low = r.gap_high = s_.size[1];
  for (const solid::SolidSolver* b : bodies_) {
    if (!b->is_membrane()) continue;
    const std::vector<geometry::Patch> p = b->current_patches();
    const geometry::MembraneShape m = shape_of(p);
    r.cell_area += m.enclosed;
    r.cell_x.push_back(m.moments.centroid[0]);
    // The membrane's extent across the channel: both faces sampled around.
    for (const Vec3& x : membrane_face_points(p, 256)) {
      r.gap_low = std::min(r.gap_low, x[1] - y0);
      r.gap_high = std::min(r.gap_high, y1 - x[1]);
    }
  }
  suspension_.push_back(std::move(r));
}

void Scene::accumulate_profile() {
  if (s_.flow == "shear") return;
  const fluid::SectionData sec = fluid_->section(0.5, 65);
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

nlohmann::json Scene::metric_state() const {
  nlohmann::json profile{{"points", nlohmann::json::array()},
                         {"velocity", nlohmann::json::array()},
                         {"flow_rate", profile_sum_.flow_rate},
                         {"area", profile_sum_.area}};
  for (std::size_t i = 0; i < profile_sum_.points.size(); ++i) {
    const Vec3 &x = profile_sum_.points[i], &v = profile_sum_.velocity[i];
    profile["points"].push_back({x[0], x[1], x[2]});
    profile["velocity"].push_back({v[0], v[1], v[2]});
  }
  nlohmann::json suspension = nlohmann::json::array();
  for (const solid::SuspensionRecord& r : suspension_)
    suspension.push_back({{"time", r.time},
                          {"mean_velocity", r.mean_velocity},
                          {"cell_area", r.cell_area},
                          {"gap_low", r.gap_low},
                          {"gap_high", r.gap_high},
                          {"cell_x", r.cell_x}});
  nlohmann::json rates = nlohmann::json::array();
  for (const auto& [t, q] : flow_rates_) rates.push_back({t, q});
  nlohmann::json equilibrium = nlohmann::json::array();
  for (const auto& e : equilibrium_)
    equilibrium.push_back(e ? nlohmann::json(e->state()) : nlohmann::json(nullptr));
  nlohmann::json state{{"profile_from", profile_from_},
                       {"profile_count", profile_count_},
                       {"profile_sum", std::move(profile)},
                       {"suspension", std::move(suspension)},
                       {"flow_rates", std::move(rates)},
                       {"equilibrium", std::move(equilibrium)}};
  // The least contact distances so far (absent: none yet within the cut-off).
  if (std::isfinite(contact_cell_min_)) state["contact_cell_gap_min"] = contact_cell_min_;
  if (std::isfinite(contact_wall_min_)) state["contact_wall_gap_min"] = contact_wall_min_;
  if (overlaps_max_ > 0) state["contact_overlap_points_max"] = overlaps_max_;
  // s_I as -s_interface_raise has left it (absent from earlier checkpoints: s_I as the options give it).
  if (coupler_)
    state["s_interface"] = {{"value", coupler_->interface_scaling()},
                            {"raise_threshold", raise_threshold_},
                            {"raise_previous", std::isfinite(raise_previous_) ? raise_previous_ : -1.0},
                            {"raises", s_interface_raises_}};
  return state;
}

void Scene::restore_metric_state(const nlohmann::json& state) {
  // Checkpoints of earlier versions hold the same state as one flat list of numbers.
  if (state.is_array()) return restore_flat_metric_state(state.get<std::vector<double>>());
  try {
    // The window the profile was summed over: a restart that moves it (-final_time, -metrics_average_from)
    // has no average over the new one (the steps before the restart are gone), so profile_mean.csv is not
    // written.
    profile_from_ = state.at("profile_from").get<double>();
    profile_count_ = state.at("profile_count").get<int>();
    const nlohmann::json& p = state.at("profile_sum");
    fluid::SectionData sum;
    for (const auto& x : p.at("points")) sum.points.emplace_back(x.at(0), x.at(1), x.at(2));
    for (const auto& v : p.at("velocity")) sum.velocity.emplace_back(v.at(0), v.at(1), v.at(2));
    if (sum.points.size() != sum.velocity.size()) throw std::runtime_error("profile of unequal lengths");
    sum.flow_rate = p.at("flow_rate").get<double>();
    sum.area = p.at("area").get<double>();
    std::vector<solid::SuspensionRecord> records;
    for (const auto& j : state.at("suspension")) {
      solid::SuspensionRecord r;
      r.time = j.at("time"), r.mean_velocity = j.at("mean_velocity"), r.cell_area = j.at("cell_area");
      r.gap_low = j.at("gap_low"), r.gap_high = j.at("gap_high");
      r.cell_x = j.at("cell_x").get<std::vector<double>>();
      records.push_back(std::move(r));
    }
    std::vector<std::pair<double, double>> rates;
    for (const auto& tq : state.at("flow_rates")) rates.emplace_back(tq.at(0), tq.at(1));
    // The stretching test's records (absent from earlier checkpoints, which had no stretched body).
    if (state.contains("equilibrium")) {
      const nlohmann::json& eq = state.at("equilibrium");
      if (eq.size() != equilibrium_.size()) throw std::runtime_error("equilibrium records of another scene");
      for (std::size_t b = 0; b < equilibrium_.size(); ++b) {
        if (eq[b].is_null() != !equilibrium_[b])
          throw std::runtime_error("equilibrium records of another scene");
        if (equilibrium_[b]) equilibrium_[b]->restore(eq[b].get<std::vector<double>>());
      }
    }
    if (state.contains("contact_cell_gap_min"))
      contact_cell_min_ = state.at("contact_cell_gap_min").get<double>();
    if (state.contains("contact_wall_gap_min"))
      contact_wall_min_ = state.at("contact_wall_gap_min").get<double>();
    overlaps_max_ = state.value("contact_overlap_points_max", 0);
    profile_sum_ = std::move(sum);
    suspension_ = std::move(records);
    flow_rates_ = std::move(rates);
    if (coupler_ && state.contains("s_interface")) {
      const nlohmann::json& si = state.at("s_interface");
      coupler_->set_interface_scaling(si.at("value").get<double>());
      raise_threshold_ = si.at("raise_threshold").get<double>();
      const double previous = si.at("raise_previous").get<double>();  // < 0: none yet
      raise_previous_ = previous >= 0 ? previous : std::numeric_limits<double>::infinity();
      s_interface_raises_ = si.at("raises").get<int>();
    }
  } catch (const std::exception& e) {
    throw std::invalid_argument(std::string("option -restart: the checkpoint's scene records are damaged (") +
                                e.what() + ")");
  }
}

void Scene::restore_flat_metric_state(const std::vector<double>& state) {
  std::size_t k = 0;
  auto next = [&]() {
    if (k >= state.size())
      throw std::invalid_argument("option -restart: the checkpoint's scene records are damaged");
    return state[k++];
  };
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
    const double plasma_mean = plasma_mean_velocity(fo, s_.size[1]);
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
  if (!flow_rates_.empty() && s_.flow == "poiseuille" && s_.domain != "narrowing" && wall_dir_ >= 0) {
    // The channel Reynolds number rho u H / mu: with the mean velocity measured over the last tenth of the
    // run (cells slow the flow), and with the plasma's f H^2 / (12 mu) for the same body force.
    const fluid::FluidOptions& fo = fluid_->options();
    const double H = s_.size[wall_dir_], t1 = flow_rates_.back().first,
                 from = t1 - 0.1 * (t1 - flow_rates_.front().first);
    double area = H, q = 0, n = 0;
    for (int d = 0; d < s_.dim; ++d)
      if (d != 0 && d != wall_dir_) area *= s_.size[d];
    for (const auto& [t, rate] : flow_rates_)
      if (t >= from) q += rate, n += 1;
    m.emplace_back("channel_reynolds", fo.density * q / n / area * H / fo.viscosity);
    m.emplace_back("channel_reynolds_plasma", fo.density * plasma_mean_velocity(fo, H) * H / fo.viscosity);
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
  // The s_I used, chosen or given (-s_interface), the area error an automatic choice aims at, and with
  // -s_interface_raise the value at the end and how often it was raised.
  if (const coupling::Repulsion* r = coupler_ ? coupler_->repulsion() : nullptr) {
    // The repulsion's constants, and the least distances over the run (left out where none came within
    // the cut-off).
    m.emplace_back("repulsion_cutoff", r->cutoff());
    m.emplace_back("repulsion_pressure", r->scale());
    if (std::isfinite(contact_cell_min_)) m.emplace_back("contact_cell_gap_min", contact_cell_min_);
    if (std::isfinite(contact_wall_min_)) m.emplace_back("contact_wall_gap_min", contact_wall_min_);
  } else if (std::isfinite(contact_wall_min_)) {
    m.emplace_back("contact_wall_gap_min", contact_wall_min_);  // (sampled, without the repulsion)
  }
  // Membranes that crossed, with or without the repulsion (a run without it shows what it prevents).
  if (membranes_ >= 2) m.emplace_back("contact_overlap_points_max", overlaps_max_);
  if (!bodies_.empty()) {
    m.emplace_back("s_interface", s_.coupling.s_interface);
    if (s_.s_interface_auto) m.emplace_back("s_interface_target", s_.s_interface_target);
    if (s_.s_interface_raise) {
      m.emplace_back("s_interface_final", coupler_->interface_scaling());
      m.emplace_back("s_interface_raises", s_interface_raises_);
    }
  }
  solid::FlowScales flow;
  flow.viscosity = fluid_->options().viscosity;
  flow.density = fluid_->options().density;
  if (s_.flow == "shear") flow.shear_rate = s_.shear_rate;
  if (wall_dir_ >= 0) flow.half_width = 0.5 * s_.size[wall_dir_];
  const double fluid_element = bodies_.empty() ? 0.0 : geometry::smallest_element_extent(patch_);
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
      // At a finite Reynolds number a body settles off the centre line (inertial migration): its offset and
      // distance from the nearer wall over H averaged over the last tenth of the run, the drift left there,
      // and when it came within 1 % of H of that offset for good.
      const double H = s_.size[wall_dir_];
      const solid::LateralEquilibrium eq = solid::lateral_equilibrium(
          trackers_[b].centroid_track(), wall_dir_, s_.origin[wall_dir_] + 0.5 * H, 0.01 * H);
      m.emplace_back(name + "_lateral_offset_equilibrium", eq.offset);
      m.emplace_back(name + "_wall_distance_over_height", 0.5 - std::abs(eq.offset) / H);
      m.emplace_back(name + "_lateral_drift_final", eq.drift);
      m.emplace_back(name + "_lateral_settle_time", eq.settle_time);
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
    const std::vector<geometry::Patch> references = bodies_[b]->reference_patches();
    const geometry::Patch& reference = references[0];  // (its mesh: every part has the same)
    const BodySettings& bs = body_settings(name);
    for (const auto& [k, v] : solid::dimensionless_numbers(references, bodies_[b]->is_membrane(),
                                                           bs.thickness, bs.shear_modulus, flow))
      m.emplace_back(name + "_" + k, v);
    // The material law's constants (its name is in summary_text): G, and the law's own.
    m.emplace_back(name + "_shear_modulus", bs.shear_modulus);
    if (bs.material == "mooney_rivlin")
      m.emplace_back(name + "_mooney_rivlin_fraction", bs.mooney_rivlin_fraction);
    const bool surface_law = bs.material == "skalak" || bs.material == "strain_hardening_membrane";
    if (bs.material == "strain_hardening" || bs.material == "strain_hardening_membrane")
      m.emplace_back(name + "_hardening_c3", bs.hardening_c3);
    if (surface_law) m.emplace_back(name + "_area_dilation", bs.area_dilation);
    if (equilibrium_[b]) {
      // The stretching test: the pull, the final diameters and when equilibrium came (NaN: not reached).
      m.emplace_back(name + "_stretch_force", bs.stretch_force);
      m.emplace_back(name + "_stretch_patch", bs.stretch_patch);
      m.emplace_back(name + "_stretch_ramp", bs.stretch_ramp);
      m.emplace_back(name + "_axial_diameter", equilibrium_[b]->last().axial);
      m.emplace_back(name + "_transverse_diameter", equilibrium_[b]->last().transverse);
      m.emplace_back(name + "_equilibrium_time", equilibrium_[b]->time());
      // Equal and opposite forces: the centroid stays where it was (the distance it moved) [cm].
      const auto track = trackers_[b].centroid_track();
      m.emplace_back(name + "_centroid_shift", (track.back().second - track.front().second).norm());
    }
    // lambda = mu_in / mu_out, where an inner viscosity was given (issue 27).
    if (bs.inner_viscosity > 0)
      m.emplace_back(name + "_viscosity_ratio", bs.inner_viscosity / flow.viscosity);
    if (bodies_[b]->is_membrane()) {
      // The mid-surface encloses incompressible fluid: a change of its area/volume is a conservation error
      // of the coupling (r_A measures the band's own).
      const double enclosed0 = shape_of(references).enclosed;
      m.emplace_back(name + "_enclosed_change",
                     shape_of(bodies_[b]->current_patches()).enclosed / enclosed0 - 1);
      // The bending modulus the solid shell implies, in erg: an incompressible thin plate's E h^3 / (12 (1 -
      // nu^2)) with E = 3 G, nu = 1/2 (G h^3 / 3); the surface laws (skalak, strain_hardening_membrane),
      // G (1 + C) h^3 / 6 (their area term stiffens every layer: docs/materials.md; C = 1 is the plate's).
      const double bending = surface_law ? (1 + bs.area_dilation) / 6 : 1.0 / 3;
      if (reference.physical_dim() == 3)
        m.emplace_back(name + "_bending_modulus", bending * bs.shear_modulus * std::pow(bs.thickness, 3));
    }
    if (!bodies_[b]->is_membrane()) {
      // phi: against the membrane whose enclosed region holds this body's centroid (the nearest such).
      const geometry::Vec3 c = geometry::patch_moments(reference).centroid;
      for (const solid::SolidSolver* o : bodies_) {
        if (!o->is_membrane()) continue;
        const std::vector<geometry::Patch> mem = o->reference_patches();
        const geometry::MembraneShape ms = shape_of(mem);
        if ((ms.moments.centroid - c).norm() < ms.effective_radius) {
          m.emplace_back(name + "_phi", solid::filling_fraction(reference, mem));
          break;
        }
      }
    }
    // The Lagrangian mesh actually used (automatic counts are chosen from the fluid mesh).
    for (int d = 0; d < reference.param_dim(); ++d)
      m.emplace_back(name + "_elements_" + std::to_string(d), reference.n_elements(d));
    for (int d = 0; d < reference.param_dim(); ++d)
      m.emplace_back(name + "_degree_" + std::to_string(d), reference.degree(d));
    // (a thin shell's reference patch is its view as a solid shell, linear across: degree_0 1)
    if (bs.thin_shell) m.emplace_back(name + "_thin_shell", 1.0);
    double ratio = 0;
    for (const geometry::Patch& part : references)
      ratio = std::max(ratio,
                       coupling::resolution(fluid_element, {name, part, bodies_[b]->is_membrane()}).ratio());
    m.emplace_back(name + "_mesh_ratio", ratio);
    if (references.size() > 1) m.emplace_back(name + "_patches", static_cast<double>(references.size()));
  }
  return m;
}

double Scene::average_from() const {
  return s_.metrics_average_from >= 0 ? s_.metrics_average_from : 0.5 * s_.final_time;
}

std::vector<std::pair<std::string, std::string>> Scene::summary_text() const {
  std::vector<std::pair<std::string, std::string>> t;
  if (!bodies_.empty()) t.emplace_back("s_interface_choice", s_.s_interface_auto ? "auto" : "given");
  for (size_t b = 0; b < bodies_.size(); ++b) {
    t.emplace_back(bodies_[b]->name() + "_regime", trackers_[b].regime(average_from()));
    t.emplace_back(bodies_[b]->name() + "_material", body_settings(bodies_[b]->name()).material);
  }
  return t;
}

std::vector<std::pair<std::string, double>> Scene::metrics() {
  last_ = flow_metrics();
  // The contact repulsion's least distances at this step [cm] (inf: none within its cut-off).
  if (coupler_ && coupler_->repulsion()) {
    if (membranes_ >= 2) last_.emplace_back("contact_cell_gap", contact_last_.cell_gap);
    if (s_.coupling.repulsion.walls) last_.emplace_back("contact_wall_gap", contact_last_.wall_gap);
  } else if (coupler_ && membranes_ >= 1 && !s_.coupling.repulsion.enabled) {
    // Without the repulsion: the membranes' least distance from the walls, sampled (where there are walls).
    const double gap = membrane_wall_gap();
    if (!std::isnan(gap)) {
      contact_wall_min_ = std::min(contact_wall_min_, gap);
      last_.emplace_back("contact_wall_gap", gap);
    }
  }
  // Points of a membrane inside another, with or without the repulsion.
  if (membranes_ >= 2) {
    const int overlaps = membrane_overlaps();
    overlaps_max_ = std::max(overlaps_max_, overlaps);
    last_.emplace_back("contact_overlap_points", overlaps);
  }
  if (s_.domain == "narrowing") {
    // Red cells in the narrowing: the cell-free layer in the throat, from its walls to the nearest red-cell
    // membrane inside it [cm] (NaN while none is there).
    std::vector<Vec3> red;
    for (const solid::SolidSolver* b : bodies_)
      if (body_settings(b->name()).biconcave())
        for (const Vec3& x : membrane_face_points(b->current_patches(), 256)) red.push_back(x);
    if (!red.empty())
      last_.emplace_back("throat_cell_free_layer", solid::throat_gaps(red, s_.channel).mean());
  }
  for (size_t b = 0; b < bodies_.size(); ++b) {
    for (const auto& [k, v] : trackers_[b].metrics()) last_.emplace_back(bodies_[b]->name() + "_" + k, v);
    for (const auto& [k, v] : shape_symmetry(b)) last_.emplace_back(bodies_[b]->name() + "_" + k, v);
    if (bodies_[b]->is_membrane()) {
      // The mid-surface's bounding box [cm]: a cell's diameters in shear as peers report them.
      const std::vector<geometry::Patch> parts = bodies_[b]->current_patches();
      Vec3 e;
      if (parts.size() == 1) {
        e = s_.dim == 2 ? solid::mid_surface_extent(parts[0], 256, 1) : solid::mid_surface_extent(parts[0]);
      } else {  // (each part sampled about as densely as the default one patch's 65 x 129)
        const std::vector<Vec3> x = mid_points(parts, 49, 49);
        Vec3 lo = x.front(), hi = x.front();
        for (const Vec3& y : x) lo = lo.cwiseMin(y), hi = hi.cwiseMax(y);
        e = hi - lo;
      }
      for (int d = 0; d < s_.dim; ++d) last_.emplace_back(bodies_[b]->name() + "_extent_" + "xyz"[d], e[d]);
    }
    if (equilibrium_[b]) {
      // The stretching test: D_A, D_T [cm] and their largest relative change over the equilibrium window.
      last_.emplace_back(bodies_[b]->name() + "_axial_diameter", equilibrium_[b]->last().axial);
      last_.emplace_back(bodies_[b]->name() + "_transverse_diameter", equilibrium_[b]->last().transverse);
      last_.emplace_back(bodies_[b]->name() + "_diameter_change", equilibrium_[b]->last_change());
    }
  }
  return last_;
}

int Scene::membrane_overlaps() const {
  // Each membrane's mid-surface sampled (2D: 256 points; 3D: 17 x 33, against 2 x 2 triangles per element
  // and direction: a check of crossing, not of the last chord's distance), against the bodies whose boxes
  // meet its own.
  std::vector<std::vector<geometry::Patch>> patches;
  std::vector<std::vector<Vec3>> samples;
  std::vector<Vec3> lo, hi;
  for (const solid::SolidSolver* b : bodies_) {
    if (!b->is_membrane()) continue;
    patches.push_back(b->current_patches());
    const bool parts = patches.back().size() > 1;  // (a part: about 17 x 33 / 6 points)
    samples.push_back(s_.dim == 2 ? mid_points(patches.back(), 256, 1)
                                  : mid_points(patches.back(), parts ? 9 : 17, parts ? 11 : 33));
    Vec3 l, h;
    patches.back()[0].bounding_box(l, h);
    for (const geometry::Patch& p : patches.back()) {
      Vec3 pl, ph;
      p.bounding_box(pl, ph);
      l = l.cwiseMin(pl), h = h.cwiseMax(ph);
    }
    lo.push_back(l), hi.push_back(h);
  }
  const std::vector<Vec3> shifts = geometry::neighbour_image_shifts(patch_);
  int count = 0;
  for (size_t a = 0; a < patches.size(); ++a)
    for (size_t b = 0; b < patches.size(); ++b) {
      if (a == b) continue;
      // b brought next to a first (bodies of a periodic channel drift by whole periods), then its images.
      const Vec3 gap = 0.5 * (lo[b] + hi[b] - lo[a] - hi[a]);
      const Vec3 near = geometry::nearest_image(patch_, gap) - gap;
      for (const Vec3& image : shifts) {
        const Vec3 t = near + image;
        // b's points moved by t against a's box first.
        bool meet = true;
        for (int d = 0; d < s_.dim; ++d)
          meet = meet && lo[b][d] + t[d] <= hi[a][d] && lo[a][d] <= hi[b][d] + t[d];
        if (!meet) continue;
        std::vector<Vec3> pts = samples[b];
        for (Vec3& x : pts) x += t;
        const std::vector<char> in = coupling::inside_membrane(patches[a], pts, s_.dim == 2 ? 0 : 2);
        count += static_cast<int>(std::count(in.begin(), in.end(), 1));
      }
    }
  return count;
}

double Scene::membrane_wall_gap() {
  if (!wall_probe_)
    wall_probe_ =
        std::make_unique<coupling::Repulsion>(patch_, geometry::smallest_element_extent(patch_), 0.0);
  Vec3 lo, hi, normal;
  patch_.bounding_box(lo, hi);
  if (!std::isfinite(wall_probe_->wall_distance(0.5 * (lo + hi), normal)))
    return std::numeric_limits<double>::quiet_NaN();
  double gap = std::numeric_limits<double>::infinity();
  for (const solid::SolidSolver* b : bodies_) {
    if (!b->is_membrane()) continue;
    const std::vector<geometry::Patch> p = b->current_patches();
    for (const Vec3& x : s_.dim == 2 ? mid_points(p, 256, 1) : mid_points(p, 17, 33))
      gap = std::min(gap, wall_probe_->wall_distance(x, normal));
  }
  return gap;
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
    const fluid::SectionData sec = fluid_->section(0.5, 65);
    m.emplace_back("flow_rate", sec.flow_rate);
    m.emplace_back("mean_velocity", sec.flow_rate / sec.area);
    double umax = 0;
    for (const Vec3& v : sec.velocity) umax = std::max(umax, v[0]);
    m.emplace_back("max_velocity", umax);
    if (s_.domain == "rectangle" && s_.flow == "poiseuille" && wall_dir_ == 1) {
      // Plane Poiseuille: u_max = f H^2 / (8 mu), mean f H^2 / (12 mu) (f a force per volume).
      const double H = s_.size[1], f = fo.body_force[0];
      const double exact = f * H * H / (8 * fo.viscosity), plasma_mean = plasma_mean_velocity(fo, H);
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
  // A space whose velocity is divergence-free pointwise records how far it is from that after every step.
  if (const std::optional<double> d = fluid_->max_divergence_ratio())
    m.emplace_back("fluid_max_divergence_ratio", *d);
  return m;
}

}  // namespace cellfsi::app
