#pragma once
// Incompressible Navier-Stokes on the divergence-conforming B-spline space (dc_space.hpp), Galerkin, without
// stabilisation: the Evans-Hughes discretisation on an axis-aligned box, alone (no immersed cells yet; issue
// 44, part 1).
//
// What it solves (kinematic pressure, nu = mu / rho, g = f / rho; CGS as fluid/fluid_solver.hpp):
//   dv/dt + c (v.grad)v - div(2 nu eps(v)) + grad p = g,   div v = 0,
// c = 0 in Stokes mode. The weak form is in dc_kernel.hpp. Boundaries: a periodic direction is periodic; both
// ends of every other direction are walls moving tangentially with a prescribed velocity. On a wall the
// normal velocity is imposed strongly (its unknowns are the coefficients of the one velocity function nonzero
// there) and the tangential velocity weakly, by symmetric Nitsche with penalty
//   beta = C_pen nu (k + 1)^2 / h,   C_pen = 4 by default (-fluid_dc_penalty),
// h the element size normal to the wall. Why 4: on a wall w.n = 0, so eps(w) n . w involves only d_n w_t, of
// degree k - 1 in the normal direction; the polynomial trace inequality ||u||^2_face <= k^2 / h ||u||^2_K for
// degree k - 1 and Young's inequality make the Nitsche form coercive for beta > 2 nu k^2 / h. C_pen (k + 1)^2
// with C_pen = 4 is more than twice that bound for every k, and any larger value keeps the optimal rates.
//
// The pressure is defined up to a constant: one pressure unknown is held fixed during each solve (a unit row)
// and afterwards the pressure is shifted to zero mean over the box.
//
// Time: generalized-alpha for first-order systems as common/generalized_alpha.hpp and FluidSolver: unknown
// U_{n+1} = (v, p)_{n+1}; momentum at v_{n+alpha_f} and vdot_{n+alpha_m}, pressure at t_{n+1}; continuity
// div v_{n+alpha_f} = 0. Since div is exact in this space and the initial velocity is divergence-free
// (project_initial_state), every v_n and vdot_n is divergence-free to the linear solver's round-off.
// Nonlinear solver: Newton with the exact tangent; linear solver: PETSc KSP with prefix "fluid_" (default:
// preonly with MUMPS LU, relative pivot threshold 0.5), set from options last.
//
// Viscosity: uniform (options().viscosity) or a field nu^h on the pressure space (set_viscosity,
// project_viscosity), used at each point by the viscous and the Nitsche terms, the penalty included.
//
// Parallelism: the elements are split into contiguous ranges of their lexicographic index, one per rank; the
// unknowns are numbered by the lowest rank whose elements touch them, rank by rank, and that numbering is cut
// into equal runs of rows (PETSc's MPIAIJ rows). Each rank assembles its elements (entries for other ranks'
// rows travel through PETSc's stash) and MUMPS solves in parallel. The state (U, its rate) is replicated on
// every rank: after each linear solve the update is gathered to all (VecScatterCreateToAll). Simple and exact
// (1 and 2 ranks agree to 7e-15, tested), but O(unknowns) memory and communication per rank: a partition of
// the element grid with ghost width k + 1 (the velocity's stencil half-width) is the next step for large
// runs.
#include <petscksp.h>

#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/generalized_alpha.hpp"
#include "fluid/div_conforming/dc_space.hpp"
#include "fluid/immersed_point.hpp"
#include "geometry/inversion.hpp"

