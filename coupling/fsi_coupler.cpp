#include "coupling/fsi_coupler.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <petscdmda.h>

#include "common/petsc_error.hpp"
#include "coupling/band_region.hpp"
#include "coupling/interface_marking.hpp"

namespace cellfsi::coupling {

namespace {

/// PETSc log events of the phases of a coupled step (-log_view shows where a step goes).
struct CouplingEvents {
  PetscLogEvent solid = 0, locate = 0, residual = 0, jacobian = 0, band_factor = 0, band_update = 0,
                solve = 0;
  CouplingEvents()
      : solid(register_log_event("cellfsi coupling", "FsiSolidUpdate")),
        locate(register_log_event("cellfsi coupling", "FsiLocate")),
        residual(register_log_event("cellfsi coupling", "FsiResidual")),
        jacobian(register_log_event("cellfsi coupling", "FsiJacobian")),
        band_factor(register_log_event("cellfsi coupling", "FsiBandFactor")),
        band_update(register_log_event("cellfsi coupling", "FsiBandUpdate")),
        solve(register_log_event("cellfsi coupling", "FsiLinearSolve")) {}
};

const CouplingEvents& events() {
  static const CouplingEvents e;
  return e;
}

/// RAII begin/end of a log event.
class EventScope {
 public:
  explicit EventScope(PetscLogEvent e) : e_(e) { PetscLogEventBegin(e_, 0, 0, 0, 0); }
  ~EventScope() { PetscLogEventEnd(e_, 0, 0, 0, 0); }
  EventScope(const EventScope&) = delete;
  EventScope& operator=(const EventScope&) = delete;

