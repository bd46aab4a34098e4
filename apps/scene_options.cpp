// SceneSettings::from_options: the scene's, the coupling's and each body's option tables
// (common/option_table.hpp), the checks between options, and the memory check before allocating.
#include <petscsys.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <random>
#include <sstream>
#include <stdexcept>

#include "apps/scene.hpp"
#include "common/option_table.hpp"
#include "coupling/interface_marking.hpp"
#include "coupling/solver_policy.hpp"

namespace cellfsi::app {

using geometry::Vec3;

namespace {

/// Index of `word` in `words` (the table has checked that it is one of them).
template <class Enum>
Enum enum_of(const std::string& word, const std::vector<std::string>& words) {
  return static_cast<Enum>(std::find(words.begin(), words.end(), word) - words.begin());
}

const std::vector<std::string> kMarkings{"support", "central"};
const std::vector<std::string> kAccelerations{"none", "anderson"};
const std::vector<std::string> kSolidTangents{"isotropic", "consistent", "collocation"};
const std::vector<std::string> kShapes{"hollow_ellipse",   "ellipse",   "rbc",
                                       "hollow_ellipsoid", "ellipsoid", "rbc_3d"};
const std::vector<std::string> kArrangements{"even", "staggered", "random", "scattered"};
const std::vector<std::string> kMaterials{"neo_hookean", "mooney_rivlin", "strain_hardening", "skalak",
                                          "strain_hardening_membrane"};
// C3 / G of the strain-hardening law: Mills et al. (2004) fitted 1/30; 100 makes the law 600 times stiffer
// than neo-Hookean at I1 - 3 = 1 (a stretch of 1.9), far beyond any cell.
constexpr double kMaxHardening = 100;
// Skalak's C (area-dilation modulus G h (1 + 2C)): a red cell's membrane is about 1e4 times stiffer in area
// than in shear, and K / G h = 1 + 2C = 2e4 at this bound; the stiffer the law, the smaller the step it needs
// (docs/materials.md).
constexpr double kMaxAreaRatio = 1e4;
constexpr double kMaxOriginOverSize = 1e6;     // |domain origin| / domain extent
// G [dyn/cm^2]: cells are 1e1 ... 1e5, rubber 1e7; the capsule at 48 x 24, dt 5e-4 ran at 1e9, its coupling
// diverged at 1e10 and its membrane inverted at 1e11.
constexpr double kMaxShearModulus = 1e8;
// Bytes per Lagrangian element of degree 2 (body_bytes): a run's peak resident memory grew by 8.0 kB per
// element of a 2D body (a ring of 4000 -> 40000 elements, a filled ellipse of 4000 -> 36000) and by 24.5 kB
// per element of a 3D membrane (768 -> 6912).
constexpr double kBodyBytesPerElement2d = 8e3, kBodyBytesPerElement3d = 24e3;

/// The smallest Eulerian element size [cm] of the scene's mesh (a narrowing: in its throat).
double smallest_element_size(const SceneSettings& s) {
  double h = 1e300;
  for (int d = 0; d < s.dim; ++d) h = std::min(h, s.size[d] / s.elements[d]);
  if (s.domain == "narrowing") h = std::min(h, s.channel.throat_height / s.elements[1]);
  return h;
}

/// s_I from -s_interface: a number in 1 ... kMaxInterfaceScaling, or auto (coupling::
/// automatic_interface_scaling on the smallest element, for -s_interface_target; capped at the largest
/// valid value, with a note).
void read_interface_scaling(SceneSettings& s, const OptionTable& t, const std::string& text) {
  double& s_i = s.coupling.s_interface;
  const std::string valid =
      "auto, or a number 1 ... " + option_value_text(coupling::kMaxInterfaceScaling) +
      " (the studies use 1e6 ... 1e11; a larger s_I outweighs the rest of the Jacobian by more than its LU "
      "resolves in double precision: 1e300 failed the factorisation)";
  s.s_interface_auto = text == "auto";
  // The divergence-conforming space keeps a cell's volume without s_I (fluid/dc_immersed_fluid.hpp): a
  // value for it means nothing there. "auto", the scene files' value, means none.
  if (s.fluid_space == "div_conforming") {
    const std::string why = "not with -fluid_space div_conforming, whose velocity is divergence-free pointwise "
                            "and needs no interface scaling (leave it out, or auto)";
    if (!s.s_interface_auto) t.bad("s_interface", text, why);
    if (t.given("s_interface_target")) t.bad("s_interface_target", option_value_text(s.s_interface_target), why);
    if (s.s_interface_raise) t.bad("s_interface_raise", "true", why);
    s.s_interface_auto = false;
    s_i = 1;
    return;
  }
  if (!s.s_interface_auto) {
    if (t.given("s_interface_target"))
      t.bad("s_interface_target", option_value_text(s.s_interface_target),
            "only with -s_interface auto (here -s_interface " + text + ")");
    if (s.s_interface_raise)
      t.bad("s_interface_raise", "true", "only with -s_interface auto (here -s_interface " + text + ")");
    char* end = nullptr;
    s_i = std::strtod(text.c_str(), &end);
    if (text.empty() || *end != '\0') t.bad("s_interface", text.empty() ? "''" : text, valid);
    if (!(s_i >= 1 && s_i <= coupling::kMaxInterfaceScaling))
      t.bad("s_interface", option_value_text(s_i), valid);
    return;
  }
  const double needed = coupling::automatic_interface_scaling(smallest_element_size(s), s.degree,
                                                              s.coupling.marking, s.s_interface_target);
  s_i = std::clamp(needed, 1.0, coupling::kMaxInterfaceScaling);
  if (needed > coupling::kMaxInterfaceScaling)
    CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                              "cellfsi: note: -s_interface auto: the area error %g needs s_I = %.3g at this "
                              "mesh; using the largest valid, %g\n",
                              s.s_interface_target, needed, coupling::kMaxInterfaceScaling));
}

