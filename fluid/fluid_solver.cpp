#include "fluid/fluid_solver.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "common/petsc_error.hpp"
#include "geometry/quadrature.hpp"

namespace cellfsi::fluid {

using geometry::BasisValues;
using geometry::Index3;
using geometry::MapValues;
using geometry::Mat3;
using geometry::Param;

// ---------------------------------------------------------------------------------------------------------------
// Options

namespace {

[[noreturn]] void bad_option(const std::string& name, const std::string& value, const std::string& valid) {
  throw std::invalid_argument("option -" + name + " = " + value + " is invalid; valid: " + valid);
}

std::string str(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

/// Raw option values (read in a PETSc options block, so -help lists them), checked afterwards.
struct RawFluidOptions {
  PetscReal density, viscosity, rho_inf, c_i;
  PetscReal body_force[4] = {0, 0, 0, 0};
  PetscInt n_body_force = 0;
  PetscBool body_force_set = PETSC_FALSE, stokes = PETSC_FALSE;
  PetscReal wall[3][2][4] = {};
  PetscInt n_wall[3][2] = {};
  PetscBool wall_set[3][2] = {};
};

PetscErrorCode read_fluid_options(RawFluidOptions& r, int dim) {
  PetscFunctionBeginUser;
  PetscOptionsBegin(PETSC_COMM_WORLD, nullptr, "Fluid (VMS Navier-Stokes; CGS units)", nullptr);
  PetscCall(PetscOptionsReal("-fluid_density", "rho_1 [g/cm^3]", nullptr, r.density, &r.density, nullptr));
  PetscCall(
      PetscOptionsReal("-fluid_viscosity", "mu [g/(cm s)]", nullptr, r.viscosity, &r.viscosity, nullptr));
  r.n_body_force = 4;
  PetscCall(PetscOptionsRealArray("-fluid_body_force", "Body force per volume fx,fy[,fz] [dyn/cm^3]", nullptr,
                                  r.body_force, &r.n_body_force, &r.body_force_set));
  PetscCall(PetscOptionsBool("-fluid_stokes", "Drop convection (Stokes flow)", nullptr, r.stokes, &r.stokes,
                             nullptr));
  PetscCall(PetscOptionsReal("-fluid_rho_inf", "Generalized-alpha spectral radius at infinity, [0, 1]",
                             nullptr, r.rho_inf, &r.rho_inf, nullptr));
  PetscCall(PetscOptionsReal("-fluid_c_i", "C_I of tau_M", nullptr, r.c_i, &r.c_i, nullptr));
  const char axes[3] = {'x', 'y', 'z'};
  for (int d = 0; d < dim; ++d)
    for (int s = 0; s < 2; ++s) {
      char name[64];
      std::snprintf(name, sizeof name, "-fluid_wall_velocity_%c%d", axes[d], s);
      r.n_wall[d][s] = 4;
      PetscCall(PetscOptionsRealArray(
          name, "Velocity of the wall at the start (0) or end (1) of this direction [cm/s]", nullptr,
          r.wall[d][s], &r.n_wall[d][s], &r.wall_set[d][s]));
    }
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

Vec3 vector_option(const std::string& name, const PetscReal* v, PetscInt n, int dim) {
  if (n != dim)
    bad_option(name, std::to_string(n) + " values", std::to_string(dim) + " comma-separated values");
  return Vec3(v[0], v[1], dim == 3 ? v[2] : 0.0);
}

}  // namespace

void FluidOptions::set_from_options(int dim) {
  RawFluidOptions r;
  r.density = density, r.viscosity = viscosity, r.rho_inf = rho_inf, r.c_i = c_i;
  r.stokes = stokes ? PETSC_TRUE : PETSC_FALSE;
  call_reporting_input_errors([&] { return read_fluid_options(r, dim); }, {{"-fluid_density", 'r'},
                                                                           {"-fluid_viscosity", 'r'},
                                                                           {"-fluid_body_force", 'R'},
                                                                           {"-fluid_stokes", 'b'},
                                                                           {"-fluid_rho_inf", 'r'},
                                                                           {"-fluid_c_i", 'r'},
                                                                           {"-fluid_wall_velocity_x0", 'R'},
                                                                           {"-fluid_wall_velocity_x1", 'R'},
                                                                           {"-fluid_wall_velocity_y0", 'R'},
                                                                           {"-fluid_wall_velocity_y1", 'R'},
                                                                           {"-fluid_wall_velocity_z0", 'R'},
                                                                           {"-fluid_wall_velocity_z1", 'R'}});
  density = r.density, viscosity = r.viscosity, rho_inf = r.rho_inf, c_i = r.c_i;
  stokes = r.stokes == PETSC_TRUE;
  if (r.body_force_set) body_force = vector_option("fluid_body_force", r.body_force, r.n_body_force, dim);
  const char axes[3] = {'x', 'y', 'z'};
  for (int d = 0; d < dim; ++d)
    for (int s = 0; s < 2; ++s)
      if (r.wall_set[d][s])
        wall_velocity[d][s] = vector_option(std::string("fluid_wall_velocity_") + axes[d] + std::to_string(s),
                                            r.wall[d][s], r.n_wall[d][s], dim);
  validate();
}

void FluidOptions::validate() const {
  if (!(density > 0)) bad_option("fluid_density", str(density), "> 0 [g/cm^3]");
  if (!(viscosity > 0)) bad_option("fluid_viscosity", str(viscosity), "> 0 [g/(cm s)]");
  if (!(rho_inf >= 0 && rho_inf <= 1)) bad_option("fluid_rho_inf", str(rho_inf), "0 <= rho_inf <= 1");
  if (!(dt > 0)) bad_option("dt", str(dt), "> 0 [s]");
  if (!(c_i > 0)) bad_option("fluid_c_i", str(c_i), "> 0");
}

// ---------------------------------------------------------------------------------------------------------------
// Physical basis at a quadrature point

namespace {

/// Basis functions in physical coordinates, the quadrature Jacobian and the metric G of tau_M at one point.
struct PhysicalPoint {
  int n = 0;
  std::vector<double> N, dN, lapN;
  double detJ = 0;
  std::array<std::array<double, 3>, 3> G{};
};

void physical_point(const geometry::Patch& patch, const Index3& e, const Param& xi, BasisValues& bv,
                    MapValues& mv, PhysicalPoint& out) {
  const int D = patch.param_dim();
  patch.basis(xi, 2, bv, &e);
  patch.map(bv, mv);
  const Mat3 J = mv.dx;
  Mat3 Jinv = Mat3::Identity();
  Jinv.topLeftCorner(D, D) = J.topLeftCorner(D, D).inverse();  // Jinv(a, j) = d xi_a / d x_j
  out.detJ = std::abs(J.topLeftCorner(D, D).determinant());
  out.n = bv.n;
  out.N.resize(bv.n);
  out.dN.resize(3 * bv.n);
  out.lapN.resize(bv.n);
  bool affine = true;
  for (int i = 0; i < D && affine; ++i) affine = mv.d2x[i].topLeftCorner(D, D).isZero(0.0);
  for (int k = 0; k < bv.n; ++k) {
    out.N[k] = bv.value[k];
    double g[3] = {0, 0, 0};
    for (int j = 0; j < D; ++j)
      for (int a = 0; a < D; ++a) g[j] += bv.d1[3 * k + a] * Jinv(a, j);
    for (int j = 0; j < 3; ++j) out.dN[3 * k + j] = g[j];
    // Hessian in x: Jinv^T (H_xi - sum_m dN/dx_m d2x_m/dxi2) Jinv; only its trace is needed.
    Mat3 H = Mat3::Zero();
    for (int a = 0; a < D; ++a)
      for (int b = 0; b < D; ++b) {
        double h = bv.d2[9 * k + 3 * a + b];
        if (!affine)
          for (int m = 0; m < D; ++m) h -= g[m] * mv.d2x[m](a, b);
        H(a, b) = h;
      }
    double lap = 0;
    for (int i = 0; i < D; ++i)
      for (int a = 0; a < D; ++a)
        for (int b = 0; b < D; ++b) lap += Jinv(a, i) * H(a, b) * Jinv(b, i);
    out.lapN[k] = lap;
  }
  // G with parent coordinates in [-1, 1]: d xi_parent / d x = (2 / h_a) d xi / d x.
  double scale[3] = {1, 1, 1};
  for (int a = 0; a < D; ++a) {
    const double h = patch.knots(a).element_end(e[a]) - patch.knots(a).element_begin(e[a]);
    scale[a] = 2.0 / h;
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double s = 0;
      if (i < D && j < D)
        for (int a = 0; a < D; ++a) s += scale[a] * scale[a] * Jinv(a, i) * Jinv(a, j);
      out.G[i][j] = s;
    }
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// Construction

FluidSolver::FluidSolver(MPI_Comm comm, const geometry::Patch& patch, const FluidOptions& options)
    : comm_(comm), patch_(patch), opt_(options), inverter_(patch), element_basis_(patch) {
  dim_ = patch.param_dim();
  if (dim_ != patch.physical_dim() || dim_ < 2)
    throw std::invalid_argument("FluidSolver: the Eulerian patch must be 2D in 2D or 3D in 3D");
  opt_.validate();
  dof_ = dim_ + 1;
  const double r = opt_.rho_inf;
  alpha_.alpha_m = (3.0 - r) / (2.0 * (1.0 + r));
  alpha_.alpha_f = 1.0 / (1.0 + r);
  alpha_.gamma = 0.5 + alpha_.alpha_m - alpha_.alpha_f;

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
  // Block AIJ with one block per control point: element blocks are inserted node by node.
  char mat_type[64] = MATBAIJ;
  CELLFSI_PETSC(
      PetscOptionsGetString(nullptr, "fluid_", "-mat_type_jacobian", mat_type, sizeof mat_type, nullptr));
  CELLFSI_PETSC(DMSetMatType(da_, mat_type));
  CELLFSI_PETSC(DMCreateMatrix(da_, &J_));
  CELLFSI_PETSC(MatSetOption(J_, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));

  // The pressure of the first control point is pinned (see the header).
  if (xs_[0] == 0 && xs_[1] == 0 && xs_[2] == 0) {
    PetscInt lo = 0;
    CELLFSI_PETSC(VecGetOwnershipRange(U_, &lo, nullptr));
    pin_row_ = lo + dim_;
  }

  CELLFSI_PETSC(SNESCreate(comm, &snes_));
  CELLFSI_PETSC(SNESSetOptionsPrefix(snes_, "fluid_"));
  CELLFSI_PETSC(SNESSetFunction(snes_, F_, fluid_residual, this));
  CELLFSI_PETSC(SNESSetJacobian(snes_, J_, J_, fluid_jacobian, this));
  // The paper's linear solver, as defaults that the command line overrides: GMRES (rtol 1e-5), restricted
  // additive Schwarz with one subdomain per rank, LU subdomain solves with nested-dissection ordering.
  KSP ksp;
  PC pc;
  CELLFSI_PETSC(SNESGetKSP(snes_, &ksp));
  CELLFSI_PETSC(KSPSetType(ksp, KSPGMRES));
  CELLFSI_PETSC(KSPSetTolerances(ksp, 1e-5, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT));
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
  const char* defaults[][2] = {{"-fluid_pc_asm_overlap", "4"},
                               {"-fluid_sub_pc_type", "lu"},
                               {"-fluid_sub_pc_factor_mat_solver_type", "mumps"},
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
  DMDestroy(&da_scalar_);
  DMDestroy(&da_);
}

// ---------------------------------------------------------------------------------------------------------------
// Initial and boundary data

void FluidSolver::set_initial_velocity(const std::function<Vec3(const Vec3&)>& v0) {
  PetscScalar* u;
  CELLFSI_PETSC(VecGetArray(U_, &u));
  PetscInt idx = 0;
  for (PetscInt k = xs_[2]; k < xs_[2] + xm_[2]; ++k)
    for (PetscInt j = xs_[1]; j < xs_[1] + xm_[1]; ++j)
      for (PetscInt i = xs_[0]; i < xs_[0] + xm_[0]; ++i, ++idx) {
        // Isoparametric: control values f(X_A) reproduce every linear f exactly.
        const Vec3 v = v0(patch_.control_points()[patch_.control_index(i, j, k)]);
        for (int c = 0; c < dim_; ++c) u[idx * dof_ + c] = v[c];
        u[idx * dof_ + dim_] = 0.0;
      }
  CELLFSI_PETSC(VecRestoreArray(U_, &u));
  CELLFSI_PETSC(VecSet(Udot_, 0.0));
  apply_dirichlet_values(U_, time_);
}

void FluidSolver::set_scaling(const std::function<double(int)>& s) {
  PetscScalar* a;
  CELLFSI_PETSC(VecGetArray(S_, &a));
  PetscInt idx = 0;
  for (PetscInt k = xs_[2]; k < xs_[2] + xm_[2]; ++k)
    for (PetscInt j = xs_[1]; j < xs_[1] + xm_[1]; ++j)
      for (PetscInt i = xs_[0]; i < xs_[0] + xm_[0]; ++i, ++idx) a[idx] = s(patch_.control_index(i, j, k));
  CELLFSI_PETSC(VecRestoreArray(S_, &a));
}

void FluidSolver::apply_dirichlet_values(Vec U, double /*t*/) const {
  PetscScalar* u;
  CELLFSI_PETSC(VecGetArray(U, &u));
  PetscInt idx = 0;
  for (PetscInt k = xs_[2]; k < xs_[2] + xm_[2]; ++k)
    for (PetscInt j = xs_[1]; j < xs_[1] + xm_[1]; ++j)
      for (PetscInt i = xs_[0]; i < xs_[0] + xm_[0]; ++i, ++idx) {
        const PetscInt m[3] = {i, j, k};
        for (int d = 0; d < dim_; ++d) {
          if (patch_.knots(d).periodic()) continue;
          for (int s = 0; s < 2; ++s)
            if (m[d] == (s == 0 ? 0 : patch_.n_control(d) - 1))
              for (int c = 0; c < dim_; ++c) u[idx * dof_ + c] = opt_.wall_velocity[d][s][c];
        }
      }
  if (pin_row_ >= 0) u[dim_] = 0.0;
  CELLFSI_PETSC(VecRestoreArray(U, &u));
}

std::vector<PetscInt> FluidSolver::dirichlet_rows() const {
  std::vector<PetscInt> rows;
  PetscInt lo = 0;
  CELLFSI_PETSC(VecGetOwnershipRange(U_, &lo, nullptr));
  PetscInt idx = 0;
  for (PetscInt k = xs_[2]; k < xs_[2] + xm_[2]; ++k)
    for (PetscInt j = xs_[1]; j < xs_[1] + xm_[1]; ++j)
      for (PetscInt i = xs_[0]; i < xs_[0] + xm_[0]; ++i, ++idx) {
        const PetscInt m[3] = {i, j, k};
        bool wall = false;
        for (int d = 0; d < dim_; ++d)
          if (!patch_.knots(d).periodic() && (m[d] == 0 || m[d] == patch_.n_control(d) - 1)) wall = true;
        if (wall)
          for (int c = 0; c < dim_; ++c) rows.push_back(lo + idx * dof_ + c);
      }
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
}

// ---------------------------------------------------------------------------------------------------------------
// Assembly

namespace {

/// Local (ghosted) offset of the node with unwrapped indices m.
inline PetscInt local_node(const PetscInt m[3], const PetscInt gxs[3], const PetscInt gxm[3]) {
  return ((m[2] - gxs[2]) * gxm[1] + (m[1] - gxs[1])) * gxm[0] + (m[0] - gxs[0]);
}

/// The first basis function per direction of the element that basis values bv were evaluated in.
inline void first_functions(const geometry::Patch& patch, const BasisValues& bv, int first[3]) {
  for (int d = 0; d < 3; ++d) first[d] = d < patch.param_dim() ? bv.span[d] - patch.degree(d) : 0;
}

/// Calls f(k, node) for each of the (p+1)^d functions of the element whose first functions are `first`: k in
/// basis order (direction 0 fastest), node its local (ghosted) offset.
template <class F>
void for_each_element_node(const geometry::Patch& patch, const int first[3], const PetscInt gxs[3],
                           const PetscInt gxm[3], F&& f) {
  int np[3] = {1, 1, 1};
  for (int d = 0; d < patch.param_dim(); ++d) np[d] = patch.degree(d) + 1;
  int k = 0;
  for (int c2 = 0; c2 < np[2]; ++c2)
    for (int b1 = 0; b1 < np[1]; ++b1)
      for (int a0 = 0; a0 < np[0]; ++a0, ++k) {
        const PetscInt m[3] = {first[0] + a0, first[1] + b1, first[2] + c2};
        f(k, local_node(m, gxs, gxm));
      }
}

/// Point samples from per-rank buffers (per point: found, v[3], grad v[9], vdot[3], and p when stride is 17).
/// Every point is found by exactly one rank (the owner of its element): a sum gathers them on every rank.
std::vector<PointSample> gather_samples(MPI_Comm comm, const std::vector<double>& buf, int stride) {
  std::vector<double> all(buf.size());
  CELLFSI_PETSC(
      MPI_Allreduce(buf.data(), all.data(), static_cast<int>(buf.size()), MPI_DOUBLE, MPI_SUM, comm));
  std::vector<PointSample> out(buf.size() / stride);
  for (size_t i = 0; i < out.size(); ++i) {
    const double* o = &all[i * stride];
    PointSample& s = out[i];
    s.found = o[0] > 0.5;
    for (int c = 0; c < 3; ++c) {
      s.v[c] = o[1 + c];
      s.vdot[c] = o[13 + c];
      for (int j = 0; j < 3; ++j) s.grad_v(c, j) = o[4 + 3 * c + j];
    }
    if (stride > 16) s.p = o[16];
  }
  return out;
}

/// The fields at a point from the element's nodal values (Vf, Vd interleaved by node, dof D + 1; S), for
/// FluidSolver::assemble. D is a template parameter so that the small loops unroll and the sums stay in
/// registers.
template <int D>
void point_fields(const PointBasis& b, const double* Vf, const double* Vd, const double* S,
                  const std::array<std::array<double, 3>, 3>& G, PointFields& pf) {
  constexpr int nd = D + 1;
  double s = 0, v[D] = {}, vdot[D] = {}, lap_v[D] = {}, dv[D][D] = {}, p = 0, dp[D] = {};
  if constexpr (D == 2) {
    // The same sums two at a time: lanes (x, y) of v, vdot, lap_v, the columns of dv and dp, and (p, s).
    typedef double Pair __attribute__((vector_size(16)));
    typedef double PairU __attribute__((vector_size(16), aligned(8), may_alias));
    Pair v2{}, vdot2{}, lap2{}, dvx{}, dvy{}, dp2{}, ps{};
    for (int k = 0; k < b.n; ++k) {
      const double N = b.N[k], lapN = b.lapN[k], pk = Vf[k * nd + D];
      const Pair Nk{N, N}, vk = *reinterpret_cast<const PairU*>(Vf + k * nd);
      const Pair dNk = *reinterpret_cast<const PairU*>(b.dN + 3 * k);
      v2 += Nk * vk;
      vdot2 += Nk * *reinterpret_cast<const PairU*>(Vd + k * nd);
      lap2 += Pair{lapN, lapN} * vk;
      dvx += Pair{dNk[0], dNk[0]} * vk;
      dvy += Pair{dNk[1], dNk[1]} * vk;
      dp2 += dNk * Pair{pk, pk};
      ps += Nk * Pair{pk, S[k]};
    }
    for (int i = 0; i < 2; ++i) {
      v[i] = v2[i];
      vdot[i] = vdot2[i];
      lap_v[i] = lap2[i];
      dv[i][0] = dvx[i];
      dv[i][1] = dvy[i];
      dp[i] = dp2[i];
    }
    p = ps[0];
    s = ps[1];
  } else {
    for (int k = 0; k < b.n; ++k) {
      const double N = b.N[k], lapN = b.lapN[k];
      const double* dN = b.dN + 3 * k;
      s += N * S[k];
      for (int i = 0; i < D; ++i) {
        const double vk = Vf[k * nd + i];
        v[i] += N * vk;
        vdot[i] += N * Vd[k * nd + i];
        lap_v[i] += lapN * vk;
        for (int j = 0; j < D; ++j) dv[i][j] += dN[j] * vk;
      }
      const double pk = Vf[k * nd + D];
      p += N * pk;
      for (int j = 0; j < D; ++j) dp[j] += dN[j] * pk;
    }
  }
  // Every member assigned (no zero-fill of the whole struct first).
  pf.s = s;
  pf.p = p;
  for (int i = 0; i < 3; ++i) {
    pf.v[i] = i < D ? v[i] : 0.0;
    pf.vdot[i] = i < D ? vdot[i] : 0.0;
    pf.lap_v[i] = i < D ? lap_v[i] : 0.0;
    pf.dp[i] = i < D ? dp[i] : 0.0;
    for (int j = 0; j < 3; ++j) pf.dv[i][j] = i < D && j < D ? dv[i][j] : 0.0;
  }
  pf.G = G;
}

/// The element matrix of vms_tangent_element_blocks (n x n column-major blocks of bs x bs) in the row-major
/// layout of vms_tangent_element and MatSetValuesBlocked: K[(A bs + c) n bs + B bs + e] = Kb[(A n + B) bs^2 +
/// e bs + c].
void rows_from_blocks(int n, int bs, const double* Kb, double* K) {
  const std::size_t ld = static_cast<std::size_t>(n) * bs, bs2 = static_cast<std::size_t>(bs) * bs;
  for (int A = 0; A < n; ++A)
    for (int B = 0; B < n; ++B) {
      const double* kb = Kb + (static_cast<std::size_t>(A) * n + B) * bs2;
      double* k = K + static_cast<std::size_t>(A) * bs * ld + static_cast<std::size_t>(B) * bs;
      for (int c = 0; c < bs; ++c)
        for (int e = 0; e < bs; ++e) k[c * ld + e] = kb[e * bs + c];
    }
}

/// Adds element node blocks straight into the value array of a sequential BAIJ matrix of block size dof (the
/// one-rank Jacobian), as MatSetValuesBlockedLocal(ADD_VALUES) would, without its per-block searches: the
/// element's column blocks are sorted once and located in each of its block rows (sorted in ja) by one merge.
/// Not usable (usable() false) for any other matrix: MPI, AIJ, another block size, no local-to-global map.
class SeqBaijInserter {
 public:
  SeqBaijInserter(Mat J, int bs) : J_(J), bs_(bs) {
    if (!J) return;
    PetscBool seqbaij = PETSC_FALSE;
    CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(J), MATSEQBAIJ, &seqbaij));
    PetscInt mbs = 0;
    CELLFSI_PETSC(MatGetBlockSize(J, &mbs));
    if (!seqbaij || mbs != bs) return;
    ISLocalToGlobalMapping rmap = nullptr, cmap = nullptr;
    CELLFSI_PETSC(MatGetLocalToGlobalMapping(J, &rmap, &cmap));
    if (!rmap || rmap != cmap) return;
    PetscInt lbs = 0;
    CELLFSI_PETSC(ISLocalToGlobalMappingGetBlockSize(rmap, &lbs));
    if (lbs != bs) return;
    PetscBool done = PETSC_FALSE;
    PetscInt nrows = 0;
    CELLFSI_PETSC(MatGetRowIJ(J, 0, PETSC_FALSE, PETSC_TRUE, &nrows, &ia_, &ja_, &done));
    if (!done) return;
    got_ij_ = true;
    map_ = rmap;
    CELLFSI_PETSC(ISLocalToGlobalMappingGetBlockIndices(map_, &global_));
    CELLFSI_PETSC(MatSeqBAIJGetArray(J, &a_));
  }
  SeqBaijInserter(const SeqBaijInserter&) = delete;
  SeqBaijInserter& operator=(const SeqBaijInserter&) = delete;
  ~SeqBaijInserter() {
    try {
      finish();
    } catch (...) {
    }
  }
  bool usable() const { return a_ != nullptr; }

  /// Finds the blocks of the element with local nodes lnode in the matrix. Returns false if one is not in the
  /// matrix's nonzero pattern. (Prefetching them here, before the element matrix is formed, measured no
  /// gain.)
  bool prepare(int n, const PetscInt* lnode) {
    located_ = locate(n, lnode);
    return located_;
  }

  /// Adds the (n bs) x (n bs) row-major element matrix K over the nodes given to prepare. Returns false,
  /// having added nothing, if prepare failed.
  bool add(int n, const double* K) {
    if (!located_) return false;
    switch (bs_) {
      case 3:
        add_blocks<3>(n, K);
        break;
      case 4:
        add_blocks<4>(n, K);
        break;
      default:
        add_blocks<0>(n, K);
        break;
    }
    return true;
  }

  /// Adds the element matrix in vms_tangent_element_blocks' layout (the matrix's own block layout) over the
  /// nodes given to prepare, which must have succeeded.
  void add_blocks(int n, const double* Kb) {
    if (bs_ == 3)
      add_node_blocks<3>(n, Kb);
    else if (bs_ == 4)
      add_node_blocks<4>(n, Kb);
    else
      add_node_blocks<0>(n, Kb);
  }

  /// Gives the arrays back to the matrix (before MatAssemblyBegin or any MatSetValues).
  void finish() {
    if (a_) {
      double* a = a_;
      a_ = nullptr;
      CELLFSI_PETSC(MatSeqBAIJRestoreArray(J_, &a));
    }
    if (global_) {
      const PetscInt* g = global_;
      global_ = nullptr;
      CELLFSI_PETSC(ISLocalToGlobalMappingRestoreBlockIndices(map_, &g));
    }
    if (got_ij_) {
      got_ij_ = false;
      PetscBool done = PETSC_FALSE;
      PetscInt nrows = 0;
      CELLFSI_PETSC(MatRestoreRowIJ(J_, 0, PETSC_FALSE, PETSC_TRUE, &nrows, &ia_, &ja_, &done));
    }
  }

 private:
  Mat J_;
  int bs_;
  const PetscInt *ia_ = nullptr, *ja_ = nullptr, *global_ = nullptr;
  ISLocalToGlobalMapping map_ = nullptr;
  bool got_ij_ = false;
  double* a_ = nullptr;
  bool located_ = false;
  std::vector<PetscInt> offset_;                   // pos_ - the row's start, kept from the previous element
  std::vector<PetscInt> pos_;                      // pos_[A n + B]: block index of (A, B) in a_
  std::vector<std::pair<PetscInt, int>> columns_;  // (global block column, B), sorted

  // Row by row. A block is usually where it was in the previous element, relative to its row's start (the
  // same stencil around the row's node, the same displacement between the nodes): tried first. Otherwise the
  // element's columns are sorted (insertion sort: few, mostly in order already) and found by one pass over
  // the row, where the next sorted column is usually the next entry (runs of consecutive nodes) or else
  // searched.
  bool locate(int n, const PetscInt* lnode) {
    columns_.clear();
    const std::size_t nn = static_cast<std::size_t>(n) * n;
    pos_.resize(nn);
    if (offset_.size() != nn) offset_.assign(nn, -1);
    for (int A = 0; A < n; ++A) {
      const PetscInt r = global_[lnode[A]], lo = ia_[r], hi = ia_[r + 1];
      PetscInt* pa = pos_.data() + static_cast<std::size_t>(A) * n;
      PetscInt* oa = offset_.data() + static_cast<std::size_t>(A) * n;
      bool same = true;
      for (int B = 0; B < n && same; ++B) {
        const PetscInt k = lo + oa[B];
        same = oa[B] >= 0 && k < hi && ja_[k] == global_[lnode[B]];
        pa[B] = k;
      }
      if (same) continue;
      if (columns_.empty()) {
        columns_.resize(n);
        for (int B = 0; B < n; ++B) {
          const std::pair<PetscInt, int> c{global_[lnode[B]], B};
          int i = B;
          for (; i > 0 && columns_[i - 1] > c; --i) columns_[i] = columns_[i - 1];
          columns_[i] = c;
        }
      }
      PetscInt k = lo, found = -1, previous = -1;
      for (const auto& [g, B] : columns_) {
        if (g != previous) {  // (a node twice in the element: a periodic direction shorter than it)
          if (k == hi || ja_[k] != g) k = std::lower_bound(ja_ + k, ja_ + hi, g) - ja_;
          if (k == hi || ja_[k] != g) return false;
          found = k++;
          previous = g;
        }
        pa[B] = found;
        oa[B] = found - lo;
      }
    }
    return true;
  }

  template <int BS>
  void add_node_blocks(int n, const double* Kb) {
    const int bs2 = BS > 0 ? BS * BS : bs_ * bs_;
    // Two doubles at a time (the compiler kept this scalar).
    typedef double Pair __attribute__((vector_size(16), aligned(8), may_alias));
    for (std::size_t k = 0; k < static_cast<std::size_t>(n) * n; ++k) {
      double* blk = a_ + pos_[k] * bs2;
      const double* kb = Kb + k * bs2;
      int i = 0;
      for (; i + 2 <= bs2; i += 2)
        *reinterpret_cast<Pair*>(blk + i) += *reinterpret_cast<const Pair*>(kb + i);
      if (i < bs2) blk[i] += kb[i];
    }
  }

  // SeqBAIJ blocks are column-major: entry (c, e) of block k is a_[k bs^2 + e bs + c].
  template <int BS>
  void add_blocks(int n, const double* K) {
    const int bs = BS > 0 ? BS : bs_, bs2 = bs * bs;
    const std::size_t ld = static_cast<std::size_t>(n) * bs;
    for (int A = 0; A < n; ++A)
      for (int B = 0; B < n; ++B) {
        double* blk = a_ + pos_[static_cast<std::size_t>(A) * n + B] * bs2;
        const double* k = K + static_cast<std::size_t>(A) * bs * ld + static_cast<std::size_t>(B) * bs;
        for (int e = 0; e < bs; ++e)
          for (int c = 0; c < bs; ++c) blk[e * bs + c] += k[c * ld + e];
      }
  }
};

}  // namespace

void FluidSolver::assemble(Vec U, Vec F, Mat J, const std::vector<char>* in_band, bool band_side) {
  const int D = dim_, nd = dof_;
  const double af = alpha_.alpha_f, am = alpha_.alpha_m, gm = alpha_.gamma, dt = opt_.dt;
  VmsParameters prm;
  prm.dim = D;
  prm.nu = opt_.viscosity / opt_.density;
  for (int c = 0; c < 3; ++c) prm.g[c] = opt_.body_force[c] / opt_.density;
  prm.dt = dt;
  prm.c_i = opt_.c_i;
  prm.stokes = opt_.stokes;
  const TangentScales ts{af, am / (gm * dt), 1.0};

  Vec U_loc, F_loc = nullptr;
  CELLFSI_PETSC(DMGetLocalVector(da_, &U_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_, U, INSERT_VALUES, U_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_scalar_, S_, INSERT_VALUES, S_loc_));
  const PetscScalar *u, *un, *udn, *sh;
  PetscScalar* f = nullptr;
  CELLFSI_PETSC(VecGetArrayRead(U_loc, &u));
  CELLFSI_PETSC(VecGetArrayRead(Un_loc_, &un));
  CELLFSI_PETSC(VecGetArrayRead(Udotn_loc_, &udn));
  CELLFSI_PETSC(VecGetArrayRead(S_loc_, &sh));
  if (F) {
    CELLFSI_PETSC(DMGetLocalVector(da_, &F_loc));
    CELLFSI_PETSC(VecSet(F_loc, 0.0));
    CELLFSI_PETSC(VecGetArray(F_loc, &f));
  }
  if (J) {
    // Dirichlet rows are zeroed after assembly; keeping their pattern lets the matrix be assembled again.
    CELLFSI_PETSC(MatSetOption(J, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));
    CELLFSI_PETSC(MatZeroEntries(J));
  }

  SeqBaijInserter direct(J, nd);  // usable only for a one-rank BAIJ Jacobian

  BasisValues bv;
  MapValues mv;
  PhysicalPoint pp;
  ElementValues scratch;
  std::vector<double> Re, Ke, Kb, Vf, Vd, S;
  std::vector<PetscInt> lidx, lnode;

  // Gathers the element's nodal fields at the alpha levels: Vf = velocity at n+alpha_f and pressure at n+1,
  // Vd = velocity rate at n+alpha_m, S = s^h; lnode = local node indices, lidx = local dof indices.
  auto gather = [&](const int first[3]) {
    int np[3] = {1, 1, 1};
    for (int d = 0; d < D; ++d) np[d] = patch_.degree(d) + 1;
    const int n = np[0] * np[1] * np[2];
    Vf.assign(n * nd, 0.0);
    Vd.assign(n * nd, 0.0);
    S.assign(n, 1.0);
    lidx.resize(n * nd);
    lnode.resize(n);
    for_each_element_node(patch_, first, gxs_, gxm_, [&](int k, PetscInt node) {
      lnode[k] = node;
      S[k] = sh[node];
      for (int c = 0; c < nd; ++c) {
        const PetscInt li = node * nd + c;
        lidx[k * nd + c] = li;
        const double x1 = u[li], x0 = un[li], xd0 = udn[li];
        const double xd1 = (x1 - x0) / (gm * dt) - (1.0 - gm) / gm * xd0;
        if (c < D) {
          Vf[k * nd + c] = x0 + af * (x1 - x0);
          Vd[k * nd + c] = xd0 + am * (xd1 - xd0);
        } else {
          Vf[k * nd + c] = x1;
        }
      }
    });
    return n;
  };

  auto fields = [&](const PointBasis& b, const std::array<std::array<double, 3>, 3>& G, PointFields& pf) {
    if (D == 2)
      point_fields<2>(b, Vf.data(), Vd.data(), S.data(), G, pf);
    else
      point_fields<3>(b, Vf.data(), Vd.data(), S.data(), G, pf);
  };

  auto scatter = [&](int n, bool matrix_done) {
    if (F)
      for (int r = 0; r < n * nd; ++r) f[lidx[r]] += Re[r];
    if (!J || matrix_done) return;
    // Straight into the value array of a one-rank BAIJ matrix; a block outside its pattern (never on the
    // DMDA's box stencil) hands the matrix back and switches to PETSc's insertion for the rest of the
    // assembly.
    if (direct.usable()) {
      if (direct.add(n, Ke.data())) return;
      direct.finish();
    }
    // Node blocks (the DMDA matrix has block size dof): one index per node instead of per unknown.
    CELLFSI_PETSC(MatSetValuesBlockedLocal(J, n, lnode.data(), n, lnode.data(), Ke.data(), ADD_VALUES));
  };

  PointFields pf;
  std::vector<PointFields> point_fields;
  if (in_band && static_cast<int>(in_band->size()) != patch_.n_elements())
    throw std::invalid_argument("FluidSolver: the element mask has " + std::to_string(in_band->size()) +
                                " entries for " + std::to_string(patch_.n_elements()) + " elements");
  const int ne0 = patch_.n_elements(0), ne1 = patch_.n_elements(1);
  for (const Index3& e : owned_elements()) {
    if (in_band && ((*in_band)[e[0] + ne0 * (e[1] + ne1 * e[2])] != 0) != band_side) continue;
    int first[3];
    const ElementValues& ev = element_basis_.evaluate(e, scratch, first);
    const int n = gather(first);
    // On a one-rank BAIJ matrix the tangent is formed in its block layout and added straight into it.
    const bool blocks = J && direct.usable() && direct.prepare(n, lnode.data());
    // Axis-affine patches (2D): the tangent's products are sum-factorised over the basis' univariate factors.
    const bool tensor = ev.tensor && D == 2;
    Re.assign(n * nd, 0.0);
    if (J) {
      if (blocks || tensor)
        Ke.resize(static_cast<size_t>(n * nd) * n * nd);  // overwritten
      else
        Ke.assign(static_cast<size_t>(n * nd) * n * nd, 0.0);
    }
    point_fields.resize(ev.nq);
    for (int q = 0; q < ev.nq; ++q) {
      const PointBasis pb{n, &ev.N[static_cast<size_t>(q) * n], &ev.dN[static_cast<size_t>(q) * n * 3],
                          &ev.lapN[static_cast<size_t>(q) * n]};
      fields(pb, ev.G[q], point_fields[q]);
      if (F) vms_residual(prm, pb, point_fields[q], ev.weight[q], Re.data());
    }
    // The element tangent at once: small matrix products over the quadrature points (same result as summing
    // vms_tangent over them, to round-off; tested).
    if (J) {
      const ElementPoints points{
          n, ev.nq, ev.N.data(), ev.dN.data(), ev.lapN.data(), ev.weight.data(), point_fields.data()};
      if (blocks || tensor) {
        TensorFactors tf;
        for (int d = 0; d < 3; ++d) {
          tf.np[d] = ev.np[d];
          tf.nq[d] = ev.nq1[d];
          tf.value[d] = ev.factor_value[d].data();
          tf.deriv[d] = ev.factor_deriv[d].data();
        }
        if (blocks) {
          vms_tangent_element_blocks(prm, points, ts, Ke.data(), tensor ? &tf : nullptr);
          direct.add_blocks(n, Ke.data());
        } else {  // for MatSetValuesBlockedLocal: the blocks' rows side by side
          Kb.resize(Ke.size());
          vms_tangent_element_blocks(prm, points, ts, Kb.data(), &tf);
          rows_from_blocks(n, nd, Kb.data(), Ke.data());
        }
      } else {
        vms_tangent_element(prm, points, ts, Ke.data());
      }
    }
    scatter(n, blocks);
  }

  // Immersed-solid points (paper Eq. (10)) in this rank's elements.
  static const PetscLogEvent immersed_event = register_log_event("cellfsi fluid", "FluidImmersed");
  CELLFSI_PETSC(PetscLogEventBegin(immersed_event, 0, 0, 0, 0));
  for (const LocatedPoint& ip : immersed_) {
    if (in_band && !band_side) break;
    physical_point(patch_, ip.element, ip.xi, bv, mv, pp);
    int first[3];
    first_functions(patch_, bv, first);
    const int n = gather(first);
    if (direct.usable()) direct.prepare(n, lnode.data());
    Re.assign(n * nd, 0.0);
    if (J) Ke.assign(static_cast<size_t>(n * nd) * n * nd, 0.0);
    const PointBasis pb{pp.n, pp.N.data(), pp.dN.data(), pp.lapN.data()};
    fields(pb, pp.G, pf);
    if (F) immersed_residual(prm, pb, pf, ip.data, Re.data());
    if (J) immersed_tangent(prm, pb, pf, ts, ip.data, Ke.data());
    scatter(n, false);
  }
  CELLFSI_PETSC(PetscLogEventEnd(immersed_event, 0, 0, 0, 0));

  CELLFSI_PETSC(VecRestoreArrayRead(U_loc, &u));
  CELLFSI_PETSC(VecRestoreArrayRead(Un_loc_, &un));
  CELLFSI_PETSC(VecRestoreArrayRead(Udotn_loc_, &udn));
  CELLFSI_PETSC(VecRestoreArrayRead(S_loc_, &sh));
  CELLFSI_PETSC(DMRestoreLocalVector(da_, &U_loc));

  const std::vector<PetscInt> rows = dirichlet_rows();
  if (F) {
    CELLFSI_PETSC(VecRestoreArray(F_loc, &f));
    CELLFSI_PETSC(VecSet(F, 0.0));
    CELLFSI_PETSC(DMLocalToGlobal(da_, F_loc, ADD_VALUES, F));
    CELLFSI_PETSC(DMRestoreLocalVector(da_, &F_loc));
    // Dirichlet rows: F = U - U_D, with U_D the values apply_dirichlet_values sets.
    Vec UD;
    CELLFSI_PETSC(VecDuplicate(U, &UD));
    CELLFSI_PETSC(VecCopy(U, UD));
    apply_dirichlet_values(UD, time_ + opt_.dt);
    PetscInt lo = 0;
    CELLFSI_PETSC(VecGetOwnershipRange(F, &lo, nullptr));
    PetscScalar* fa;
    const PetscScalar *ua, *uda;
    CELLFSI_PETSC(VecGetArray(F, &fa));
    CELLFSI_PETSC(VecGetArrayRead(U, &ua));
    CELLFSI_PETSC(VecGetArrayRead(UD, &uda));
    for (PetscInt r : rows) fa[r - lo] = ua[r - lo] - uda[r - lo];
    CELLFSI_PETSC(VecRestoreArray(F, &fa));
    CELLFSI_PETSC(VecRestoreArrayRead(U, &ua));
    CELLFSI_PETSC(VecRestoreArrayRead(UD, &uda));
    CELLFSI_PETSC(VecDestroy(&UD));
  }
  if (J) {
    direct.finish();
    CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
    const double diagonal = in_band && band_side ? 0.0 : 1.0;
    CELLFSI_PETSC(
        MatZeroRows(J, static_cast<PetscInt>(rows.size()), rows.data(), diagonal, nullptr, nullptr));
  }
}

PetscErrorCode fluid_residual(SNES, Vec U, Vec F, void* ctx) {
  PetscFunctionBeginUser;
  try {
    static_cast<FluidSolver*>(ctx)->assemble(U, F, nullptr);
  } catch (const std::exception& e) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "%s", e.what());
  }
  PetscFunctionReturn(0);
}

PetscErrorCode fluid_jacobian(SNES, Vec U, Mat J, Mat, void* ctx) {
  PetscFunctionBeginUser;
  try {
    static_cast<FluidSolver*>(ctx)->assemble(U, nullptr, J);
  } catch (const std::exception& e) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "%s", e.what());
  }
  PetscFunctionReturn(0);
}

