#include "fluid/fluid_solver.hpp"
#include "fluid/state_file.hpp"

#ifdef __GLIBC__
#include <malloc.h>  // malloc_trim
#endif

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "common/petsc_error.hpp"
#include "fluid/point_evaluation.hpp"
#include "geometry/element_region.hpp"

namespace cellfsi::fluid {

using geometry::BasisValues;
using geometry::Index3;
using geometry::MapValues;
using geometry::Mat3;
using geometry::Param;

namespace {

/// Calls f(idx, {i, j, k}) for every control point (DMDA node) this rank owns, the box of corner xs and
/// extents xm (DMDAGetCorners), in the order of the rank's part of a global vector: idx is the node's index
/// there (its unknowns start at idx * dof), {i, j, k} its global multi-index.
template <class F>
void for_each_owned_node(const PetscInt xs[3], const PetscInt xm[3], F&& f) {
  PetscInt idx = 0;
  for (PetscInt k = xs[2]; k < xs[2] + xm[2]; ++k)
    for (PetscInt j = xs[1]; j < xs[1] + xm[1]; ++j)
      for (PetscInt i = xs[0]; i < xs[0] + xm[0]; ++i, ++idx) f(idx, std::array<PetscInt, 3>{i, j, k});
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// Construction

FluidSolver::FluidSolver(MPI_Comm comm, const geometry::Patch& patch, const FluidOptions& options)
    : comm_(comm), patch_(patch), opt_(options), inverter_(patch), element_basis_(patch),
      affine_(geometry::affine_map(patch)) {
  dim_ = patch.param_dim();
  if (dim_ != patch.physical_dim() || dim_ < 2)
    throw std::invalid_argument("FluidSolver: the Eulerian patch must be 2D in 2D or 3D in 3D");
  opt_.validate();
  dof_ = dim_ + 1;
  alpha_ = GeneralizedAlpha::from_rho_inf(opt_.rho_inf, opt_.dt);

  int p = 0;
  DMBoundaryType bt[3] = {DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE};
  PetscInt n[3] = {1, 1, 1};
  for (int d = 0; d < dim_; ++d) {
    p = std::max(p, patch.degree(d));
    n[d] = patch.n_control(d);
    if (patch.knots(d).periodic()) bt[d] = DM_BOUNDARY_PERIODIC;
  }
  if (dim_ == 2) {
    CELLFSI_PETSC(DMDACreate2d(comm, bt[0], bt[1], DMDA_STENCIL_BOX, n[0], n[1], PETSC_DECIDE, PETSC_DECIDE,
                               dof_, p, nullptr, nullptr, &da_));
  } else {
    CELLFSI_PETSC(DMDACreate3d(comm, bt[0], bt[1], bt[2], DMDA_STENCIL_BOX, n[0], n[1], n[2], PETSC_DECIDE,
                               PETSC_DECIDE, PETSC_DECIDE, dof_, p, nullptr, nullptr, nullptr, &da_));
  }
  CELLFSI_PETSC(DMSetUp(da_));
  const char* names[4] = {"velocity_x", "velocity_y", "velocity_z", "pressure"};
  for (int c = 0; c < dim_; ++c) CELLFSI_PETSC(DMDASetFieldName(da_, c, names[c]));
  CELLFSI_PETSC(DMDASetFieldName(da_, dim_, names[3]));
  CELLFSI_PETSC(DMDACreateCompatibleDMDA(da_, 1, &da_scalar_));

  PetscInt xs[3], xm[3], gxs[3], gxm[3];
  CELLFSI_PETSC(DMDAGetCorners(da_, &xs[0], &xs[1], &xs[2], &xm[0], &xm[1], &xm[2]));
  CELLFSI_PETSC(DMDAGetGhostCorners(da_, &gxs[0], &gxs[1], &gxs[2], &gxm[0], &gxm[1], &gxm[2]));
  for (int d = 0; d < 3; ++d) xs_[d] = xs[d], xm_[d] = xm[d], gxs_[d] = gxs[d], gxm_[d] = gxm[d];

  CELLFSI_PETSC(DMCreateGlobalVector(da_, &U_));
  CELLFSI_PETSC(VecDuplicate(U_, &Udot_));
  CELLFSI_PETSC(VecDuplicate(U_, &F_));
  CELLFSI_PETSC(VecSet(U_, 0.0));
  CELLFSI_PETSC(VecSet(Udot_, 0.0));
  CELLFSI_PETSC(DMCreateLocalVector(da_, &Un_loc_));
  CELLFSI_PETSC(VecDuplicate(Un_loc_, &Udotn_loc_));
  CELLFSI_PETSC(DMCreateGlobalVector(da_scalar_, &S_));
  CELLFSI_PETSC(VecSet(S_, 1.0));
  CELLFSI_PETSC(DMCreateLocalVector(da_scalar_, &S_loc_));

  // The pressure of the first control point is pinned (see the header), or the linear solver is given the
  // constant pressure as the Jacobian's null space.
  // Factorisation packages other than MUMPS (PETSc's own LU, the paper's setting) have no null-pivot
  // detection: unless the null space was asked for explicitly, they get the pin (measured: PETSc's LU with
  // the null space broke down in step 12 of the Poiseuille scene).
  PetscBool asked = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-fluid_pressure_null_space", &asked));
  for (const char* name : {"-fluid_sub_pc_factor_mat_solver_type", "-fluid_pc_factor_mat_solver_type"}) {
    char package[64] = "";
    PetscBool set = PETSC_FALSE;
    CELLFSI_PETSC(PetscOptionsGetString(nullptr, nullptr, name, package, sizeof package, &set));
    if (set && std::string(package) != "mumps" && !asked) opt_.pressure_null_space = false;
  }
  if (!opt_.pressure_null_space && xs_[0] == 0 && xs_[1] == 0 && xs_[2] == 0) {
    PetscInt lo = 0;
    CELLFSI_PETSC(VecGetOwnershipRange(U_, &lo, nullptr));
    pin_row_ = lo + dim_;
  }

  CELLFSI_PETSC(SNESCreate(comm, &snes_));
  CELLFSI_PETSC(SNESSetOptionsPrefix(snes_, "fluid_"));
  create_jacobian_matrix();
  // The paper's linear solver, as defaults that the command line overrides: GMRES (rtol 1e-5), restricted
  // additive Schwarz with one subdomain per rank, LU subdomain solves with nested-dissection ordering.
  KSP ksp;
  PC pc;
  CELLFSI_PETSC(SNESGetKSP(snes_, &ksp));
  CELLFSI_PETSC(KSPSetType(ksp, KSPGMRES));
  CELLFSI_PETSC(KSPSetTolerances(ksp, KrylovDefaults::rtol, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT));
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, PCASM));
  // Defaults beyond the paper, measured in docs/performance.md (bench/run_fluid_solvers.sh): MUMPS for the
  // subdomain LU (it pivots: PETSc's LU without pivoting hit a zero pivot with s^h = 1e10 on an AIJ matrix;
  // on the BAIJ matrix both factor at about the same speed), and reuse of the LU preconditioner for 10 linear
  // solves across Newton iterations and steps (at Re ~ 1e-4 the Jacobian barely changes: 2.2x faster at 128 x
  // 64). The paper's exact setting: -fluid_sub_pc_factor_mat_solver_type petsc
  // -fluid_snes_lag_preconditioner 1. On several ranks, an ASM overlap of 4 (PETSc's default: 1): with
  // s^h = 1e10 on a capsule's band, overlap 1 took 1324 GMRES iterations for 4 steps of the 96 x 48 cubic
  // capsule on 2 ranks, overlap 4 took 138 (1 rank: 24).
  // With the constant pressure as null space the Jacobian is singular: MUMPS then detects the null pivot
  // (ICNTL(24) = 1) and its solution stays in the range (measured: the same Newton and GMRES iterations and
  // velocity to all printed digits as with the pin on the Poiseuille and capsule scenes; without it the
  // solves degrade and Newton diverged in step 12).
  if (opt_.pressure_null_space)
    for (const char* name : {"-fluid_sub_mat_mumps_icntl_24", "-fluid_mat_mumps_icntl_24"}) {
      PetscBool set = PETSC_FALSE;
      CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, name, &set));
      if (!set) CELLFSI_PETSC(PetscOptionsSetValue(nullptr, name, "1"));
      CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, name, &set));  // a default: not the user's
    }
  const std::string overlap = std::to_string(KrylovDefaults::asm_overlap);
  const char* defaults[][2] = {{"-fluid_pc_asm_overlap", overlap.c_str()},
                               {"-fluid_sub_pc_type", KrylovDefaults::sub_pc_type},
                               {"-fluid_sub_pc_factor_mat_solver_type", KrylovDefaults::sub_solver},
                               {"-fluid_snes_lag_preconditioner", "10"},
                               {"-fluid_snes_lag_preconditioner_persists", "true"}};
  for (auto& kv : defaults) {
    PetscBool set = PETSC_FALSE;
    CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, kv[0], &set));
    if (set) continue;
    CELLFSI_PETSC(PetscOptionsSetValue(nullptr, kv[0], kv[1]));
    // Querying marks a default as used: if the user picks a preconditioner without subdomains it is not an
    // unknown option of theirs.
    CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, kv[0], &set));
  }
  CELLFSI_PETSC(SNESSetFromOptions(snes_));
}