 private:
  PetscLogEvent e_;
};

/// The iterations of the KSP's last solve; throws if it failed.
int iterations_or_throw(KSP ksp) {
  KSPConvergedReason kr;
  CELLFSI_PETSC(KSPGetConvergedReason(ksp, &kr));
  PetscInt lits = 0;
  CELLFSI_PETSC(KSPGetIterationNumber(ksp, &lits));
  if (kr < 0) throw std::runtime_error("linear solve failed: " + fluid::linear_solve_failure(ksp));
  return static_cast<int>(lits);
}

/// PCSHELL apply of a solver object `S` with method `F`(r, x) (its exceptions become PETSc errors).
template <class S, void (S::*F)(Vec, Vec)>
PetscErrorCode shell_apply(PC pc, Vec r, Vec x) {
  PetscFunctionBeginUser;
  void* ctx = nullptr;
  PetscCall(PCShellGetContext(pc, &ctx));
  try {
    (static_cast<S*>(ctx)->*F)(r, x);
  } catch (const std::exception& e) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "%s", e.what());
  }
  PetscFunctionReturn(0);
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

FsiCoupler::FsiCoupler(fluid::FluidSolver& fluid, std::vector<solid::SolidSolver*> bodies,
                       CouplerOptions options)
    : fluid_(fluid), bodies_(std::move(bodies)), opt_(options), locator_(fluid.patch()) {
  tp_ = solid::TimeParameters::from_rho_inf(fluid.options().rho_inf, fluid.options().dt);
  if (!(opt_.tolerance > 0 && opt_.tolerance < 1))
    throw std::invalid_argument("coupler tolerance must be in (0, 1)");
  check_interface_scaling(opt_.s_interface);
  for (auto* b : bodies_)
    if (b->dim() != fluid.dim())
      throw std::invalid_argument("body '" + b->name() + "' has another dimension");
  collocation_loc_.resize(bodies_.size());
  quadrature_loc_.resize(bodies_.size());
  CELLFSI_PETSC(VecDuplicate(fluid.solution(), &X_));
  CELLFSI_PETSC(VecDuplicate(X_, &dX_));
  CELLFSI_PETSC(VecDuplicate(X_, &F_));
  events();
  if (opt_.acceleration == Acceleration::anderson)
    anderson_ = std::make_unique<AndersonAcceleration>(X_, fluid.dim() + 1, opt_.acceleration_columns,
                                                       opt_.acceleration_reuse);
  solver_ = opt_.solver;
  int fluid_ranks = 1;
  MPI_Comm_size(fluid.comm(), &fluid_ranks);
  // The band solver needs one fluid rank and a SeqBAIJ Jacobian, the Fourier solver a BAIJ one (see the
  // header).
  PetscBool seq_baij = PETSC_FALSE, mpi_baij = PETSC_FALSE;
  const auto jacobian = reinterpret_cast<PetscObject>(fluid.jacobian_matrix());
  CELLFSI_PETSC(PetscObjectTypeCompare(jacobian, MATSEQBAIJ, &seq_baij));
  CELLFSI_PETSC(PetscObjectTypeCompare(jacobian, MATMPIBAIJ, &mpi_baij));
  const bool baij = seq_baij || mpi_baij;
  if (solver_ == CouplingSolver::automatic)
    solver_ =
        baij && fourier_inapplicable(fluid.patch()).empty() ? CouplingSolver::fourier : CouplingSolver::band;
  if (solver_ == CouplingSolver::band && (fluid_ranks > 1 || !seq_baij)) solver_ = CouplingSolver::fluid;
  if (solver_ == CouplingSolver::band) setup_band();
  if (solver_ == CouplingSolver::fourier) {
    const geometry::Patch& patch = fluid.patch();
    if (!baij)
      throw std::invalid_argument(
          "the Fourier solver (-coupling_solver fourier) needs a BAIJ fluid Jacobian "
          "(-fluid_mat_type_jacobian "
          "baij)");
    const std::string why = fourier_inapplicable(patch);
    if (!why.empty()) throw std::invalid_argument("-coupling_solver fourier does not apply: " + why);
    std::array<int, 3> n{1, 1, 1}, degree{0, 0, 0};
    std::array<bool, 3> periodic{false, false, false};
    for (int d = 0; d < fluid.dim(); ++d) {
      n[d] = patch.n_control(d);
      degree[d] = patch.degree(d);
      periodic[d] = patch.knots(d).periodic();
    }
    if (!(opt_.fourier_threshold > 0)) throw std::invalid_argument("Fourier threshold must be > 0");
    if (opt_.fourier_overlap < 0) throw std::invalid_argument("Fourier overlap must be >= 0");
    AO natural = nullptr;  // the DMDA's natural ordering -> its global ordering
    CELLFSI_PETSC(DMDAGetAO(fluid.dm(), &natural));
    fourier_ = std::make_unique<fluid::RegionCorrectedSolver>(n, periodic, degree, fluid.dim() + 1,
                                                              "coupling_fourier_", fluid.comm(), natural);
    fourier_->set_region(opt_.fourier_threshold, opt_.fourier_overlap);
    fourier_->set_region_solves(opt_.fourier_region_solves);
    CELLFSI_PETSC(KSPCreate(fluid.comm(), &fourier_ksp_));
    CELLFSI_PETSC(KSPSetOptionsPrefix(fourier_ksp_, "coupling_fourier_"));
    // Right preconditioning (the true residual decides) and the fluid's linear tolerance. A residual at the
    // coupling loop's round-off level (fluid_atol) is not solved for: the Jacobian is singular (the constant
    // pressure) and such a residual is partly outside its range, where no Krylov iteration reduces it
    // (measured: a rigid tracer in undisturbed shear, tests/external, |F| = 3.6e-18 stalled at 9e-5 of it for
    // 492 FGMRES iterations, while the loop iterated for the solid's residual).
    CELLFSI_PETSC(KSPSetType(fourier_ksp_, KSPFGMRES));
    CELLFSI_PETSC(KSPSetTolerances(fourier_ksp_, 1e-5, opt_.fluid_atol, PETSC_DEFAULT, 500));
    CELLFSI_PETSC(KSPGMRESSetRestart(fourier_ksp_, 100));
    PC pc;
    CELLFSI_PETSC(KSPGetPC(fourier_ksp_, &pc));
    CELLFSI_PETSC(PCSetType(pc, PCSHELL));
    CELLFSI_PETSC(PCShellSetContext(pc, fourier_.get()));
    CELLFSI_PETSC(
        PCShellSetApply(pc, shell_apply<fluid::RegionCorrectedSolver, &fluid::RegionCorrectedSolver::apply>));
    CELLFSI_PETSC(PCShellSetName(pc, "cellfsi Fourier bulk + region LU (fluid/region_corrected_solver.hpp)"));
    CELLFSI_PETSC(KSPSetFromOptions(fourier_ksp_));
  }
}

void FsiCoupler::setup_band() {
  if (opt_.band_margin < 0) throw std::invalid_argument("band margin must be >= 0");
  CELLFSI_PETSC(MatDuplicate(fluid_.jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, &J_fixed_));
  CELLFSI_PETSC(MatDuplicate(fluid_.jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, &J_band_));
  CELLFSI_PETSC(KSPCreate(fluid_.comm(), &band_ksp_));
  CELLFSI_PETSC(KSPSetOptionsPrefix(band_ksp_, "coupling_band_"));
  // The preconditioner is the exact inverse of the operator (both are K_fixed + K_band): one FGMRES
  // iteration, which costs one application and one product (GMRES would apply the preconditioner twice).
  // The fluid's linear tolerance, so that the two solvers' answers agree to it; a residual already at the
  // coupling loop's round-off level (fluid_atol) is not solved for (see the Fourier solver's set-up).
  CELLFSI_PETSC(KSPSetType(band_ksp_, KSPFGMRES));
  CELLFSI_PETSC(KSPSetTolerances(band_ksp_, 1e-5, opt_.fluid_atol, PETSC_DEFAULT, PETSC_DEFAULT));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(band_ksp_, &pc));
  CELLFSI_PETSC(PCSetType(pc, PCSHELL));
  CELLFSI_PETSC(PCShellSetContext(pc, &band_));
  CELLFSI_PETSC(PCShellSetApply(pc, shell_apply<fluid::BandSchurSolver, &fluid::BandSchurSolver::solve>));
  CELLFSI_PETSC(PCShellSetName(pc, "cellfsi band Schur complement (fluid/band_schur.hpp)"));
  CELLFSI_PETSC(KSPSetFromOptions(band_ksp_));
}