void FluidSolver::evaluate_residual(Vec U, Vec F) {
  CELLFSI_PETSC(DMGlobalToLocal(da_, U_, INSERT_VALUES, Un_loc_));
  CELLFSI_PETSC(DMGlobalToLocal(da_, Udot_, INSERT_VALUES, Udotn_loc_));
  assemble(U, F, nullptr);
}

void FluidSolver::evaluate_jacobian(Vec U, Mat J) {
  CELLFSI_PETSC(DMGlobalToLocal(da_, U_, INSERT_VALUES, Un_loc_));
  CELLFSI_PETSC(DMGlobalToLocal(da_, Udot_, INSERT_VALUES, Udotn_loc_));
  assemble(U, nullptr, J);
}

// ---------------------------------------------------------------------------------------------------------------
// Time step

void FluidSolver::setup() {
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

StepStats FluidSolver::step() {
  StepStats st;
  CELLFSI_PETSC(DMGlobalToLocal(da_, U_, INSERT_VALUES, Un_loc_));
  CELLFSI_PETSC(DMGlobalToLocal(da_, Udot_, INSERT_VALUES, Udotn_loc_));
  Vec X;
  CELLFSI_PETSC(VecDuplicate(U_, &X));
  CELLFSI_PETSC(VecCopy(U_, X));  // predictor: same state
  apply_dirichlet_values(X, time_ + opt_.dt);
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
  if (st.converged) {
    // Udot_{n+1} = (U_{n+1} - U_n) / (gamma dt) - (1 - gamma) / gamma Udot_n
    const double gm = alpha_.gamma;
    CELLFSI_PETSC(VecAXPBYPCZ(Udot_, 1.0 / (gm * opt_.dt), -1.0 / (gm * opt_.dt), -(1.0 - gm) / gm, X, U_));
    CELLFSI_PETSC(VecCopy(X, U_));
    ++steps_;
    time_ = steps_ * opt_.dt;  // not accumulated: t_k = k dt exactly as written in outputs
  }
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
  const double gm = alpha_.gamma;
  CELLFSI_PETSC(VecAXPBYPCZ(Udot_, 1.0 / (gm * opt_.dt), -1.0 / (gm * opt_.dt), -(1.0 - gm) / gm, X, U_));
  CELLFSI_PETSC(VecCopy(X, U_));
  ++steps_;
  time_ = steps_ * opt_.dt;
}

void FluidSolver::restore(Vec U, Vec Udot, int steps) {
  if (steps < 0) throw std::invalid_argument("FluidSolver::restore: steps must be >= 0");
  CELLFSI_PETSC(VecCopy(U, U_));
  CELLFSI_PETSC(VecCopy(Udot, Udot_));
  steps_ = steps;
  time_ = steps_ * opt_.dt;
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
  for (size_t i = 0; i < data.size(); ++i)
    if (owns_element(elements[i])) immersed_.push_back({elements[i], xi[i], data[i]});
}

std::vector<PointSample> FluidSolver::sample_alpha(Vec X, const std::vector<Index3>& elements,
                                                   const std::vector<Param>& xi) const {
  const int D = dim_, nd = dof_;
  const double af = alpha_.alpha_f, am = alpha_.alpha_m, gm = alpha_.gamma, dt = opt_.dt;
  const int stride = 1 + 3 + 9 + 3;
  std::vector<double> buf(xi.size() * stride, 0.0);
  Vec X_loc;
  CELLFSI_PETSC(DMGetLocalVector(da_, &X_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_, X, INSERT_VALUES, X_loc));
  const PetscScalar *x, *un, *udn;
  CELLFSI_PETSC(VecGetArrayRead(X_loc, &x));
  CELLFSI_PETSC(VecGetArrayRead(Un_loc_, &un));
  CELLFSI_PETSC(VecGetArrayRead(Udotn_loc_, &udn));
  BasisValues bv;
  MapValues mv;
  PhysicalPoint pp;
  for (size_t i = 0; i < xi.size(); ++i) {
    if (!owns_element(elements[i])) continue;
    physical_point(patch_, elements[i], xi[i], bv, mv, pp);
    double* o = &buf[i * stride];
    o[0] = 1.0;
    int first[3];
    first_functions(patch_, bv, first);
    for_each_element_node(patch_, first, gxs_, gxm_, [&](int k, PetscInt node) {
      for (int c = 0; c < D; ++c) {
        const PetscInt li = node * nd + c;
        const double vf = un[li] + af * (x[li] - un[li]);
        const double rate1 = (x[li] - un[li]) / (gm * dt) - (1.0 - gm) / gm * udn[li];
        const double rm = udn[li] + am * (rate1 - udn[li]);
        o[1 + c] += pp.N[k] * vf;
        for (int j = 0; j < D; ++j) o[4 + 3 * c + j] += pp.dN[3 * k + j] * vf;
        o[13 + c] += pp.N[k] * rm;
      }
    });
  }
  CELLFSI_PETSC(VecRestoreArrayRead(X_loc, &x));
  CELLFSI_PETSC(VecRestoreArrayRead(Un_loc_, &un));
  CELLFSI_PETSC(VecRestoreArrayRead(Udotn_loc_, &udn));
  CELLFSI_PETSC(DMRestoreLocalVector(da_, &X_loc));
  return gather_samples(comm_, buf, stride);
}

// ---------------------------------------------------------------------------------------------------------------
// L2 projection of initial data and L2 errors

void FluidSolver::project_initial_state(const std::function<Vec3(const Vec3&)>& v0,
                                        const std::function<Vec3(const Vec3&)>& vdot0) {
  const int D = dim_;
  Mat M;
  CELLFSI_PETSC(DMCreateMatrix(da_scalar_, &M));
  std::vector<Vec> rhs(2 * D);
  for (auto& b : rhs) CELLFSI_PETSC(DMCreateGlobalVector(da_scalar_, &b));
  std::vector<Vec> rhs_loc(2 * D);
  for (int c = 0; c < 2 * D; ++c) {
    CELLFSI_PETSC(DMCreateLocalVector(da_scalar_, &rhs_loc[c]));
    CELLFSI_PETSC(VecSet(rhs_loc[c], 0.0));
  }
  std::vector<PetscScalar*> r(2 * D);
  for (int c = 0; c < 2 * D; ++c) CELLFSI_PETSC(VecGetArray(rhs_loc[c], &r[c]));
  const Index3 ng = geometry::default_gauss(patch_, 2);
  std::vector<geometry::QuadraturePoint> qp;
  BasisValues bv;
  MapValues mv;
  std::vector<PetscInt> lidx;
  std::vector<double> Me;
  for (const Index3& e : owned_elements()) {
    geometry::element_quadrature(patch_, e, ng, qp);
    bool first_point = true;
    for (const auto& q : qp) {
      patch_.basis(q.xi, 1, bv, &e);
      patch_.map(bv, mv);
      const double w = q.weight * std::abs(mv.dx.topLeftCorner(D, D).determinant());
      const int n = bv.n;
      if (first_point) {
        lidx.resize(n);
        int first[3];
        first_functions(patch_, bv, first);
        for_each_element_node(patch_, first, gxs_, gxm_, [&](int k, PetscInt node) { lidx[k] = node; });
        Me.assign(n * n, 0.0);
        first_point = false;
      }
      const Vec3 f0 = v0(mv.x), f1 = vdot0(mv.x);
      for (int a = 0; a < n; ++a) {
        for (int c = 0; c < D; ++c) {
          r[c][lidx[a]] += w * bv.value[a] * f0[c];
          r[D + c][lidx[a]] += w * bv.value[a] * f1[c];
        }
        for (int b = 0; b < n; ++b) Me[a * n + b] += w * bv.value[a] * bv.value[b];
      }
    }
    CELLFSI_PETSC(MatSetValuesLocal(M, static_cast<PetscInt>(lidx.size()), lidx.data(),
                                    static_cast<PetscInt>(lidx.size()), lidx.data(), Me.data(), ADD_VALUES));
  }
  CELLFSI_PETSC(MatAssemblyBegin(M, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(M, MAT_FINAL_ASSEMBLY));
  for (int c = 0; c < 2 * D; ++c) {
    CELLFSI_PETSC(VecRestoreArray(rhs_loc[c], &r[c]));
    CELLFSI_PETSC(VecSet(rhs[c], 0.0));
    CELLFSI_PETSC(DMLocalToGlobal(da_scalar_, rhs_loc[c], ADD_VALUES, rhs[c]));
  }
  KSP ksp;
  CELLFSI_PETSC(KSPCreate(comm_, &ksp));
  CELLFSI_PETSC(KSPSetOptionsPrefix(ksp, "fluid_projection_"));
  CELLFSI_PETSC(KSPSetOperators(ksp, M, M));
  CELLFSI_PETSC(KSPSetType(ksp, KSPCG));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, PCJACOBI));
  CELLFSI_PETSC(KSPSetTolerances(ksp, 1e-14, 1e-30, PETSC_DEFAULT, 2000));
  CELLFSI_PETSC(KSPSetFromOptions(ksp));
  Vec x;
  CELLFSI_PETSC(VecDuplicate(rhs[0], &x));
  for (int c = 0; c < 2 * D; ++c) {
    CELLFSI_PETSC(KSPSolve(ksp, rhs[c], x));
    KSPConvergedReason reason;
    CELLFSI_PETSC(KSPGetConvergedReason(ksp, &reason));
    if (reason < 0) throw std::runtime_error("L2 projection of the initial state did not converge");
    CELLFSI_PETSC(VecStrideScatter(x, c % D, c < D ? U_ : Udot_, INSERT_VALUES));
  }
  CELLFSI_PETSC(VecStrideSet(U_, D, 0.0));
  CELLFSI_PETSC(VecStrideSet(Udot_, D, 0.0));
  apply_dirichlet_values(U_, time_);
  CELLFSI_PETSC(VecDestroy(&x));
  CELLFSI_PETSC(KSPDestroy(&ksp));
  for (int c = 0; c < 2 * D; ++c) {
    CELLFSI_PETSC(VecDestroy(&rhs[c]));
    CELLFSI_PETSC(VecDestroy(&rhs_loc[c]));
  }
  CELLFSI_PETSC(MatDestroy(&M));
}