void FluidSolver::create_jacobian_matrix() {
  if (J_) return;
  // Block AIJ with one block per control point (the default): element blocks are inserted node by node.
  CELLFSI_PETSC(DMSetMatType(da_, opt_.jacobian_type.c_str()));
  CELLFSI_PETSC(DMCreateMatrix(da_, &J_));
  CELLFSI_PETSC(MatSetOption(J_, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));
  // The constant pressure as the Jacobian's null space (or the pin of the constructor).
  if (opt_.pressure_null_space) {
    Vec constant;
    CELLFSI_PETSC(VecDuplicate(U_, &constant));
    CELLFSI_PETSC(VecSet(constant, 0.0));
    CELLFSI_PETSC(VecStrideSet(constant, dim_, 1.0));
    CELLFSI_PETSC(VecNormalize(constant, nullptr));
    MatNullSpace nsp;
    CELLFSI_PETSC(MatNullSpaceCreate(comm_, PETSC_FALSE, 1, &constant, &nsp));
    CELLFSI_PETSC(MatSetNullSpace(J_, nsp));
    // Without walls the continuity rows sum to zero for any state: the constant pressure is also the left
    // null vector, whose component of a right-hand side (round-off) KSP then removes.
    bool walls = false;
    for (int d = 0; d < dim_; ++d) walls = walls || !patch_.knots(d).periodic();
    if (!walls) CELLFSI_PETSC(MatSetTransposeNullSpace(J_, nsp));
    CELLFSI_PETSC(MatNullSpaceDestroy(&nsp));
    CELLFSI_PETSC(VecDestroy(&constant));
  }
  CELLFSI_PETSC(SNESSetFunction(snes_, F_, fluid_residual, this));
  CELLFSI_PETSC(SNESSetJacobian(snes_, J_, J_, fluid_jacobian, this));
}

