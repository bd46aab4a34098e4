#pragma once
// The fluid as the rest of cellfsi sees it: one abstract face over a discretisation of incompressible
// Navier-Stokes on one Eulerian NURBS patch, with the immersed-solid terms of the paper's Eq. (10). coupling/
// and apps/ hold this type only (tests/unit/coupling/test_fluid_interface.cpp drives the coupling loop
// through a fake one; tests/check_fluid_interface.cmake checks that coupling/ and apps/ include no
// discretisation's header). The VMS solver (fluid/fluid_solver.hpp: equal-order splines, node blocks of dim + 1 unknowns) is
// the one create_fluid makes today; a divergence-conforming space (velocity component i of degree k' + 1
// along x_i) implements the same face with its own unknowns.
//
// What every implementation shares:
//   * the geometry: the Eulerian patch patch() (its elements are the discretisation's elements, numbered as
//     Patch::element_multi_index; point location, the s^h marking and the element regions of coupling/ work
//     on it);
//   * time stepping: generalized-alpha for first-order systems on a global PETSc vector of unknowns U
//     (solution()) and its rate (kept inside), the Newton iteration either the fluid's own (step()) or driven
//     from outside (begin_step, residual, jacobian, end_step: the coupling loop, paper Sec. 2.3);
//   * fields by the patch's control points: the scaling field s^h and the viscosity field are given as values
//     at the patch's control points (natural, folded index), i.e. as functions of the patch's own spline
//     space. A discretisation uses them as it sees fit; one without s^h ignores set_scaling (documented by
//     the implementation).
// What is left to each: the layout of the unknowns (block_layout() says whether it is node blocks on the
// patch's control net, which the Fourier preconditioner needs; region_unknowns() says which unknowns an
// element region couples, which the band preconditioner needs), its own linear solver, output and state
// files.
//
// Lifecycle (STYLE.md lesson 3): create (create_fluid, after FluidOptions::set_from_options), set the initial
// state, optionally setup(), then steps (step(), or a coupler's begin_step ... end_step), output and
// checkpoints between steps; destroyed with its owner (RAII).
#include <petscao.h>
#include <petscksp.h>
#include <petscviewer.h>

#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fluid/fluid_options.hpp"
#include "fluid/immersed_point.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::fluid {

using geometry::Vec3;

/// What one time step cost.
struct StepStats {
  int newton_iterations = 0;
  int linear_iterations = 0;
  bool converged = false;
  std::string reason;  // SNES converged reason
};

/// The solids' stiffness in the coupled Jacobian as the block iteration sees it (-coupling_solid_tangent
/// collocation): a velocity increment dv of the fluid moves a body only through its values at the body's
/// collocation points (kinematic_update, then the collocation solve), not through dv at each quadrature
/// point, as the consistent tangent assumes. On a body about as fine as the fluid the two differ by 20 %
/// for the first correction of a step and by 70-90 % for the later ones
/// (docs/notes/2026-11-28-solid-tangent.md). So the tangent is: the velocity at the collocation points
/// (elements, xi), control(dv, dc) for the bodies' control increments (n_columns: unknowns times 3
/// components, the columns below), and at each immersed point (ImmersedPoint::solid_begin, solid_end) its
/// functions' first columns and spatial gradients.
struct SolidLinearization {
  int n_columns = 0;
  std::vector<geometry::Index3> elements;  // the collocation points, every body's in turn
  std::vector<geometry::Param> xi;
  /// dv: 3 values per collocation point (t_{n+alpha_f} velocity increments), the same on every rank; dc:
  /// n_columns values. May be collective over the fluid's ranks (the coupler's is: each body's columns
  /// dealt out to the ranks).
  std::function<void(const std::vector<double>& dv, std::vector<double>& dc)> control;
  std::vector<int> column;   // per entry: the column of the function's component 0 (1 and 2 follow)
  std::vector<double> grad;  // per entry: 3 values, d N / d x
};

/// Velocity, its gradient and its time derivative at a point (at t_{n+1} after a step).
struct PointSample {
  bool found = false;
  Vec3 v = Vec3::Zero();
  geometry::Mat3 grad_v = geometry::Mat3::Zero();  // grad_v(i, j) = d v_i / d x_j
  Vec3 vdot = Vec3::Zero();
  double p = 0;  // kinematic pressure
};

