// See coupled_linear_solver.hpp.
#include "coupling/coupled_linear_solver.hpp"

#include <petscdmda.h>

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "common/petsc_error.hpp"
#include "coupling/coupling_events.hpp"
#include "geometry/element_region.hpp"
#include "solvers/near_operator.hpp"
#include "solvers/pc_types.hpp"

namespace cellfsi::coupling {

using geometry::contains;  // (element masks: geometry/element_region.hpp)

namespace {

bool is_cellfsi_type(const std::string& type) { return type == solvers::kPCFourier || type == solvers::kPCBand; }

bool starts_with(const std::string& s, const char* p) { return s.rfind(p, 0) == 0; }

/// Options set as defaults (the user's own values win): the fluid's defaults for the subdomain solves of a
/// PETSc PC on the coupled Jacobian (MUMPS LU; MUMPS' null-pivot detection for the constant pressure). ASM's
/// overlap 4 is set with the type (configure), before the options are read. Querying marks a default as used: with a PC type that does not read it, it is not "unknown".
void set_default_options(bool pressure_null_space) {
  std::vector<std::pair<std::string, std::string>> defaults{{"-coupling_sub_pc_type", "lu"},
                                                            {"-coupling_sub_pc_factor_mat_solver_type", "mumps"}};
  if (pressure_null_space) {
    defaults.emplace_back("-coupling_sub_mat_mumps_icntl_24", "1");
    defaults.emplace_back("-coupling_mat_mumps_icntl_24", "1");
  }
  for (const auto& [name, value] : defaults) {
    PetscBool set = PETSC_FALSE;
    CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, name.c_str(), &set));
    if (!set) CELLFSI_PETSC(PetscOptionsSetValue(nullptr, name.c_str(), value.c_str()));
    CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, name.c_str(), &set));
  }
}

}  // namespace

std::string fourier_inapplicable(const geometry::Patch& patch) {
  int walls = 0;
  for (int d = 0; d < patch.param_dim(); ++d)
    if (!patch.knots(d).periodic() && patch.n_control(d) > 1) ++walls;
  if (walls > 1)
    return "the fluid domain has " + std::to_string(walls) + " non-periodic directions (at most 1)";
  if (!geometry::translation_invariant(patch))
    return "the fluid mesh is not uniform along its periodic directions (e.g. the narrowing channel)";
  return "";
}

std::string default_pc_type(const SolverSituation& s) {
  if (s.baij && s.fourier_inapplicable.empty()) return solvers::kPCFourier;
  if (s.baij && s.fluid_ranks == 1) return solvers::kPCBand;
  return PCASM;
}

int jacobian_copies(const std::string& pc_type, bool partial_jacobian, bool bulk_stencil) {
  // cellfsi_band: the kept part, MUMPS' input copy of it and the whole; cellfsi_fourier: the part away from
  // the cells (unless partial_jacobian is off) and the whole, or with the bulk stencil the whole only while
  // the bulk solver is built (then the rows near the cells).
  if (pc_type == solvers::kPCBand) return 3;
  if (pc_type == solvers::kPCFourier && bulk_stencil) return 1;
  if (pc_type == solvers::kPCFourier) return partial_jacobian ? 2 : 1;
  return 1;
}

std::string renamed_option(const std::string& name) {
  static const std::vector<std::pair<std::string, std::string>> renamed{
      {"coupling_solver", "coupling_pc_type"},
      {"coupling_fourier_threshold", "coupling_pc_fourier_threshold"},
      {"coupling_fourier_overlap", "coupling_pc_fourier_overlap"},
      {"coupling_fourier_region_solves", "coupling_pc_fourier_region_solves"},
      {"coupling_fourier_partial_jacobian", "coupling_partial_jacobian"},
      {"coupling_band_margin", "coupling_region_margin"},
      {"coupling_band_refresh_steps", "coupling_refresh_steps"},
      {"coupling_band_schur_lag", "coupling_refresh_lag"},
      {"coupling_band_refactor_every", "coupling_refactor_every"}};
  for (const auto& [old_name, new_name] : renamed)
    if (name == old_name) return new_name;
  return "";
}