/// The coupling's options (and the scene's body list, averaging window and mesh-ratio limit).
void read_coupling(SceneSettings& s, std::vector<std::string>& names) {
  coupling::CouplerOptions& c = s.coupling;
  coupling::LinearSolverOptions& l = c.linear;
  std::string marking = kMarkings[static_cast<int>(c.marking)],
              acceleration = kAccelerations[static_cast<int>(c.acceleration)], s_interface = "auto",
              solid_tangent = kSolidTangents[static_cast<int>(coupling::default_solid_tangent(s.dim))];
  // "-solid_bodies ''" would read as no list at all: name the mistake.
  PetscBool has = PETSC_FALSE;
  char value[8] = "";
  PetscOptionsHasName(nullptr, nullptr, "-solid_bodies", &has);
  if (has) PetscOptionsGetString(nullptr, nullptr, "-solid_bodies", value, sizeof value, nullptr);
  if (has && value[0] == '\0')
    bad_option(
        "solid_bodies", "(empty)",
        "one or more comma-separated names, e.g. membrane,nucleus (for a run without cells use a scene "
        "without bodies, e.g. scenes/shear.yaml)");
  // The coupled solve's defaults for this dimension, and the PC types' own (coupling/solver_policy.hpp):
  // listed for -help and range-checked with the rest (the PC types read theirs themselves).
  l = coupling::linear_solver_defaults(s.dim);
  coupling::PCTypeOptions pc;
  OptionTable t("cellfsi immersed bodies and coupling");
  t.texts("solid_bodies", names, "Names of the immersed bodies, e.g. membrane,nucleus", 64)
      .text("s_interface", s_interface,
            "s_I: s^h on the basis functions at interfaces (paper 3.3): auto (chosen from the mesh to keep "
            "the membranes' area error near -s_interface_target; docs/validation.md, \"The automatic s_I\") "
            "or a number")
      .real("s_interface_target", s.s_interface_target,
            "-s_interface auto: the area error |r_A| (paper Eq. 21) to keep over the run",
            between(1e-6, 0.1, "", "(r_A ~ s_I^(-1/2): below 1e-6 needs s_I beyond 1e12 at any mesh)"))
      .flag("s_interface_raise", s.s_interface_raise,
            "-s_interface auto: s_I times 4 (halving the drift of r_A) each time a membrane's growing |r_A| "
            "passes half the target, then half-way from there to the target, and so on (at most 1e12)")
      .text("s_interface_marking", marking,
            "Functions given s_I: support (every function nonzero on an element the interface crosses) or "
            "central (only those whose support it crosses in an inner element)",
            kMarkings)
      .real("coupling_tolerance", c.tolerance, "Drop of every residual's L2 norm per step",
            {[](const double& v) { return v > 0 && v < 1; }, "0 < tolerance < 1"})
      .integer("coupling_max_iterations", c.max_iterations, "Block-iterative iterations per step",
               at_least(1));
  coupling::add_pc_lag_option(t, l);
  t.text("coupling_acceleration", acceleration,
         "Iterates of the coupling loop: none (x - dx, the paper's) or anderson (Anderson acceleration of "
         "that map; the same stopping test)",
         kAccelerations)
      .integer("coupling_acceleration_columns", c.acceleration_columns,
               "Difference pairs kept by the Anderson acceleration", int_between(1, 50))
      .integer("coupling_acceleration_reuse", c.acceleration_reuse,
               "Previous time steps whose Anderson pairs are kept (0: none)",
               int_between(0, 1000, "(0: this step's pairs only)"))
      .flag("coupling_monitor", c.monitor, "Print every coupling iteration's residuals")
      .text("coupling_solid_tangent", solid_tangent,
            "The solids' stiffness in the fluid's Jacobian: isotropic (a viscosity from each material's "
            "small-strain shear modulus), consistent (the material's tangent at the point's deformation, "
            "and its stress) or collocation (that tangent through the body's own interpolation of the "
            "velocity at its collocation points; divergence-conforming fluid only, consistent elsewhere); "
            "default collocation in 3D, consistent in 2D; the solution does not depend on it, the coupling "
            "iterations do",
            kSolidTangents);
  coupling::add_solver_options(t, l, pc);
  // The contact repulsion (coupling/repulsion.hpp): defaults from the mesh and the membranes.
  t.flag("coupling_repulsion", c.repulsion.enabled,
         "Contact repulsion between membranes, and between membranes and walls, below "
         "-coupling_repulsion_cutoff: "
         "the pressure P0 (1 - s)^2 / s^2, s = distance / cut-off (coupling/README.md, \"Repulsion\")")
      .real("coupling_repulsion_cutoff", c.repulsion.cutoff,
            "Distance [cm] below which the repulsion acts (0: the fluid's smallest element extent)",
            non_negative("[cm]"))
      .real("coupling_repulsion_pressure", c.repulsion.scale,
            "The repulsion's pressure scale P0 [dyn/cm^2] (its pressure at half the cut-off; 0: the largest "
            "G h / R "
            "of the membranes, R the radius of a circle or sphere of a membrane's perimeter or area)",
            non_negative("[dyn/cm^2]"))
      .flag("coupling_repulsion_walls", c.repulsion.walls,
            "The repulsion also between membranes and the walls");
  t.real("coupling_max_mesh_ratio", s.max_mesh_ratio,
         "Largest Lagrangian / smallest Eulerian element size (paper Remark 3)", positive())
      .real("metrics_average_from", s.metrics_average_from,
            "Start of the metrics' averaging window [s] (default: half the final time)");
  t.read();
  // A negative value is the default's marker; given, it (or nan) would silently mean the default.
  if (t.given("metrics_average_from") && !(s.metrics_average_from >= 0))
    t.bad("metrics_average_from", option_value_text(s.metrics_average_from),
          "0 <= time < -final_time = " + option_value_text(s.final_time) +
              " s (leave it out for the default, half the final time)");
  if (s.metrics_average_from >= s.final_time)
    t.bad("metrics_average_from", option_value_text(s.metrics_average_from),
          "less than -final_time = " + option_value_text(s.final_time) + " s");
  c.marking = enum_of<coupling::Marking>(marking, kMarkings);
  c.acceleration = enum_of<coupling::Acceleration>(acceleration, kAccelerations);
  c.solid_tangent = enum_of<coupling::SolidTangent>(solid_tangent, kSolidTangents);
  read_interface_scaling(s, t, s_interface);
}

/// The least MemAvailable over the ranks of comm (collective); 1e300 where it is unknown (no check).
double least_available_memory(MPI_Comm comm) {
  double available = available_memory_bytes();
  if (!(available > 0)) available = 1e300;
  MPI_Allreduce(MPI_IN_PLACE, &available, 1, MPI_DOUBLE, MPI_MIN, comm);
  return available;
}