void FluidSolver::release_jacobian_matrix() {
  // SNESReset drops the SNES's (and its KSP's) references to the matrix; its type and options stay.
  CELLFSI_PETSC(SNESReset(snes_));
  MatDestroy(&J_);
#ifdef __GLIBC__
  // glibc keeps the freed pages of the matrix in its heap rather than returning them (measured at 32^3:
  // resident 694 MB before and after; 150 MB after malloc_trim), and later large allocations (MUMPS' factors)
  // do not reuse them: hand them back.
  malloc_trim(0);
#endif
}

FluidSolver::~FluidSolver() {
  SNESDestroy(&snes_);
  MatDestroy(&J_);
  VecDestroy(&F_);
  VecDestroy(&U_);
  VecDestroy(&Udot_);
  VecDestroy(&Un_loc_);
  VecDestroy(&Udotn_loc_);
  VecDestroy(&S_);
  VecDestroy(&S_loc_);
  VecDestroy(&Nu_);
  VecDestroy(&Nu_loc_);
  DMDestroy(&da_scalar_);
  DMDestroy(&da_);
}

// ---------------------------------------------------------------------------------------------------------------
// Initial and boundary data

void FluidSolver::set_initial_velocity(const std::function<Vec3(const Vec3&)>& v0) {
  PetscScalar* u;
  CELLFSI_PETSC(VecGetArray(U_, &u));
  for_each_owned_node(xs_, xm_, [&](PetscInt idx, const std::array<PetscInt, 3>& m) {
    // Isoparametric: control values f(X_A) reproduce every linear f exactly.
    const Vec3 v = v0(patch_.control_points()[patch_.control_index(m[0], m[1], m[2])]);
    for (int c = 0; c < dim_; ++c) u[idx * dof_ + c] = v[c];
    u[idx * dof_ + dim_] = 0.0;
  });
  CELLFSI_PETSC(VecRestoreArray(U_, &u));
  CELLFSI_PETSC(VecSet(Udot_, 0.0));
  apply_dirichlet_values(U_, time_);
}

void FluidSolver::set_scaling(const std::function<double(int)>& s) {
  PetscScalar* a;
  CELLFSI_PETSC(VecGetArray(S_, &a));
  for_each_owned_node(xs_, xm_, [&](PetscInt idx, const std::array<PetscInt, 3>& m) {
    a[idx] = s(patch_.control_index(m[0], m[1], m[2]));
  });
  CELLFSI_PETSC(VecRestoreArray(S_, &a));
}

void FluidSolver::set_viscosity(const std::function<double(int)>& mu) {
  if (!Nu_) {
    CELLFSI_PETSC(DMCreateGlobalVector(da_scalar_, &Nu_));
    CELLFSI_PETSC(DMCreateLocalVector(da_scalar_, &Nu_loc_));
  }
  PetscScalar* a;
  CELLFSI_PETSC(VecGetArray(Nu_, &a));
  for_each_owned_node(xs_, xm_, [&](PetscInt idx, const std::array<PetscInt, 3>& m) {
    a[idx] = mu(patch_.control_index(m[0], m[1], m[2])) / opt_.density;
  });
  CELLFSI_PETSC(VecRestoreArray(Nu_, &a));
}