std::string option_inapplicable(const std::string& name, const std::string& pc_type) {
  const bool fourier = pc_type == solvers::kPCFourier, band = pc_type == solvers::kPCBand;
  const std::string in_use = "this coupled run solves with -coupling_pc_type " + pc_type;
  // The coupling loop is a coupled run's nonlinear iteration, and its KSP the coupled run's linear solver.
  if (starts_with(name, "fluid_snes_"))
    return "in a coupled run the nonlinear iteration is the coupling loop (-coupling_tolerance, "
           "-coupling_max_iterations, -coupling_monitor, -coupling_acceleration); -fluid_snes_ options act on "
           "runs without cells";
  if (name != "fluid_mat_type_jacobian")
    for (const char* p : {"fluid_ksp_", "fluid_pc_", "fluid_sub_", "fluid_mat_"})
      if (starts_with(name, p))
        return "a coupled run solves with the KSP -coupling_ (e.g. -" + std::string("coupling_") +
               name.substr(6) + "): -fluid_ solver options act on runs without cells";
  if ((starts_with(name, "coupling_pc_fourier_") || starts_with(name, "coupling_fourier_")) && !fourier)
    return in_use;
  if ((starts_with(name, "coupling_pc_band_") || starts_with(name, "coupling_band_") ||
       name == "coupling_refactor_every") &&
      !band)
    return in_use;
  if ((name == "coupling_partial_jacobian" || name == "coupling_bulk_stencil") && !fourier) return in_use;
  if ((name == "coupling_region_margin" || name == "coupling_refresh_steps" || name == "coupling_refresh_lag") &&
      !fourier && !band)
    return in_use + ", which refreshes its preconditioner every -coupling_pc_lag solves";
  if (name == "coupling_pc_lag" && (fourier || band))
    return in_use + ", which is refreshed by the motion of the cells (-coupling_refresh_steps)";
  return "";
}