/// Bytes a run holds for a body of these element counts (its NurbsSolid: collocation matrix and LU, states,
/// quadrature data; its placement checks and coupling data), measured per element at degree 2 and scaled
/// with the (p + 1)^d basis functions an element's points couple with.
double body_bytes(const BodySettings& b, int dim, const std::array<int, 3>& n) {
  double elements = b.patches;  // (each of the patches has n[0] x n[1] x n[2] elements)
  for (int d = 0; d < dim; ++d) elements *= n[d];
  const double per_element = dim == 2 ? kBodyBytesPerElement2d : kBodyBytesPerElement3d;
  // The basis tabulated at the quadrature points (NurbsSolid, since the constants were measured): (p + 1)^d
  // points of (p + 1)^d functions, each a value, a gradient and an unknown index; per point X, weight and
  // offset.
  const double f = std::pow(b.degree + 1.0, dim - 1) * (b.degree_through() + 1.0);
  const double table = f * (f * (8.0 * (dim + 1) + 4.0) + 36.0);
  return elements * (per_element * f / std::pow(3.0, dim) + table);
}

/// Bodies the machine cannot hold are refused before any is built (a membrane of 1 x 1e8 elements allocated
/// for 25 s, then failed with std::bad_alloc): the bodies listed so far and `count` copies of `b`, against
/// the least memory available on any rank. A lower bound: in one process every fluid rank holds a copy.
/// Collective.
void check_body_memory(const SceneSettings& s, const BodySettings& b, int count, const std::string& pre) {
  double need = 0;
  for (const BodySettings& o : s.bodies) need += body_bytes(o, s.dim, body_element_counts(s, o));
  const std::array<int, 3> n = body_element_counts(s, b);
  const double own = count * body_bytes(b, s.dim, n);
  need += own;
  const double available = least_available_memory(PETSC_COMM_WORLD);
  if (need <= available) return;
  std::ostringstream given, used, w;
  for (int d = 0; d < s.dim; ++d) {
    given << (d ? "," : "") << b.elements[d];
    used << (d ? " x " : "") << n[d];
  }
  const bool automatic =
      std::find(b.elements.begin(), b.elements.begin() + s.dim, 0) != b.elements.begin() + s.dim;
  w << std::setprecision(3) << "fewer elements: the bodies need at least " << need / 1e9 << " GB (body '"
    << b.name << "'" << (count > 1 ? " and its copies" : "") << ": " << own / 1e9 << " GB for " << used.str()
    << " elements" << (automatic ? ", where 0 asks for elements slightly smaller than the fluid's" : "")
    << ") and " << available / 1e9 << " GB are available";
  bad_option(pre + "elements", given.str(), w.str());
}

/// A body's options that are not BodySettings' own fields as read (lists before their checks, and the row).
struct BodyOptionValues {
  std::vector<double> axes, center, axis, stretch_axis;
  std::vector<int> elements;
  int count = 1, seed = 1;
  double spread = 0;
  std::string arrangement = kArrangements[0];
};

/// The table of one body's options (-solid_NAME_*): every option, its default, help and range.
void declare_body_options(OptionTable& t, BodySettings& b, BodyOptionValues& v, int D) {
  const auto dim = [D] { return D; };
  t.text("shape", b.shape,
         "Body shape (the first three 2D, the last three 3D; rbc_3d: the Evans-Fung RBC, its axis of "
         "symmetry along z before -angle, docs/geometry.md)",
         kShapes)
      .reals("semi_axes", v.axes, "Semi-axes a,b[,c] [cm] (membranes: of the mid-surface)", nullptr,
             positive("[cm]"))
      .reals("center", v.center, "Centre x,y[,z] [cm] (default: the domain's centre)", dim, finite("[cm]"))
      .real("angle", b.angle_deg,
            "Rotation [degrees]: 2D, of the first semi-axis from +x; 3D, of the body about -axis "
            "(right-handed)",
            finite("[degrees]"))
      .reals("axis", v.axis, "3D: rotation axis x,y,z of -angle", nullptr, finite())
      .real("area", b.area,
            "rbc: area enclosed by the mid-line [cm^2] (0: the default RBC, docs/design.md §3)")
      .real("thickness", b.thickness, "Membrane thickness h [cm]")
      .integers("elements", v.elements,
                "Lagrangian elements per direction (through/around; radial,around; 0: slightly smaller than "
                "the fluid's)",
                dim, at_least(0, "(0: automatic)"))
      .real(
          "element_ratio", b.element_ratio,
          "Automatic counts (0 in -elements): the body's element size over the smallest fluid element's (0: "
          "the fluid space's rule: 0.9 on the paper's space; on the divergence-conforming one 0.1125 for 2D "
          "membranes, 0.225 for the rest; docs/fluid.md)",
          between(0, 1, "", "(0: the space's rule)"))
      .integer("degree", b.degree, "Lagrangian degree, 2..4",
               {[](const long long& v) { return v >= 2 && v <= 4; }, "2, 3 or 4"})
      .integer("thickness_degree", b.thickness_degree,
               "Membranes: Lagrangian degree through the thickness, from -degree to 4 (0: -degree); more "
               "collocation points across a thin shell at less cost than a higher -degree (docs/geometry.md)",
               {[](const long long& v) { return v == 0 || (v >= 2 && v <= 4); }, "0, 2, 3 or 4"})
      .flag("thin_shell", b.thin_shell,
            "3D membranes on six patches (rbc_3d, -patches 6): a thin shell described by its mid-surface "
            "alone (Kirchhoff-Love), the thickness not an unknown; collocated at the mid-surface, its points "
            "at "
            "three heights through -thickness, its internal force handed to the fluid on its mid-surface; "
            "not yet "
            "fit for long runs (docs/geometry.md)")
      .integer(
          "patches", b.patches,
          "rbc_3d: 1, the polar patch (its poles at the dimples' centres), or 6, the faces of a cube mapped "
          "onto the cell, without poles (-elements 1,n,n: n x n on each face; docs/geometry.md)",
          {[](const long long& v) { return v == 1 || v == 6; }, "1 or 6"})
      .real("shear_modulus", b.shear_modulus, "G [dyn/cm^2]",
            material(1e-6, kMaxShearModulus, "[dyn/cm^2]",
                     "stiffer than any cell, and a stiffer body needs a far smaller -dt"))
      .text("material", b.material,
            "Material law (docs/materials.md), all with the small-strain shear modulus G; neo_hookean is the "
            "paper's",
            kMaterials)
      .real("mooney_rivlin_fraction", b.mooney_rivlin_fraction,
            "mooney_rivlin: a, the share of the I2 term (C10 = (1 - a) G/2, C01 = a G/2; in 2D the law is "
            "neo_hookean whatever a)",
            between(0, 1, "", "(0: neo-Hookean)"))
      .real("hardening_c3", b.hardening_c3,
            "strain_hardening: C3 / G in W = G/2 (I1 - 3) + C3 (I1 - 3)^3 (Mills et al. 2004: 1/30); "
            "strain_hardening_membrane: the same with the in-plane shape change in place of I1 - 3",
            between(0, kMaxHardening, "", "(0: neo-Hookean)"))
      .real("area_dilation", b.area_dilation,
            "skalak: C in Skalak's W_s = G h / 4 (I1^2 + 2 I1 - 2 I2 + C I2^2), the area-dilation modulus "
            "G h (1 + 2C); strain_hardening_membrane: the same modulus (3D membranes; docs/materials.md)",
            between(0, kMaxAreaRatio, "", "(0: area modulus G h, the C term off)"))
      .real("density", b.density, "rho_2 [g/cm^3]", material(1e-6, 1e3, "[g/cm^3]"))
      .real("inner_viscosity", b.inner_viscosity,
            "Membranes: viscosity mu of the fluid inside (a cytosol; for a compound cell, around the "
            "nucleus) [g/(cm s)], the units of -fluid_viscosity (0: the fluid's, no contrast)")
      .real(
          "stretch_force", b.stretch_force,
          "Membranes: the optical-tweezers stretching test (docs/validation.md): a force F [dyn] on each end "
          "of the membrane along -stretch_axis, +F at the far end, -F at the near one, spread evenly over "
          "the material within -stretch_patch of the end (1 pN = 1e-7 dyn; Mills et al. 2004 pulled up to "
          "1.93e-5). Given (0 too), the diameters along and across the axis and the time to equilibrium are "
          "measured",
          non_negative("[dyn]"))
      .real("stretch_patch", b.stretch_patch,
            "Contact diameter d of each bead [cm]: the force acts on the material (both faces) within d/2 of "
            "the end of the mid-surface",
            positive("[cm]"))
      .reals("stretch_axis", v.stretch_axis, "Direction x,y,z of the stretch (normalised)", nullptr, finite())
      .real(
          "stretch_ramp", b.stretch_ramp,
          "Time [s] over which the force grows linearly from 0 to -stretch_force (0: in full from the first "
          "step; a sudden large pull may invert an element or stall the coupling in the first steps)",
          non_negative("[s]"))
      .integer("count", v.count,
               "Copies of the body (NAME_1 ... NAME_N) spread evenly along x, the periodic flow direction; "
               "-center gives the row's y (and z)",
               int_between(1, 64))
      .text(
          "arrangement", v.arrangement,
          "Copies across the flow: even (all at the row), staggered (+-spread alternately), random (uniform "
          "in +-spread, -seed); or scattered: anywhere in the domain at random (-seed), at least one fluid "
          "element from the walls and every other body",
          kArrangements)
      .real("spread", v.spread, "Offset across the flow of staggered or random copies [cm]",
            non_negative("[cm]"))
      .integer("seed", v.seed, "Seed of the random arrangement");
}

