#pragma once
// Incompressible Navier-Stokes (VMS, paper Sec. 2.1-2.3) on one Eulerian NURBS patch, with PETSc: the
// discretisation behind fluid::ImmersedFluid (immersed_fluid.hpp) that fluid::create_fluid makes. Only fluid/,
// its tests and benchmarks include this header; coupling/ and apps/ see the interface.
//
// The control net is partitioned with a DMDA (dof = dim + 1: velocity, kinematic pressure; periodic
// directions handled natively; stencil width = degree, exact for tensor-product splines). An element belongs
// to the rank that owns the first control point of its support, so every element's control points lie in that
// rank's ghosted region. Time: generalized-alpha for first-order systems (Jansen, Whiting & Hulbert 2000),
// unknown U_{n+1}; velocity at t_{n+alpha_f}, its rate at t_{n+alpha_m}, pressure at t_{n+1}. Nonlinear
// solver: PETSc SNES (Newton with line search) with options prefix "fluid_", linear solver KSP (GMRES,
// restricted additive Schwarz with LU subdomain solves and nested-dissection ordering by default, as in the
// paper).
//
// Boundaries: a periodic direction is periodic; both ends of every other direction are no-slip walls moving
// with a prescribed uniform velocity (the open knot vectors interpolate there, so wall control values are the
// wall velocity). With no traction boundary the pressure is defined up to a constant: the linear solvers are
// given the constant pressure as the Jacobian's null space (MatNullSpace; MUMPS detects the null pivot) and
// after each step the pressure is shifted so that the first control value is 0. -fluid_pressure_null_space
// false pins that value instead (a Dirichlet row), the same answer: velocity to 5e-13, pressure to 1e-10
// relative after the constant, scene metrics to the coupling tolerance (docs/fluid.md).
#include <petscdmda.h>
#include <petscsnes.h>

#include <array>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/generalized_alpha.hpp"
#include "fluid/element_basis.hpp"
#include "fluid/immersed_fluid.hpp"
#include "fluid/linear_solve_failure.hpp"
#include "fluid/vms_kernel.hpp"
#include "geometry/inversion.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::fluid {

using geometry::Vec3;

/// An immersed-solid quadrature point (paper Eq. (10)): position and the kernel's data.
struct ImmersedPointData {
  Vec3 x = Vec3::Zero();
  ImmersedPoint data;
};

class FluidSolver;
/// SNES callbacks (the solver passes itself as context).
PetscErrorCode fluid_residual(SNES, Vec U, Vec F, void* solver);
PetscErrorCode fluid_jacobian(SNES, Vec U, Mat J, Mat P, void* solver);

/// The VMS discretisation (paper Sec. 2.1-2.3) behind fluid::ImmersedFluid; the methods marked `override`
/// are documented there.
class FluidSolver final : public ImmersedFluid {
 public:
  FluidSolver(MPI_Comm comm, const geometry::Patch& patch, const FluidOptions& options);
  ~FluidSolver() override;
  FluidSolver(const FluidSolver&) = delete;
  FluidSolver& operator=(const FluidSolver&) = delete;

  /// Sets the velocity control values from a function of position (exact for fields in the spline space whose
  /// control values are their Greville-point values, e.g. linear fields on affine meshes); pressure 0;
  /// velocity rate 0. Wall control values take the wall velocity.
  void set_initial_velocity(const std::function<Vec3(const Vec3&)>& v0) override;
  void project_initial_velocity(const std::function<Vec3(const Vec3&)>& v0) override {
    project_initial_state(v0, [](const Vec3&) { return Vec3(Vec3::Zero()); });
  }
  /// Sets velocity and velocity rate to the L2 projections of v0 and vdot0 (optimal-order initial data; a
  /// rate consistent with the flow keeps generalized-alpha second order from the first step); pressure 0.
  /// Wall control values then take the wall velocity. Collective; solves mass-matrix systems with CG (prefix
  /// fluid_projection_).
  void project_initial_state(const std::function<Vec3(const Vec3&)>& v0,
                             const std::function<Vec3(const Vec3&)>& vdot0);

  /// L2 norms over the domain of v_h - v_exact and of v_exact at the current time (collective).
  struct L2Error {
    double error = 0, norm = 0;
  };
  L2Error velocity_l2_error(const std::function<Vec3(const Vec3&)>& v_exact) const;

  /// Sets the scaling field s^h by control value (natural node index -> s); applies to owned nodes. s^h
  /// multiplies tau_M and tau_C at each quadrature point (vms_kernel.hpp).
  void set_scaling(const std::function<double(int node)>& s) override;
  /// Immersed points, all of them on every rank (each rank keeps those in its elements).
  void set_immersed_points(const std::vector<ImmersedPointData>& points);
  bool owns_element(const geometry::Index3& e) const override;