CoupledLinearSolver::CoupledLinearSolver(fluid::ImmersedFluid& fluid, LinearSolverOptions options,
                                         std::function<std::vector<char>()> active_elements)
    : fluid_(fluid), opt_(std::move(options)), active_elements_(std::move(active_elements)) {
  coupling_events();
  solvers::register_pc_types();
  if (opt_.region_margin < 0) throw std::invalid_argument("region margin must be >= 0");
  if (!(opt_.rtol > 0 && opt_.rtol < 1))
    throw std::invalid_argument("the coupled solve's rtol must be in (0, 1)");
  set_default_options(fluid.options().pressure_null_space);
  const Mat J = fluid.jacobian_matrix();
  PetscBool seq_baij = PETSC_FALSE, mpi_baij = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(J), MATSEQBAIJ, &seq_baij));
  CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(J), MATMPIBAIJ, &mpi_baij));
  SolverSituation s;
  s.baij = seq_baij || mpi_baij;
  CELLFSI_PETSC(MPI_Comm_size(fluid.comm(), &s.fluid_ranks));
  s.fourier_inapplicable = fourier_inapplicable(fluid.patch());
  CELLFSI_PETSC(KSPCreate(fluid.comm(), &ksp_));
  CELLFSI_PETSC(KSPSetOptionsPrefix(ksp_, kCouplingPrefix));
  configure(opt_.pc_type.empty() ? default_pc_type(s) : opt_.pc_type);
  CELLFSI_PETSC(KSPSetFromOptions(ksp_));
  const std::string type = pc_type();
  // What the cellfsi types need of the Jacobian, refused here with the reason.
  if (type == solvers::kPCFourier) {
    if (!s.baij)
      throw std::invalid_argument("-coupling_pc_type cellfsi_fourier needs a BAIJ fluid Jacobian "
                                  "(-fluid_mat_type_jacobian baij)");
    if (!s.fourier_inapplicable.empty())
      throw std::invalid_argument("-coupling_pc_type cellfsi_fourier does not apply: " + s.fourier_inapplicable);
    const std::optional<fluid::BlockLayout> layout = fluid.block_layout();
    if (!layout)
      throw std::invalid_argument("-coupling_pc_type cellfsi_fourier needs the fluid's unknowns in node blocks "
                                  "on the control net");
    const solvers::BoxMesh box{layout->n, layout->degree, layout->periodic, layout->dof, layout->natural};
    PC pc;
    CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
    solvers::pc_fourier_set_box(pc, box);
    if (opt_.bulk_stencil && !fluid.options().pressure_null_space) {
      // (The default in 3D gives way; asked for, it is refused.)
      PetscBool given = PETSC_FALSE;
      CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-coupling_bulk_stencil", &given));
      if (given)
        throw std::invalid_argument("-coupling_bulk_stencil needs the constant pressure as the Jacobian's null "
                                    "space (-fluid_pressure_null_space true): a pinned pressure row is not "
                                    "part of the bulk stencil");
      opt_.bulk_stencil = false;
    }
    if (opt_.bulk_stencil) {
      // The operator that replaces the Jacobian carries its null spaces.
      CELLFSI_PETSC(MatGetNullSpace(J, &null_space_));
      CELLFSI_PETSC(MatGetTransposeNullSpace(J, &transpose_null_space_));
      if (null_space_) CELLFSI_PETSC(PetscObjectReference(reinterpret_cast<PetscObject>(null_space_)));
      if (transpose_null_space_)
        CELLFSI_PETSC(PetscObjectReference(reinterpret_cast<PetscObject>(transpose_null_space_)));
    }
  } else {
    opt_.bulk_stencil = false;  // (given by the user, the option checks refuse it: option_inapplicable)
  }
  if (!cellfsi_type_) {
    // A PETSc PC sets itself up on the Jacobian of the current state now, so that its inner solvers (ASM's
    // subdomains) read their options and misspelt ones are reported before any step; factorisations wait
    // for the first solve.
    fluid.jacobian(fluid.solution(), J);
    CELLFSI_PETSC(KSPSetOperators(ksp_, J, J));
    CELLFSI_PETSC(KSPSetUp(ksp_));
  }
  if (type == solvers::kPCBand && (s.fluid_ranks > 1 || !seq_baij))
    throw std::invalid_argument("-coupling_pc_type cellfsi_band needs one fluid rank and a BAIJ Jacobian "
                                "(-fluid_mat_type_jacobian baij); on several ranks use cellfsi_fourier or a "
                                "PETSc PC such as asm");
}

CoupledLinearSolver::~CoupledLinearSolver() {
  KSPDestroy(&ksp_);
  MatDestroy(&J_fixed_);
  MatDestroy(&near_op_);
  MatDestroy(&near_);
  MatNullSpaceDestroy(&null_space_);
  MatNullSpaceDestroy(&transpose_null_space_);
}

void CoupledLinearSolver::configure(const std::string& type) {
  cellfsi_type_ = is_cellfsi_type(type);
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
  if (cellfsi_type_) {
    // Right preconditioning (the true residual decides) and the fluid's linear tolerance. A residual at the
    // coupling loop's round-off level (fluid_atol) is not solved for: the Jacobian is singular (the constant
    // pressure) and such a residual is partly outside its range, where no Krylov iteration reduces it
    // (measured: a rigid tracer in undisturbed shear, tests/external, |F| = 3.6e-18 stalled at 9e-5 of it for
    // 492 FGMRES iterations, while the loop iterated for the solid's residual). cellfsi_band is the exact
    // inverse of the operator: one FGMRES iteration, one application and one product.
    CELLFSI_PETSC(KSPSetType(ksp_, KSPFGMRES));
    CELLFSI_PETSC(KSPSetTolerances(ksp_, opt_.rtol, opt_.fluid_atol, PETSC_DEFAULT, 500));
    CELLFSI_PETSC(KSPGMRESSetRestart(ksp_, 100));
  } else {
    // The fluid's own defaults (fluid/fluid_solver.cpp): GMRES, rtol 1e-5, ASM with LU subdomain solves.
    CELLFSI_PETSC(KSPSetType(ksp_, KSPGMRES));
    CELLFSI_PETSC(KSPSetTolerances(ksp_, 1e-5, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT));
  }
  CELLFSI_PETSC(PCSetType(pc, type.c_str()));
  if (type == PCASM) CELLFSI_PETSC(PCASMSetOverlap(pc, 4));
}

