// See pc_types.hpp.
#include "solvers/pc_types.hpp"

#include <cstring>
#include <exception>
#include <memory>
#include <string>

#include "common/petsc_error.hpp"
#include "solvers/nested_dissection.hpp"

namespace cellfsi::solvers {

namespace {

constexpr const char* kContextKey = "cellfsi_pc_context";
constexpr const char* kHandlerKey = "cellfsi_pc_options_handler";

/// What a cellfsi PC holds: its solver and options (one of the two parts is used, by its type).
struct Context {
  // cellfsi_fourier
  std::unique_ptr<RegionCorrectedSolver> fourier;
  PetscReal threshold = 1e-3;  // relative deviation from the bulk operator that puts a node in the region
  PetscInt overlap = 0;        // node layers the region is grown by
  PetscInt region_solves = 1;  // region LU solves per application: 1 (bulk, region) or 2 (region, bulk, region)
  // cellfsi_band
  std::unique_ptr<BandSchurSolver> band;
  PetscBool fused = PETSC_TRUE;  // BandSchurSolver::set_fused_solve
  PetscReal blr = 1e-10;         // BandSchurSolver::set_blr_tolerance
  // cellfsi_lu_single
  std::unique_ptr<SinglePrecisionLU> single;
  PetscInt ordering = 0;  // index in kSingleOrderings
};

const char* const kSingleOrderings[] = {kMatOrderingNestedDissection, "mumps"};

PetscErrorCode destroy_context(void* p) {
  delete static_cast<Context*>(p);
  return 0;
}

Context* context(PC pc) {
  PetscContainer c = nullptr;
  CELLFSI_PETSC(PetscObjectQuery(reinterpret_cast<PetscObject>(pc), kContextKey,
                                 reinterpret_cast<PetscObject*>(&c)));
  if (!c) return nullptr;
  void* p = nullptr;
  CELLFSI_PETSC(PetscContainerGetPointer(c, &p));
  return static_cast<Context*>(p);
}

std::string prefix_of(PC pc) {
  const char* p = nullptr;
  CELLFSI_PETSC(PCGetOptionsPrefix(pc, &p));
  return p ? p : "";
}

/// Runs `f`, turning an exception into a PETSc error carrying its message (PETSC_ERR_USER_INPUT for bad
/// input, which CELLFSI_PETSC turns back into std::invalid_argument with the same message).
template <class F>
PetscErrorCode guarded(PC pc, F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    SETERRQ(PetscObjectComm(reinterpret_cast<PetscObject>(pc)), PETSC_ERR_USER_INPUT, "%s", e.what());
  } catch (const std::exception& e) {
    SETERRQ(PetscObjectComm(reinterpret_cast<PetscObject>(pc)), PETSC_ERR_LIB, "%s", e.what());
  }
  return 0;
}

void apply_fourier_options(Context& c) {
  if (!c.fourier) return;
  c.fourier->set_region(c.threshold, static_cast<int>(c.overlap));
  c.fourier->set_region_solves(static_cast<int>(c.region_solves));
}

// --- the PCSHELL callbacks ---------------------------------------------------------------------------------

PetscErrorCode set_up(PC pc) {
  return guarded(pc, [&] {
    Context* c = context(pc);
    Mat P = nullptr;
    CELLFSI_PETSC(PCGetOperators(pc, nullptr, &P));
    if (pc_is(pc, kPCLUSingle)) {
      if (!c->single)
        c->single = std::make_unique<SinglePrecisionLU>(PetscObjectComm(reinterpret_cast<PetscObject>(pc)));
      c->single->set_ordering(kSingleOrderings[c->ordering]);
      c->single->factor(P);
    } else if (pc_is(pc, kPCFourier)) {
      if (!c->fourier || !c->fourier->bulk().built())
        throw std::logic_error(
            "cellfsi_fourier: set up before its box and bulk operator were given (solvers::pc_fourier_set_box "
            "and pc_fourier_set_bulk; in cellfsi the coupling loop gives them)");
      c->fourier->set_operator(P);
    } else {
      if (!c->band || !c->band->factored())
        throw std::logic_error(
            "cellfsi_band: set up before its kept part and band were given (solvers::pc_band_set_split; in "
            "cellfsi the coupling loop gives them)");
      c->band->set_operator(P);
    }
  });
}

PetscErrorCode apply(PC pc, Vec r, Vec x) {
  return guarded(pc, [&] {
    Context* c = context(pc);
    if (pc_is(pc, kPCLUSingle))
      c->single->solve(r, x);
    else if (pc_is(pc, kPCFourier))
      c->fourier->apply(r, x);
    else
      c->band->solve(r, x);
  });
}

PetscErrorCode view(PC pc, PetscViewer v) {
  PetscBool ascii = PETSC_FALSE;
  PetscCall(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(v), PETSCVIEWERASCII, &ascii));
  if (!ascii) return 0;
  const Context* c = context(pc);
  if (pc_is(pc, kPCLUSingle)) {
    PetscCall(
        PetscViewerASCIIPrintf(v, "  MUMPS LU in single precision, ordering %s\n", kSingleOrderings[c->ordering]));
    if (c->single && c->single->factored())
      PetscCall(PetscViewerASCIIPrintf(v,
                                       "  %" PetscInt_FMT " unknowns, %.3e operations, %lld entries in the factors "
                                       "(%.1f MB), %d analyses\n",
                                       c->single->size(), c->single->operations(), c->single->factor_entries(),
                                       4.0 * static_cast<double>(c->single->factor_entries()) / 1048576.0,
                                       c->single->analyses()));
  } else if (pc_is(pc, kPCFourier)) {
    PetscCall(PetscViewerASCIIPrintf(v, "  region: nodes deviating by more than %g from the bulk operator, grown "
                                        "by %" PetscInt_FMT " layers; %" PetscInt_FMT " region solve(s) per "
                                        "application\n",
                                     static_cast<double>(c->threshold), c->overlap, c->region_solves));
    if (c->fourier && c->fourier->bulk().built())
      PetscCall(PetscViewerASCIIPrintf(v,
                                       "  bulk: %d wave vectors, %.1f MB of banded factors on this rank, uniform to "
                                       "%.2e; region: %d differing nodes, %" PetscInt_FMT " unknowns\n",
                                       c->fourier->bulk().n_modes(), c->fourier->bulk().factor_bytes() / 1048576.0,
                                       c->fourier->bulk().deviation(), c->fourier->n_differing_nodes(),
                                       c->fourier->n_region()));
    if (c->fourier && c->fourier->region_ksp()) {
      PetscCall(PetscViewerASCIIPushTab(v));
      PetscCall(KSPView(c->fourier->region_ksp(), v));
      PetscCall(PetscViewerASCIIPopTab(v));
    }
  } else {
    PetscCall(PetscViewerASCIIPrintf(v, "  fused solve %s, block low-rank tolerance of the kept part %g\n",
                                     c->fused ? "yes" : "no", static_cast<double>(c->blr)));
    if (c->band && c->band->factored())
      PetscCall(PetscViewerASCIIPrintf(v,
                                       "  band: %" PetscInt_FMT " of %" PetscInt_FMT " unknowns, edge %" PetscInt_FMT
                                       ", Schur complement %" PetscInt_FMT " nonzeros\n",
                                       c->band->n_band(), c->band->n_total(), c->band->n_edge(),
                                       c->band->schur_nonzeros()));
  }
  return 0;
}

