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

#include "common/petsc_error.hpp"
#include "coupling/placement.hpp"
#include "fluid/fluid_output.hpp"
#include "geometry/measures.hpp"

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
  PetscInt checkpoint_every = 100;
  PetscBool restart = PETSC_FALSE;
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
                                  r.size, &r.n_size, &r.size_set));
  r.n_origin = 3;
  PetscCall(PetscOptionsRealArray("-domain_origin", "Domain corner x,y[,z] [cm]", nullptr, r.origin,
                                  &r.n_origin, &r.origin_set));
  r.n_periodic = 3;
  PetscCall(PetscOptionsBoolArray("-domain_periodic", "Periodic flag per direction, e.g. 1,0", nullptr,
                                  r.periodic, &r.n_periodic, &r.periodic_set));
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
  PetscCall(PetscOptionsInt("-checkpoint_every",
                            "Write DIR/checkpoint every N steps (0: only at the end and when interrupted)",
                            nullptr, r.checkpoint_every, &r.checkpoint_every, nullptr));
  PetscCall(PetscOptionsBool("-restart",
                             "Continue the run in the output folder from its checkpoint (same options; "
                             "-final_time may grow)",
                             nullptr, r.restart, &r.restart, nullptr));
  PetscCall(PetscOptionsString("-output_dir", "Output folder (default out/<scene>)", nullptr, r.output_dir,
                               r.output_dir, sizeof r.output_dir, nullptr));
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