std::string CoupledLinearSolver::pc_type() const {
  PC pc;
  PCType t = nullptr;
  CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
  CELLFSI_PETSC(PCGetType(pc, &t));
  return t ? t : "";
}

PetscInt CoupledLinearSolver::corrected_unknowns() const {
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
  if (const solvers::BandSchurSolver* b = solvers::pc_band_solver(pc)) return b->n_band();
  if (const solvers::RegionCorrectedSolver* f = solvers::pc_fourier_solver(pc)) return f->n_region();
  return 0;
}

void CoupledLinearSolver::fall_back(const std::string& type, const std::string& why, bool even_if_asked) {
  if (!opt_.pc_type.empty() && !even_if_asked)
    throw std::invalid_argument("-coupling_pc_type " + opt_.pc_type + ": " + why + "; use another PC type");
  fell_back_ = true;
  region_.clear();
  MatDestroy(&J_fixed_);
  opt_.bulk_stencil = false;  // (the bulk solver was not built: the whole Jacobian is still there)
  configure(type);
  // The user's KSP options win over the fallback's defaults, as at construction (configure, then
  // KSPSetFromOptions). Where the user had asked for a PC type, the options would set it again, so only the
  // tolerance is taken from them.
  if (opt_.pc_type.empty()) {
    CELLFSI_PETSC(KSPSetFromOptions(ksp_));
  } else {
    const char* prefix = nullptr;
    PetscReal rtol = 0;
    PetscBool set = PETSC_FALSE;
    CELLFSI_PETSC(KSPGetOptionsPrefix(ksp_, &prefix));
    CELLFSI_PETSC(PetscOptionsGetReal(nullptr, prefix, "-ksp_rtol", &rtol, &set));
    if (set) CELLFSI_PETSC(KSPSetTolerances(ksp_, rtol, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT));
  }
  marking_changed_ = pc_stale_ = true;
  steps_since_refresh_ = 0;
  CELLFSI_PETSC(PetscPrintf(fluid_.comm(), "cellfsi: note: %s; the coupling loop uses -coupling_pc_type %s\n",
                            why.c_str(), type.c_str()));
}