FsiCoupler::~FsiCoupler() {
  VecDestroy(&X_);
  VecDestroy(&dX_);
  VecDestroy(&F_);
  MatDestroy(&J_fixed_);
  MatDestroy(&J_band_);
  KSPDestroy(&band_ksp_);
  KSPDestroy(&fourier_ksp_);
}

void FsiCoupler::use_fluid_solver() {
  solver_ = CouplingSolver::fluid;
  fell_back_ = true;
  band_.release();
  MatDestroy(&J_fixed_);
  MatDestroy(&J_band_);
  KSPDestroy(&band_ksp_);
}

std::vector<char> FsiCoupler::active_elements() const {
  std::vector<char> active = elements_supporting(fluid_.patch(), marked_);
  const geometry::Patch& patch = fluid_.patch();
  const int n0 = patch.n_elements(0), n1 = patch.n_elements(1);
  for (const auto& body : quadrature_loc_)
    for (const Location& l : body) active[l.element[0] + n0 * (l.element[1] + n1 * l.element[2])] = 1;
  return active;
}

bool FsiCoupler::ensure_band_factorization() {
  const std::vector<char> active = active_elements();
  const bool stale = opt_.band_refactor_every > 0 && steps_since_factor_ >= opt_.band_refactor_every;
  if (!stale && band_.factored() && contains(region_, active)) return false;
  EventScope ev(events().band_factor);
  region_ = grow_elements(fluid_.patch(), active, opt_.band_margin);
  // A region that holds most of the domain (a coarse 3D mesh around a compound capsule) leaves nothing to
  // keep: its Schur complement is the whole problem (measured at 16^3: 25 % slower than the fluid's solver).
  const auto in_region = std::count(region_.begin(), region_.end(), 1);
  if (2 * in_region > static_cast<long>(region_.size())) {
    use_fluid_solver();
    CELLFSI_PETSC(
        PetscPrintf(fluid_.comm(),
                    "cellfsi: note: the band region holds %ld of %zu elements; the coupling loop uses "
                    "-coupling_solver fluid\n",
                    static_cast<long>(in_region), region_.size()));
    return false;
  }
  const std::vector<int> nodes = functions_on_elements(fluid_.patch(), region_);
  // One fluid rank: the DMDA's global numbering is the natural one, node-major and unknown-minor.
  const int dof = fluid_.dim() + 1;
  std::vector<PetscInt> unknowns;
  unknowns.reserve(nodes.size() * dof);
  for (int n : nodes)
    for (int c = 0; c < dof; ++c) unknowns.push_back(static_cast<PetscInt>(n) * dof + c);
  IS band;
  CELLFSI_PETSC(ISCreateGeneral(PETSC_COMM_SELF, static_cast<PetscInt>(unknowns.size()), unknowns.data(),
                                PETSC_COPY_VALUES, &band));
  fluid_.jacobian_part(X_, J_fixed_, region_, false);
  try {
    band_.factor(J_fixed_, band, "coupling_band_");
  } catch (...) {
    region_.clear();  // the next call builds again
    ISDestroy(&band);
    throw;
  }
  CELLFSI_PETSC(ISDestroy(&band));
  if (opt_.monitor) {
    PetscLogDouble resident = 0;
    CELLFSI_PETSC(PetscMemoryGetCurrentUsage(&resident));
    CELLFSI_PETSC(PetscPrintf(
        fluid_.comm(),
        "  band factorisation: %d of %d elements, %" PetscInt_FMT " of %" PetscInt_FMT
        " unknowns (edge %" PetscInt_FMT "), Schur complement %" PetscInt_FMT " nonzeros; resident %.0f MB\n",
        static_cast<int>(std::count(region_.begin(), region_.end(), 1)), fluid_.patch().n_elements(),
        band_.n_band(), band_.n_total(), band_.n_edge(), band_.schur_nonzeros(), resident / 1048576.0));
  }
  steps_since_factor_ = 0;
  return true;
}