/// Reads -solid_bodies and each body's -solid_<name>_* options, and the coupling options.
void read_bodies(SceneSettings& s) {
  char* names[65] = {};
  PetscInt n = 65;
  PetscBool set = PETSC_FALSE;
  PetscReal s_i = s.coupling.s_interface, tol = s.coupling.tolerance, ratio = s.max_mesh_ratio,
            avg = s.metrics_average_from;
  PetscInt max_it = s.coupling.max_iterations, lag = s.coupling.preconditioner_lag;
  PetscInt margin = s.coupling.band_margin, refactor = s.coupling.band_refactor_every,
           schur_lag = s.coupling.band_schur_lag, refresh = s.coupling.band_refresh_steps;
  PetscBool monitor = PETSC_FALSE;
  const char* solvers[] = {"band", "fluid", "CouplingSolver", "", nullptr};
  PetscEnum solver = static_cast<PetscEnum>(s.coupling.solver);
  const char* markings[] = {"support", "central", "Marking", "", nullptr};
  PetscEnum marking = static_cast<PetscEnum>(s.coupling.marking);
  const char* accelerations[] = {"none", "anderson", "Acceleration", "", nullptr};
  PetscEnum acceleration = static_cast<PetscEnum>(s.coupling.acceleration);
  PetscInt acc_columns = s.coupling.acceleration_columns, acc_reuse = s.coupling.acceleration_reuse;
  call_reporting_input_errors(
      [&]() -> PetscErrorCode {
        PetscFunctionBeginUser;
        PetscOptionsBegin(PETSC_COMM_WORLD, nullptr, "cellfsi immersed bodies and coupling", nullptr);
        PetscCall(PetscOptionsStringArray("-solid_bodies",
                                          "Names of the immersed bodies, e.g. membrane,nucleus", nullptr,
                                          names, &n, &set));
        PetscCall(PetscOptionsReal("-s_interface",
                                   "s_I: s^h on the basis functions at interfaces (paper 3.3)", nullptr, s_i,
                                   &s_i, nullptr));
        PetscCall(PetscOptionsEnum("-s_interface_marking",
                                   "Functions given s_I: support (every function nonzero on an element the "
                                   "interface crosses) or central (only those whose support it crosses in an "
                                   "inner element)",
                                   nullptr, markings, marking, &marking, nullptr));
        PetscCall(PetscOptionsReal("-coupling_tolerance", "Drop of every residual's L2 norm per step",
                                   nullptr, tol, &tol, nullptr));
        PetscCall(PetscOptionsInt("-coupling_max_iterations", "Block-iterative iterations per step", nullptr,
                                  max_it, &max_it, nullptr));
        PetscCall(PetscOptionsInt("-coupling_pc_lag", "Linear solves between preconditioner rebuilds",
                                  nullptr, lag, &lag, nullptr));
        PetscCall(PetscOptionsEnum("-coupling_acceleration",
                                   "Iterates of the coupling loop: none (x - dx, the paper's) or anderson "
                                   "(Anderson acceleration of that map; the same stopping test)",
                                   nullptr, accelerations, acceleration, &acceleration, nullptr));
        PetscCall(PetscOptionsInt("-coupling_acceleration_columns",
                                  "Difference pairs kept by the Anderson acceleration", nullptr, acc_columns,
                                  &acc_columns, nullptr));
        PetscCall(PetscOptionsInt("-coupling_acceleration_reuse",
                                  "Previous time steps whose Anderson pairs are kept (0: none)", nullptr,
                                  acc_reuse, &acc_reuse, nullptr));
        PetscCall(PetscOptionsBool("-coupling_monitor", "Print every coupling iteration's residuals", nullptr,
                                   monitor, &monitor, nullptr));
        PetscCall(PetscOptionsEnum(
            "-coupling_solver",
            "Linear solver of the coupling loop: band (the Jacobian away from the cells factorised once, the "
            "band "
            "around them re-solved exactly; one fluid rank) or fluid (the fluid's KSP, -fluid_ options)",
            nullptr, solvers, solver, &solver, nullptr));
        PetscCall(
            PetscOptionsInt("-coupling_band_margin",
                            "Elements around the s^h band and immersed points in the band solver's region",
                            nullptr, margin, &margin, nullptr));
        PetscCall(PetscOptionsInt("-coupling_band_refactor_every",
                                  "Steps between factorisations of the band solver's fixed part (0: when the "
                                  "cells leave its region)",
                                  nullptr, refactor, &refactor, nullptr));
        PetscCall(
            PetscOptionsInt("-coupling_band_refresh_steps",
                            "Steps between refreshes of the band Jacobian while the s^h marking stays (it "
                            "is refreshed whenever the marking moves)",
                            nullptr, refresh, &refresh, nullptr));
        PetscCall(PetscOptionsInt("-coupling_band_schur_lag",
                                  "Coupling iterations between re-assemblies of the band Jacobian and "
                                  "factorisations of its Schur complement inside a step (0: none)",
                                  nullptr, schur_lag, &schur_lag, nullptr));
        PetscCall(PetscOptionsReal("-coupling_max_mesh_ratio",
                                   "Largest Lagrangian / smallest Eulerian element size (paper Remark 3)",
                                   nullptr, ratio, &ratio, nullptr));
        PetscCall(
            PetscOptionsReal("-metrics_average_from",
                             "Start of the metrics' averaging window [s] (default: half the final time)",
                             nullptr, avg, &avg, nullptr));
        PetscOptionsEnd();
        PetscFunctionReturn(0);
      },
      {{"-s_interface", 'r'},
       {"-coupling_tolerance", 'r'},
       {"-coupling_max_iterations", 'i'},
       {"-coupling_pc_lag", 'i'},
       {"-coupling_acceleration_columns", 'i'},
       {"-coupling_acceleration_reuse", 'i'},
       {"-coupling_band_margin", 'i'},
       {"-coupling_band_refactor_every", 'i'},
       {"-coupling_band_schur_lag", 'i'},
       {"-coupling_band_refresh_steps", 'i'},
       {"-coupling_max_mesh_ratio", 'r'},
       {"-metrics_average_from", 'r'}});
  if (set && n > 64) bad("solid_bodies", std::to_string(n) + " names", "at most 64 bodies");
  PetscBool given = PETSC_FALSE;
  PetscOptionsHasName(nullptr, nullptr, "-solid_bodies", &given);
  if (given && (!set || n == 0 || (n == 1 && names[0] && names[0][0] == '\0')))
    bad("solid_bodies", "(empty)",
        "one or more comma-separated names, e.g. membrane,nucleus (for a run without cells use a scene "
        "without bodies, e.g. scenes/shear.yaml)");
  if (!(s_i >= 1)) bad("s_interface", str(s_i), ">= 1");
  if (!(tol > 0 && tol < 1)) bad("coupling_tolerance", str(tol), "0 < tolerance < 1");
  if (max_it < 1) bad("coupling_max_iterations", std::to_string(max_it), ">= 1");
  if (lag < 1) bad("coupling_pc_lag", std::to_string(lag), ">= 1");
  if (acc_columns < 1 || acc_columns > 50)
    bad("coupling_acceleration_columns", std::to_string(acc_columns), "1 ... 50");
  if (acc_reuse < 0 || acc_reuse > 1000)
    bad("coupling_acceleration_reuse", std::to_string(acc_reuse), "0 ... 1000 (0: this step's pairs only)");
  if (margin < 0) bad("coupling_band_margin", std::to_string(margin), ">= 0");
  if (refactor < 0)
    bad("coupling_band_refactor_every", std::to_string(refactor), ">= 0 (0: only when needed)");
  if (schur_lag < 0)
    bad("coupling_band_schur_lag", std::to_string(schur_lag), ">= 0 (0: none inside a step)");
  if (refresh < 1) bad("coupling_band_refresh_steps", std::to_string(refresh), ">= 1 (1: every step)");
  if (!(ratio > 0)) bad("coupling_max_mesh_ratio", str(ratio), "> 0");
  if (avg >= s.final_time)
    bad("metrics_average_from", str(avg), "less than -final_time = " + str(s.final_time) + " s");
  s.coupling.s_interface = s_i;
  s.coupling.tolerance = tol;
  s.coupling.marking = static_cast<coupling::Marking>(marking);
  s.coupling.max_iterations = static_cast<int>(max_it);
  s.coupling.preconditioner_lag = static_cast<int>(lag);
  s.coupling.solver = static_cast<coupling::CouplingSolver>(solver);
  s.coupling.band_margin = static_cast<int>(margin);
  s.coupling.band_refactor_every = static_cast<int>(refactor);
  s.coupling.band_schur_lag = static_cast<int>(schur_lag);
  s.coupling.band_refresh_steps = static_cast<int>(refresh);
  s.coupling.monitor = monitor == PETSC_TRUE;
  s.coupling.acceleration = static_cast<coupling::Acceleration>(acceleration);
  s.coupling.acceleration_columns = static_cast<int>(acc_columns);
  s.coupling.acceleration_reuse = static_cast<int>(acc_reuse);
  s.max_mesh_ratio = ratio;
  s.metrics_average_from = avg;
  std::vector<std::string> list;
  for (PetscInt i = 0; set && i < std::min<PetscInt>(n, 64); ++i) {
    list.emplace_back(names[i]);
    PetscFree(names[i]);
  }
  const int D = s.dim;
  for (const std::string& name : list) {
    const bool ok = !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
      return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
    });
    if (!ok) bad("solid_bodies", name, "names of lower-case letters, digits and _");
    for (const BodySettings& o : s.bodies)
      if (o.name == name) bad("solid_bodies", name, "distinct names");
    BodySettings b;
    b.name = name;
    const std::string pre = "solid_" + name + "_";
    char shape[64] = "hollow_ellipse";
    PetscReal axes[4] = {2e-4, 1e-4, 1e-4, 0}, center[4] = {0, 0, 0, 0};
    PetscInt n_axes = 4, n_center = 4, n_el = 4, elements[4] = {0, 0, 0, 0}, degree = 2;
    PetscBool axes_set = PETSC_FALSE, center_set = PETSC_FALSE, el_set = PETSC_FALSE;
    PetscReal angle = 0, h = b.thickness, G = b.shear_modulus, rho = b.density, area = 0;
    PetscReal axis[4] = {0, 0, 1, 0};
    PetscInt n_axis = 4;
    PetscBool axis_set = PETSC_FALSE;
    PetscInt count = 1, seed = 1;
    PetscReal spread = 0;
    const char* arrangements[] = {"even", "staggered", "random", "Arrangement", "", nullptr};
    PetscEnum arrangement = static_cast<PetscEnum>(0);
    std::string o = "-" + pre;
    call_reporting_input_errors(
        [&]() -> PetscErrorCode {
          PetscFunctionBeginUser;
          PetscOptionsBegin(PETSC_COMM_WORLD, pre.c_str(), ("cellfsi body '" + name + "'").c_str(), nullptr);
          PetscCall(PetscOptionsString("-shape",
                                       "hollow_ellipse, ellipse, rbc (2D); hollow_ellipsoid, ellipsoid (3D)",
                                       nullptr, shape, shape, sizeof shape, nullptr));
          PetscCall(PetscOptionsRealArray("-semi_axes",
                                          "Semi-axes a,b[,c] [cm] (membranes: of the mid-surface)", nullptr,
                                          axes, &n_axes, &axes_set));
          PetscCall(PetscOptionsRealArray("-center", "Centre x,y[,z] [cm] (default: the domain's centre)",
                                          nullptr, center, &n_center, &center_set));
          PetscCall(
              PetscOptionsReal("-angle",
                               "Rotation [degrees]: 2D, of the first semi-axis from +x; 3D, of the body "
                               "about -axis (right-handed)",
                               nullptr, angle, &angle, nullptr));
          PetscCall(PetscOptionsRealArray("-axis", "3D: rotation axis x,y,z of -angle (default 0,0,1)",
                                          nullptr, axis, &n_axis, &axis_set));
          PetscCall(PetscOptionsReal(
              "-area", "rbc: area enclosed by the mid-line [cm^2] (default 1.2868e-7, DESIGN.md)", nullptr,
              area, &area, nullptr));
          PetscCall(PetscOptionsReal("-thickness", "Membrane thickness h [cm]", nullptr, h, &h, nullptr));
          PetscCall(PetscOptionsIntArray("-elements",
                                         "Lagrangian elements per direction (through/around; radial,around; "
                                         "0: slightly smaller than the fluid's)",
                                         nullptr, elements, &n_el, &el_set));
          PetscCall(PetscOptionsInt("-degree", "Lagrangian degree, 2..4", nullptr, degree, &degree, nullptr));
          PetscCall(PetscOptionsReal("-shear_modulus", "G [dyn/cm^2]", nullptr, G, &G, nullptr));
          PetscCall(PetscOptionsReal("-density", "rho_2 [g/cm^3]", nullptr, rho, &rho, nullptr));
          PetscCall(PetscOptionsInt("-count",
                                    "Copies of the body (NAME_1 ... NAME_N) spread evenly along x, the "
                                    "periodic flow direction; -center gives the row's y (and z)",
                                    nullptr, count, &count, nullptr));
          PetscCall(PetscOptionsEnum("-arrangement",
                                     "Copies across the flow: even (all at the row), staggered (+-spread "
                                     "alternately), random (uniform in +-spread, -seed)",
                                     nullptr, arrangements, arrangement, &arrangement, nullptr));
          PetscCall(PetscOptionsReal("-spread", "Offset across the flow of staggered or random copies [cm]",
                                     nullptr, spread, &spread, nullptr));
          PetscCall(
              PetscOptionsInt("-seed", "Seed of the random arrangement", nullptr, seed, &seed, nullptr));
          PetscOptionsEnd();
          PetscFunctionReturn(0);
        },
        {{o + "semi_axes", 'R'},
         {o + "center", 'R'},
         {o + "angle", 'r'},
         {o + "axis", 'R'},
         {o + "area", 'r'},
         {o + "thickness", 'r'},
         {o + "elements", 'I'},
         {o + "degree", 'i'},
         {o + "shear_modulus", 'r'},
         {o + "density", 'r'},
         {o + "count", 'i'},
         {o + "spread", 'r'},
         {o + "seed", 'i'}});
    b.shape = shape;
    const bool is2d = b.shape == "hollow_ellipse" || b.shape == "ellipse" || b.shape == "rbc";
    const bool is3d = b.shape == "hollow_ellipsoid" || b.shape == "ellipsoid";
    if (!is2d && !is3d)
      bad(pre + "shape", b.shape, "hollow_ellipse, ellipse, rbc, hollow_ellipsoid or ellipsoid");
    if ((D == 2) != is2d) bad(pre + "shape", b.shape, D == 2 ? "a 2D shape (-dim 2)" : "a 3D shape (-dim 3)");
    if (b.shape != "rbc") {
      if (!axes_set && D == 3) axes[2] = axes[1];
      if (axes_set && n_axes != D)
        bad(pre + "semi_axes", std::to_string(n_axes) + " values", std::to_string(D) + " values");
      b.semi_axes.assign(axes, axes + D);
      for (double a : b.semi_axes)
        if (!(a > 0)) bad(pre + "semi_axes", str(a), "every semi-axis > 0 [cm]");
    } else {
      b.semi_axes.clear();
    }
    if (center_set && n_center != D)
      bad(pre + "center", std::to_string(n_center) + " values", std::to_string(D) + " values");
    b.center = center_set ? Vec3(center[0], center[1], D == 3 ? center[2] : 0.0) : Vec3(NAN, NAN, NAN);
    if (!std::isfinite(angle)) bad(pre + "angle", str(angle), "a finite angle [degrees]");
    b.angle_deg = angle;
    if (axis_set && D != 3) bad(pre + "axis", std::to_string(n_axis) + " values", "only in 3D (-dim 3)");
    if (axis_set && n_axis != 3) bad(pre + "axis", std::to_string(n_axis) + " values", "3 values x,y,z");
    const Vec3 ax(axis[0], axis[1], axis[2]);
    if (!(ax.norm() > 0) || !std::isfinite(ax.norm())) bad(pre + "axis", "0,0,0", "a nonzero direction");
    b.axis = ax.normalized();
    if (b.shape != "rbc" && area != 0) bad(pre + "area", str(area), "only for shape rbc");
    if (b.shape == "rbc" && !(area >= 0)) bad(pre + "area", str(area), "> 0 [cm^2] (0: the default RBC)");
    b.area = area;
    if (b.membrane()) {
      if (!(h > 0)) bad(pre + "thickness", str(h), "> 0 [cm]");
      for (double a : b.semi_axes)
        if (!(h < a)) bad(pre + "thickness", str(h), "smaller than every semi-axis");
    }
    b.thickness = h;
    if (el_set && n_el != D)
      bad(pre + "elements", std::to_string(n_el) + " values", std::to_string(D) + " values");
    for (int d = 0; d < D; ++d)
      if (elements[d] < 0) bad(pre + "elements", std::to_string(elements[d]), "counts >= 0 (0: automatic)");
    if (b.membrane() && elements[0] > 1)
      bad(pre + "elements", std::to_string(elements[0]), "1 element through a membrane's thickness");
    const int mult = 4;  // every builder needs a multiple of 4 elements around
    const int around = D == 2 ? 1 : 2;
    if (elements[around] % mult)
      bad(pre + "elements", std::to_string(elements[around]), "a multiple of 4 around the body");
    if (D == 3 && elements[1] % 2)
      bad(pre + "elements", std::to_string(elements[1]), "an even number of polar elements");
    for (int d = 0; d < 3; ++d) b.elements[d] = d < D ? static_cast<int>(elements[d]) : 1;
    if (degree < 2 || degree > 4) bad(pre + "degree", std::to_string(degree), "2, 3 or 4");
    b.degree = static_cast<int>(degree);
    if (!(G > 0)) bad(pre + "shear_modulus", str(G), "> 0 [dyn/cm^2]");
    if (!(rho > 0)) bad(pre + "density", str(rho), "> 0 [g/cm^3]");
    b.shear_modulus = G;
    b.density = rho;
    if (count < 1 || count > 64) bad(pre + "count", std::to_string(count), "1 ... 64");
    if (!(spread >= 0) || !std::isfinite(spread)) bad(pre + "spread", str(spread), ">= 0 [cm]");
    if (count == 1) {
      // A row's options without a row would do nothing.
      if (arrangement != 0)
        bad(pre + "arrangement", arrangements[arrangement], "even (or -" + pre + "count 2 or more)");
      if (spread > 0) bad(pre + "spread", str(spread), "0 (or -" + pre + "count 2 or more)");
      s.bodies.push_back(b);
      continue;
    }
    if (arrangement == 1 && count % 2)
      bad(pre + "count", std::to_string(count),
          "an even count with -" + pre +
              "arrangement staggered (an odd one puts the first and the last copy, "
              "side by side across the periodic end, on the same side)");
    // Copies: x evenly over the periodic flow direction, y (and z) from the row's centre and the arrangement.
    if (!s.periodic[0]) bad(pre + "count", std::to_string(count), "1 unless the domain is periodic in x");
    if (s.bodies.size() + static_cast<std::size_t>(count) > 64)
      bad(pre + "count", std::to_string(count), "at most 64 bodies in all");
    Vec3 row = b.center;
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(row[d])) row[d] = d < D ? s.origin[d] + 0.5 * s.size[d] : 0.0;
    std::mt19937 rng(static_cast<unsigned>(seed));
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    for (int i = 0; i < count; ++i) {
      BodySettings c = b;
      c.name = name + "_" + std::to_string(i + 1);
      for (const BodySettings& other : s.bodies)
        if (other.name == c.name) bad("solid_bodies", c.name, "distinct names (a copy of " + name + ")");
      c.center = row;
      c.center[0] = s.origin[0] + (i + 0.5) * s.size[0] / count;
      int across = 1;  // across the flow: the wall direction (the last non-periodic one), else y
      for (int d = D - 1; d >= 1; --d)
        if (!s.periodic[d]) {
          across = d;
          break;
        }
      if (arrangement == 1) c.center[across] += (i % 2 == 0 ? spread : -spread);
      if (arrangement == 2) c.center[across] += spread * uni(rng);
      s.bodies.push_back(c);
    }
  }
}

}  // namespace