namespace cellfsi::fluid::dc {

/// Physical and numerical settings; the defaults are the paper's plasma (CGS), as fluid::FluidOptions.
struct DcFluidOptions {
  double density = 1.025;          // rho [g/cm^3]
  double viscosity = 0.012;        // mu [g/(cm s)]
  Vec3 body_force = Vec3::Zero();  // f [dyn/cm^3], uniform
  /// An additional body force per unit volume f(x, t) [dyn/cm^3] (manufactured solutions); none if empty.
  std::function<Vec3(const Vec3&, double)> body_force_field;
  bool stokes = false;   // drop convection
  double rho_inf = 0.5;  // generalized-alpha spectral radius at infinity
  double dt = 5e-4;      // time step [s]
  double penalty = 4.0;  // C_pen of the Nitsche penalty C_pen nu (k + 1)^2 / h
  /// Velocity of the wall at side s (0: x_d = lo, 1: x_d = hi) of non-periodic direction d; its normal
  /// component must be 0.
  std::array<std::array<Vec3, 2>, 3> wall_velocity{
      {{Vec3::Zero(), Vec3::Zero()}, {Vec3::Zero(), Vec3::Zero()}, {Vec3::Zero(), Vec3::Zero()}}};
  /// A wall velocity that varies along the walls, v_w(x, t) (its tangential part is imposed; the normal part
  /// must vanish); replaces wall_velocity if set.
  std::function<Vec3(const Vec3&, double)> wall_velocity_field;
  int newton_max_it = 20;
  double newton_rtol = 1e-12;  // on the residual's 2-norm, relative to the first
  /// On the update's max-norm, relative to the solution's: Newton's error after such an update is of its
  /// square, below round-off.
  double newton_stol = 1e-10;
  /// Reads -fluid_density, -fluid_viscosity, -fluid_stokes, -fluid_rho_inf, -fluid_dt, -fluid_dc_penalty.
  void set_from_options();
  /// Throws std::invalid_argument naming the value and its range.
  void validate() const;
};

/// What a solve (one time step or a steady solve) cost.
struct DcSolveStats {
  int newton_iterations = 0;
  bool converged = false;
  double residual_norm = 0;  // last residual's 2-norm
};

class DivConformingFluid {
 public:
  /// Collective on comm.
  DivConformingFluid(MPI_Comm comm, const DivConformingSpace& space, const DcFluidOptions& options);
  ~DivConformingFluid();
  DivConformingFluid(const DivConformingFluid&) = delete;
  DivConformingFluid& operator=(const DivConformingFluid&) = delete;

  /// Divergence-free L2 projections of v0 and vdot0 (v0 . n and vdot0 . n must vanish on the walls): each
  /// is the velocity of the saddle-point problem (v, w) - (p, div w) = (v0, w), (q, div v) = 0, so it is
  /// pointwise divergence-free and of optimal order for divergence-free data. Pressure 0.
  /// Fields uniform along the periodic directions with no component along the others (rest, a shear or a
  /// channel profile) are projected by project_columnar, any other by project_saddle_point.
  void project_initial_state(const std::function<Vec3(const Vec3&)>& v0,
                             const std::function<Vec3(const Vec3&)>& vdot0);
  /// The saddle-point projection above of f (coefficients; pressure 0): one Newton solve, so one MUMPS
  /// factorisation. Collective.
  std::vector<double> project_saddle_point(const std::function<Vec3(const Vec3&)>& f);
  /// The same projection for an f uniform along the periodic directions, with no component along the others
  /// (checked at every Gauss point to round-off of f's largest value): then it is the L2 projection of the
  /// profile onto the non-periodic directions' functions (the x-mean of a discretely divergence-free field is
  /// one, and f is orthogonal to the rest), found from one column of elements by a sparse Cholesky of its
  /// mass matrix (the size of one profile). Writes X and returns true, or returns false for any other f.
  /// Every rank computes it whole (no communication).
  bool project_columnar(const std::function<Vec3(const Vec3&)>& f, std::vector<double>& X) const;
  /// Sets the unknowns directly (velocity then pressure, dc_space.hpp's numbering); velocity rate 0.
  void set_state(const std::vector<double>& u);

  /// Restores a state saved from state() and state_rate() after `steps` steps (a restart); time = steps dt.
  void restore(const std::vector<double>& u, const std::vector<double>& udot, int steps);

  /// The tangent at the current state, of a time step (time_step: the state as the first iterate of the next
  /// step) or of the steady problem, with unit rows for the walls' normal velocities and, if pin_pressure,
  /// the pressure pin; in the PETSc numbering (on one rank the natural one of dc_space.hpp). The matrix
  /// belongs to the solver and changes with the next solve. For the tests of a solver of this operator
  /// (dc_fourier.hpp). Collective.
  Mat jacobian(bool time_step, bool pin_pressure);

  /// The steady problem (no time derivative) at the current time, from the current state as first guess.
  /// Throws std::invalid_argument on a box without walls (its steady problem is singular).
  DcSolveStats solve_steady();
  /// One generalized-alpha step. The state advances only if Newton converged.
  DcSolveStats step();
  double time() const { return time_; }
  int steps_taken() const { return steps_; }