void FluidSolver::clear_viscosity() {
  CELLFSI_PETSC(VecDestroy(&Nu_));
  CELLFSI_PETSC(VecDestroy(&Nu_loc_));
}

std::vector<double> FluidSolver::viscosity_on_zero() const {
  return Nu_ ? gather_to_zero(Nu_) : std::vector<double>{};
}

void FluidSolver::apply_dirichlet_values(Vec U, double /*t*/) const {
  PetscScalar* u;
  CELLFSI_PETSC(VecGetArray(U, &u));
  for_each_owned_node(xs_, xm_, [&](PetscInt idx, const std::array<PetscInt, 3>& m) {
    for (int d = 0; d < dim_; ++d) {
      if (patch_.knots(d).periodic()) continue;
      for (int s = 0; s < 2; ++s)
        if (m[d] == (s == 0 ? 0 : patch_.n_control(d) - 1))
          for (int c = 0; c < dim_; ++c) u[idx * dof_ + c] = opt_.wall_velocity[d][s][c];
    }
  });
  if (pin_row_ >= 0) u[dim_] = 0.0;
  CELLFSI_PETSC(VecRestoreArray(U, &u));
}

std::vector<PetscInt> FluidSolver::dirichlet_rows() const {
  std::vector<PetscInt> rows;
  PetscInt lo = 0;
  CELLFSI_PETSC(VecGetOwnershipRange(U_, &lo, nullptr));
  for_each_owned_node(xs_, xm_, [&](PetscInt idx, const std::array<PetscInt, 3>& m) {
    bool wall = false;
    for (int d = 0; d < dim_; ++d)
      if (!patch_.knots(d).periodic() && (m[d] == 0 || m[d] == patch_.n_control(d) - 1)) wall = true;
    if (wall)
      for (int c = 0; c < dim_; ++c) rows.push_back(lo + idx * dof_ + c);
  });
  if (pin_row_ >= 0) rows.push_back(pin_row_);
  return rows;
}

std::vector<Index3> FluidSolver::owned_elements() const {
  std::vector<int> owned[3];
  for (int d = 0; d < 3; ++d) {
    if (d >= dim_) {
      owned[d] = {0};
      continue;
    }
    const geometry::KnotVector& kv = patch_.knots(d);
    for (int e = 0; e < kv.n_elements(); ++e) {
      const PetscInt first = kv.element_span(e) - kv.degree();
      if (first >= xs_[d] && first < xs_[d] + xm_[d]) owned[d].push_back(e);
    }
  }
  std::vector<Index3> out;
  for (int ez : owned[2])
    for (int ey : owned[1])
      for (int ex : owned[0]) out.push_back({ex, ey, ez});
  return out;
}

bool FluidSolver::owns_element(const Index3& e) const {
  for (int d = 0; d < dim_; ++d) {
    const geometry::KnotVector& kv = patch_.knots(d);
    const PetscInt first = kv.element_span(e[d]) - kv.degree();
    if (first < xs_[d] || first >= xs_[d] + xm_[d]) return false;
  }
  return true;
}

void FluidSolver::set_immersed_points(const std::vector<ImmersedPointData>& points) {
  immersed_.clear();
  for (const auto& ip : points) {
    const geometry::InversionResult r = inverter_.invert(ip.x);
    if (!r.inside) {
      std::ostringstream os;
      os << "immersed point (" << ip.x.transpose() << ") lies outside the fluid domain (distance "
         << r.distance << " cm)";
      throw std::runtime_error(os.str());
    }
    if (owns_element(r.element)) immersed_.push_back({r.element, r.xi, ip.data});
  }
  sort_immersed_points();
}

void FluidSolver::sort_immersed_points() {
  // By element (z, y, x), as the assembly sums each element's points before adding them to the matrix; points
  // of one element keep their order. The keys are sorted and the points moved once (a stable sort of the
  // points themselves, 300 bytes each, cost a third of the coupler's work per iteration at 16^3, perf).
  std::vector<std::pair<std::int64_t, std::size_t>> order(immersed_.size());
  for (std::size_t i = 0; i < immersed_.size(); ++i) {
    const Index3& e = immersed_[i].element;
    order[i] = {(static_cast<std::int64_t>(e[2]) << 42) | (static_cast<std::int64_t>(e[1]) << 21) | e[0], i};
  }
  std::sort(order.begin(), order.end());
  // Into the kept second buffer: at 64^3 the points are tens of MB, and a new buffer at every coupling
  // iteration is that many page faults.
  immersed_sorted_.clear();
  immersed_sorted_.reserve(immersed_.size());
  for (const auto& o : order) immersed_sorted_.push_back(std::move(immersed_[o.second]));
  immersed_.swap(immersed_sorted_);
}

