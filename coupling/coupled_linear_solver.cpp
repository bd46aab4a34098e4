// See coupled_linear_solver.hpp.
#include "coupling/coupled_linear_solver.hpp"

#include <stdexcept>

#include "common/petsc_error.hpp"
#include "coupling/coupling_events.hpp"
#include "solvers/pc_types.hpp"

namespace cellfsi::coupling {

namespace {

bool is_cellfsi_type(const std::string& type) {
  return type == solvers::kPCFourier || type == solvers::kPCBand || type == solvers::kPCBulk;
}

/// The KSP's and PC's types and defaults of the path for `type`, before the options are read.
void configure_ksp(KSP ksp, const std::string& type, const LinearSolverOptions& options) {
  if (is_cellfsi_type(type))
    CellfsiSolve::configure_ksp(ksp, options, type);
  else
    PetscPCSolve::configure_ksp(ksp, type);
}

/// The path for `type`.
std::unique_ptr<SolvePath> make_solve_path(const std::string& type, SolveContext& context) {
  if (type == solvers::kPCFourier) return std::make_unique<FourierSolve>(context);
  if (type == solvers::kPCBand) return std::make_unique<BandSolve>(context);
  if (type == solvers::kPCBulk) return std::make_unique<BulkSolve>(context);
  return std::make_unique<PetscPCSolve>(context);
}

/// Options set as defaults (the user's own values win). Querying marks a default as used: with a PC type that
/// does not read it, it is not "unknown".
void set_default_options(const std::vector<std::pair<std::string, std::string>>& defaults) {
  for (const auto& [name, value] : defaults) {
    PetscBool set = PETSC_FALSE;
    CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, name.c_str(), &set));
    if (!set) CELLFSI_PETSC(PetscOptionsSetValue(nullptr, name.c_str(), value.c_str()));
    CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, name.c_str(), &set));
  }
}

}  // namespace

PC SolvePath::pc() const {
  PC pc;
  CELLFSI_PETSC(KSPGetPC(c_.ksp, &pc));
  return pc;
}

void CellfsiSolve::configure_ksp(KSP ksp, const LinearSolverOptions& options, const std::string& type) {
  // Right preconditioning (the true residual decides) and the fluid's linear tolerance. A residual at the
  // coupling loop's round-off level (fluid_atol) is not solved for: the Jacobian is singular (the constant
  // pressure) and such a residual is partly outside its range, where no Krylov iteration reduces it
  // (measured: a rigid tracer in undisturbed shear, tests/external, |F| = 3.6e-18 stalled at 9e-5 of it for
  // 492 FGMRES iterations, while the loop iterated for the solid's residual). cellfsi_band is the exact
  // inverse of the operator: one FGMRES iteration, one application and one product.
  CELLFSI_PETSC(KSPSetType(ksp, KSPFGMRES));
  const double rtol = type == solvers::kPCBulk ? kBulkRtol : options.rtol;
  CELLFSI_PETSC(KSPSetTolerances(ksp, rtol, options.fluid_atol, PETSC_DEFAULT, CellfsiKrylov::max_iterations));
  CELLFSI_PETSC(KSPGMRESSetRestart(ksp, CellfsiKrylov::restart));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, type.c_str()));
}

int CellfsiSolve::solve(Vec X, Vec F, Vec dX, bool first_iteration, SolveCounts& counts) {
  // At a step's first iteration the Jacobian is refreshed if the s^h marking moved (its s_I rows changed)
  // or refresh_steps steps have passed; otherwise the previous Newton matrix is kept (only the immersed
  // points moved, a little). Measured on the default scene (64 x 32, 400 steps, band solver): 159 refreshes
  // instead of 400, 30 s instead of 48, 1565 coupling iterations instead of 1555, the same metrics to 1.3e-7.
  const LinearSolverOptions& o = c_.options;
  ++solves_since_refresh_;
  if (first_iteration) ++steps_since_refresh_;
  const bool refresh = resplit_ ||
                       (first_iteration && (marking_changed_ || steps_since_refresh_ >= o.refresh_steps)) ||
                       (o.refresh_lag > 0 && solves_since_refresh_ >= o.refresh_lag);
  if (first_iteration) marking_changed_ = false;
  if (refresh) refresh_jacobian(X);
  Mat J = operator_matrix();
  CELLFSI_PETSC(KSPSetOperators(c_.ksp, J, J));
  if (refresh) {
    EventScope ev(coupling_events().pc_setup);
    set_up_pc();  // the region's LU, or the band's Schur complement (and the kept part's LU when re-split)
    ++counts.refreshes;
    if (refresh_factorizes()) ++counts.factorizations;
    solves_since_refresh_ = steps_since_refresh_ = 0;
    after_refresh();
    resplit_ = false;
  }
  EventScope ev(coupling_events().solve);
  CELLFSI_PETSC(KSPSolve(c_.ksp, F, dX));
  return iterations_or_throw(c_.ksp);
}