  const std::vector<double>& state() const { return U_; }          // velocity then pressure
  const std::vector<double>& state_rate() const { return Udot_; }  // velocity rate (pressure entries 0)
  const DivConformingSpace& space() const { return space_; }
  const DcFluidOptions& options() const { return opt_; }
  KSP ksp() const { return ksp_; }
  MPI_Comm comm() const { return comm_; }
  /// The PETSc numbering (rows of jacobian(), the linear solver's vectors) of each natural unknown.
  const std::vector<PetscInt>& petsc_numbering() const { return petsc_index_; }
  /// The elements this rank assembles: linear indices [begin, end) (DivConformingSpace::element_multi_index).
  std::array<int, 2> owned_elements() const { return {elem_begin_, elem_end_}; }

  /// Errors against an exact solution over the box (n_gauss = k + 4 per direction): velocity L2, velocity
  /// H1 seminorm, pressure L2 after both pressures are shifted to zero mean; and the exact norms.
  struct Errors {
    double v_l2 = 0, v_h1 = 0, p_l2 = 0;
    double v_l2_norm = 0, v_h1_norm = 0, p_l2_norm = 0;
  };
  Errors errors(const std::function<Vec3(const Vec3&)>& v,
                const std::function<geometry::Mat3(const Vec3&)>& grad_v,
                const std::function<double(const Vec3&)>& p) const;
  /// max |div v_h| / max |grad v_h| (Frobenius) over the Gauss points of every element (0 for v_h = 0).
  double divergence_ratio() const;
  /// max |v_h| over the same points.
  double max_velocity() const;
  // --- A viscosity that varies in space (as FluidSolver's; docs/fluid.md, "The viscosity field") ---
  /// Sets the viscosity field by control value of the pressure space (degree k): mu[A] is the dynamic
  /// viscosity [g/(cm s)] of pressure function A, so that nu^h = sum_A (mu_A / rho) q_A. The viscous term and
  /// the Nitsche terms (their penalty included) then use nu^h at each point; the weak form needs no grad nu
  /// (Galerkin).
  void set_viscosity(const std::vector<double>& mu);
  /// The L2 projection of mu(x) [g/(cm s)] onto the pressure space, as the field (order k + 1 for a smooth
  /// mu).
  void project_viscosity(const std::function<double(const Vec3&)>& mu);
  void clear_viscosity() { nu_field_.clear(); }
  bool has_viscosity_field() const { return !nu_field_.empty(); }
  /// The field's kinematic viscosity nu_A per pressure function (empty without a field).
  const std::vector<double>& viscosity_field() const { return nu_field_; }

  /// Velocity, its gradient (grad_v(i, j) = d v_i / d x_j) and the pressure at points anywhere in the box
  /// (periodic coordinates wrapped; on a mapped space, found by NURBS inversion, geometry::PointInverter;
  /// a point outside the domain throws std::invalid_argument). Local: the state is on every rank.
  struct Sample {
    Vec3 v = Vec3::Zero();
    geometry::Mat3 grad_v = geometry::Mat3::Zero();
    double p = 0;
  };
  std::vector<Sample> sample(const std::vector<Vec3>& points) const;
  /// Writes the fields as a VTK structured grid (.vts) sampled at samples_per_element + 1 points per element
  /// and direction (element ends shared; on a mapped space uniform in the parameters and mapped): arrays
  /// velocity, pressure, divergence. Rank 0 writes; collective.
  void write_vtk(const std::string& path, int samples_per_element = 2) const;