// ---------------------------------------------------------------------------------------------------------------
// Time step

void FluidSolver::setup() {
  create_jacobian_matrix();
  // The Jacobian at the initial state lets the linear solver set itself up: inner solvers (ASM subdomains,
  // multigrid levels) read their options here, so misspelt ones are reported before any time step.
  // Factorisations are deferred to the first solve, so this costs one Jacobian assembly.
  CELLFSI_PETSC(SNESSetUp(snes_));
  evaluate_jacobian(U_, J_);
  KSP ksp;
  CELLFSI_PETSC(SNESGetKSP(snes_, &ksp));
  CELLFSI_PETSC(KSPSetOperators(ksp, J_, J_));
  CELLFSI_PETSC(KSPSetUp(ksp));
}

void FluidSolver::release_linear_solver() {
  KSP ksp;
  CELLFSI_PETSC(SNESGetKSP(snes_, &ksp));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCReset(pc));
}

StepStats FluidSolver::step() {
  StepStats st;
  Vec X;
  CELLFSI_PETSC(VecDuplicate(U_, &X));
  create_jacobian_matrix();
  begin_step(X);
  CELLFSI_PETSC(SNESSolve(snes_, nullptr, X));
  PetscInt its = 0, lits = 0;
  SNESConvergedReason reason;
  CELLFSI_PETSC(SNESGetIterationNumber(snes_, &its));
  CELLFSI_PETSC(SNESGetLinearSolveIterations(snes_, &lits));
  CELLFSI_PETSC(SNESGetConvergedReason(snes_, &reason));
  st.newton_iterations = static_cast<int>(its);
  st.linear_iterations = static_cast<int>(lits);
  st.converged = reason > 0;
  st.reason = SNESConvergedReasons[reason];
  if (reason == SNES_DIVERGED_LINEAR_SOLVE) {
    KSP ksp;
    CELLFSI_PETSC(SNESGetKSP(snes_, &ksp));
    st.reason += " (" + linear_solve_failure(ksp) + ")";
  }
  if (st.converged) end_step(X);
  CELLFSI_PETSC(VecDestroy(&X));
  return st;
}

// ---------------------------------------------------------------------------------------------------------------
// Newton driven from outside (coupling)

void FluidSolver::begin_step(Vec X) {
  CELLFSI_PETSC(DMGlobalToLocal(da_, U_, INSERT_VALUES, Un_loc_));
  CELLFSI_PETSC(DMGlobalToLocal(da_, Udot_, INSERT_VALUES, Udotn_loc_));
  CELLFSI_PETSC(VecCopy(U_, X));  // predictor: same state
  apply_dirichlet_values(X, time_ + opt_.dt);
}

void FluidSolver::end_step(Vec X) {
  // Udot_{n+1} = (U_{n+1} - U_n) / (gamma dt) - (1 - gamma) / gamma Udot_n (GeneralizedAlpha::rate), then U.
  const double gm = alpha_.gamma, dt = alpha_.dt;
  CELLFSI_PETSC(VecAXPBYPCZ(Udot_, 1.0 / (gm * dt), -1.0 / (gm * dt), -(1.0 - gm) / gm, X, U_));
  CELLFSI_PETSC(VecCopy(X, U_));
  if (opt_.pressure_null_space) normalize_pressure(U_);
  ++steps_;
  time_ = steps_ * opt_.dt;  // not accumulated: t_k = k dt exactly as written in outputs
}

void FluidSolver::normalize_pressure(Vec U) const {
  // The gauge of the pin: the first control point's pressure 0 (its owner starts at the corner 0, 0, 0).
  PetscScalar* u;
  PetscInt n = 0;
  CELLFSI_PETSC(VecGetLocalSize(U, &n));
  CELLFSI_PETSC(VecGetArray(U, &u));
  double p0 = xs_[0] == 0 && xs_[1] == 0 && xs_[2] == 0 && n > 0 ? u[dim_] : 0.0;
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &p0, 1, MPI_DOUBLE, MPI_SUM, comm_));
  for (PetscInt i = dim_; i < n; i += dof_) u[i] -= p0;
  CELLFSI_PETSC(VecRestoreArray(U, &u));
}

void FluidSolver::restore(Vec U, Vec Udot, int steps) {
  if (steps < 0) throw std::invalid_argument("FluidSolver::restore: steps must be >= 0");
  CELLFSI_PETSC(VecCopy(U, U_));
  CELLFSI_PETSC(VecCopy(Udot, Udot_));
  steps_ = steps;
  time_ = steps_ * opt_.dt;
}