/// The shape, its semi-axes, centre and rotation axis.
void check_body_geometry(OptionTable& t, BodySettings& b, BodyOptionValues& v, int D) {
  const bool is2d = b.shape == "hollow_ellipse" || b.shape == "ellipse" || b.shape == "rbc";
  if ((D == 2) != is2d) t.bad("shape", b.shape, D == 2 ? "a 2D shape (-dim 2)" : "a 3D shape (-dim 3)");
  if (!b.biconcave()) {
    if (!t.given("semi_axes") && D == 3 && v.axes.size() == 2) v.axes.push_back(v.axes[1]);  // c = b
    if (static_cast<int>(v.axes.size()) != D)
      t.bad("semi_axes", std::to_string(v.axes.size()) + " values", std::to_string(D) + " values");
    b.semi_axes = v.axes;
  } else {
    b.semi_axes.clear();
  }
  const std::vector<double>& c = v.center;
  b.center = t.given("center") ? Vec3(c[0], c[1], D == 3 ? c[2] : 0.0) : Vec3(NAN, NAN, NAN);
  if (t.given("axis") && D != 3)
    t.bad("axis", std::to_string(v.axis.size()) + " values", "only in 3D (-dim 3)");
  if (v.axis.size() != 3) t.bad("axis", std::to_string(v.axis.size()) + " values", "3 values x,y,z");
  const Vec3 ax(v.axis[0], v.axis[1], v.axis[2]);
  if (!(ax.norm() > 0)) t.bad("axis", "0,0,0", "a nonzero direction");
  b.axis = ax.normalized();
  if (b.shape != "rbc" && b.area != 0) t.bad("area", option_value_text(b.area), "only for shape rbc");
  if (b.shape == "rbc" && !(b.area >= 0))
    t.bad("area", option_value_text(b.area), "> 0 [cm^2] (0: the default RBC)");
}

/// A membrane's thickness and the inner viscosity, which only a membrane encloses.
void check_membrane(OptionTable& t, const BodySettings& b) {
  if (b.membrane()) {
    if (!(b.thickness > 0)) t.bad("thickness", option_value_text(b.thickness), "> 0 [cm]");
    for (double a : b.semi_axes)
      if (!(b.thickness < a))
        t.bad("thickness", option_value_text(b.thickness), "smaller than every semi-axis");
    // The 3D RBC's two sheets are C0 apart at its dimples: a thicker shell would fold through itself.
    if (b.shape == "rbc_3d" && !(b.thickness < geometry::EvansFung{}.C0))
      t.bad("thickness", option_value_text(b.thickness),
            "smaller than the RBC's thickness at its dimples, C0 = " +
                option_value_text(geometry::EvansFung{}.C0) + " [cm]");
  }
  if (t.given("inner_viscosity")) {
    // The bounds of -fluid_viscosity (fluid/fluid_options.cpp).
    const Valid<double> mu = material(1e-8, 1e6, "[g/(cm s)]");
    if (!mu.ok(b.inner_viscosity)) t.bad("inner_viscosity", option_value_text(b.inner_viscosity), mu.text);
    if (!b.membrane())
      t.bad("inner_viscosity", option_value_text(b.inner_viscosity),
            "only for a membrane (shape hollow_ellipse, rbc or hollow_ellipsoid): a bulky " + b.shape +
                " (e.g. a nucleus) is solid throughout and encloses no fluid");
  }
}