FluidSolver::L2Error FluidSolver::velocity_l2_error(const std::function<Vec3(const Vec3&)>& v_exact) const {
  const int D = dim_, nd = dof_;
  Vec U_loc;
  CELLFSI_PETSC(DMGetLocalVector(da_, &U_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_, U_, INSERT_VALUES, U_loc));
  const PetscScalar* u;
  CELLFSI_PETSC(VecGetArrayRead(U_loc, &u));
  const Index3 ng = geometry::default_gauss(patch_, 3);
  std::vector<geometry::QuadraturePoint> qp;
  BasisValues bv;
  MapValues mv;
  double sums[2] = {0, 0};
  for (const Index3& e : owned_elements()) {
    geometry::element_quadrature(patch_, e, ng, qp);
    for (const auto& q : qp) {
      patch_.basis(q.xi, 1, bv, &e);
      patch_.map(bv, mv);
      const double w = q.weight * std::abs(mv.dx.topLeftCorner(D, D).determinant());
      int first[3];
      first_functions(patch_, bv, first);
      Vec3 vh = Vec3::Zero();
      for_each_element_node(patch_, first, gxs_, gxm_, [&](int k, PetscInt node) {
        for (int c = 0; c < D; ++c) vh[c] += bv.value[k] * u[node * nd + c];
      });
      const Vec3 ve = v_exact(mv.x);
      sums[0] += w * (vh - ve).squaredNorm();
      sums[1] += w * ve.squaredNorm();
    }
  }
  CELLFSI_PETSC(VecRestoreArrayRead(U_loc, &u));
  CELLFSI_PETSC(DMRestoreLocalVector(da_, &U_loc));
  double all[2];
  CELLFSI_PETSC(MPI_Allreduce(sums, all, 2, MPI_DOUBLE, MPI_SUM, comm_));
  return {std::sqrt(all[0]), std::sqrt(all[1])};
}