/// Flow rate through the section xi_0 = u (integral of v . n over it; per unit depth in 2D) and the velocity
/// along it at n_profile points equally spaced in xi_1 (2D) — collective; valid on every rank.
struct SectionData {
  double flow_rate = 0;
  double area = 0;  // length (2D) or area (3D) of the section
  std::vector<geometry::Vec3> points, velocity;
};

/// The unknowns as node blocks on the patch's control net: `dof` unknowns per control point (velocity
/// components, then the pressure), interleaved. What structured-grid solvers need (the Fourier bulk solver
/// of solvers/pc_types.hpp, the near operator of solvers/near_operator.hpp). The handles belong to the fluid.
struct BlockLayout {
  std::array<int, 3> n{1, 1, 1};       // control points per direction (1 beyond the dimension)
  std::array<int, 3> degree{0, 0, 0};  // spline degree per direction
  std::array<bool, 3> periodic{false, false, false};
  int dof = 1;                                   // unknowns per control point
  AO natural = nullptr;                          // natural (lexicographic) <-> PETSc global node numbering
  ISLocalToGlobalMapping local_to_global = nullptr;  // ghosted local -> global unknowns (MatSetValuesLocal)
};

class ImmersedFluid {
 public:
  virtual ~ImmersedFluid() = default;

  // --- What it is ---
  virtual MPI_Comm comm() const = 0;
  virtual int dim() const = 0;
  /// The Eulerian geometry: its elements are the discretisation's; its control points index the fields of
  /// set_scaling and set_viscosity.
  virtual const geometry::Patch& patch() const = 0;
  /// The settings in effect (the implementation may have adjusted pressure_null_space to its solver).
  virtual const FluidOptions& options() const = 0;
  /// The node-block layout of the unknowns, or nothing when they are not node blocks on the control net.
  virtual std::optional<BlockLayout> block_layout() const = 0;
  /// The kind of each of this rank's unknowns (its entries of solution(), in order): 0 .. dim-1 a velocity
  /// component, dim the pressure (the coupling loop's Anderson norm weighs each kind alike).
  virtual std::vector<int> unknown_kinds() const = 0;

  // --- State and its own time stepping (runs without cells) ---
  /// Sets the velocity from a function of position (the discretisation's interpolant); pressure 0, rate 0.
  virtual void set_initial_velocity(const std::function<Vec3(const Vec3&)>& v0) = 0;
  /// Sets the velocity to the L2 projection of v0 onto the discretisation's space, which holds every field of
  /// that space exactly (a channel's parabola on degree >= 2 elements, where the interpolant of
  /// set_initial_velocity is exact only for linear fields); pressure 0, rate 0. Costs a mass-matrix assembly
  /// and solve (a scalar matrix of the fluid's mesh).
  virtual void project_initial_velocity(const std::function<Vec3(const Vec3&)>& v0) = 0;
  /// Sets up the fluid's own linear solver on the Jacobian of the current state, so every solver option has
  /// been read; optional (step() does it lazily). Call after setting the initial state.
  virtual void setup() = 0;
  /// Advances one time step with the fluid's own nonlinear solver (no cells).
  virtual StepStats step() = 0;
  virtual double time() const = 0;
  virtual int steps_taken() const = 0;
  /// U at the latest time level: a global vector of the unknowns (the layout of the coupling loop's iterate).
  virtual Vec solution() const = 0;

  // --- Sampling ---
  /// v, grad v, vdot and p at physical points (collective; every rank gets every value; found is false for a
  /// point outside the domain).
  virtual std::vector<PointSample> sample(const std::vector<Vec3>& points) const = 0;
  /// v and grad v at t_{n+alpha_f} of the iterate X at points already located in the patch (element, xi)
  /// (collective; every rank gets every value). vdot is the rate at t_{n+alpha_m}; p is not sampled.
  virtual std::vector<PointSample> sample_alpha(Vec X, const std::vector<geometry::Index3>& elements,
                                                const std::vector<geometry::Param>& xi) const = 0;
  /// Flow rate through the section xi_0 = u and the velocity profile along it (collective).
  virtual SectionData section(double u, int n_profile = 33) const = 0;