/// The stretching test: a membrane's ends; its other options only with the force.
void check_stretching(OptionTable& t, BodySettings& b, const BodyOptionValues& v, int D, const std::string& pre) {
  b.stretched = t.given("stretch_force");
  if (b.stretched && !b.membrane())
    t.bad(
        "stretch_force", option_value_text(b.stretch_force),
        "only for a membrane (shape hollow_ellipse, rbc, hollow_ellipsoid or rbc_3d): its ends are those of "
        "its mid-surface");
  std::string axis_text;
  for (std::size_t k = 0; k < v.stretch_axis.size(); ++k) {
    if (k) axis_text += ',';  // not (k ? "," : "") + ...: GCC 12 warns falsely (-Wrestrict) on that
    axis_text += option_value_text(v.stretch_axis[k]);
  }
  const std::string only_stretched = "only with -" + pre + "stretch_force (the stretching test)";
  if (t.given("stretch_patch") && !b.stretched)
    t.bad("stretch_patch", option_value_text(b.stretch_patch), only_stretched);
  if (t.given("stretch_axis") && !b.stretched) t.bad("stretch_axis", axis_text, only_stretched);
  if (t.given("stretch_ramp") && !b.stretched)
    t.bad("stretch_ramp", option_value_text(b.stretch_ramp), only_stretched);
  if (v.stretch_axis.size() != 3) t.bad("stretch_axis", axis_text, "3 values x,y,z");
  const Vec3 sa(v.stretch_axis[0], v.stretch_axis[1], v.stretch_axis[2]);
  if (!(sa.norm() > 0)) t.bad("stretch_axis", axis_text, "a nonzero direction");
  if (D == 2 && sa[2] != 0) t.bad("stretch_axis", axis_text, "a direction in the plane (z = 0) in 2D");
  b.stretch_axis = sa.normalized();
}

/// The material law's constants (a law's constant given to another law would do nothing) and the elements.
void check_law_and_elements(OptionTable& t, BodySettings& b, const BodyOptionValues& v, int D,
                            const std::string& pre) {
  const std::string law_now = " (the material is " + b.material + ")";
  if (t.given("mooney_rivlin_fraction") && b.material != "mooney_rivlin")
    t.bad("mooney_rivlin_fraction", option_value_text(b.mooney_rivlin_fraction),
          "only with -" + pre + "material mooney_rivlin" + law_now);
  const bool surface_law = b.material == "skalak" || b.material == "strain_hardening_membrane";
  if (t.given("hardening_c3") && b.material != "strain_hardening" &&
      b.material != "strain_hardening_membrane")
    t.bad("hardening_c3", option_value_text(b.hardening_c3),
          "only with -" + pre + "material strain_hardening or strain_hardening_membrane" + law_now);
  if (t.given("area_dilation") && !surface_law)
    t.bad("area_dilation", option_value_text(b.area_dilation),
          "only with -" + pre + "material skalak or strain_hardening_membrane" + law_now);
  // skalak and strain_hardening_membrane are laws of a membrane's surface: they need the membrane's normal,
  // which a bulky body has not, and in 2D (plane strain) their constants cannot be told apart
  // (docs/materials.md).
  if (surface_law && !(D == 3 && b.membrane()))
    t.bad("material", b.material,
          "neo_hookean, mooney_rivlin or strain_hardening for " +
              std::string(D == 3 ? "a bulky body" : "a 2D body") + " (" + b.material +
              ": 3D membranes only)");
  if (t.given("thickness_degree") && b.thickness_degree > 0) {
    if (!b.membrane())
      t.bad("thickness_degree", std::to_string(b.thickness_degree),
            "0 for a bulky " + b.shape +
                " (membranes only: shape hollow_ellipse, rbc, hollow_ellipsoid or "
                "rbc_3d)");
    else if (b.thickness_degree < b.degree)
      t.bad("thickness_degree", std::to_string(b.thickness_degree),
            "0 or from -" + pre + "degree (" + std::to_string(b.degree) + ") to 4");
  }
  if (b.thin_shell) {
    if (!(D == 3 && b.membrane()))
      t.bad("thin_shell", "true",
            "false for " + std::string(D == 3 ? "a bulky body" : "a 2D body") +
                " (3D membranes only: shape hollow_ellipsoid or rbc_3d)");
    else if (!(b.shape == "rbc_3d" && b.patches == 6))
      // (a polar mid-surface has no normal at its poles, where the thin shell's faces and view are taken)
      t.bad("thin_shell", "true",
            "false for shape " + b.shape +
                " on one patch (a thin shell needs a mid-surface without poles: "
                "shape rbc_3d with -" +
                pre + "patches 6)");
    else if (t.given("thickness_degree") && b.thickness_degree > 0)
      t.bad("thickness_degree", std::to_string(b.thickness_degree),
            "0 with -" + pre + "thin_shell (a thin shell has no degree through its thickness)");
  }
  const std::vector<int>& elements = v.elements;
  if (b.membrane() && elements[0] > 1)
    t.bad("elements", std::to_string(elements[0]), "1 element through a membrane's thickness");
  const int around = D == 2 ? 1 : 2;  // every builder needs a multiple of 4 elements around
  if (b.patches > 1) {
    // The cube's faces: n x n elements each, any n.
    if (elements[1] && elements[2] && elements[1] != elements[2])
      t.bad(
          "elements",
          std::to_string(elements[0]) + "," + std::to_string(elements[1]) + "," + std::to_string(elements[2]),
          "1,n,n with -" + pre + "patches 6 (n x n elements on each face; 0: automatic)");
  } else {
    if (elements[around] % 4)
      t.bad("elements", std::to_string(elements[around]), "a multiple of 4 around the body");
    if (D == 3 && elements[1] % 2)
      t.bad("elements", std::to_string(elements[1]), "an even number of polar elements");
  }
  for (int d = 0; d < 3; ++d) b.elements[d] = d < D ? elements[d] : 1;
}