double fluid_jacobian_bytes(const SceneSettings& s) {
  double nodes = 1, coupled = 1;
  for (int d = 0; d < s.dim; ++d) {
    nodes *= s.periodic[d] ? s.elements[d] : s.elements[d] + s.degree;
    coupled *= 2 * s.degree + 1;
  }
  const double dof = s.dim + 1;
  return nodes * coupled * dof * dof * sizeof(PetscScalar);
}

double available_memory_bytes() {
  std::ifstream in("/proc/meminfo");
  for (std::string key; in >> key;) {
    double kb = 0;
    std::string unit;
    in >> kb >> unit;
    if (key == "MemAvailable:") return kb * 1024.0;
  }
  return 0;
}

namespace {

/// A mesh the machine cannot hold is refused now, with the estimate, instead of allocating for minutes: the
/// fluid Jacobian (three times with the band solver: its kept part, its band part and their sum), shared over
/// the nodes of the fluid ranks, against the least memory available on any of them. Collective.
void check_memory(const SceneSettings& s) {
  MPI_Comm comm = PETSC_COMM_WORLD;
  int size = 1;
  MPI_Comm_size(comm, &size);
  double available = available_memory_bytes();
  if (!(available > 0)) available = 1e300;  // unknown: no check
  MPI_Allreduce(MPI_IN_PLACE, &available, 1, MPI_DOUBLE, MPI_MIN, comm);
  MPI_Comm node = MPI_COMM_NULL;
  MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  int node_rank = 0, leaders = 0;
  MPI_Comm_rank(node, &node_rank);
  MPI_Comm_free(&node);
  int leader = node_rank == 0 ? 1 : 0;
  MPI_Allreduce(&leader, &leaders, 1, MPI_INT, MPI_SUM, comm);
  const bool band = !s.bodies.empty() && size == 1 && s.coupling.solver == coupling::CouplingSolver::band;
  const double need = (band ? 3 : 1) * fluid_jacobian_bytes(s) / std::max(1, leaders);
  if (need <= available) return;
  std::ostringstream v, w;
  for (int d = 0; d < s.dim; ++d) v << (d ? "," : "") << s.elements[d];
  w << std::setprecision(3) << "fewer elements: a run needs at least " << need / 1e9 << " GB per node ("
    << (band ? "the fluid Jacobian three times: its kept part, its band part and their sum"
             : "the fluid Jacobian")
    << "; LU factors come on top) and " << available / 1e9 << " GB are available";
  bad("fluid_elements", v.str(), w.str());
}

}  // namespace