std::optional<BlockLayout> FluidSolver::block_layout() const {
  BlockLayout b;
  for (int d = 0; d < dim_; ++d) {
    b.n[d] = patch_.n_control(d);
    b.degree[d] = patch_.degree(d);
    b.periodic[d] = patch_.knots(d).periodic();
  }
  b.dof = dof_;
  CELLFSI_PETSC(DMDAGetAO(da_, &b.natural));
  CELLFSI_PETSC(DMGetLocalToGlobalMapping(da_, &b.local_to_global));
  return b;
}

std::vector<int> FluidSolver::unknown_kinds() const {
  PetscInt n = 0;
  CELLFSI_PETSC(VecGetLocalSize(U_, &n));
  std::vector<int> kinds(static_cast<std::size_t>(n));
  for (PetscInt i = 0; i < n; ++i) kinds[i] = static_cast<int>(i % dof_);  // (a rank owns whole nodes)
  return kinds;
}

std::vector<PetscInt> FluidSolver::region_unknowns(const std::vector<char>& in_region) const {
  // The DMDA's AO maps unknowns (node-major, unknown-minor): a node's first unknown stands for its block. (On
  // one rank the DMDA's numbering is the natural one.)
  const std::vector<int> natural = geometry::functions_on_elements(patch_, in_region);
  std::vector<PetscInt> first(natural.size());
  for (std::size_t i = 0; i < natural.size(); ++i) first[i] = static_cast<PetscInt>(natural[i]) * dof_;
  AO ao = nullptr;
  CELLFSI_PETSC(DMDAGetAO(da_, &ao));
  CELLFSI_PETSC(AOApplicationToPetsc(ao, static_cast<PetscInt>(first.size()), first.data()));
  std::sort(first.begin(), first.end());
  std::vector<PetscInt> unknowns;
  unknowns.reserve(first.size() * dof_);
  for (PetscInt f : first)
    for (int c = 0; c < dof_; ++c) unknowns.push_back(f + c);
  return unknowns;
}

// State files (state_file.hpp).

/// A vector as a PETSc binary file holds it (VecLoad reads it back): the class id and the length as
/// big-endian 32-bit integers, then the values as big-endian doubles, in the DMDA's natural ordering (any
/// number of ranks can read it). Collective; the bytes on rank 0, empty elsewhere.
std::string vec_binary_on_rank_zero(Vec v) {
  DM dm = nullptr;
  CELLFSI_PETSC(VecGetDM(v, &dm));
  Vec natural = v;
  if (dm) {
    CELLFSI_PETSC(DMDACreateNaturalVector(dm, &natural));
    CELLFSI_PETSC(DMDAGlobalToNaturalBegin(dm, v, INSERT_VALUES, natural));
    CELLFSI_PETSC(DMDAGlobalToNaturalEnd(dm, v, INSERT_VALUES, natural));
  }
  VecScatter to_zero = nullptr;
  Vec all = nullptr;
  CELLFSI_PETSC(VecScatterCreateToZero(natural, &to_zero, &all));
  CELLFSI_PETSC(VecScatterBegin(to_zero, natural, all, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(to_zero, natural, all, INSERT_VALUES, SCATTER_FORWARD));
  PetscInt n = 0;
  CELLFSI_PETSC(VecGetLocalSize(all, &n));
  std::string bytes;
  if (n > 0) {
    PetscInt header[2] = {VEC_FILE_CLASSID, 0};
    CELLFSI_PETSC(VecGetSize(natural, &header[1]));
    std::vector<PetscScalar> values(static_cast<std::size_t>(n));
    const PetscScalar* a = nullptr;
    CELLFSI_PETSC(VecGetArrayRead(all, &a));
    std::copy(a, a + n, values.begin());
    CELLFSI_PETSC(VecRestoreArrayRead(all, &a));
#if !defined(PETSC_WORDS_BIGENDIAN)
    CELLFSI_PETSC(PetscByteSwap(header, PETSC_INT, 2));
    CELLFSI_PETSC(PetscByteSwap(values.data(), PETSC_SCALAR, n));
#endif
    bytes.append(reinterpret_cast<const char*>(header), sizeof header);
    bytes.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(PetscScalar));
  }
  CELLFSI_PETSC(VecScatterDestroy(&to_zero));
  CELLFSI_PETSC(VecDestroy(&all));
  if (natural != v) CELLFSI_PETSC(VecDestroy(&natural));
  return bytes;
}


StateRead read_state_pair(PetscViewer viewer, Vec u, Vec udot) {
  // A file of another size is the caller's input error, reported by it once (no PETSc traceback).
  PetscPushErrorHandler(PetscReturnErrorHandler, nullptr);
  const PetscErrorCode e1 = VecLoad(u, viewer);
  const PetscErrorCode e2 = e1 ? e1 : VecLoad(udot, viewer);
  PetscPopErrorHandler();
  if (e1 || e2) return StateRead::does_not_fit;
  return all_finite(u) && all_finite(udot) ? StateRead::ok : StateRead::not_finite;
}