/// PCSetFromOptions of both types (an options handler: a PCSHELL has no set-from-options of its own).
PetscErrorCode set_from_options(PetscObject obj, PetscOptionItems* PetscOptionsObject, void*) {
  PC pc = reinterpret_cast<PC>(obj);
  Context* c = nullptr;
  PetscCall(guarded(pc, [&] { c = context(pc); }));
  if (!c) return 0;  // the PC has another type now
  if (pc_is(pc, kPCFourier)) {
    PetscOptionsHeadBegin(PetscOptionsObject, "cellfsi_fourier options");
    PetscCall(PetscOptionsReal("-pc_fourier_threshold",
                               "Relative deviation of a node's rows from the bulk operator that puts it in the "
                               "LU-corrected region",
                               "solvers/pc_types.hpp", c->threshold, &c->threshold, nullptr));
    PetscCall(PetscOptionsRangeInt("-pc_fourier_overlap", "Node layers the LU-corrected region is grown by",
                                   "solvers/pc_types.hpp", c->overlap, &c->overlap, nullptr, 0, 20));
    PetscCall(PetscOptionsRangeInt("-pc_fourier_region_solves",
                                   "Region LU solves per application: 1 (bulk, region) or 2 (region, bulk, "
                                   "region)",
                                   "solvers/pc_types.hpp", c->region_solves, &c->region_solves, nullptr, 1, 2));
    if (!(c->threshold > 0))
      SETERRQ(PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
              "-%spc_fourier_threshold %g is invalid. Valid values are > 0", prefix_of(pc).c_str(),
              static_cast<double>(c->threshold));
    PetscCall(guarded(pc, [&] { apply_fourier_options(*c); }));
    PetscOptionsHeadEnd();
  } else if (pc_is(pc, kPCLUSingle)) {
    PetscOptionsHeadBegin(PetscOptionsObject, "cellfsi_lu_single options");
    PetscCall(PetscOptionsEList("-pc_lu_single_ordering",
                                "Fill-reducing ordering: SCOTCH's nested dissection of the node graph, or MUMPS' "
                                "own choice",
                                "solvers/single_precision_lu.hpp", kSingleOrderings, 2, kSingleOrderings[c->ordering],
                                &c->ordering, nullptr));
    PetscOptionsHeadEnd();
  } else if (pc_is(pc, kPCBand)) {
    PetscOptionsHeadBegin(PetscOptionsObject, "cellfsi_band options");
    PetscCall(PetscOptionsBool("-pc_band_fused", "One MUMPS solve with the Schur complement's inside it",
                               "solvers/pc_types.hpp", c->fused, &c->fused, nullptr));
    PetscCall(PetscOptionsReal("-pc_band_blr_tolerance",
                               "Block low-rank threshold of the kept part's factors (0: full rank)",
                               "solvers/pc_types.hpp", c->blr, &c->blr, nullptr));
    if (!(c->blr >= 0 && c->blr < 1))
      SETERRQ(PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
              "-%spc_band_blr_tolerance %g is invalid. Valid values are in [0, 1)", prefix_of(pc).c_str(),
              static_cast<double>(c->blr));
    if (c->band) {
      c->band->set_fused_solve(c->fused);
      c->band->set_blr_tolerance(c->blr);
    }
    PetscOptionsHeadEnd();
  }
  return 0;
}