  // --- Immersed solids and a step driven from outside (the coupling loop of paper Sec. 2.3) ---
  /// One immersed solid point in element `element` (linear index, DivConformingSpace::element_multi_index)
  /// at x: the physical point on a box, the parametric one on a mapped space (DivConformingSpace::mapped).
  struct ImmersedAt {
    int element = 0;
    Vec3 x = Vec3::Zero();
    ImmersedPoint data;
  };
  /// The immersed points this rank assembles, in any elements (their rows travel to their owners through
  /// PETSc's stashes; the coupler deals the points out evenly: ImmersedFluid::assembles_points_anywhere).
  /// Their terms (dc_kernel.hpp, dc_immersed_residual) enter every residual and tangent of a step until
  /// replaced.
  void set_immersed_points(const std::vector<ImmersedAt>& points);
  std::size_t n_immersed_points() const { return immersed_.size(); }
  /// Starts a step driven from outside: keeps (U_n, Udot_n); the iterate's first value is state().
  void begin_step();
  /// The residual of the step's iterate U (natural numbering, on every rank) into F (PETSc numbering), the
  /// fixed rows (walls' normal velocities, the pressure pin) zero. Collective.
  /// pin_pressure false: the pin's row keeps its continuity residual (a solver that handles the constant
  /// pressure itself, as the coupled solve with the bulk inverse).
  /// part: U holds the iterate only at that part's unknowns (gather_part), and only those are read.
  void step_residual(const std::vector<double>& U, Vec F, bool pin_pressure = true,
                     std::optional<int> part = std::nullopt);
  /// Its exact tangent into J (a matrix like jacobian()'s), the fixed rows unit rows. with_immersed false:
  /// the bulk operator (no immersed points, the uniform viscosity). Collective.
  /// pin_pressure false: the pressure pin's row is left as assembled (a translation-invariant operator for
  /// DcFourierSolver::build).
  void step_tangent(const std::vector<double>& U, Mat J, bool with_immersed = true, bool pin_pressure = true);
  /// step_tangent(U, J, false, false) with U and the step's start state (its velocity and rate) averaged
  /// along the periodic directions (DivConformingSpace::average_periodic): the bulk operator of the mean
  /// flow, translation-invariant whatever the cells did to the flow (DcFourierSolver::build). Collective.
  void bulk_tangent_of_mean(const std::vector<double>& U, Mat J);
  /// J := bulk (a matrix of matrix()'s pattern holding step_tangent(..., with_immersed = false)) plus the
  /// immersed points' tangent at U, the fixed rows unit rows: the tangent with its bulk part kept from
  /// another state (the coupling loop's Jacobian: the bulk changes with the flow only through terms of the
  /// order of the Reynolds number). Collective.
  void step_tangent_from(Mat bulk, const std::vector<double>& U, Mat J, bool pin_pressure = true);
  /// The immersed points' tangent over the unknowns it touches alone (S: the velocity unknowns of the
  /// elements with points on any rank), its rows S in PETSc order dealt out in equal runs to the ranks: the
  /// points' matrix divides by the ranks however few ranks' rows the cells lie in (in the fluid's own rows it
  /// did not).
  struct ImmersedMatrix {
    Mat C = nullptr;                   // |S| x |S|, AIJ, rows and columns in S's order
    std::vector<PetscInt> row_of;      // natural unknown -> its row of C, -1 outside S
    std::vector<PetscInt> fluid_rows;  // this rank's rows of C, as rows of the fluid's PETSc vectors
    VecScatter to_s = nullptr;         // the fluid's vectors at S's rows (forward), added back (reverse)
    Vec in = nullptr, out = nullptr;   // C's vectors
    /// y += C x lifted to the fluid's rows (x, y: the fluid's vectors). Collective.
    void multiply_add(Vec x, Vec y) const;
    void destroy();
  };
  /// The immersed points' part of the step's tangent at U alone into C.C (ADD_VALUES, then assembled; the
  /// fixed rows zero): step_tangent_from(bulk, U, J, false) is bulk + C lifted to the fluid's rows.
  /// Collective.
  /// part: as step_residual's (kAssemblyPart covers the points).
  void immersed_tangent(const std::vector<double>& U, const ImmersedMatrix& C,
                        std::optional<int> part = std::nullopt);
  /// The solids' stiffness through their collocation (fluid::SolidLinearization): with `on`, the points'
  /// tangent (immersed_tangent, step_tangent*) leaves out the stiffness of every point with
  /// ImmersedPoint::solid_begin >= 0, which solid_blocks() then gives.
  void set_solid_stiffness_apart(bool on) { solid_apart_ = on; }
  /// Per element with such points, its momentum rows' derivative with respect to the solids' control
  /// increments: sum over the points of w d_j N_A,i (c_ijkl + delta_jk tau_il + delta_ik tau_lj) dN_r/dx_l
  /// (`column` and `grad`: SolidLinearization's tables). rows: PETSc numbering, -1 for a fixed row
  /// (VecSetValues skips it); values rows x cols, row-major.
  struct SolidBlock {
    std::vector<PetscInt> rows;
    std::vector<int> cols;
    std::vector<double> values;
  };
  /// Not on a mapped space (std::logic_error): there the points carry their consistent tangent.
  std::vector<SolidBlock> solid_blocks(const std::vector<int>& column, const std::vector<double>& grad) const;
  /// d v(t_{n+alpha_f}) / d U of a step's iterate (alpha_f).
  double velocity_alpha() const { return alpha_.alpha_f; }
  /// The elements that hold this rank's immersed points, sorted.
  std::vector<int> immersed_elements() const;
  /// A matrix preallocated for immersed_tangent: each owned row's distinct columns over the elements with
  /// points on every rank (their velocity blocks: the points' terms have no pressure), counted exactly (a
  /// MATPREALLOCATOR filled with the blocks took 1.2-1.5 s of each refresh at 32^3; with this count the whole
  /// refresh takes 1.0 s). The caller calls destroy(). Collective.
  ImmersedMatrix create_immersed_matrix() const;
  /// Accepts U as U_{n+1}: the rate, the time, the pressure's zero mean, divergence_history().
  void end_step(const std::vector<double>& U);
  /// v and grad v at t_{n+alpha_f} and the acceleration at t_{n+alpha_m} of the step's iterate U at points
  /// (element, x) (x as ImmersedAt's; local: U is on every rank).
  struct StepSample {
    Vec3 v = Vec3::Zero(), a = Vec3::Zero();
    geometry::Mat3 grad_v = geometry::Mat3::Zero();
  };
  /// part: as step_residual's (the part gathered with these elements).
  std::vector<StepSample> sample_step(const std::vector<double>& U, const std::vector<int>& elements,
                                      const std::vector<Vec3>& x,
                                      std::optional<int> part = std::nullopt) const;
  /// A global vector in the PETSc numbering (the linear solver's), and the moves between it and the
  /// natural numbering on every rank. Collective.
  Vec create_vector() const;
  void gather(Vec X, std::vector<double>& U) const;
  void scatter(const std::vector<double>& U, Vec X) const;
  /// The parts of an iterate a rank reads in a coupling iteration: kAssemblyPart, the unknowns of its own
  /// elements and of the elements given (those of its immersed points: step_residual, immersed_tangent);
  /// kSamplePart, those of the elements given alone (the points it samples: sample_step).
  static constexpr int kAssemblyPart = 0, kSamplePart = 1;
  /// U (natural numbering, resized to every unknown) at the part's unknowns only, the other entries left as
  /// they were: where gather() moves every unknown to every rank, this moves a rank's share, so that its cost
  /// divides by the ranks. One VecScatter is kept per part, made again when the elements change on any rank
  /// (elements: linear indices, sorted, unique). move false: U already holds them (a whole gather); only the
  /// part is set for part_levels. Collective.
  void gather_part(Vec X, std::vector<double>& U, int part, const std::vector<int>& elements,
                   bool move = true) const;
  /// The matrix the tangents are assembled into (jacobian(), step_tangent), and the fluid's own solver's;
  /// made at the first call (its pattern: every element's unknowns, about 600 entries a row in 3D at k' = 2,
  /// 84 M at 32^3), so a coupled run that never needs it (-coupling_bulk_stencil) never holds it.
  /// Collective at that first call.
  Mat matrix();
  /// Frees matrix() and the linear solver's factors; the next matrix(), jacobian(), step() or solve makes it
  /// again. Collective.
  void release_matrix();
  bool matrix_made() const { return J_ != nullptr; }
  /// bulk_tangent_of_mean(U) in a matrix like matrix() that holds only the rows DcFourierSolver::build reads
  /// and checks: the unknowns at x (and in 3D z) index 0, its stencil, and at two more positions, (n_x/2,
  /// n_z/2) and (n_x/3, 2 n_z/3), for its check (deviation()); the other rows are empty. Assembled from the
  /// elements that touch those rows alone. At 64^3 the whole matrix holds 676 M entries (8 GB); this one
  /// about three planes' worth. The caller destroys it. Collective.
  Mat bulk_stencil_tangent(const std::vector<double>& U);
  /// divergence_history() after each step() (the "at every step").
  const std::vector<double>& divergence_history() const { return div_history_; }