bool CoupledLinearSolver::build_bulk(Vec X) {
  // Once per run: the bulk operator at the first iterate (from the initial state, the undisturbed flow,
  // uniform along the periodic directions to the projection's round-off; after a restart, the restored
  // state, whose disturbance by the cells changes the Jacobian by about Re ~ 1e-4 of its entries). The
  // Jacobian's matrix holds it meanwhile: the refresh that follows re-assembles it.
  EventScope ev(coupling_events().factor);
  Mat J = fluid_.jacobian_matrix();
  fluid_.bulk_jacobian(X, J);
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
  const double dev = solvers::pc_fourier_set_bulk(pc, J, true);
  bulk_built_ = true;
  if (!(dev <= opt_.uniformity)) {  // NaN (a broken operator) counts as not uniform
    char amount[32];
    std::snprintf(amount, sizeof amount, "%.2e", dev);
    int ranks = 1;
    CELLFSI_PETSC(MPI_Comm_size(fluid_.comm(), &ranks));
    PetscBool seq_baij = PETSC_FALSE;
    CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(J), MATSEQBAIJ, &seq_baij));
    fall_back(ranks == 1 && seq_baij ? solvers::kPCBand : PCASM,
              std::string("the fluid Jacobian away from the cells differs by ") + amount +
                  " of a row's largest entry between periodic positions (the mesh or the flow is not uniform "
                  "along the periodic directions)");
    return false;
  }
  const solvers::RegionCorrectedSolver* f = solvers::pc_fourier_solver(pc);
  double factor_mb = f->bulk().factor_bytes() / 1048576.0;  // this rank's; summed over the ranks
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &factor_mb, 1, MPI_DOUBLE, MPI_SUM, fluid_.comm()));
  CELLFSI_PETSC(PetscPrintf(fluid_.comm(),
                            "cellfsi: Fourier bulk solver: %d wave vectors, %.1f MB of banded factors, operator "
                            "uniform to %.2e\n",
                            f->bulk().n_modes(), factor_mb, dev));
  marking_changed_ = true;
  if (opt_.bulk_stencil) {  // from here on the stencil and the near rows
    PetscLogDouble before = 0, after = 0;
    CELLFSI_PETSC(PetscMemoryGetCurrentUsage(&before));
    fluid_.release_jacobian_matrix();
    CELLFSI_PETSC(PetscMemoryGetCurrentUsage(&after));
    if (opt_.monitor)
      CELLFSI_PETSC(PetscPrintf(fluid_.comm(), "  the whole Jacobian released: resident %.0f -> %.0f MB\n",
                                before / 1048576.0, after / 1048576.0));
  }
  return true;
}

bool CoupledLinearSolver::ensure_band_factorization(Vec X) {
  const std::vector<char> active = active_elements_();
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
  const solvers::BandSchurSolver* band = solvers::pc_band_solver(pc);
  const bool stale = opt_.refactor_every > 0 && steps_since_factor_ >= opt_.refactor_every;
  if (!stale && band && band->factored() && contains(region_, active)) return false;
  EventScope ev(coupling_events().factor);
  region_ = grow_elements(fluid_.patch(), active, opt_.region_margin);
  // A region that holds most of the domain (a coarse 3D mesh around a compound capsule) leaves nothing to
  // keep: its Schur complement is the whole problem (measured at 16^3: 25 % slower than ASM on the whole).
  const auto in_region = std::count(region_.begin(), region_.end(), 1);
  if (2 * in_region > static_cast<long>(region_.size())) {
    fall_back(PCASM,
              "the band region holds " + std::to_string(in_region) + " of " + std::to_string(region_.size()) +
                  " elements",
              true);
    return false;
  }
  const std::vector<PetscInt> unknowns = fluid_.region_unknowns(region_);
  IS is;
  CELLFSI_PETSC(ISCreateGeneral(PETSC_COMM_SELF, static_cast<PetscInt>(unknowns.size()), unknowns.data(),
                                PETSC_COPY_VALUES, &is));
  if (!J_fixed_) CELLFSI_PETSC(MatDuplicate(fluid_.jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, &J_fixed_));
  fluid_.jacobian_part(X, J_fixed_, region_, false);
  try {
    solvers::pc_band_set_split(pc, J_fixed_, is);
  } catch (...) {
    region_.clear();  // the next call builds again
    ISDestroy(&is);
    throw;
  }
  CELLFSI_PETSC(ISDestroy(&is));
  steps_since_factor_ = 0;
  if (opt_.monitor) {
    PetscLogDouble resident = 0;
    CELLFSI_PETSC(PetscMemoryGetCurrentUsage(&resident));
    band = solvers::pc_band_solver(pc);
    CELLFSI_PETSC(PetscPrintf(
        fluid_.comm(),
        "  band factorisation: %ld of %zu elements, %" PetscInt_FMT " of %" PetscInt_FMT
        " unknowns (edge %" PetscInt_FMT "), Schur complement %" PetscInt_FMT " nonzeros; resident %.0f MB\n",
        static_cast<long>(in_region), region_.size(), band->n_band(), band->n_total(), band->n_edge(),
        band->schur_nonzeros(), resident / 1048576.0));
  }
  return true;
}