/// The body, or with -solid_NAME_count > 1 its copies (NAME_1 ... NAME_N), added to the scene's bodies.
void add_body_or_copies(SceneSettings& s, const BodySettings& b, const BodyOptionValues& v, OptionTable& t,
                        const std::string& pre) {
  const int D = s.dim, count = v.count;
  const double spread = v.spread;
  const std::string& arrangement = v.arrangement;
  if (count == 1) {
    // A row's options without a row would do nothing.
    if (arrangement != kArrangements[0])
      t.bad("arrangement", arrangement, "even (or -" + pre + "count 2 or more)");
    if (spread > 0) t.bad("spread", option_value_text(spread), "0 (or -" + pre + "count 2 or more)");
    s.bodies.push_back(b);
    return;
  }
  if (arrangement == "scattered" && spread > 0)
    t.bad("spread", option_value_text(spread), "0 with -" + pre + "arrangement scattered (placed anywhere)");
  if (arrangement == "staggered" && count % 2)
    t.bad("count", std::to_string(count),
          "an even count with -" + pre +
              "arrangement staggered (an odd one puts the first and the last copy, side by side across the "
              "periodic end, on the same side)");
  // Copies: x evenly over the periodic flow direction, y (and z) from the row's centre and the arrangement.
  if (!s.periodic[0]) t.bad("count", std::to_string(count), "1 unless the domain is periodic in x");
  if (s.bodies.size() + static_cast<std::size_t>(count) > 64)
    t.bad("count", std::to_string(count), "at most 64 bodies in all");
  Vec3 row = b.center;
  for (int d = 0; d < 3; ++d)
    if (!std::isfinite(row[d])) row[d] = d < D ? s.origin[d] + 0.5 * s.size[d] : 0.0;
  std::mt19937 rng(static_cast<unsigned>(v.seed));
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  int across = 1;  // across the flow: the wall direction (the last non-periodic one), else y
  for (int d = D - 1; d >= 1; --d)
    if (!s.periodic[d]) {
      across = d;
      break;
    }
  for (int i = 0; i < count; ++i) {
    BodySettings c = b;
    c.name = b.name + "_" + std::to_string(i + 1);
    for (const BodySettings& other : s.bodies)
      if (other.name == c.name) bad_option("solid_bodies", c.name, "distinct names (a copy of " + b.name + ")");
    c.center = row;
    c.center[0] = s.origin[0] + (i + 0.5) * s.size[0] / count;
    if (arrangement == "staggered") c.center[across] += (i % 2 == 0 ? spread : -spread);
    if (arrangement == "random") c.center[across] += spread * uni(rng);
    c.scattered = arrangement == "scattered";
    c.scatter_seed = static_cast<unsigned>(v.seed) * 1000003u + static_cast<unsigned>(i);
    s.bodies.push_back(c);
  }
}

/// One body's options (-solid_NAME_*), checked in the order the user reads them, and its copies when
/// -solid_NAME_count > 1.
void read_body(SceneSettings& s, const std::string& name) {
  const int D = s.dim;
  BodySettings b;
  b.name = name;
  const std::string pre = "solid_" + name + "_";
  BodyOptionValues v;
  v.axes = b.semi_axes;
  v.axis = {b.axis[0], b.axis[1], b.axis[2]};
  v.stretch_axis = {b.stretch_axis[0], b.stretch_axis[1], b.stretch_axis[2]};
  v.elements.assign(b.elements.begin(), b.elements.begin() + D);
  OptionTable t("cellfsi body '" + name + "'", pre);
  declare_body_options(t, b, v, D);
  t.read();
  check_body_geometry(t, b, v, D);
  check_membrane(t, b);
  check_stretching(t, b, v, D, pre);
  if (b.patches > 1) {
    // The faces are one body of several patches: what measures a single patch (the random placement's
    // outline) does not take them yet.
    if (b.shape != "rbc_3d")
      t.bad("patches", std::to_string(b.patches), "1 for shape " + b.shape + " (6: rbc_3d only)");
    if (v.count > 1) t.bad("patches", std::to_string(b.patches), "1 with -" + pre + "count 2 or more");
  }
  check_law_and_elements(t, b, v, D, pre);
  // A ratio above Remark 3's bound would be refused later without naming it. (With no automatic count it
  // sizes nothing: not refused, so that a scene's ratio does not stand in the way of counts given.)
  if (b.element_ratio > s.max_mesh_ratio)
    t.bad("element_ratio", option_value_text(b.element_ratio),
          "at most -coupling_max_mesh_ratio = " + option_value_text(s.max_mesh_ratio) + " (paper Remark 3)");
  check_body_memory(s, b, v.count, pre);
  add_body_or_copies(s, b, v, t, pre);
}