  // --- A viscosity that varies in space (docs/fluid.md, "The viscosity field") ---
  /// Sets the viscosity field by control value: the dynamic viscosity mu_A [g/(cm s)] of each natural node
  /// index (applies to owned nodes), so that nu^h = sum_A (mu_A / rho_1) N_A. Each quadrature point then
  /// uses its own nu^h in the viscous term, tau_M and the immersed terms, and grad nu^h in r_M
  /// (vms_kernel.hpp). Elements whose control values are all equal are assembled as with a uniform viscosity
  /// of that value (the element kernels' fast paths, bit for bit); without a field every result is
  /// options().viscosity's.
  void set_viscosity(const std::function<double(int node)>& mu) override;
  /// The L2 projection of a viscosity mu(x) [g/(cm s)] onto the fluid's spline space, as the field (an
  /// optimal-order nu^h for a smooth mu; collective, CG with prefix fluid_projection_).
  void project_viscosity(const std::function<double(const Vec3&)>& mu);
  /// Back to the uniform options().viscosity.
  void clear_viscosity();
  bool has_viscosity_field() const { return Nu_ != nullptr; }
  /// The field's kinematic viscosity nu_A (a vector of the one-dof DMDA, like scaling()); null without one.
  Vec viscosity_field() const { return Nu_; }
  /// The field's kinematic viscosity nu_A by natural node index on rank 0 (empty elsewhere, and everywhere
  /// without a field).
  std::vector<double> viscosity_on_zero() const;

  void setup() override;
  /// Frees what setup() built in the fluid's own linear solver (e.g. ASM's subdomain copy of the Jacobian),
  /// for a coupled run that solves with another solver; a later solve sets it up again.
  void release_linear_solver();
  /// Advances one time step (SNES with prefix fluid_).
  StepStats step() override;
  double time() const override { return time_; }
  int steps_taken() const override { return steps_; }

  std::vector<PointSample> sample(const std::vector<Vec3>& points) const override;
  SectionData section(double u, int n_profile = 33) const override;

  // --- Driving the Newton iteration from outside: the coupling layer's block-iterative loop (paper Sec. 2.3)
  // ---
  void begin_step(Vec X) override;
  void residual(Vec X, Vec F) override { assemble(X, F, nullptr); }
  void jacobian(Vec X, Mat J) override { assemble(X, nullptr, J); }
  void jacobian_part(Vec X, Mat J, const std::vector<char>& in_region, bool region_side) override {
    assemble(X, nullptr, J, &in_region, region_side);
  }
  void jacobian_add_part(Vec X, Mat J, const std::vector<char>& in_region) override {
    assemble(X, nullptr, J, &in_region, true, true);
  }
  /// (Where a viscosity field differs from options().viscosity, the Fourier solver's region takes those
  /// nodes in.)
  void bulk_jacobian(Vec X, Mat J) override;
  std::vector<PointSample> sample_alpha(Vec X, const std::vector<geometry::Index3>& elements,
                                        const std::vector<geometry::Param>& xi) const override;
  void set_immersed_points(const std::vector<geometry::Index3>& elements,
                           const std::vector<geometry::Param>& xi,
                           const std::vector<ImmersedPoint>& data) override;
  void end_step(Vec X) override;
  /// The unknowns of the control points on the region's elements, all dim + 1 of each.
  std::vector<PetscInt> region_unknowns(const std::vector<char>& in_region) const override;
  /// Restores the state after `steps` steps (U and its rate, as solution() and solution_rate() held them; a
  /// restart from a checkpoint).
  void restore(Vec U, Vec Udot, int steps);
  /// The Jacobian matrix (KSP prefix fluid_; node blocks with -fluid_mat_type_jacobian baij).
  Mat jacobian_matrix() const override { return J_; }
  void release_jacobian_matrix() override;
  KSP ksp() const;

  // --- Output and checkpoints (fluid_output.cpp, fluid_solver.cpp) ---
  std::string write_fields(const std::string& dir, const std::string& stem, int samples_per_element,
                           const std::function<Vec3(const Vec3&)>& undisturbed) const override;
  std::string state_bytes() const override;
  LoadedState load_state(PetscViewer viewer, int steps) override;

  /// Residual and Jacobian of the current state (for tests): F(U) with U the current unknown at t_{n+1}.
  void evaluate_residual(Vec U, Vec F);
  void evaluate_jacobian(Vec U, Mat J);

  DM dm() const { return da_; }
  Vec solution() const override { return U_; }  // U at the latest time level
  Vec solution_rate() const { return Udot_; }
  SNES snes() const { return snes_; }
  const geometry::Patch& patch() const override { return patch_; }
  const FluidOptions& options() const override { return opt_; }
  int dim() const override { return dim_; }
  MPI_Comm comm() const override { return comm_; }
  /// Node blocks of dim + 1 (velocity, kinematic pressure) on the DMDA of the control net.
  std::optional<BlockLayout> block_layout() const override;
  std::vector<int> unknown_kinds() const override;