 private:
  /// A part of the assembly: the elements marked in `elements` (linear index) into the rows marked in
  /// `rows` (natural index); the other rows get nothing.
  struct RowSubset {
    std::vector<char> rows, elements;
  };
  /// The fields and their derivatives with respect to the unknowns that assemble() needs.
  struct Levels {
    std::vector<double> v;  // coefficients of the velocity at which momentum is evaluated (pressure: U's)
    std::vector<double> a;  // coefficients of the acceleration
    double dv_dU = 1, da_dU = 0;
    double nu = 0, convection = 0, t = 0;
    bool nitsche = true;
    bool viscosity_field = true;  // use nu^h where there is a field (false: lv.nu, as a projection's 0)
    std::function<Vec3(const Vec3&)> g;  // body force per unit mass (or the data of a projection)
  };
  Levels steady_levels(const std::vector<double>& U) const;
  /// Adds the interior terms of the residual of every owned element to F (no assembly calls): the generic
  /// assembly's sums for J = null, in less time.
  void interior_residual(const Levels& lv, Vec F) const;
  template <int D, int NV, int NP>
  void interior_residual_sized(const Levels& lv, Vec F) const;
  /// interior_residual for a uniform body force, by sum factorisation over blocks of elements of one basis
  /// class.
  void interior_residual_batched(const Levels& lv, Vec F) const;
  /// Adds the immersed points' terms to F and J (no assembly calls).
  /// (rows: J's row of each natural unknown, petsc_index_ if null)
  void assemble_immersed(const Levels& lv, Vec F, Mat J, const std::vector<PetscInt>* rows = nullptr) const;
  /// assemble_immersed's residual (J null), by sum factorisation at each point.
  void immersed_residual(const Levels& lv, Vec F) const;
  /// A generalized-alpha step from (Un, Udotn) with iterate U.
  Levels step_levels(const std::vector<double>& U, const std::vector<double>& Un,
                     const std::vector<double>& Udotn) const;
  /// step_levels of the current step's iterate U (from U_n within a step, from the state before one).
  Levels iterate_levels(const std::vector<double>& U) const;
  /// iterate_levels at a part's unknowns alone (gather_part), in that part's kept storage: the other entries
  /// are stale, and the reference holds until the part's next call.
  const Levels& part_levels(const std::vector<double>& U, int part) const;
  /// Levels' scalars (dv_dU, da_dU, nu, convection, t, g) of a generalized-alpha step.
  void set_step_scalars(Levels& lv) const;
  /// Zeroes this rank's fixed rows of J with `diagonal` on them (the pressure pin's row too if pin_pressure).
  /// Collective.
  void zero_fixed_rows(Mat J, bool pin_pressure, double diagonal, const RowSubset* subset = nullptr) const;
  std::function<Vec3(const Vec3&)> body_force_per_mass(double t) const;
  /// Residual F and, if J is not null, the tangent (PETSc numbering), both without the fixed rows; with a
  /// subset only its elements' tangent into its rows (F is then only zeroed).
  /// Collective.
  void assemble(const Levels& lv, Vec F, Mat J, bool with_immersed = true,
                const RowSubset* subset = nullptr) const;
  /// Newton on R(U) = 0 with levels(U) describing the fields; fixed rows (wall normals, the pressure pin)
  /// keep U's values.
  DcSolveStats newton(std::vector<double>& U,
                      const std::function<Levels(const std::vector<double>&)>& levels);
  /// A matrix with the pattern of the rows marked in `wanted` (natural index; null: every row), each row the
  /// unknowns of the elements in its support; `touching` (if given) marks those elements. Collective.
  Mat create_matrix(const std::vector<char>* wanted, std::vector<char>* touching = nullptr) const;
  /// The basis of element e (linear index, one of this rank's) at its n_gauss()^dim Gauss points. The space's
  /// knots are uniform, so elements at the same distance from the walls (all, along a periodic direction)
  /// share values and derivatives: one evaluation per such class, cached; the element's unknowns and points
  /// are set in the returned object, which the next call overwrites.
  const ElementBasis& element_basis(int e) const;
  /// The class of element e whose basis element_basis caches (elements of a class share their values).
  int basis_class(int e) const;
  /// The coefficients src[unknown - shift] of the local unknowns [local_first, local_first + n) of the m elements
  /// members[0 .. m) (this rank's), into out[b * m + e] (the sum-factorised kernels' layout).
  void gather_block(const int* members, int m, int local_first, int n, const double* src, int shift,
                    std::vector<double>& out) const;
  /// The local unknowns of element e (natural numbering, add_point_residual's order): this rank's kept list
  /// for its own elements, else computed into scratch.
  const int* unknowns_of(int e, std::vector<int>& scratch) const;
  /// This rank's elements grouped by basis_class (made at the first call).
  const std::vector<std::vector<int>>& elements_by_class() const;
  /// Calls f(eb) for each of this rank's elements with its basis at the element's Gauss points.
  template <class F>
  void for_owned_elements(int n_gauss, F&& f) const;
  void shift_pressure_to_zero_mean(std::vector<double>& U) const;
  /// The wall velocity at x with its part along the unit normal n removed.
  Vec3 wall_velocity(int d, int side, const Vec3& x, double t, const std::array<double, 3>& n) const;
  int n_gauss() const { return space_.degree() + 2; }  // exact for the mass matrix (degree 2k + 2)

