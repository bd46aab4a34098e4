#pragma once
// A scene: the domain, the flow, the immersed bodies, time stepping and output settings, read from the
// options database (a scene YAML file is read into it: nested keys become prefixes, the command line
// overrides). Flows: a shear flow between moving walls, a channel flow driven by a body force, or rest.
// Bodies (cells): membranes (capsules) and bulky bodies (nuclei) listed by -solid_bodies, each with options
// -solid_<name>_<key>.
#include <array>
#include <nlohmann/json.hpp>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "coupling/fsi_coupler.hpp"
#include "fluid/immersed_fluid.hpp"
#include "geometry/builders.hpp"
#include "solid/body_metrics.hpp"
#include "solid/external_load.hpp"
#include "solid/nurbs_solid.hpp"
#include "solid/suspension_metrics.hpp"

namespace cellfsi::app {

/// One immersed body (a cell membrane or a nucleus).
struct BodySettings {
  std::string name;
  // hollow_ellipse | ellipse | rbc (2D); hollow_ellipsoid | ellipsoid | rbc_3d (3D)
  std::string shape = "hollow_ellipse";
  std::vector<double> semi_axes{2e-4, 1e-4};  // mid-surface semi-axes [cm] (rbc, rbc_3d: none)
  geometry::Vec3 center = geometry::Vec3::Zero();
  double angle_deg = 0;                           // rotation [degrees]: 2D from +x, 3D about `axis`
  geometry::Vec3 axis = geometry::Vec3::UnitZ();  // 3D: rotation axis (unit)
  double area = 0;                       // rbc: enclosed area of the mid-line [cm^2] (0: the default RBC)
  double thickness = 5e-7;               // membranes [cm]
  std::array<int, 3> elements{0, 0, 0};  // Lagrangian elements per direction; 0: from the fluid mesh
  double element_ratio = 0;  // automatic counts: element size / smallest fluid element (0: the space's rule)
  int degree = 2;
  // Membranes: the degree through the thickness (direction 0), -degree or above (0: -degree). A thin shell's
  // one element then holds thickness_degree + 1 collocation points across it instead of degree + 1.
  int thickness_degree = 0;
  int degree_through() const { return thickness_degree > 0 ? thickness_degree : degree; }
  // 3D membranes: a thin shell about the builder's mid-surface (solid::NurbsSolid's second constructor)
  bool thin_shell = false;
  // rbc_3d: 1, the polar patch (its poles at the dimples' centres), or 6, a cube's faces mapped onto the cell
  // (no poles; geometry::biconcave_rbc_3d_faces, solid::CompositeSolid)
  int patches = 1;
  double shear_modulus = 7500;           // G [dyn/cm^2], the small-strain shear modulus of every material law
  std::string material = "neo_hookean";  // neo_hookean | mooney_rivlin | strain_hardening | skalak |
                                         // strain_hardening_membrane
  double mooney_rivlin_fraction = 0.5;   // mooney_rivlin: a, the I2 term's share
  double hardening_c3 = 1.0 / 30;        // strain_hardening(_membrane): C3 / G (Mills et al. 2004)
  double area_dilation = 10;             // skalak, strain_hardening_membrane: C, area modulus G h (1 + 2C)
  double density = 1.1;                  // rho_2 [g/cm^3]
  double inner_viscosity = 0;            // membranes: mu of the fluid inside [g/(cm s)] (0: the fluid's)
  // The optical-tweezers stretching test (membranes; solid/external_load.hpp): a force stretch_force [dyn] on
  // the material within stretch_patch / 2 [cm] of each end of the mid-surface along stretch_axis (+ at the
  // far end, - at the near one). `stretched`: -solid_NAME_stretch_force given (0 too), the diameters measured.
  bool stretched = false;
  double stretch_force = 0;
  double stretch_patch = 2e-4;
  double stretch_ramp = 0;  // [s]: the force grows linearly from 0 to stretch_force over it (0: at once)
  geometry::Vec3 stretch_axis = geometry::Vec3::UnitX();
  // A copy of -solid_NAME_arrangement scattered: its centre is drawn at random (place_scattered_copies), from
  // this seed (the row's -seed and the copy's number).
  bool scattered = false;
  unsigned scatter_seed = 0;
  bool membrane() const { return shape.rfind("hollow", 0) == 0 || biconcave(); }
  bool biconcave() const { return shape == "rbc" || shape == "rbc_3d"; }  // Evans-Fung: no semi-axes
};

struct SceneSettings {
  std::string name = "shear";
  int dim = 2;
  std::string domain = "rectangle";          // rectangle | box | narrowing
  std::vector<double> size{0.0024, 0.0012};  // domain extent [cm]
  geometry::Vec3 origin = geometry::Vec3::Zero();
  std::array<bool, 3> periodic{true, false, false};
  geometry::NarrowingChannel channel;
  std::array<int, 3> elements{64, 32, 1};
  int degree = 3;
  std::string flow = "shear";  // shear | poiseuille | rest
  std::string flow_start = "rest";  // rest | developed (poiseuille in a straight channel)
  double shear_rate = 70.0;    // [1/s]
  double final_time = 0.05;    // [s]
  int output_every = 0;        // write fluid.pvd every N steps (0: never)
  int checkpoint_every = 100;  // write DIR/checkpoint every N steps (0: only at the end and when interrupted)
  bool restart = false;        // continue the run in output_dir from its checkpoint
  std::string output_dir;      // default out/<name>
  bool output_dir_adopt = false;  // write into a non-empty folder cellfsi did not make (apps/run_output.hpp)
  double dt = 5e-4;            // time step [s] (-dt)
  std::vector<BodySettings> bodies;
  coupling::CouplerOptions coupling;  // coupling.s_interface: the s_I used (chosen by the rule when auto)
  bool s_interface_auto = true;       // -s_interface auto: s_I chosen from the mesh
  double s_interface_target = 1e-3;   // -s_interface_target: the area error the choice aims at
  bool s_interface_raise = false;     // -s_interface_raise: s_I raised during the run as r_A drifts
  double max_mesh_ratio = 1.0;       // largest Lagrangian / smallest Eulerian element size (paper Remark 3)
  std::string fluid_space = "equal_order";  // -fluid_space (read and checked by fluid::FluidOptions)
  double metrics_average_from = -1;  // start of the averaging window [s]; < 0: half the final time
  // Stretched bodies: equilibrium when neither diameter changed by more than the tolerance (relative) over
  // the window [s]; with equilibrium_stop the run ends there.
  double equilibrium_tolerance = 1e-3;
  double equilibrium_window = 1e-3;
  bool equilibrium_stop = false;