/// Whether every entry of v is finite (collective).
bool all_finite(Vec v) {
  const PetscScalar* a = nullptr;
  PetscInt n = 0;
  CELLFSI_PETSC(VecGetLocalSize(v, &n));
  CELLFSI_PETSC(VecGetArrayRead(v, &a));
  int finite = 1;
  for (PetscInt i = 0; i < n && finite; ++i) finite = std::isfinite(PetscRealPart(a[i]));
  CELLFSI_PETSC(VecRestoreArrayRead(v, &a));
  MPI_Allreduce(MPI_IN_PLACE, &finite, 1, MPI_INT, MPI_MIN, PetscObjectComm(reinterpret_cast<PetscObject>(v)));
  return finite == 1;
}



std::string FluidSolver::state_bytes() const { return vec_binary_on_rank_zero(U_) + vec_binary_on_rank_zero(Udot_); }

ImmersedFluid::LoadedState FluidSolver::load_state(PetscViewer viewer, int steps) {
  Vec U = nullptr, Udot = nullptr;
  CELLFSI_PETSC(VecDuplicate(U_, &U));
  CELLFSI_PETSC(VecDuplicate(U_, &Udot));
  const StateRead read = read_state_pair(viewer, U, Udot);
  const LoadedState r = read == StateRead::ok             ? LoadedState::ok
                        : read == StateRead::does_not_fit ? LoadedState::does_not_fit
                                                          : LoadedState::not_finite;
  if (r == LoadedState::ok) restore(U, Udot, steps);
  VecDestroy(&U);
  VecDestroy(&Udot);
  return r;
}

KSP FluidSolver::ksp() const {
  KSP k;
  CELLFSI_PETSC(SNESGetKSP(snes_, &k));
  return k;
}

void FluidSolver::set_immersed_points(const std::vector<Index3>& elements, const std::vector<Param>& xi,
                                      const std::vector<ImmersedPoint>& data) {
  if (elements.size() != xi.size() || xi.size() != data.size())
    throw std::invalid_argument("set_immersed_points: elements, xi and data differ in size");
  immersed_.clear();
  immersed_.reserve(data.size());
  for (size_t i = 0; i < data.size(); ++i)
    if (owns_element(elements[i])) immersed_.push_back({elements[i], xi[i], data[i]});
  sort_immersed_points();
}

template <class Value, class Rate>
std::vector<PointSample> FluidSolver::sample_local(const std::vector<Index3>& elements,
                                                   const std::vector<Param>& xi,
                                                   const std::vector<char>& located, Value&& value,
                                                   Rate&& rate) const {
  std::vector<PointSample> local(xi.size());
  BasisValues bv;
  MapValues mv;
  PhysicalPoint pp;
  std::vector<PetscInt> nodes;
  for (size_t i = 0; i < xi.size(); ++i) {
    if (!located[i] || !owns_element(elements[i])) continue;
    physical_point(patch_, elements[i], xi[i], 1, bv, mv, pp, affine());
    element_nodes(patch_, pp, gxs_, gxm_, nodes);
    const PointValues v = interpolate(pp, dim_, [&](int k, int c) { return value(nodes[k] * dof_ + c, c); });
    const PointValues r = interpolate(pp, dim_, [&](int k, int c) { return rate(nodes[k] * dof_ + c, c); });
    local[i] = {true, v.v, v.grad_v, r.v, v.scalar};
  }
  return local;
}

std::vector<PointSample> FluidSolver::sample_alpha(Vec X, const std::vector<Index3>& elements,
                                                   const std::vector<Param>& xi) const {
  const int D = dim_;
  Vec X_loc;
  CELLFSI_PETSC(DMGetLocalVector(da_, &X_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_, X, INSERT_VALUES, X_loc));
  const PetscScalar *x, *un, *udn;
  CELLFSI_PETSC(VecGetArrayRead(X_loc, &x));
  CELLFSI_PETSC(VecGetArrayRead(Un_loc_, &un));
  CELLFSI_PETSC(VecGetArrayRead(Udotn_loc_, &udn));
  // Velocity at t_{n+alpha_f}, its rate at t_{n+alpha_m}; no pressure (its nodal values are taken as 0).
  const std::vector<PointSample> local = sample_local(
      elements, xi, std::vector<char>(xi.size(), 1),
      [&](PetscInt li, int c) { return c < D ? alpha_.value_alpha_f(x[li], un[li]) : 0.0; },
      [&](PetscInt li, int c) { return c < D ? alpha_.rate_alpha_m(x[li], un[li], udn[li]) : 0.0; });
  CELLFSI_PETSC(VecRestoreArrayRead(X_loc, &x));
  CELLFSI_PETSC(VecRestoreArrayRead(Un_loc_, &un));
  CELLFSI_PETSC(VecRestoreArrayRead(Udotn_loc_, &udn));
  CELLFSI_PETSC(DMRestoreLocalVector(da_, &X_loc));
  return gather_samples(local);
}