CoupledLinearSolver::CoupledLinearSolver(fluid::ImmersedFluid& fluid, LinearSolverOptions options,
                                         std::function<std::vector<char>()> active_elements)
    : opt_(std::move(options)), context_{fluid, opt_, std::move(active_elements)} {
  coupling_events();
  solvers::register_pc_types();
  if (opt_.region_margin < 0) throw std::invalid_argument("region margin must be >= 0");
  if (!(opt_.rtol > 0 && opt_.rtol < 1))
    throw std::invalid_argument("the coupled solve's rtol must be in (0, 1)");
  set_default_options(PetscPCDefaults::options(fluid.options().pressure_null_space));
  SolverSituation s;
  s.baij = fluid.jacobian_is_blocked();  // (a fluid that makes its matrix when first asked is not made to)
  CELLFSI_PETSC(MPI_Comm_size(fluid.comm(), &s.fluid_ranks));
  const bool seq_baij = s.baij && s.fluid_ranks == 1;
  s.fourier_inapplicable = fourier_inapplicable(fluid.patch());
  s.own_bulk_inverse = fluid.has_bulk_inverse();
  CELLFSI_PETSC(KSPCreate(fluid.comm(), &ksp_));
  context_.ksp = ksp_;
  CELLFSI_PETSC(KSPSetOptionsPrefix(ksp_, kCouplingPrefix));
  configure_ksp(ksp_, opt_.pc_type.empty() ? default_pc_type(s) : opt_.pc_type, opt_);
  CELLFSI_PETSC(KSPSetFromOptions(ksp_));
  PetscBool stencil_given = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-coupling_bulk_stencil", &stencil_given));
  if (const std::optional<bool> by_type = pc_type_bulk_stencil(pc_type()); by_type && !stencil_given)
    opt_.bulk_stencil = *by_type;
  PetscBool steps_given = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-coupling_refresh_steps", &steps_given));
  if (const std::optional<int> by_type = pc_type_refresh_steps(pc_type()); by_type && !steps_given)
    opt_.refresh_steps = *by_type;
  path_ = make_solve_path(pc_type(), context_);
  path_->start(s, seq_baij);
}

CoupledLinearSolver::~CoupledLinearSolver() {
  KSPDestroy(&ksp_);
  path_.reset();
}

std::string CoupledLinearSolver::pc_type() const {
  PC pc;
  PCType t = nullptr;
  CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
  CELLFSI_PETSC(PCGetType(pc, &t));
  return t ? t : "";
}

int CoupledLinearSolver::solve(Vec X, Vec F, Vec dX, bool first_iteration, SolveCounts& counts) {
  while (std::optional<FallBack> f = path_->prepare(X, first_iteration, counts)) fall_back(*f);
  try {
    return path_->solve(X, F, dX, first_iteration, counts);
  } catch (const LinearSolveFailed& e) {
    // A bulk operator built once from the first state can drift from the flow's: from rest at a finite Re
    // the developed flow's convective Jacobian is another (measured: plasma Re 40, FGMRES stalled at 0.7 of
    // its start in step 425). Built again from the flow now, the solve is tried once more. (Only a solve that
    // did not converge: PETSc errors, a failed factorisation among them, go through.)
    if (!path_->rebuild()) throw;
    CELLFSI_PETSC(PetscPrintf(context_.fluid.comm(),
                              "cellfsi: note: %s; the bulk operator is built again from the flow now and the "
                              "solve repeated\n",
                              e.what()));
    while (std::optional<FallBack> f = path_->prepare(X, first_iteration, counts)) fall_back(*f);
    return e.iterations + path_->solve(X, F, dX, first_iteration, counts);
  }
}

void CoupledLinearSolver::fall_back(const FallBack& f) {
  if (!opt_.pc_type.empty() && !f.even_if_asked)
    throw std::invalid_argument("-coupling_pc_type " + opt_.pc_type + ": " + f.why + "; use another PC type");
  fell_back_ = true;
  path_.reset();
  opt_.bulk_stencil = false;  // (the bulk solver was not built: the whole Jacobian is still there)
  configure_ksp(ksp_, f.pc_type, opt_);
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
  path_ = make_solve_path(f.pc_type, context_);
  CELLFSI_PETSC(PetscPrintf(context_.fluid.comm(),
                            "cellfsi: note: %s; the coupling loop uses -coupling_pc_type %s\n", f.why.c_str(),
                            f.pc_type.c_str()));
}

}  // namespace cellfsi::coupling