/// The shell's destroy: the context goes with its container.
PetscErrorCode destroy(PC pc) {
  PetscCall(PetscObjectCompose(reinterpret_cast<PetscObject>(pc), kContextKey, nullptr));
  return 0;
}

/// PCCreate of both types: a PCSHELL with the callbacks above, renamed to the type asked for.
PetscErrorCode create(PC pc, const char* type, const char* name) {
  PetscCall(PCSetType(pc, PCSHELL));
  PetscCall(PCShellSetName(pc, name));  // while it is a PCSHELL: the name is what PCView prints first
  PetscCall(PCShellSetSetUp(pc, set_up));
  PetscCall(PCShellSetApply(pc, apply));
  PetscCall(PCShellSetView(pc, view));
  PetscCall(PCShellSetDestroy(pc, destroy));
  PetscCall(PetscObjectChangeTypeName(reinterpret_cast<PetscObject>(pc), type));
  PetscContainer c = nullptr;
  PetscCall(PetscContainerCreate(PetscObjectComm(reinterpret_cast<PetscObject>(pc)), &c));
  PetscCall(PetscContainerSetPointer(c, new Context));
  PetscCall(PetscContainerSetUserDestroy(c, destroy_context));
  PetscCall(PetscObjectCompose(reinterpret_cast<PetscObject>(pc), kContextKey, reinterpret_cast<PetscObject>(c)));
  PetscCall(PetscContainerDestroy(&c));
  // One options handler per PC object, whatever types it takes in turn (PETSc keeps at most five).
  PetscObject marker = nullptr;
  PetscCall(PetscObjectQuery(reinterpret_cast<PetscObject>(pc), kHandlerKey, &marker));
  if (!marker) {
    PetscCall(PetscObjectAddOptionsHandler(reinterpret_cast<PetscObject>(pc), set_from_options, nullptr, nullptr));
    PetscContainer m = nullptr;
    PetscCall(PetscContainerCreate(PetscObjectComm(reinterpret_cast<PetscObject>(pc)), &m));
    PetscCall(PetscObjectCompose(reinterpret_cast<PetscObject>(pc), kHandlerKey, reinterpret_cast<PetscObject>(m)));
    PetscCall(PetscContainerDestroy(&m));
  }
  return 0;
}