// ---------------------------------------------------------------------------------------------------------------
// Sampling and gathering

std::vector<PointSample> FluidSolver::sample(const std::vector<Vec3>& points) const {
  std::vector<Index3> elements(points.size());
  std::vector<Param> xi(points.size());
  std::vector<char> located(points.size(), 0);
  for (size_t i = 0; i < points.size(); ++i) {
    const geometry::InversionResult r = inverter_.invert(points[i]);
    if (!r.inside) continue;
    elements[i] = r.element;
    xi[i] = r.xi;
    located[i] = 1;
  }
  Vec U_loc, Ud_loc;
  CELLFSI_PETSC(DMGetLocalVector(da_, &U_loc));
  CELLFSI_PETSC(DMGetLocalVector(da_, &Ud_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_, U_, INSERT_VALUES, U_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_, Udot_, INSERT_VALUES, Ud_loc));
  const PetscScalar *u, *ud;
  CELLFSI_PETSC(VecGetArrayRead(U_loc, &u));
  CELLFSI_PETSC(VecGetArrayRead(Ud_loc, &ud));
  const std::vector<PointSample> local = sample_local(
      elements, xi, located, [&](PetscInt li, int) { return u[li]; },
      [&](PetscInt li, int) { return ud[li]; });
  CELLFSI_PETSC(VecRestoreArrayRead(U_loc, &u));
  CELLFSI_PETSC(VecRestoreArrayRead(Ud_loc, &ud));
  CELLFSI_PETSC(DMRestoreLocalVector(da_, &U_loc));
  CELLFSI_PETSC(DMRestoreLocalVector(da_, &Ud_loc));
  return gather_samples(local);
}

std::vector<PointSample> FluidSolver::gather_samples(const std::vector<PointSample>& local) const {
  // Every point is found by exactly one rank (the owner of its element): a sum gathers them on every rank.
  constexpr int stride = 17;  // found, v[3], grad v[9], vdot[3], p
  std::vector<double> buf(local.size() * stride, 0.0), all(buf.size());
  for (size_t i = 0; i < local.size(); ++i) {
    const PointSample& s = local[i];
    if (!s.found) continue;
    double* o = &buf[i * stride];
    o[0] = 1.0;
    for (int c = 0; c < 3; ++c) {
      o[1 + c] = s.v[c];
      o[13 + c] = s.vdot[c];
      for (int j = 0; j < 3; ++j) o[4 + 3 * c + j] = s.grad_v(c, j);
    }
    o[16] = s.p;
  }
  CELLFSI_PETSC(
      MPI_Allreduce(buf.data(), all.data(), static_cast<int>(buf.size()), MPI_DOUBLE, MPI_SUM, comm_));
  std::vector<PointSample> out(local.size());
  for (size_t i = 0; i < out.size(); ++i) {
    const double* o = &all[i * stride];
    PointSample& s = out[i];
    s.found = o[0] > 0.5;
    for (int c = 0; c < 3; ++c) {
      s.v[c] = o[1 + c];
      s.vdot[c] = o[13 + c];
      for (int j = 0; j < 3; ++j) s.grad_v(c, j) = o[4 + 3 * c + j];
    }
    s.p = o[16];
  }
  return out;
}

std::vector<double> FluidSolver::gather_to_zero(Vec global) const {
  DM dm;
  CELLFSI_PETSC(VecGetDM(global, &dm));
  if (!dm) dm = da_;
  Vec natural, seq;
  VecScatter scatter;
  CELLFSI_PETSC(DMDACreateNaturalVector(dm, &natural));
  CELLFSI_PETSC(DMDAGlobalToNaturalBegin(dm, global, INSERT_VALUES, natural));
  CELLFSI_PETSC(DMDAGlobalToNaturalEnd(dm, global, INSERT_VALUES, natural));
  CELLFSI_PETSC(VecScatterCreateToZero(natural, &scatter, &seq));
  CELLFSI_PETSC(VecScatterBegin(scatter, natural, seq, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(scatter, natural, seq, INSERT_VALUES, SCATTER_FORWARD));
  PetscInt n = 0;
  CELLFSI_PETSC(VecGetLocalSize(seq, &n));
  std::vector<double> out(n);
  const PetscScalar* a;
  CELLFSI_PETSC(VecGetArrayRead(seq, &a));
  std::copy(a, a + n, out.begin());
  CELLFSI_PETSC(VecRestoreArrayRead(seq, &a));
  CELLFSI_PETSC(VecScatterDestroy(&scatter));
  CELLFSI_PETSC(VecDestroy(&seq));
  CELLFSI_PETSC(VecDestroy(&natural));
  return out;
}

}  // namespace cellfsi::fluid