int FsiCoupler::solve_band(CouplerStats& st, bool first_iteration) {
  // The region is checked every iteration: the immersed points move with the solids.
  ++solves_since_schur_;
  // At a step's first iteration the band is refreshed if the s^h marking moved (its s_I rows changed) or
  // band_refresh_steps steps have passed; otherwise the previous Newton matrix is kept (only the immersed
  // points moved, a little). Measured on the default scene (64 x 32, 400 steps): 159 refreshes instead of
  // 400, 30 s instead of 48, 1565 coupling iterations instead of 1555, the same metrics to 1.3e-7.
  if (first_iteration) ++steps_since_refresh_;
  const bool step_refresh =
      first_iteration && (band_marking_changed_ || steps_since_refresh_ >= opt_.band_refresh_steps);
  if (first_iteration) band_marking_changed_ = false;
  bool refresh = step_refresh || (opt_.band_schur_lag > 0 && solves_since_schur_ >= opt_.band_schur_lag);
  if (ensure_band_factorization()) {
    ++st.factorizations;
    refresh = true;
  }
  if (solver_ != CouplingSolver::band) return solve_fluid(st);  // the region was too large
  // Between refreshes the Newton matrix stays that of the last refresh (a chord iteration): the operator and
  // the preconditioner are the same matrix, so one FGMRES iteration solves exactly.
  Mat J = fluid_.jacobian_matrix();
  if (refresh) {
    {
      EventScope ev(events().jacobian);
      fluid_.jacobian_part(X_, J_band_, region_, true);
      CELLFSI_PETSC(MatCopy(J_fixed_, J, SAME_NONZERO_PATTERN));
      CELLFSI_PETSC(MatAXPY(J, 1.0, J_band_, SAME_NONZERO_PATTERN));
    }
    EventScope ev(events().band_update);
    band_.set_band(J_band_);
    ++st.band_refreshes;
    solves_since_schur_ = 0;
    steps_since_refresh_ = 0;
  }
  EventScope ev(events().solve);
  CELLFSI_PETSC(KSPSetOperators(band_ksp_, J, J));
  CELLFSI_PETSC(KSPSolve(band_ksp_, F_, dX_));
  return iterations_or_throw(band_ksp_);
}

