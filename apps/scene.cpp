#include "apps/scene.hpp"

#include <petscsys.h>

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "fluid/fluid_output.hpp"
#include "fluid/petsc_error.hpp"

namespace cellfsi::app {

using geometry::Vec3;

namespace {

std::string str(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

[[noreturn]] void bad(const std::string& option, const std::string& value, const std::string& valid) {
  throw std::invalid_argument("option -" + option + " = " + value + " is invalid; valid: " + valid);
}

/// Raw values as read; checked by validate().
struct Raw {
  char name[256] = "", domain[64] = "rectangle", flow[64] = "shear", output_dir[PETSC_MAX_PATH_LEN] = "";
  PetscInt dim = 2;
  // Arrays hold one more than the largest valid count, so PETSc reports an extra value instead of dropping
  // it.
  PetscReal size[4] = {0.0024, 0.0012, 0.0012, 0};
  PetscInt n_size = 0;
  PetscBool size_set = PETSC_FALSE;
  PetscReal origin[4] = {0, 0, 0, 0};
  PetscInt n_origin = 0;
  PetscBool origin_set = PETSC_FALSE;
  PetscBool periodic[4] = {PETSC_TRUE, PETSC_FALSE, PETSC_FALSE, PETSC_FALSE};
  PetscInt n_periodic = 0;
  PetscBool periodic_set = PETSC_FALSE;
  PetscInt elements[4] = {64, 32, 32, 0};
  PetscInt n_elements = 0;
  PetscBool elements_set = PETSC_FALSE;
  PetscInt degree = 3;
  PetscReal shear_rate = 70.0, final_time = 0.05, dt = 5e-4;
  PetscInt output_every = 0;
  PetscReal ch[6];
};

PetscErrorCode read_raw(Raw& r, const geometry::NarrowingChannel& ch0) {
  PetscFunctionBeginUser;
  r.ch[0] = ch0.length, r.ch[1] = ch0.height, r.ch[2] = ch0.throat_height, r.ch[3] = ch0.throat_length;
  r.ch[4] = ch0.transition_length, r.ch[5] = ch0.throat_center;
  PetscOptionsBegin(PETSC_COMM_WORLD, nullptr, "cellfsi scene (DESIGN.md section 4; CGS units)", nullptr);
  PetscCall(PetscOptionsString("-scene", "Scene name (default: the YAML file's stem)", nullptr, r.name,
                               r.name, sizeof r.name, nullptr));
  PetscCall(PetscOptionsInt("-dim", "Spatial dimension, 2 or 3", nullptr, r.dim, &r.dim, nullptr));
  PetscCall(PetscOptionsString("-domain", "Eulerian domain: rectangle, box or narrowing", nullptr, r.domain,
                               r.domain, sizeof r.domain, nullptr));
  r.n_size = 3;
  PetscCall(PetscOptionsRealArray("-domain_size", "Domain extent Lx,Ly[,Lz] [cm] (rectangle, box)", nullptr,
                                  r.size, &r.n_size, nullptr));
  r.n_origin = 3;
  PetscCall(PetscOptionsRealArray("-domain_origin", "Domain corner x,y[,z] [cm]", nullptr, r.origin,
                                  &r.n_origin, nullptr));
  r.n_periodic = 3;
  PetscCall(PetscOptionsBoolArray("-domain_periodic", "Periodic flag per direction, e.g. 1,0", nullptr,
                                  r.periodic, &r.n_periodic, nullptr));
  PetscCall(PetscOptionsReal("-channel_length", "Narrowing channel: period in x [cm]", nullptr, r.ch[0],
                             &r.ch[0], nullptr));
  PetscCall(PetscOptionsReal("-channel_height", "Narrowing channel: height [cm]", nullptr, r.ch[1], &r.ch[1],
                             nullptr));
  PetscCall(PetscOptionsReal("-channel_throat_height", "Narrowing channel: throat height [cm]", nullptr,
                             r.ch[2], &r.ch[2], nullptr));
  PetscCall(PetscOptionsReal("-channel_throat_length", "Narrowing channel: throat length [cm]", nullptr,
                             r.ch[3], &r.ch[3], nullptr));
  PetscCall(PetscOptionsReal("-channel_transition_length", "Narrowing channel: transition length [cm]",
                             nullptr, r.ch[4], &r.ch[4], nullptr));
  PetscCall(PetscOptionsReal("-channel_throat_center", "Narrowing channel: x of the throat centre [cm]",
                             nullptr, r.ch[5], &r.ch[5], nullptr));
  r.n_elements = 4;
  PetscCall(PetscOptionsIntArray("-fluid_elements", "Eulerian elements NX,NY[,NZ]", nullptr, r.elements,
                                 &r.n_elements, &r.elements_set));
  PetscCall(PetscOptionsInt("-fluid_degree", "Eulerian degree p (continuity p-1), 2..8", nullptr, r.degree,
                            &r.degree, nullptr));
  PetscCall(PetscOptionsString("-flow", "shear (moving walls), poiseuille (body force) or rest", nullptr,
                               r.flow, r.flow, sizeof r.flow, nullptr));
  PetscCall(PetscOptionsReal("-shear_rate", "Shear rate of the shear flow [1/s]", nullptr, r.shear_rate,
                             &r.shear_rate, nullptr));
  PetscCall(PetscOptionsReal("-final_time", "End time [s]", nullptr, r.final_time, &r.final_time, nullptr));
  PetscCall(PetscOptionsReal("-dt", "Time step [s]", nullptr, r.dt, &r.dt, nullptr));
  PetscCall(PetscOptionsInt("-output_every", "Write fluid.pvd every N steps (0: never)", nullptr,
                            r.output_every, &r.output_every, nullptr));
  PetscCall(PetscOptionsString("-output_dir", "Output folder (default out/<scene>)", nullptr, r.output_dir,
                               r.output_dir, sizeof r.output_dir, nullptr));
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

}  // namespace

SceneSettings SceneSettings::from_options(const std::string& default_name) {
  SceneSettings s;
  Raw r;
  std::snprintf(r.name, sizeof r.name, "%s", default_name.c_str());
  call_reporting_input_errors([&] { return read_raw(r, s.channel); }, {{"-dim", 'i'},
                                                                       {"-domain_size", 'R'},
                                                                       {"-domain_origin", 'R'},
                                                                       {"-domain_periodic", 'B'},
                                                                       {"-channel_length", 'r'},
                                                                       {"-channel_height", 'r'},
                                                                       {"-channel_throat_height", 'r'},
                                                                       {"-channel_throat_length", 'r'},
                                                                       {"-channel_transition_length", 'r'},
                                                                       {"-channel_throat_center", 'r'},
                                                                       {"-fluid_elements", 'I'},
                                                                       {"-fluid_degree", 'i'},
                                                                       {"-shear_rate", 'r'},
                                                                       {"-final_time", 'r'},
                                                                       {"-dt", 'r'},
                                                                       {"-output_every", 'i'}});
  s.name = r.name;
  if (s.name.empty()) bad("scene", "''", "a non-empty name");
  if (r.dim != 2 && r.dim != 3) bad("dim", str(r.dim), "2 or 3");
  s.dim = static_cast<int>(r.dim);
  s.domain = r.domain;
  if (s.domain != "rectangle" && s.domain != "box" && s.domain != "narrowing")
    bad("domain", s.domain, "rectangle, box or narrowing");
  if (s.domain == "box" && s.dim != 3) bad("domain", "box", "box needs -dim 3");
  if (s.domain != "box" && s.dim == 3) bad("dim", "3", "3D needs -domain box");
  const int D = s.dim;
  auto count = [&](const char* option, PetscBool set, PetscInt n) {
    if (set && n != D)
      bad(option, std::to_string(n) + " values",
          std::to_string(D) + " comma-separated values (-dim " + std::to_string(D) + ")");
  };
  count("domain_size", r.size_set, r.n_size);
  count("domain_origin", r.origin_set, r.n_origin);
  count("domain_periodic", r.periodic_set, r.n_periodic);
  count("fluid_elements", r.elements_set, r.n_elements);
  s.size.assign(r.size, r.size + D);
  for (int d = 0; d < D; ++d)
    if (!(s.size[d] > 0)) bad("domain_size", str(s.size[d]), "every extent > 0 [cm]");
  s.origin = Vec3(r.origin[0], r.origin[1], D == 3 ? r.origin[2] : 0.0);
  // Default periodicity: every direction but the last (2D: x; 3D: x and y), the last bounded by walls.
  if (!r.periodic_set)
    for (int d = 0; d < D; ++d) r.periodic[d] = d < D - 1 ? PETSC_TRUE : PETSC_FALSE;
  for (int d = 0; d < 3; ++d) s.periodic[d] = d < D && r.periodic[d] == PETSC_TRUE;
  s.channel.length = r.ch[0], s.channel.height = r.ch[1], s.channel.throat_height = r.ch[2];
  s.channel.throat_length = r.ch[3], s.channel.transition_length = r.ch[4], s.channel.throat_center = r.ch[5];
  if (s.domain == "narrowing") s.channel.validate();
  for (int d = 0; d < 3; ++d) s.elements[d] = d < D ? static_cast<int>(r.elements[d]) : 1;
  for (int d = 0; d < D; ++d)
    if (s.elements[d] < 1) bad("fluid_elements", std::to_string(s.elements[d]), "every count >= 1");
  if (r.degree < 2 || r.degree > 8) bad("fluid_degree", std::to_string(r.degree), "2 <= p <= 8");
  s.degree = static_cast<int>(r.degree);
  for (int d = 0; d < D; ++d)
    if (s.periodic[d] && s.elements[d] < s.degree)
      bad("fluid_elements", std::to_string(s.elements[d]), ">= degree in a periodic direction");
  s.flow = r.flow;
  if (s.flow != "shear" && s.flow != "poiseuille" && s.flow != "rest")
    bad("flow", s.flow, "shear, poiseuille or rest");
  if (s.flow == "shear" && s.domain == "narrowing") bad("flow", "shear", "shear needs a rectangle or box");
  if (!(std::isfinite(r.shear_rate))) bad("shear_rate", str(r.shear_rate), "a finite number [1/s]");
  s.shear_rate = r.shear_rate;
  if (!(r.final_time > 0)) bad("final_time", str(r.final_time), "> 0 [s]");
  s.final_time = r.final_time;
  if (!(r.dt > 0)) bad("dt", str(r.dt), "> 0 [s]");
  if (r.output_every < 0) bad("output_every", std::to_string(r.output_every), ">= 0");
  s.output_every = static_cast<int>(r.output_every);
  s.output_dir = r.output_dir[0] ? r.output_dir : "out/" + s.name;
  s.dt = r.dt;
  return s;
}

Scene::Scene(MPI_Comm comm, const SceneSettings& settings) : s_(settings) {
  const int D = s_.dim;
  if (s_.domain == "rectangle")
    patch_ = geometry::rectangle(s_.size[0], s_.size[1], s_.elements[0], s_.elements[1], s_.degree,
                                 {s_.periodic[0], s_.periodic[1]}, s_.origin);
  else if (s_.domain == "box")
    patch_ = geometry::box(s_.size[0], s_.size[1], s_.size[2], s_.elements[0], s_.elements[1], s_.elements[2],
                           s_.degree, {s_.periodic[0], s_.periodic[1], s_.periodic[2]}, s_.origin);
  else
    patch_ = geometry::narrowing_channel(s_.channel, s_.elements[0], s_.elements[1], s_.degree);
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
    // Walls move at -+ gammadot H / 2 along x, so a centred cell stays put (DESIGN.md section 3).
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
  fluid_->set_initial_velocity(
      [=](const Vec3& x) { return shear ? Vec3(rate * (x[wd] - mid), 0, 0) : Vec3::Zero(); });
}

std::vector<std::pair<std::string, double>> Scene::metrics() {
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
      const double exact = f * H * H / (8 * fo.viscosity);
      m.emplace_back("max_velocity_exact", exact);
      m.emplace_back("max_velocity_rel_error", std::abs(umax - exact) / std::abs(exact));
      m.emplace_back(
          "mean_velocity_rel_error",
          std::abs(sec.flow_rate / sec.area - f * H * H / (12 * fo.viscosity)) / std::abs(2 * exact / 3));
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