/// A mesh the machine cannot hold is refused now, with the estimate, instead of allocating for minutes: the
/// fluid Jacobian (three times with the band solver: its kept part, its band part and their sum), shared over
/// the nodes of the fluid ranks, against the least memory available on any of them. Collective.
void check_memory(SceneSettings& s) {
  MPI_Comm comm = PETSC_COMM_WORLD;
  int size = 1;
  MPI_Comm_size(comm, &size);
  const double available = least_available_memory(comm);
  MPI_Comm node = MPI_COMM_NULL;
  MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  int node_rank = 0, leaders = 0;
  MPI_Comm_rank(node, &node_rank);
  MPI_Comm_free(&node);
  int leader = node_rank == 0 ? 1 : 0;
  MPI_Allreduce(&leader, &leaders, 1, MPI_INT, MPI_SUM, comm);
  // The preconditioner the run will use and the copies of the Jacobian it keeps (coupling/solver_policy.hpp
  // decides).
  char type[16] = "baij";  // -fluid_mat_type_jacobian: both cellfsi types need BAIJ
  CELLFSI_PETSC(
      PetscOptionsGetString(nullptr, nullptr, "-fluid_mat_type_jacobian", type, sizeof type, nullptr));
  coupling::SolverSituation situation;
  // (the divergence-conforming fluid assembles AIJ whatever the option; its bulk inverse needs a box periodic
  // along x, and z in 3D: DcImmersedFluid::has_bulk_inverse)
  const bool dc = s.fluid_space == "div_conforming";
  situation.baij = !dc && std::string(type) == "baij";
  situation.own_bulk_inverse =
      dc && s.domain != "narrowing" && s.periodic[0] && (s.dim == 2 || s.periodic[2]);
  situation.fluid_ranks = size;
  coupling::LinearSolverOptions& l = s.coupling.linear;
  // The domain is built only for the choice between several copies: a mesh that cannot hold one is refused
  // without it.
  const bool fits_once = fluid_jacobian_bytes(s) / std::max(1, leaders) <= available;
  if (!s.bodies.empty() && l.pc_type.empty() && fits_once)
    situation.fourier_inapplicable = coupling::fourier_inapplicable(build_domain(s));
  const std::string pc = s.bodies.empty() || !fits_once ? std::string("none")
                         : l.pc_type.empty()            ? coupling::default_pc_type(situation)
                                                        : l.pc_type;
  // cellfsi_fourier's second copy of the Jacobian (-coupling_partial_jacobian) is dropped unless asked for
  // when memory is short (coupling::plan_memory).
  PetscBool partial_given = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-coupling_partial_jacobian", &partial_given));
  const coupling::MemoryPlan plan = coupling::plan_memory(
      pc, l, partial_given == PETSC_TRUE, fluid_jacobian_bytes(s) / std::max(1, leaders), available);
  if (plan.partial_jacobian != l.partial_jacobian) {
    l.partial_jacobian = plan.partial_jacobian;
    CELLFSI_PETSC(
        PetscPrintf(comm,
                    "cellfsi: note: %.3g GB available: cellfsi_fourier keeps one copy of the %.3g GB Jacobian "
                    "(-coupling_partial_jacobian false)\n",
                    available / 1e9, fluid_jacobian_bytes(s) / 1e9));
  }
  const int copies = plan.jacobian_copies;
  const double need = copies * fluid_jacobian_bytes(s) / std::max(1, leaders);
  if (need <= available) return;
  std::ostringstream v, w;
  for (int d = 0; d < s.dim; ++d) v << (d ? "," : "") << s.elements[d];
  w << std::setprecision(3) << "fewer elements: a run needs at least " << need / 1e9 << " GB per node (the "
    << "fluid Jacobian"
    << (copies == 1 ? std::string() : " " + std::to_string(copies) + " times with -coupling_pc_type " + pc)
    << "; LU factors come on top) and " << available / 1e9 << " GB are available";
  bad_option("fluid_elements", v.str(), w.str());
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

SceneSettings SceneSettings::from_options(const std::string& default_name, bool fluid_side) {
  SceneSettings s;
  s.name = default_name;
  char space[32] = "equal_order";  // (its value is checked with the fluid's options)
  CELLFSI_PETSC(PetscOptionsGetString(nullptr, nullptr, "-fluid_space", space, sizeof space, nullptr));
  s.fluid_space = space;
  // Lists as the table reads them; where a 3D default is not in SceneSettings, z repeats y (extent,
  // elements) and only the last direction is bounded by walls.
  std::vector<double> size = s.size, origin{s.origin[0], s.origin[1], s.origin[2]};
  std::vector<bool> periodic(s.periodic.begin(), s.periodic.end());
  std::vector<int> elements(s.elements.begin(), s.elements.end());
  const auto dim = [&s] { return s.dim; };
  OptionTable t("cellfsi scene (docs/design.md §4; CGS units)");
  t.text("scene", s.name, "Scene name (default: the YAML file's stem)")
      .integer("dim", s.dim, "Spatial dimension, 2 or 3",
               {[](const long long& v) { return v == 2 || v == 3; }, "2 or 3"})
      .text("domain", s.domain, "Eulerian domain", {"rectangle", "box", "narrowing"})
      .reals("domain_size", size, "Domain extent Lx,Ly[,Lz] [cm] (rectangle, box)", dim, positive("[cm]"))
      .reals("domain_origin", origin, "Domain corner x,y[,z] [cm]", dim, finite("[cm]"))
      .flags("domain_periodic", periodic, "Periodic flag per direction, e.g. 1,0", dim)
      .real("channel_length", s.channel.length, "Narrowing channel: period in x [cm]")
      .real("channel_height", s.channel.height, "Narrowing channel: height [cm]")
      .real("channel_throat_height", s.channel.throat_height, "Narrowing channel: throat height [cm]")
      .real("channel_throat_length", s.channel.throat_length, "Narrowing channel: throat length [cm]")
      .real("channel_transition_length", s.channel.transition_length,
            "Narrowing channel: transition length [cm]")
      .real("channel_throat_center", s.channel.throat_center,
            "Narrowing channel: x of the throat centre [cm]")
      .integers("fluid_elements", elements, "Eulerian elements NX,NY[,NZ]", dim, at_least(1, "(every count)"))
      .integer("fluid_degree", s.degree, "Eulerian degree p (continuity p-1), 2..8",
               {[](const long long& v) { return v >= 2 && v <= 8; }, "2 <= p <= 8"})
      .text("flow", s.flow, "shear (moving walls), poiseuille (body force) or rest",
            {"shear", "poiseuille", "rest"})
      .text("flow_start", s.flow_start,
            "Channel flow's start: rest, or developed (the plasma's Poiseuille profile f y (H - y) / (2 mu) "
            "between the walls of a rectangle or box, for a channel at a finite Reynolds number)",
            {"rest", "developed"})
      .real("shear_rate", s.shear_rate, "Shear rate of the shear flow [1/s]", finite("[1/s]"))
      .real("final_time", s.final_time, "End time [s]", positive("[s]"))
      .real("dt", s.dt, "Time step [s]", positive("[s]"))
      .integer("output_every", s.output_every, "Write fluid.pvd every N steps (0: never)", at_least(0))
      .integer("checkpoint_every", s.checkpoint_every,
               "Write DIR/checkpoint every N steps (0: only at the end and when interrupted)",
               at_least(0, "(0: only at the end and when interrupted)"))
      .flag("restart", s.restart,
            "Continue the run in the output folder from its checkpoint (same options; -final_time may grow)")
      .text("output_dir", s.output_dir, "Output folder (default out/<scene>)")
      .flag("output_dir_adopt", s.output_dir_adopt,
            "Write into an existing non-empty folder that cellfsi did not make (no file of the names cellfsi "
            "writes may be in it; cellfsi then marks it as its own)")
      .real("equilibrium_tolerance", s.equilibrium_tolerance,
            "Stretched bodies (-solid_NAME_stretch_force): at equilibrium once neither diameter has changed "
            "by more than this fraction of itself over -equilibrium_window",
            between(1e-8, 1))
      .real("equilibrium_window", s.equilibrium_window,
            "Stretched bodies: the window of the equilibrium test [s]", positive("[s]"))
      .flag("equilibrium_stop", s.equilibrium_stop,
            "Stretched bodies: end the run (completed) at the step where every stretched body is at "
            "equilibrium, before -final_time");
  t.read();
  if (s.name.empty()) t.bad("scene", "''", "a non-empty name");
  if (s.domain == "box" && s.dim != 3) t.bad("domain", "box", "box needs -dim 3");
  if (s.domain != "box" && s.dim == 3) t.bad("dim", "3", "3D needs -domain box");
  const int D = s.dim;
  if (!t.given("domain_size") && D == 3 && size.size() == 2) size.push_back(size[1]);
  if (!t.given("fluid_elements") && D == 3) elements[2] = elements[1];
  if (!t.given("domain_periodic"))
    for (int d = 0; d < D; ++d) periodic[d] = d < D - 1;  // the last direction bounded by walls
  s.size.assign(size.begin(), size.begin() + D);
  s.origin = Vec3(origin[0], origin[1], D == 3 ? origin[2] : 0.0);
  for (int d = 0; d < 3; ++d) s.periodic[d] = d < D && periodic[d];
  if (s.domain == "narrowing") {
    s.channel.validate();
    // The narrowing's extent is the channel's (it was silently ignored when given as -domain_size).
    if (t.given("domain_size"))
      t.bad("domain_size", "(given)", "not with -domain narrowing: use -channel_length, -channel_height");
    if (t.given("domain_origin"))
      t.bad("domain_origin", "(given)",
            "not with -domain narrowing (it spans 0..length x -height/2..height/2)");
    s.size = {s.channel.length, s.channel.height};
    s.origin = Vec3(0, -s.channel.height / 2, 0);
  }
  // Far from the origin the coordinates keep too few digits to tell the mesh's points apart (1e10,1e10 for
  // a 0.0024 cm box ended in "det F = -nan"); a million domain lengths out, a 64th of the domain still
  // holds about eight of a coordinate's sixteen digits.
  for (int d = 0; d < D; ++d)
    if (!(std::abs(s.origin[d]) <= kMaxOriginOverSize * s.size[d])) {
      const char axis = "xyz"[d];
      std::ostringstream v, w;
      for (int e = 0; e < D; ++e) v << (e ? "," : "") << s.origin[e];
      w << "|" << axis << "| <= " << kMaxOriginOverSize << " x the domain's extent (" << s.size[d]
        << " cm along " << axis
        << "): farther out the coordinates lose the digits that tell the mesh's points apart";
      t.bad("domain_origin", v.str(), w.str());
    }
  for (int d = 0; d < 3; ++d) s.elements[d] = d < D ? elements[d] : 1;
  for (int d = 0; d < D; ++d)
    if (s.periodic[d] && s.elements[d] < s.degree)
      t.bad("fluid_elements", std::to_string(s.elements[d]), ">= degree in a periodic direction");
  if (s.flow == "shear" && s.domain == "narrowing") t.bad("flow", "shear", "shear needs a rectangle or box");
  // The divergence-conforming space on the curved channel takes the map's second derivatives (the Piola map,
  // fluid/div_conforming/dc_piola.hpp). At p = 2 they jump between elements, and so do a cell's terms and
  // velocity gradient at a point on an element boundary: in a coupled step such a point can move from one
  // element to the other and back between iterations, and the iteration stalls (docs/fluid.md).
  if (s.fluid_space == "div_conforming" && s.domain == "narrowing" && s.degree < 3)
    t.bad("fluid_degree", std::to_string(s.degree),
          "3 <= p <= 8 with -fluid_space div_conforming on the narrowing: the Piola map needs the channel's "
          "second derivatives continuous, and at p = 2 they jump between elements");
  if (s.flow_start == "developed") {
    if (s.flow != "poiseuille") t.bad("flow_start", "developed", "only with -flow poiseuille");
    if (s.domain == "narrowing")
      t.bad("flow_start", "developed",
            "a straight channel (-domain rectangle or box): the narrowing's is not known");
    if (std::count(s.periodic.begin(), s.periodic.begin() + s.dim, false) != 1)
      t.bad("flow_start", "developed", "walls in exactly one direction (-domain_periodic), a plane channel");
    else if (!s.periodic[0])
      t.bad("flow_start", "developed", "a channel periodic along x, its axis (-domain_periodic)");
  }
  // The step count must be at least 1 and fit its int (-final_time 10 -dt 1e-12 wrapped to a negative count).
  if (!(s.dt <= s.final_time))
    t.bad("dt", option_value_text(s.dt),
          "at most -final_time = " + option_value_text(s.final_time) + " s (at least one step)");
  if (!(s.final_time / s.dt <= 1e9))
    t.bad("dt", option_value_text(s.dt),
          "at least -final_time / 1e9 = " + option_value_text(s.final_time / 1e9) + " s (at most 1e9 steps)");
  // The run takes whole steps: a final time between two of them ran on to the next with no word
  // (-final_time 0.005 -dt 0.004 ended at t = 0.008).
  const double steps = s.final_time / s.dt;
  if (std::abs(steps - std::round(steps)) > 1e-6) {
    std::ostringstream w;
    w << "a whole number of steps of -dt = " << s.dt << " s, e.g. " << std::floor(steps) * s.dt << " or "
      << std::ceil(steps) * s.dt << " s (or a -dt that divides it)";
    t.bad("final_time", option_value_text(s.final_time), w.str());
  }
  if (s.output_dir.empty()) s.output_dir = "out/" + s.name;

  std::vector<std::string> names;
  read_coupling(s, names);
  for (const std::string& name : names) {
    const bool ok = !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
      return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
    });
    if (!ok) bad_option("solid_bodies", name, "names of lower-case letters, digits and _");
    for (const BodySettings& o : s.bodies)
      if (o.name == name) bad_option("solid_bodies", name, "distinct names");
    read_body(s, name);
  }
  const bool stretched =
      std::any_of(s.bodies.begin(), s.bodies.end(), [](const BodySettings& b) { return b.stretched; });
  const std::string only_stretched = "only with a stretched body (-solid_NAME_stretch_force)";
  if (!stretched && t.given("equilibrium_tolerance"))
    t.bad("equilibrium_tolerance", option_value_text(s.equilibrium_tolerance), only_stretched);
  if (!stretched && t.given("equilibrium_window"))
    t.bad("equilibrium_window", option_value_text(s.equilibrium_window), only_stretched);
  if (!stretched && t.given("equilibrium_stop"))
    t.bad("equilibrium_stop", s.equilibrium_stop ? "true" : "false", only_stretched);
  place_scattered_copies(s);
  if (fluid_side) check_memory(s);
  return s;
}

}  // namespace cellfsi::app