int FsiCoupler::solve_fourier(CouplerStats& st, bool first_iteration) {
  Mat J = fluid_.jacobian_matrix();
  if (!fourier_->bulk().built()) {
    // Once per run: the bulk operator at the first iterate (from the initial state, the undisturbed flow,
    // uniform along the periodic directions to the projection's round-off; after a restart, the restored
    // state, whose disturbance by the cells changes the Jacobian by about Re ~ 1e-4 of its entries).
    EventScope ev(events().band_factor);
    fluid_.bulk_jacobian(X_, J);
    fourier_->set_bulk(J, true);
    ++st.factorizations;
    const double dev = fourier_->bulk().deviation();
    if (!(dev <= opt_.fourier_uniformity)) {  // NaN (a broken operator) counts as not uniform
      char amount[32];
      std::snprintf(amount, sizeof amount, "%.2e", dev);
      const std::string why = std::string("the fluid Jacobian away from the cells differs by ") + amount +
                              " of a row's largest entry between periodic positions (the mesh or the flow is "
                              "not uniform along the periodic directions)";
      if (opt_.solver == CouplingSolver::fourier)
        throw std::invalid_argument("-coupling_solver fourier: " + why +
                                    "; use -coupling_solver band or fluid");
      // Chosen by auto: the band solver where it runs (one fluid rank, SeqBAIJ), else the fluid's KSP.
      // The KSP first: its shell preconditioner points into fourier_.
      CELLFSI_PETSC(KSPDestroy(&fourier_ksp_));
      fourier_.reset();
      CELLFSI_PETSC(MatDestroy(&J_fixed_));
      region_.clear();
      fell_back_ = true;
      int ranks = 1;
      CELLFSI_PETSC(MPI_Comm_size(fluid_.comm(), &ranks));
      PetscBool seq_baij = PETSC_FALSE;
      CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(J), MATSEQBAIJ, &seq_baij));
      solver_ = ranks == 1 && seq_baij ? CouplingSolver::band : CouplingSolver::fluid;
      if (solver_ == CouplingSolver::band) setup_band();
      band_marking_changed_ = marking_changed_ = true;
      CELLFSI_PETSC(PetscPrintf(fluid_.comm(),
                                "cellfsi: note: %s; the coupling loop uses -coupling_solver %s\n",
                                why.c_str(), solver_ == CouplingSolver::band ? "band" : "fluid"));
      return solver_ == CouplingSolver::band ? solve_band(st, first_iteration) : solve_fluid(st);
    }
    double factor_mb = fourier_->bulk().factor_bytes() / 1048576.0;  // this rank's; summed over the ranks
    CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &factor_mb, 1, MPI_DOUBLE, MPI_SUM, fluid_.comm()));
    CELLFSI_PETSC(PetscPrintf(fluid_.comm(),
                              "cellfsi: Fourier bulk solver: %d wave vectors, %.1f MB of banded factors, "
                              "operator uniform to %.2e\n",
                              fourier_->bulk().n_modes(), factor_mb, dev));
    band_marking_changed_ = true;
  }
  // The Newton matrix and the region's LU are refreshed as the band solver's are (a chord iteration between).
  if (first_iteration) ++steps_since_refresh_;
  const bool refresh =
      first_iteration && (band_marking_changed_ || steps_since_refresh_ >= opt_.band_refresh_steps);
  if (first_iteration) band_marking_changed_ = false;
  if (refresh) {
    {
      // Only the elements around the cells are re-assembled (as for the band solver): the rest, kept in
      // J_fixed_, is rebuilt when the cells leave the region it was assembled for; a region of most of the
      // domain is not worth the extra matrix.
      EventScope ev(events().jacobian);
      const std::vector<char> active = active_elements();
      if (region_.empty() || !contains(region_, active)) {
        region_ = grow_elements(fluid_.patch(), active, opt_.band_margin);
        const auto in_region = std::count(region_.begin(), region_.end(), 1);
        if (!opt_.fourier_partial_jacobian || 2 * in_region > static_cast<long>(region_.size())) {
          region_.assign(region_.size(), 1);
          MatDestroy(&J_fixed_);
        } else {
          if (!J_fixed_) CELLFSI_PETSC(MatDuplicate(J, MAT_DO_NOT_COPY_VALUES, &J_fixed_));
          fluid_.jacobian_part(X_, J_fixed_, region_, false);
        }
      }
      if (J_fixed_) {
        CELLFSI_PETSC(MatCopy(J_fixed_, J, SAME_NONZERO_PATTERN));
        fluid_.jacobian_add_part(X_, J, region_);
      } else {
        fluid_.jacobian(X_, J);
      }
    }
    EventScope ev(events().band_update);
    fourier_->set_operator(J);
    ++st.band_refreshes;
    steps_since_refresh_ = 0;
    if (opt_.monitor)
      CELLFSI_PETSC(PetscPrintf(fluid_.comm(),
                                "  Fourier solver: %d nodes differ from the bulk, region %" PetscInt_FMT
                                " unknowns\n",
                                fourier_->n_differing_nodes(), fourier_->n_region()));
  }
  EventScope ev(events().solve);
  CELLFSI_PETSC(KSPSetOperators(fourier_ksp_, J, J));
  CELLFSI_PETSC(KSPSolve(fourier_ksp_, F_, dX_));
  return iterations_or_throw(fourier_ksp_);
}