void CoupledLinearSolver::make_near_operator() {
  MatDestroy(&near_op_);
  MatDestroy(&near_);
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
  const solvers::FourierBulkSolver& bulk = solvers::pc_fourier_solver(pc)->bulk();
  const geometry::Patch& patch = fluid_.patch();
  const int dim = fluid_.dim(), dof = dim + 1;
  // The rows the region's elements touch, and those they hold in full (every element of the node's support
  // in the region).
  std::vector<char> touched(bulk.n_nodes(), 0), outside(region_.size(), 0);
  for (int f : functions_on_elements(patch, region_)) touched[f] = 1;
  for (std::size_t e = 0; e < region_.size(); ++e) outside[e] = !region_[e];
  std::vector<char> near_nodes = touched;
  for (int f : functions_on_elements(patch, outside)) near_nodes[f] = 0;
  // Preallocation: a touched row's block columns are its stencil's nodes (+-degree per direction, wrapped in
  // the periodic ones), split between this rank's columns and the others'; any other row, its diagonal (the
  // unit rows of the walls).
  PetscInt lo = 0, hi = 0;
  CELLFSI_PETSC(VecGetOwnershipRange(fluid_.solution(), &lo, &hi));
  const PetscInt b0 = lo / dof, b1 = hi / dof;
  std::array<int, 3> n{1, 1, 1}, p{0, 0, 0};
  std::array<bool, 3> periodic{false, false, false};
  for (int d = 0; d < dim; ++d) {
    n[d] = patch.n_control(d);
    p[d] = patch.degree(d);
    periodic[d] = patch.knots(d).periodic();
  }
  std::vector<PetscInt> d_nnz(b1 - b0, 1), o_nnz(b1 - b0, 0);
  std::array<std::vector<int>, 3> cols;
  for (PetscInt gb = b0; gb < b1; ++gb) {
    const int node = bulk.natural_node(static_cast<int>(gb));
    if (!touched[node]) continue;
    const std::array<int, 3> c{node % n[0], (node / n[0]) % n[1], node / (n[0] * n[1])};
    for (int d = 0; d < 3; ++d) {
      cols[d].clear();
      for (int o = -p[d]; o <= p[d]; ++o) {
        int x = c[d] + o;
        if (periodic[d])
          x = (x % n[d] + n[d]) % n[d];
        else if (x < 0 || x >= n[d])
          continue;
        if (std::find(cols[d].begin(), cols[d].end(), x) == cols[d].end()) cols[d].push_back(x);
      }
    }
    PetscInt in = 0, out = 0;
    for (int z : cols[2])
      for (int y : cols[1])
        for (int x : cols[0]) {
          const PetscInt g = bulk.global_node(x + n[0] * (y + n[1] * z));
          (g >= b0 && g < b1 ? in : out) += 1;
        }
    d_nnz[gb - b0] = in;
    o_nnz[gb - b0] = out;
  }
  CELLFSI_PETSC(MatCreateBAIJ(fluid_.comm(), dof, hi - lo, hi - lo, PETSC_DETERMINE, PETSC_DETERMINE, 0,
                              d_nnz.data(), 0, o_nnz.data(), &near_));
  // Every row's diagonal block in the pattern (an assembly squeezes out what was not set): the assembly's
  // Dirichlet rows become unit rows there.
  const std::vector<PetscScalar> zero(static_cast<std::size_t>(dof) * dof, 0.0);
  for (PetscInt gb = b0; gb < b1; ++gb)
    CELLFSI_PETSC(MatSetValuesBlocked(near_, 1, &gb, 1, &gb, zero.data(), INSERT_VALUES));
  CELLFSI_PETSC(MatAssemblyBegin(near_, MAT_FLUSH_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(near_, MAT_FLUSH_ASSEMBLY));
  const ISLocalToGlobalMapping ltog = fluid_.block_layout()->local_to_global;
  CELLFSI_PETSC(MatSetLocalToGlobalMapping(near_, ltog, ltog));
  near_op_ = solvers::create_near_operator(bulk, near_, std::move(near_nodes));
  if (null_space_) CELLFSI_PETSC(MatSetNullSpace(near_op_, null_space_));
  if (transpose_null_space_) CELLFSI_PETSC(MatSetTransposeNullSpace(near_op_, transpose_null_space_));
}

void CoupledLinearSolver::refresh_near_operator(Vec X) {
  // The region: the elements around the cells, `degree` elements beyond the active ones at least, so that
  // every row the cells change (a node whose support meets an active element) is held in full; grown by
  // the margin so that it is kept for a while as the cells move.
  const std::vector<char> active = active_elements_();
  const geometry::Patch& patch = fluid_.patch();
  int reach = 0;
  for (int d = 0; d < fluid_.dim(); ++d) reach = std::max(reach, patch.degree(d));
  const bool fresh = !near_ || !contains(region_, grow_elements(patch, active, reach));
  if (fresh) {
    region_ = grow_elements(patch, active, reach + opt_.region_margin);
    make_near_operator();
  } else {
    CELLFSI_PETSC(MatZeroEntries(near_));
  }
  fluid_.jacobian_add_part(X, near_, region_);
  // (An assembly of the operator raises its state: KSP then sets the preconditioner up again.)
  CELLFSI_PETSC(MatAssemblyBegin(near_op_, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(near_op_, MAT_FINAL_ASSEMBLY));
}

void CoupledLinearSolver::refresh_jacobian(Vec X) {
  EventScope ev(coupling_events().jacobian);
  if (opt_.bulk_stencil) {
    refresh_near_operator(X);
    return;
  }
  Mat J = fluid_.jacobian_matrix();
  if (pc_type() == solvers::kPCFourier) {
    // Only the elements around the cells are re-assembled: the rest, kept in J_fixed_, is rebuilt when the
    // cells leave the region it was assembled for; a region of most of the domain is not worth the matrix.
    const std::vector<char> active = active_elements_();
    if (region_.empty() || !contains(region_, active)) {
      region_ = grow_elements(fluid_.patch(), active, opt_.region_margin);
      const auto in_region = std::count(region_.begin(), region_.end(), 1);
      if (!opt_.partial_jacobian || 2 * in_region > static_cast<long>(region_.size())) {
        region_.assign(region_.size(), 1);
        MatDestroy(&J_fixed_);
      } else {
        if (!J_fixed_) CELLFSI_PETSC(MatDuplicate(J, MAT_DO_NOT_COPY_VALUES, &J_fixed_));
        fluid_.jacobian_part(X, J_fixed_, region_, false);
      }
    }
  }
  if (J_fixed_) {
    CELLFSI_PETSC(MatCopy(J_fixed_, J, SAME_NONZERO_PATTERN));
    fluid_.jacobian_add_part(X, J, region_);
  } else {
    fluid_.jacobian(X, J);
  }
}

bool CoupledLinearSolver::may_assemble(bool first_iteration) const {
  if (first_iteration || !cellfsi_type_ || pc_type() == solvers::kPCBand) return true;
  // (solve() counts this solve before it compares with the lag.)
  return opt_.refresh_lag > 0 && solves_since_refresh_ + 1 >= opt_.refresh_lag;
}

int CoupledLinearSolver::solve(Vec X, Vec F, Vec dX, bool first_iteration, SolveCounts& counts) {
  if (first_iteration) ++steps_since_factor_;
  if (pc_type() == solvers::kPCFourier && !bulk_built_) {
    ++counts.factorizations;
    build_bulk(X);  // may fall back
  }
  if (!cellfsi_type_) return solve_generic(X, F, dX, counts);
  // The region is checked every iteration: the immersed points move with the solids.
  bool factored = false;
  if (pc_type() == solvers::kPCBand) {
    factored = ensure_band_factorization(X);
    if (factored) ++counts.factorizations;
    if (!cellfsi_type_) return solve_generic(X, F, dX, counts);  // the region held most of the domain
  }
  // At a step's first iteration the Jacobian is refreshed if the s^h marking moved (its s_I rows changed)
  // or refresh_steps steps have passed; otherwise the previous Newton matrix is kept (only the immersed
  // points moved, a little). Measured on the default scene (64 x 32, 400 steps, band solver): 159 refreshes
  // instead of 400, 30 s instead of 48, 1565 coupling iterations instead of 1555, the same metrics to 1.3e-7.
  ++solves_since_refresh_;
  if (first_iteration) ++steps_since_refresh_;
  const bool refresh = factored ||
                       (first_iteration && (marking_changed_ || steps_since_refresh_ >= opt_.refresh_steps)) ||
                       (opt_.refresh_lag > 0 && solves_since_refresh_ >= opt_.refresh_lag);
  if (first_iteration) marking_changed_ = false;
  if (refresh) refresh_jacobian(X);
  Mat J = near_op_ ? near_op_ : fluid_.jacobian_matrix();
  CELLFSI_PETSC(KSPSetOperators(ksp_, J, J));
  if (refresh) {
    EventScope ev(coupling_events().pc_setup);
    CELLFSI_PETSC(KSPSetUp(ksp_));  // the region's LU or the band's Schur complement
    ++counts.refreshes;
    solves_since_refresh_ = steps_since_refresh_ = 0;
    PC pc;
    CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
    const solvers::RegionCorrectedSolver* fourier = solvers::pc_fourier_solver(pc);
    if (fourier && !fourier->single_precision_failure().empty() && !single_failure_reported_) {
      single_failure_reported_ = true;
      CELLFSI_PETSC(PetscPrintf(fluid_.comm(),
                                "cellfsi: the region's LU in single precision failed (%s); the region is factorised "
                                "in double precision from now on (-coupling_fourier_region_pc_type lu)\n",
                                fourier->single_precision_failure().c_str()));
    }
    if (opt_.monitor && solvers::pc_fourier_solver(pc))
      CELLFSI_PETSC(PetscPrintf(fluid_.comm(),
                                "  Fourier solver: %d nodes differ from the bulk, region %" PetscInt_FMT
                                " unknowns\n",
                                solvers::pc_fourier_solver(pc)->n_differing_nodes(), corrected_unknowns()));
  }
  EventScope ev(coupling_events().solve);
  CELLFSI_PETSC(KSPSolve(ksp_, F, dX));
  return iterations_or_throw(ksp_);
}

int CoupledLinearSolver::solve_generic(Vec X, Vec F, Vec dX, SolveCounts& counts) {
  Mat J = fluid_.jacobian_matrix();
  {
    EventScope ev(coupling_events().jacobian);
    fluid_.jacobian(X, J);
  }
  EventScope ev(coupling_events().solve);
  CELLFSI_PETSC(KSPSetOperators(ksp_, J, J));
  // The preconditioner is reused for preconditioner_lag solves, and rebuilt when the marking changed: with
  // s_I >> 1 the marked rows dominate the Jacobian.
  const bool rebuild =
      solves_since_pc_ >= opt_.preconditioner_lag || (pc_stale_ && opt_.s_interface_dominates);
  pc_stale_ = false;
  CELLFSI_PETSC(KSPSetReusePreconditioner(ksp_, rebuild ? PETSC_FALSE : PETSC_TRUE));
  solves_since_pc_ = rebuild ? 1 : solves_since_pc_ + 1;
  if (rebuild) ++counts.factorizations;
  CELLFSI_PETSC(KSPSolve(ksp_, F, dX));
  return iterations_or_throw(ksp_);
}

}  // namespace cellfsi::coupling