SceneSettings SceneSettings::from_options(const std::string& default_name, bool fluid_side) {
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
                                                                       {"-output_every", 'i'},
                                                                       {"-checkpoint_every", 'i'}});
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
  if (s.domain == "narrowing") {
    s.channel.validate();
    // The narrowing's extent is the channel's (it was silently ignored when given as -domain_size).
    if (r.size_set)
      bad("domain_size", "(given)", "not with -domain narrowing: use -channel_length, -channel_height");
    if (r.origin_set)
      bad("domain_origin", "(given)",
          "not with -domain narrowing (it spans 0..length x -height/2..height/2)");
    s.size = {s.channel.length, s.channel.height};
    s.origin = Vec3(0, -s.channel.height / 2, 0);
  }
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
  // The step count must be at least 1 and fit its int (-final_time 10 -dt 1e-12 wrapped to a negative count).
  if (!(r.dt <= r.final_time))
    bad("dt", str(r.dt), "at most -final_time = " + str(r.final_time) + " s (at least one step)");
  if (!(r.final_time / r.dt <= 1e9))
    bad("dt", str(r.dt),
        "at least -final_time / 1e9 = " + str(r.final_time / 1e9) + " s (at most 1e9 steps)");
  if (r.output_every < 0) bad("output_every", std::to_string(r.output_every), ">= 0");
  s.output_every = static_cast<int>(r.output_every);
  if (r.checkpoint_every < 0)
    bad("checkpoint_every", std::to_string(r.checkpoint_every),
        ">= 0 (0: only at the end and when interrupted)");
  s.checkpoint_every = static_cast<int>(r.checkpoint_every);
  s.restart = r.restart == PETSC_TRUE;
  s.output_dir = r.output_dir[0] ? r.output_dir : "out/" + s.name;
  s.dt = r.dt;
  read_bodies(s);
  if (fluid_side) check_memory(s);
  return s;
}

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