int FsiCoupler::solve_fluid(CouplerStats& st) {
  KSP ksp = fluid_.ksp();
  Mat J = fluid_.jacobian_matrix();
  {
    EventScope ev(events().jacobian);
    fluid_.jacobian(X_, J);
  }
  EventScope ev(events().solve);
  CELLFSI_PETSC(KSPSetOperators(ksp, J, J));
  // The preconditioner is reused for preconditioner_lag solves, and rebuilt when the marking changed: with
  // s_I >> 1 the marked rows dominate the Jacobian.
  const bool rebuild =
      solves_since_pc_ >= opt_.preconditioner_lag || (marking_changed_ && opt_.s_interface > 1);
  marking_changed_ = false;
  CELLFSI_PETSC(KSPSetReusePreconditioner(ksp, rebuild ? PETSC_FALSE : PETSC_TRUE));
  solves_since_pc_ = rebuild ? 1 : solves_since_pc_ + 1;
  if (rebuild) ++st.factorizations;
  CELLFSI_PETSC(KSPSolve(ksp, F_, dX_));
  return iterations_or_throw(ksp);
}

void FsiCoupler::update_immersed(bool mark) {
  std::vector<geometry::Index3> elements;
  std::vector<geometry::Param> xi;
  std::vector<fluid::ImmersedPoint> data;
  std::vector<geometry::Vec3> interface;
  const double rho1 = fluid_.options().density;
  for (size_t b = 0; b < bodies_.size(); ++b) {
    const std::vector<solid::QuadratureData> q = bodies_[b]->quadrature_data(rho1);
    auto& warm = quadrature_loc_[b];
    warm.resize(q.size());
    for (size_t i = 0; i < q.size(); ++i) {
      warm[i] = locator_.locate_or_throw(q[i].x, &warm[i]);
      elements.push_back(warm[i].element);
      xi.push_back(warm[i].xi);
      fluid::ImmersedPoint ip;
      ip.weight = q[i].weight;
      ip.beta = q[i].beta;
      // The solid's stiffness in the fluid tangent (see fluid::ImmersedPoint::stiffness_viscosity).
      ip.stiffness_viscosity = q[i].shear_modulus * tp_.gamma * tp_.dt * tp_.alpha_f / (tp_.alpha_m * rho1);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) ip.stress[r][c] = q[i].stress(r, c);
      data.push_back(ip);
    }
    const std::vector<geometry::Vec3> pts = bodies_[b]->interface_points();
    interface.insert(interface.end(), pts.begin(), pts.end());
  }
  fluid_.set_immersed_points(elements, xi, data);
  if (!mark) return;
  std::vector<int> marked = functions_near(locator_, interface, opt_.marking);
  // With s_I >> 1 the marked rows dominate the Jacobian: a new marking invalidates a reused preconditioner.
  if (marked != marked_) {
    marked_ = std::move(marked);
    marking_changed_ = true;
    band_marking_changed_ = true;
  }
  const std::vector<double> s = scaling_values(fluid_.patch().n_control(), marked_, opt_.s_interface);
  fluid_.set_scaling([&](int node) { return s[node]; });
}

void FsiCoupler::initialize() {
  for (size_t b = 0; b < bodies_.size(); ++b) {
    const std::vector<geometry::Vec3> pts = bodies_[b]->collocation_points();
    const std::vector<fluid::PointSample> v = fluid_.sample(pts);
    std::vector<solid::Vec3> rate(pts.size());
    for (size_t i = 0; i < pts.size(); ++i) {
      if (!v[i].found)
        throw std::runtime_error("body '" + bodies_[b]->name() + "' lies outside the fluid domain");
      rate[i] = v[i].v;
    }
    bodies_[b]->set_rate(rate);
  }
  update_immersed(true);
}

void FsiCoupler::restart() {
  if (anderson_) anderson_->reset();
  update_immersed(true);
}