  /// Reads every scene option (see -help) and validates; throws std::invalid_argument naming option, value
  /// and range.
  /// fluid_side: also checks that the machine can hold the fluid mesh (the solid side holds no fluid).
  static SceneSettings from_options(const std::string& default_name, bool fluid_side = true);
};

/// Bytes of the fluid Jacobian of a scene's mesh (BAIJ values: every node couples with (2p + 1)^d nodes).
double fluid_jacobian_bytes(const SceneSettings& s);
/// MemAvailable of /proc/meminfo in bytes (0 where there is none).
double available_memory_bytes();

/// The Eulerian patch of a scene.
geometry::Patch build_domain(const SceneSettings& s);
/// A body's Lagrangian element counts per direction: those given, and where 0, slightly smaller than the
/// fluid's elements (found on a small trial mesh, without building the body).
std::array<int, 3> body_element_counts(const SceneSettings& s, const BodySettings& b);
/// The reference patch of a body (elements from the fluid mesh where not given); a body of several patches
/// (-solid_NAME_patches 6) has only build_body_parts (std::logic_error here).
geometry::Patch build_body_patch(const SceneSettings& s, const BodySettings& b);
/// The reference patches of a body: one, or its parts.
std::vector<geometry::Patch> build_body_parts(const SceneSettings& s, const BodySettings& b);
/// A body's material law (-solid_NAME_material and its constants; docs/materials.md).
std::shared_ptr<const solid::Material> make_material(const BodySettings& b);
/// A body's external loads: the stretching test's two forces at the ends of its patches' mid-surface (none
/// when not stretched).
std::vector<solid::PatchLoad> stretch_loads(const BodySettings& b,
                                            const std::vector<geometry::Patch>& reference);
/// Bodies that cannot live on solid ranks (-solid_ranks, cellfsi-solid) refused, naming the option: a body of
/// several patches (-solid_NAME_patches 6).
void check_bodies_on_solid_ranks(const SceneSettings& s);
/// The scene's bodies (the solid side of a run): a NurbsSolid each, with its loads, or a CompositeSolid of a
/// NurbsSolid a patch.
std::vector<std::unique_ptr<solid::SolidSolver>> build_bodies(const SceneSettings& s);
/// Centres for the copies of -solid_NAME_arrangement scattered, in the order of the bodies: drawn uniformly
/// over the domain's box until the copy lies inside the domain at least one fluid element (the smallest
/// element extent) from the walls and from every body placed before it (periodic images included), and
/// neither holds nor lies in another body's membrane. Throws std::invalid_argument (naming -solid_NAME_count)
/// when a copy finds no place in kScatterTries draws.
void place_scattered_copies(SceneSettings& s);
inline constexpr int kScatterTries = 2000;
/// The placement checks of docs/design.md §4 (inside the domain, no overlap, Lagrangian elements no larger
/// than max_mesh_ratio times the Eulerian ones); throws std::invalid_argument naming the option to change.
void check_bodies(const SceneSettings& s, const geometry::Patch& domain);

/// What one time step cost (a fluid-only step or a coupled one).
struct SceneStep {
  int iterations = 0, linear_iterations = 0;
  int factorizations = 0, bulk_factorizations = 0;  // see coupling::SolveCounts
  bool converged = false;
  std::string reason;
};

/// The assembled scene on the fluid side: the patch, the fluid solver, the coupling loop over the bodies
/// (wherever they live) and the metrics.
class Scene {
 public:
  Scene(MPI_Comm comm, const SceneSettings& settings);
  fluid::ImmersedFluid& fluid() { return *fluid_; }
  const SceneSettings& settings() const { return s_; }
  /// Couples the bodies (in this process or proxies of remote ones): call once, before the first step.
  void attach_bodies(std::vector<solid::SolidSolver*> bodies);
  const std::vector<solid::SolidSolver*>& bodies() const { return bodies_; }
  /// The coupling loop (null before attach_bodies or without bodies).
  const coupling::FsiCoupler* coupler() const { return coupler_.get(); }
  SceneStep step();
  /// Each body's state (SolidSolver::state) and metric records (BodyTracker::state), for a checkpoint.
  std::vector<std::vector<double>> body_states() const;
  std::vector<std::vector<double>> tracker_states() const;
  /// A restart (after attach_bodies, and after the fluid took its state: read_checkpoint): the bodies'
  /// states and records.
  void restore(const std::vector<std::vector<double>>& bodies, const std::vector<std::vector<double>>& trackers);
  /// The scene's own records (suspension rheology, the time-averaged profile, the flow rates) as named JSON
  /// fields, for a checkpoint, and their restoration (also from the flat list of numbers of earlier
  /// checkpoints); damaged records are std::invalid_argument.
  nlohmann::json metric_state() const;
  void restore_metric_state(const nlohmann::json& state);
  /// The velocity across the channel at mid-length averaged over the metrics' window (channel flows; empty
  /// before the window or for shear): points and mean velocity.
  fluid::SectionData mean_profile() const;
  /// The flow without cells where it is known (shear: gammadot (y - H/2) along x; a channel started
  /// developed: the plasma's Poiseuille profile), else empty.
  const std::function<geometry::Vec3(const geometry::Vec3&)>& undisturbed_velocity() const {
    return undisturbed_;
  }
  /// Metrics of the current state (names are the CSV/JSON keys), including errors against analytic solutions
  /// where the scene has one and, per body, "<body>_<metric>" (solid/body_metrics.hpp).
  std::vector<std::pair<std::string, double>> metrics();
  /// The run's results for summary.json: the last metrics with each body's averages over the oscillatory
  /// regime (-metrics_average_from) in place of its instantaneous values, and the s_I used.
  std::vector<std::pair<std::string, double>> summary_metrics();
  /// True when the scene has stretched bodies (-solid_NAME_stretch_force) and every one of them has reached
  /// equilibrium (-equilibrium_tolerance over -equilibrium_window).
  bool at_equilibrium() const;
  /// Words for summary.json: how s_I was set ("s_interface_choice": auto or given), each body's motion
  /// regime over the same window ("<body>_regime") and its material law ("<body>_material").
  std::vector<std::pair<std::string, std::string>> summary_text() const;