  MPI_Comm comm_;
  const DivConformingSpace& space_;
  DcFluidOptions opt_;
  int elem_begin_ = 0, elem_end_ = 0;
  std::vector<PetscInt> petsc_index_;     // natural (dc_space.hpp) -> PETSc numbering
  PetscInt row_begin_ = 0, row_end_ = 0;  // this rank's rows in PETSc numbering
  std::vector<int> owned_natural_;        // this rank's rows, in order: their natural unknowns
  std::vector<PetscInt> owned_fixed_;     // this rank's fixed rows, PETSc numbering
  std::vector<int> owned_fixed_natural_;  // and their natural indices
  GeneralizedAlpha alpha_;
  std::vector<double> U_, Udot_;
  std::vector<int> fixed_rows_;        // wall normal velocities and the pressure pin (natural numbering)
  std::vector<double> pressure_mass_;  // int q_A over the box
  std::vector<double> div_history_;
  std::vector<double> nu_field_;      // kinematic viscosity per pressure function; empty: uniform
  std::vector<ImmersedAt> immersed_;  // this rank's, sorted by element
  std::vector<int> point_order_;      // set_immersed_points' permutation (kept storage)
  bool solid_apart_ = false;          // set_solid_stiffness_apart
  struct CachedBasis {
    Index3 element;  // the element it was evaluated on
    ElementBasis basis;
  };
  mutable std::vector<std::unique_ptr<CachedBasis>> basis_cache_;  // by class (element_basis)
  mutable std::vector<std::vector<int>> class_elements_;  // this rank's elements by class (basis_class)
  mutable std::unique_ptr<geometry::PointInverter>
      inverter_;                       // sample() on a mapped space (made at its first)
  std::vector<int> element_unknowns_;  // natural unknowns of each owned element, n_local_ per element
  int n_local_ = 0;
  std::vector<double> Un_, Udotn_;  // the state at t_n of a step driven from outside
  double time_ = 0;
  int steps_ = 0;
  Mat J_ = nullptr;
  KSP ksp_ = nullptr;
  Vec F_ = nullptr, x_ = nullptr, x_all_ = nullptr;  // residual, update, update on every rank
  VecScatter to_all_ = nullptr;
  /// Unknowns (natural, sorted, unique) moved from a PETSc vector by one scatter into `values`.
  struct UnknownSet {
    std::vector<int> unknowns;
    VecScatter scatter = nullptr;
    Vec values = nullptr;
    void make(Vec X, const std::vector<PetscInt>& petsc_index);  // (collective)
    void move(Vec X, std::vector<double>& U) const;              // (collective)
    void destroy();
  };
  /// gather_part's state: the unknowns of this rank's own elements (made once), and per part those of its
  /// elements (made again when they change) and part_levels' storage.
  mutable UnknownSet own_unknowns_;
  /// Other ranks' elements' unknowns (unknowns_of), kept: the points' elements change at every iteration.
  mutable std::unordered_map<int, std::vector<int>> foreign_unknowns_;
  struct GatherPart {
    std::vector<int> elements;  // those the part's set covers (a superset of the last call's)
    UnknownSet of_elements;
    Levels levels;
  };
  mutable std::array<GatherPart, 2> parts_;
};

}  // namespace cellfsi::fluid::dc