CouplerStats FsiCoupler::step() {
  CouplerStats st;
  const fluid::FluidOptions& fo = fluid_.options();
  const solid::TimeParameters tp = solid::TimeParameters::from_rho_inf(fo.rho_inf, fo.dt);
  tp_ = tp;
  fluid_.begin_step(X_);
  for (auto* b : bodies_) b->begin_step(tp);
  if (anderson_) anderson_->begin_step();
  st.solid_residual0.assign(bodies_.size(), 0.0);
  st.solid_residual.assign(bodies_.size(), 0.0);
  double fluid_peak = 0;
  std::vector<double> solid_peak(bodies_.size(), 0.0);
  for (int it = 0; it < opt_.max_iterations; ++it) {
    // Steps 1-3 for every body, from the current fluid iterate.
    for (size_t b = 0; b < bodies_.size(); ++b) {
      const std::vector<geometry::Vec3> pts = bodies_[b]->collocation_points();
      auto& warm = collocation_loc_[b];
      warm.resize(pts.size());
      std::vector<geometry::Index3> el(pts.size());
      std::vector<geometry::Param> xi(pts.size());
      {
        EventScope ev(events().locate);
        for (size_t i = 0; i < pts.size(); ++i) {
          warm[i] = locator_.locate_or_throw(pts[i], &warm[i]);
          el[i] = warm[i].element;
          xi[i] = warm[i].xi;
        }
      }
      EventScope ev(events().solid);
      const std::vector<fluid::PointSample> v = fluid_.sample_alpha(X_, el, xi);
      std::vector<solid::VelocitySample> vs(pts.size());
      for (size_t i = 0; i < pts.size(); ++i) vs[i].v = v[i].v, vs[i].grad_v = v[i].grad_v;
      st.solid_residual[b] = bodies_[b]->kinematic_update(vs);
      if (it == 0) st.solid_residual0[b] = st.solid_residual[b];
    }
    // Step 4: immersed contributions of the updated bodies, then the fluid residual. s^h is marked once per
    // step, at the first iteration: re-marking inside the iteration makes the residual jump whenever an
    // interface point crosses a support boundary, and the iteration can cycle between two markings (seen with
    // the capsule at 64 x 32: |R_MC| alternating 9.1e-4 / 1.4e-4 for 30 iterations).
    {
      EventScope ev(events().locate);
      update_immersed(it == 0);
    }
    {
      EventScope ev(events().residual);
      fluid_.residual(X_, F_);
    }
    CELLFSI_PETSC(VecNorm(F_, NORM_2, &st.fluid_residual));
    if (it == 0) st.fluid_residual0 = st.fluid_residual;
    if (opt_.monitor) {
      CELLFSI_PETSC(PetscPrintf(fluid_.comm(), "  fsi iteration %d: |R_MC| %.3e", it, st.fluid_residual));
      for (size_t b = 0; b < bodies_.size(); ++b)
        CELLFSI_PETSC(
            PetscPrintf(fluid_.comm(), "  |R_K(%s)| %.3e", bodies_[b]->name().c_str(), st.solid_residual[b]));
      CELLFSI_PETSC(PetscPrintf(fluid_.comm(), "\n"));
    }
    // Each residual must drop by the tolerance below the largest value it has had in this step: the kinematic
    // residual is ~0 at the first iteration when the predictor matches the fluid, and grows once the fluid
    // moves.
    fluid_peak = std::max(fluid_peak, st.fluid_residual);
    bool done = st.fluid_residual <= opt_.tolerance * fluid_peak || st.fluid_residual <= opt_.fluid_atol;
    for (size_t b = 0; b < bodies_.size(); ++b) {
      solid_peak[b] = std::max(solid_peak[b], st.solid_residual[b]);
      done = done && (st.solid_residual[b] <= opt_.tolerance * solid_peak[b] ||
                      st.solid_residual[b] <= opt_.solid_atol);
    }
    if (done && it > 0) {
      st.converged = true;
      st.reason = "all residuals dropped by the tolerance";
      break;
    }
    st.iterations = it + 1;
    // Steps 5-7: K_MC, a linear solve, the update.
    try {
      st.linear_iterations += solver_ == CouplingSolver::band      ? solve_band(st, it == 0)
                              : solver_ == CouplingSolver::fourier ? solve_fourier(st, it == 0)
                                                                   : solve_fluid(st);
    } catch (const std::invalid_argument&) {
      throw;  // bad input found by the solver (a misspelt type read at the first solve)
    } catch (const std::exception& e) {
      st.reason = e.what();
      if (anderson_) anderson_->reset();
      return st;
    }
    if (anderson_)
      anderson_->update(X_, dX_);
    else
      CELLFSI_PETSC(VecAXPY(X_, -1.0, dX_));
  }
  if (!st.converged) {
    if (anderson_) anderson_->reset();
    if (st.reason.empty())
      st.reason = "no convergence in " + std::to_string(opt_.max_iterations) + " iterations";
    return st;
  }
  fluid_.end_step(X_);
  for (auto* b : bodies_) b->end_step();
  ++steps_since_factor_;
  return st;
}

}  // namespace cellfsi::coupling