PetscErrorCode create_fourier(PC pc) {
  return create(pc, kPCFourier, "cellfsi Fourier bulk solver + region LU (solvers/region_corrected.hpp)");
}

PetscErrorCode create_band(PC pc) {
  return create(pc, kPCBand, "cellfsi kept part LU + band Schur complement (solvers/band_schur.hpp)");
}

PetscErrorCode create_lu_single(PC pc) {
  return create(pc, kPCLUSingle, "cellfsi LU in single precision (solvers/single_precision_lu.hpp)");
}

Context& context_of_type(PC pc, const char* type, const char* caller) {
  Context* c = pc_is(pc, type) ? context(pc) : nullptr;
  if (!c) throw std::logic_error(std::string(caller) + ": the PC is not of type " + type);
  return *c;
}

}  // namespace

void register_pc_types() {
  static bool done = false;
  if (done) return;
  CELLFSI_PETSC(PCRegister(kPCFourier, create_fourier));
  CELLFSI_PETSC(PCRegister(kPCBand, create_band));
  CELLFSI_PETSC(PCRegister(kPCLUSingle, create_lu_single));
  register_orderings();  // the region's LU orders by -..._pc_factor_mat_ordering_type cellfsi_nd
  done = true;
}

bool pc_is(PC pc, const char* type) {
  PetscBool same = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(pc), type, &same));
  return same;
}

void pc_fourier_set_box(PC pc, const BoxMesh& box) {
  Context& c = context_of_type(pc, kPCFourier, "pc_fourier_set_box");
  // The region's LU has the options prefix <PC prefix>fourier_region_ (e.g. -coupling_fourier_region_*).
  c.fourier = std::make_unique<RegionCorrectedSolver>(box.n, box.periodic, box.degree, box.dof,
                                                      prefix_of(pc) + "fourier_",
                                                      PetscObjectComm(reinterpret_cast<PetscObject>(pc)),
                                                      box.natural);
  apply_fourier_options(c);
}

double pc_fourier_set_bulk(PC pc, Mat A, bool pin_pressure) {
  Context& c = context_of_type(pc, kPCFourier, "pc_fourier_set_bulk");
  if (!c.fourier) throw std::logic_error("pc_fourier_set_bulk before pc_fourier_set_box");
  c.fourier->set_bulk(A, pin_pressure);
  return c.fourier->bulk().deviation();
}

const RegionCorrectedSolver* pc_fourier_solver(PC pc) {
  return pc_is(pc, kPCFourier) ? context(pc)->fourier.get() : nullptr;
}

void pc_band_set_split(PC pc, Mat fixed, IS band) {
  Context& c = context_of_type(pc, kPCBand, "pc_band_set_split");
  if (!c.band) c.band = std::make_unique<BandSchurSolver>();
  c.band->set_fused_solve(c.fused);
  c.band->set_blr_tolerance(c.blr);
  // The kept part's MUMPS factors have the options prefix <PC prefix>band_ (e.g. -coupling_band_mat_mumps_*),
  // the Schur complement's <PC prefix>band_schur_.
  c.band->factor(fixed, band, prefix_of(pc) + "band_");
}

const BandSchurSolver* pc_band_solver(PC pc) { return pc_is(pc, kPCBand) ? context(pc)->band.get() : nullptr; }

const SinglePrecisionLU* pc_lu_single_solver(PC pc) {
  return pc_is(pc, kPCLUSingle) ? context(pc)->single.get() : nullptr;
}

}  // namespace cellfsi::solvers
