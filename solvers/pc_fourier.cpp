// See pc_fourier.hpp. The shape of PETSc's own types (src/ksp/pc/impls/jacobi/jacobi.c): a context, and
// set-up, apply, view, set-from-options, reset and destroy operations.
#include "solvers/pc_fourier.hpp"

#include "solvers/pc_impl.hpp"

namespace cellfsi::solvers {

namespace {

// The key under which an operator carries its bulk solver (a PetscContainer of a shared pointer).
constexpr const char* kBulkKey = "cellfsi_fourier_bulk";

/// The type's context (pc->data).
struct PCFourier {
  std::unique_ptr<RegionCorrectedSolver> solver;  // made at the first set-up, for the operator's bulk solver
  RegionOptions options;
};

PCFourier& context(PC pc) { return *static_cast<PCFourier*>(pc->data); }

PetscErrorCode set_up(PC pc) {
  return pc_impl::guarded(pc, [&] {
    PCFourier& c = context(pc);
    std::shared_ptr<FourierBulkSolver> bulk = pc_impl::composed_shared<FourierBulkSolver>(pc->pmat, kBulkKey);
    if (!bulk || !bulk->built())
      throw std::logic_error(
          "cellfsi_fourier: set up on an operator without its built bulk solver "
          "(solvers::pc_fourier_compose_bulk; "
          "in cellfsi the coupling loop gives it)");
    if (!c.solver || &c.solver->bulk() != bulk.get()) {
      c.solver =
          std::make_unique<RegionCorrectedSolver>(std::move(bulk), pc_impl::prefix_of(pc) + "fourier_");
      c.solver->set_options(c.options);
    }
    c.solver->set_operator(pc->pmat);
  });
}

PetscErrorCode apply(PC pc, Vec r, Vec x) {
  return pc_impl::guarded(pc, [&] { context(pc).solver->apply(r, x); });
}

PetscErrorCode view(PC pc, PetscViewer v) {
  const PCFourier& c = context(pc);
  return pc_impl::view_ascii(
      v, "cellfsi Fourier bulk solver + region LU (solvers/region_corrected.hpp)", [&]() -> PetscErrorCode {
        PetscCall(PetscViewerASCIIPrintf(
            v,
            "  region: nodes deviating by more than %g from the bulk operator, grown by %d "
            "layers; %d region solve(s) per application\n",
            c.options.threshold, c.options.overlap, c.options.region_solves));
        const RegionCorrectedSolver* s = c.solver.get();
        if (s)
          PetscCall(PetscViewerASCIIPrintf(
              v,
              "  bulk: %d wave vectors, %.1f MB of banded factors on this rank, uniform to "
              "%.2e; region: %d differing nodes, %" PetscInt_FMT " unknowns\n",
              s->bulk().n_modes(), s->bulk().factor_bytes() / 1048576.0, s->bulk().deviation(),
              s->n_differing_nodes(), s->n_region()));
        if (s && s->region_ksp()) {
          PetscCall(PetscViewerASCIIPushTab(v));
          PetscCall(KSPView(s->region_ksp(), v));
          PetscCall(PetscViewerASCIIPopTab(v));
        }
        return 0;
      });
}

PetscErrorCode set_from_options(PC pc, PetscOptionItems* PetscOptionsObject) {
  PCFourier& c = context(pc);
  RegionOptions o = c.options;
  PetscReal threshold = o.threshold;
  PetscInt overlap = o.overlap, solves = o.region_solves;
  PetscOptionsHeadBegin(PetscOptionsObject, "cellfsi_fourier options");
  PetscCall(PetscOptionsReal("-pc_fourier_threshold",
                             "Relative deviation of a node's rows from the bulk operator that puts it in the "
                             "LU-corrected region",
                             "solvers/pc_fourier.hpp", threshold, &threshold, nullptr));
  PetscCall(PetscOptionsRangeInt("-pc_fourier_overlap", "Node layers the LU-corrected region is grown by",
                                 "solvers/pc_fourier.hpp", overlap, &overlap, nullptr, 0,
                                 RegionOptions::kMaxOverlap));
  PetscCall(
      PetscOptionsRangeInt("-pc_fourier_region_solves",
                           "Region LU solves per application: 1 (bulk, region) or 2 (region, bulk, region)",
                           "solvers/pc_fourier.hpp", solves, &solves, nullptr, 1, 2));
  if (!(threshold > 0))
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
            "-%spc_fourier_threshold %g is invalid. Valid values are > 0", pc_impl::prefix_of(pc).c_str(),
            static_cast<double>(threshold));
  PetscOptionsHeadEnd();
  o.threshold = threshold;
  o.overlap = static_cast<int>(overlap);
  o.region_solves = static_cast<int>(solves);
  c.options = o;
  if (c.solver) PetscCall(pc_impl::guarded(pc, [&] { c.solver->set_options(o); }));
  return 0;
}

/// The region's factors go with the solver (the next set-up makes it again); the options stay.
PetscErrorCode reset(PC pc) {
  context(pc).solver.reset();
  return 0;
}

}  // namespace

PetscErrorCode pc_create_fourier(PC pc) {
  return pc_impl::create<PCFourier>(pc, set_up, apply, view, set_from_options, reset);
}

void pc_fourier_compose_bulk(Mat A, std::shared_ptr<FourierBulkSolver> bulk) {
  pc_impl::compose_shared(A, kBulkKey, std::move(bulk));
}

const RegionCorrectedSolver* pc_fourier_solver(PC pc) {
  return pc_impl::has_type(reinterpret_cast<PetscObject>(pc), kPCFourier) ? context(pc).solver.get()
                                                                          : nullptr;
}

}  // namespace cellfsi::solvers