// ---------------------------------------------------------------------------------------------------------------
// Sampling and gathering

std::vector<PointSample> FluidSolver::sample(const std::vector<Vec3>& points) const {
  const int D = dim_, nd = dof_;
  const int stride = 1 + 3 + 9 + 3 + 1;
  std::vector<double> buf(points.size() * stride, 0.0);
  Vec U_loc, Ud_loc;
  CELLFSI_PETSC(DMGetLocalVector(da_, &U_loc));
  CELLFSI_PETSC(DMGetLocalVector(da_, &Ud_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_, U_, INSERT_VALUES, U_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_, Udot_, INSERT_VALUES, Ud_loc));
  const PetscScalar *u, *ud;
  CELLFSI_PETSC(VecGetArrayRead(U_loc, &u));
  CELLFSI_PETSC(VecGetArrayRead(Ud_loc, &ud));
  BasisValues bv;
  MapValues mv;
  PhysicalPoint pp;
  for (size_t i = 0; i < points.size(); ++i) {
    const geometry::InversionResult r = inverter_.invert(points[i]);
    if (!r.inside || !owns_element(r.element)) continue;
    physical_point(patch_, r.element, r.xi, bv, mv, pp);
    double* o = &buf[i * stride];
    o[0] = 1.0;
    int first[3];
    first_functions(patch_, bv, first);
    for_each_element_node(patch_, first, gxs_, gxm_, [&](int k, PetscInt node) {
      for (int c = 0; c < D; ++c) {
        const double val = u[node * nd + c];
        o[1 + c] += pp.N[k] * val;
        for (int j = 0; j < D; ++j) o[4 + 3 * c + j] += pp.dN[3 * k + j] * val;
        o[13 + c] += pp.N[k] * ud[node * nd + c];
      }
      o[16] += pp.N[k] * u[node * nd + D];
    });
  }
  CELLFSI_PETSC(VecRestoreArrayRead(U_loc, &u));
  CELLFSI_PETSC(VecRestoreArrayRead(Ud_loc, &ud));
  CELLFSI_PETSC(DMRestoreLocalVector(da_, &U_loc));
  CELLFSI_PETSC(DMRestoreLocalVector(da_, &Ud_loc));
  return gather_samples(comm_, buf, stride);
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