  // --- The immersed step, driven from outside (the coupling loop, paper Sec. 2.3) ---
  /// Whether this rank assembles element e (the immersed points the coupler gives this rank are those in its
  /// elements, unless assembles_points_anywhere()).
  virtual bool owns_element(const geometry::Index3& e) const = 0;
  /// Whether a rank may assemble an immersed point in any element (its rows travel to their owners). Then the
  /// coupler deals each body's points out to the ranks in equal runs in the order of their elements: the
  /// points' terms and the material's evaluation divide by the ranks even where the cells sit in a few ranks'
  /// elements, and a rank's points lie in a contiguous range of elements. Otherwise (the default) a point
  /// goes to its element's owner (owns_element).
  virtual bool assembles_points_anywhere() const { return false; }
  /// True where sample_alpha() takes points of any element on any rank (the state is whole on every rank):
  /// the coupler then gives each rank a share of the collocation points and gathers the samples.
  virtual bool samples_anywhere() const { return false; }
  /// Immersed points already located (element, xi): this rank's (those in its elements, or those dealt to it
  /// where assembles_points_anywhere()).
  virtual void set_immersed_points(const std::vector<geometry::Index3>& elements,
                                   const std::vector<geometry::Param>& xi,
                                   const std::vector<ImmersedPoint>& data) = 0;
  /// The solids' stiffness for the next jacobian() through their collocation (SolidLinearization), for the
  /// points then given to set_immersed_points; returns false if this discretisation does not use it (its
  /// jacobian() then uses each point's consistent tangent). On true it takes lin's contents and leaves in lin
  /// the buffers of the linearization it replaces (contents unspecified), for the caller to clear and fill
  /// again without new pages (per point, a column and three gradients per control function of its element).
  virtual bool set_solid_linearization(SolidLinearization& /*lin*/) { return false; }
  /// The interface scaling field s^h by the patch's control points (natural index -> s; s_I on the functions
  /// the marking chose, 1 elsewhere; paper Sec. 3.3). Applies to owned control points.
  virtual void set_scaling(const std::function<double(int node)>& s) = 0;
  /// The viscosity field by the patch's control points: the dynamic viscosity mu_A [g/(cm s)] of each natural
  /// index (docs/fluid.md, "The viscosity field"). Applies to owned control points.
  virtual void set_viscosity(const std::function<double(int node)>& mu) = 0;
  /// Starts a time step: keeps the state at t_n; X (a vector like solution()) receives the predicted U_{n+1}.
  virtual void begin_step(Vec X) = 0;
  /// Residual R_MC of the iterate X (with the current immersed points, s^h and viscosity).
  virtual void residual(Vec X, Vec F) = 0;
  /// Its (approximate) tangent K_MC into J (a matrix like jacobian_matrix()).
  virtual void jacobian(Vec X, Mat J) = 0;
  /// One of two parts of K_MC that add up to jacobian(X, J), for a solver that keeps one part for many steps
  /// (solvers/band_schur.hpp). `in_region[e]` (e: Patch::element_multi_index's numbering) marks the elements
  /// of the region's part. region_side: the region's elements and every immersed point, Dirichlet rows
  /// zeroed with a zero diagonal; otherwise the other elements, Dirichlet rows zeroed with a unit diagonal.
  virtual void jacobian_part(Vec X, Mat J, const std::vector<char>& in_region, bool region_side) = 0;
  /// Adds to J the region's part of K_MC (see jacobian_part), leaving J's Dirichlet rows unit rows: the other
  /// part copied into J plus this is jacobian(X, J), with one assembly of the region's elements only.
  virtual void jacobian_add_part(Vec X, Mat J, const std::vector<char>& in_region) = 0;
  /// K_MC of the iterate X without the cells: s^h = 1 everywhere, no immersed points and the uniform
  /// options().viscosity (the bulk operator of the Fourier preconditioner, solvers/region_corrected.hpp).
  virtual void bulk_jacobian(Vec X, Mat J) = 0;
  /// Accepts X as U_{n+1}: updates the rate and the time.
  virtual void end_step(Vec X) = 0;
  /// The global indices of the unknowns the elements `in_region` couple (rows of those elements' element
  /// matrices), sorted; all of them, the same list on every rank. The band preconditioner's split.
  virtual std::vector<PetscInt> region_unknowns(const std::vector<char>& in_region) const = 0;
  /// The Jacobian's matrix (with the pressure's null space, if any); null after release_jacobian_matrix
  /// (a fluid may also make it at the first call: the divergence-conforming one does).
  virtual Mat jacobian_matrix() const = 0;
  /// jacobian_matrix() if it exists now, else null; never makes it (for destructors and error paths: a fluid
  /// that makes its matrix at the first call would make it only to detach something from it).
  virtual Mat jacobian_matrix_if_made() const { return jacobian_matrix(); }
  /// Whether jacobian_matrix() is block AIJ (MATSEQBAIJ or MATMPIBAIJ: the node-block solvers need it),
  /// asked without making a matrix that is not there yet.
  virtual bool jacobian_is_blocked() const;
  /// Frees the Jacobian's matrix, for a coupled run whose operator needs no whole matrix
  /// (-coupling_bulk_stencil); jacobian_matrix(), step() and setup() make it again.
  virtual void release_jacobian_matrix() = 0;