 private:
  void restore_flat_metric_state(const std::vector<double>& state);  // checkpoints before the JSON fields
  std::vector<std::pair<std::string, double>> flow_metrics();
  /// -s_interface_raise: s_I times 4 each time the membranes' largest |r_A|, growing, passes the next
  /// threshold (half the target, then half-way from the last threshold to the target), up to
  /// coupling::kMaxInterfaceScaling.
  void raise_interface_scaling();
  /// A suspension record of the current state (channel flow with membranes; see
  /// solid/suspension_metrics.hpp).
  void record_suspension();
  /// Membranes in a 2D channel: the shape's mirror asymmetries (keys without the body's name).
  std::vector<std::pair<std::string, double>> shape_symmetry(std::size_t body) const;
  /// Points of the membranes' mid-surfaces (sampled) that lie inside another membrane (in any periodic
  /// image): 0 while no two membranes overlap.
  int membrane_overlaps() const;
  /// Without the repulsion, the least distance of the membranes' mid-surfaces (sampled as for
  /// membrane_overlaps) from the walls [cm]; NaN where the domain has no wall (the repulsion, when on,
  /// reports its own points' gap instead).
  double membrane_wall_gap();
  /// Adds the current mid-length profile to the window's average (channel flows).
  void accumulate_profile();
  double average_from() const;  // start of the metrics' averaging window [s]
  const BodySettings& body_settings(const std::string& name) const;
  SceneSettings s_;
  geometry::Patch patch_;
  std::unique_ptr<fluid::ImmersedFluid> fluid_;
  int wall_dir_ = -1;  // the wall-normal direction (shear, poiseuille)
  std::vector<solid::SolidSolver*> bodies_;
  std::unique_ptr<coupling::FsiCoupler> coupler_;
  std::vector<solid::BodyTracker> trackers_;
  // Per body: the stretching test's diameters and equilibrium (stretched bodies only).
  std::vector<std::optional<solid::EquilibriumMonitor>> equilibrium_;
  void record_diameters();
  /// The bodies' metrics shared among the fluid's ranks (each integrates its share of the elements).
  solid::MetricShare metric_share() const;
  std::vector<std::pair<std::string, double>> last_;
  std::function<geometry::Vec3(const geometry::Vec3&)> undisturbed_;
  bool suspension_on_ = false;  // a plane channel (Poiseuille, 2D) with membranes: rheology recorded
  std::vector<solid::SuspensionRecord> suspension_;
  fluid::SectionData profile_sum_;  // velocity summed over the window's steps (points: the last section's)
  std::vector<std::pair<double, double>> flow_rates_;  // channel flows: (time, flow rate) at every record
  int profile_count_ = 0;
  double raise_threshold_ = 0;  // -s_interface_raise: the |r_A| whose passing raises s_I next
  double raise_previous_ = std::numeric_limits<double>::infinity();  // the largest |r_A| at the last step
  int s_interface_raises_ = 0;
  // The contact repulsion's least gaps [cm]: at the last step, and over the run (infinite: none within its
  // cut-off).
  coupling::RepulsionStats contact_last_;
  double contact_cell_min_ = std::numeric_limits<double>::infinity();
  double contact_wall_min_ = std::numeric_limits<double>::infinity();
  int membranes_ = 0;
  int overlaps_max_ = 0;     // the most membrane_overlaps() over the run
  std::unique_ptr<coupling::Repulsion> wall_probe_;  // membrane_wall_gap's walls (no force: P0 = 0)
  double profile_from_ = 0;  // the window start the profile is summed from (average_from() of its run)
};

}  // namespace cellfsi::app