  /// The elements whose first support node this rank owns (each element belongs to exactly one rank; per
  /// direction a contiguous range, in lexicographic order, direction 0 fastest): their control points are in
  /// this rank's ghosted region.
  std::vector<geometry::Index3> owned_elements() const;
  /// The scaling field s^h (a vector of a one-dof DMDA compatible with dm()).
  Vec scaling() const { return S_; }

  /// Natural-ordered copy of a DMDA vector on rank 0 (empty elsewhere): node-major, dof-minor.
  std::vector<double> gather_to_zero(Vec global) const;
  /// The scaling field s^h by natural node index on rank 0 (empty elsewhere).
  std::vector<double> scaling_on_zero() const { return gather_to_zero(S_); }

 private:
  friend PetscErrorCode fluid_residual(SNES, Vec, Vec, void*);
  friend PetscErrorCode fluid_jacobian(SNES, Vec, Mat, Mat, void*);

  // Either of F, J may be null. With an element mask, J receives the part of K_MC described in jacobian_part.
  // accumulate: J's entries are added to, not replaced (its Dirichlet rows end as unit rows).
  void assemble(Vec U, Vec F, Mat J, const std::vector<char>* in_region = nullptr, bool region_side = true,
                bool accumulate = false);
  void apply_dirichlet_values(Vec U, double t) const;
  /// Creates J_ (with the pressure's null space) and gives it to the SNES, if it does not exist.
  void create_jacobian_matrix();
  std::vector<PetscInt> dirichlet_rows() const;  // global PETSc indices of owned Dirichlet rows
  /// The L2 projections onto the spline space of `count` scalar functions (f(x, values) fills values[0 ..
  /// count)), as global vectors of the one-dof DMDA (the caller destroys them). Collective.
  std::vector<Vec> l2_project(int count, const std::function<void(const Vec3&, double*)>& f) const;
  /// Shifts the pressure of U by a constant so that the first control value is 0 (with the null space).
  void normalize_pressure(Vec U) const;
  /// What sample and sample_alpha share: at the points this rank's elements hold (elements[i], xi[i];
  /// skipped where located[i] is 0), v, grad v and p from the nodal values value(li, c) and the rate from
  /// rate(li, c) (li: the index in a local vector, c: the component). Not gathered (gather_samples).
  template <class Value, class Rate>
  std::vector<PointSample> sample_local(const std::vector<geometry::Index3>& elements,
                                        const std::vector<geometry::Param>& xi,
                                        const std::vector<char>& located, Value&& value, Rate&& rate) const;
  /// Every rank's samples (each found by the rank that owns its element) on every rank.
  std::vector<PointSample> gather_samples(const std::vector<PointSample>& local) const;

  MPI_Comm comm_;
  const geometry::Patch& patch_;
  FluidOptions opt_;
  int dim_ = 2, dof_ = 3;
  GeneralizedAlpha alpha_;
  DM da_ = nullptr, da_scalar_ = nullptr;
  Vec U_ = nullptr, Udot_ = nullptr;            // at t_n between steps
  Vec Un_loc_ = nullptr, Udotn_loc_ = nullptr;  // ghosted copies of t_n values during a step
  Vec S_ = nullptr, S_loc_ = nullptr;           // scaling field s^h
  Vec Nu_ = nullptr, Nu_loc_ = nullptr;         // kinematic viscosity field nu_A (null: uniform)
  Vec F_ = nullptr;
  Mat J_ = nullptr;
  SNES snes_ = nullptr;
  double time_ = 0;
  int steps_ = 0;
  // ownership (global natural indices of owned nodes, ghosted corners)
  PetscInt xs_[3]{}, xm_[3]{1, 1, 1}, gxs_[3]{}, gxm_[3]{1, 1, 1};
  PetscInt pin_row_ = -1;  // global row of the pinned pressure (owned by this rank) or -1
  geometry::PointInverter inverter_;
  ElementBasis element_basis_;
  // The patch's map if axis-aligned affine (the paper's boxes): physical_point's fast path for the immersed
  // points and the samples.
  std::optional<geometry::AffineMap> affine_;
  const geometry::AffineMap* affine() const { return affine_ ? &*affine_ : nullptr; }
  struct LocatedPoint {
    geometry::Index3 element;
    geometry::Param xi;
    ImmersedPoint data;
  };
  std::vector<LocatedPoint> immersed_;         // sorted by element
  std::vector<LocatedPoint> immersed_sorted_;  // sort_immersed_points' second buffer, kept between calls
  void sort_immersed_points();
};

}  // namespace cellfsi::fluid