  /// This discretisation's own exact inverse of the bulk operator (bulk_jacobian at X), built now and kept:
  /// apply(b, x) on vectors like solution(), a line that describes it, and the operator's largest deviation
  /// from the structure the inverse assumes (relative to a row's largest entry); or nothing if it has none
  /// (the VMS fluid: its bulk inverse is solvers/fourier_bulk.hpp, made from block_layout()). The coupled
  /// solve's PC type cellfsi_bulk applies it. Collective.
  /// stencil_operator: if not null, the coupled Jacobian as an operator whose bulk part is the inverse's own
  /// stencil (no assembled bulk; -coupling_bulk_stencil): owned by the fluid, refreshed by jacobian(X, it),
  /// its products those of jacobian() to the operator's deviation from that stencil. Its product with apply's
  /// last output z (unchanged) takes apply's input v for the bulk part, S z = v: exact for a v compatible with
  /// the bulk operator, as every coupling residual and the Krylov vectors made from them (divergence-conforming
  /// fluid).
  struct OwnBulkInverse {
    std::function<void(Vec b, Vec x)> apply;
    std::string description;
    double deviation = 0;
    Mat stencil_operator = nullptr;
  };
  virtual std::optional<OwnBulkInverse> bulk_inverse(Vec /*X*/) { return std::nullopt; }
  /// For a space whose velocity is divergence-free pointwise: the largest max|div v| / max|grad v| after any
  /// step so far (summary.json's fluid_max_divergence_ratio); nothing for one that is not.
  virtual std::optional<double> max_divergence_ratio() const { return std::nullopt; }
  /// Whether bulk_inverse gives one here.
  virtual bool has_bulk_inverse() const { return false; }
  /// Whether the discretisation uses the interface scaling s^h at all (set_scaling): false for one whose
  /// velocity is divergence-free pointwise.
  virtual bool uses_interface_scaling() const { return true; }

  // --- Output and checkpoints ---
  /// Writes the fields at the current time, sampled at samples_per_element + 1 points per element and
  /// direction (ends shared), as DIR/STEM.vts (on several ranks a piece per rank, STEM_pRRRR.vts, and the
  /// index STEM.pvts) and returns the name a .pvd lists (fluid/fluid_output.hpp keeps the series): velocity,
  /// pressure [dyn/cm^2], vorticity, divergence, the discretisation's own arrays (VMS: s_h, viscosity), and
  /// with `undisturbed` velocity_disturbance = velocity - undisturbed(x). Collective.
  virtual std::string write_fields(const std::string& dir, const std::string& stem, int samples_per_element,
                                   const std::function<Vec3(const Vec3&)>& undisturbed) const = 0;
  /// The state (U, then its rate) as the bytes of a PETSc binary file, independent of the number of ranks,
  /// on rank 0 (empty elsewhere): the caller writes them with checked writes (apps/checkpoint.cpp).
  /// Collective.
  virtual std::string state_bytes() const = 0;
  /// What load_state found.
  enum class LoadedState { ok, does_not_fit, not_finite };
  /// Reads such a file from a PETSc binary viewer and makes it the state after `steps` steps (a restart);
  /// unless `ok`, the state is unchanged. Collective.
  virtual LoadedState load_state(PetscViewer viewer, int steps) = 0;
};

/// The fluid of a run: options.space "equal_order", the VMS discretisation (fluid/fluid_solver.hpp), or
/// "div_conforming" (fluid/dc_immersed_fluid.hpp). `patch` must outlive it. Collective.
std::unique_ptr<ImmersedFluid> create_fluid(MPI_Comm comm, const geometry::Patch& patch,
                                            const FluidOptions& options);

}  // namespace cellfsi::fluid