geometry::Patch build_body_patch(const SceneSettings& s, const BodySettings& b) {
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
  if (any_auto) {
    const geometry::Patch t = make_body(s, b, trial);
    for (int d = 0; d < D; ++d) {
      if (n[d] != 0) continue;
      // Largest extent along direction d of the trial mesh (measured as the Remark 3 check measures it).
      double ext = 0, e3[3];
      for (int e = 0; e < t.n_elements(); ++e) {
        coupling::element_extents(t, e, e3);
        ext = std::max(ext, e3[d]);
      }
      int m = std::max(d == 0 ? 2 : 4, static_cast<int>(std::ceil(trial[d] * ext / target)));
      const int step = d == 0 ? 1 : (D == 3 && d == 1 ? 2 : mult);
      n[d] = (m + step - 1) / step * step;
    }
  }
  return make_body(s, b, n);
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
  const coupling::Locator locator(domain);
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
        bad("solid_" + b.name + "_center", v.str(), w.str());
      }
    coupling::BodyPlacement pl{b.name, build_body_patch(s, b), b.membrane()};
    coupling::check_inside(locator, pl);
    const coupling::Resolution r = coupling::resolution(domain, pl);
    if (r.ratio() > s.max_mesh_ratio) {
      std::ostringstream os;
      os << "Lagrangian elements no larger than " << s.max_mesh_ratio
         << " x the fluid's (paper Remark 3): body '" << b.name << "' has elements of " << r.solid_element
         << " cm, the fluid " << r.fluid_element
         << " cm; use more body elements (0: automatic) or -coupling_max_mesh_ratio";
      std::ostringstream v;
      for (int d = 0; d < s.dim; ++d) v << (d ? "," : "") << pl.patch.n_elements(d);
      bad("solid_" + b.name + "_elements", v.str(), os.str());
    }
    // The cell must span the fluid mesh: its smallest semi-axis at least one fluid element.
    if (!b.semi_axes.empty()) {
      const double amin = *std::min_element(b.semi_axes.begin(), b.semi_axes.end());
      if (amin < r.fluid_element) {
        std::ostringstream v, w;
        for (int d = 0; d < s.dim; ++d) v << (d ? "," : "") << s.elements[d];
        w << "a fluid mesh with elements no larger than the smallest semi-axis of body '" << b.name << "' ("
          << amin << " cm; now " << r.fluid_element << " cm)";
        bad("fluid_elements", v.str(), w.str());
      }
    }
    placed.push_back(std::move(pl));
  }
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
