// See pc_band.hpp. The shape of PETSc's own types (src/ksp/pc/impls/jacobi/jacobi.c): a context, and set-up,
// apply, view, set-from-options, reset and destroy operations.
#include "solvers/pc_band.hpp"

#include <memory>

#include "solvers/pc_impl.hpp"

namespace cellfsi::solvers {

namespace {

// The keys under which an operator carries its split.
constexpr const char* kFixedKey = "cellfsi_band_fixed";
constexpr const char* kBandKey = "cellfsi_band_unknowns";

/// The type's context (pc->data).
struct PCBand {
  std::unique_ptr<BandSchurSolver> band;  // made at the first set-up
  BandSchurOptions options;
  // What the factors were made of: the kept part and its state, the band's index set.
  Mat factored_fixed = nullptr;
  PetscObjectState factored_state = 0;
  IS factored_band = nullptr;
};

PCBand& context(PC pc) { return *static_cast<PCBand*>(pc->data); }

PetscErrorCode set_up(PC pc) {
  return pc_impl::guarded(pc, [&] {
    PCBand& c = context(pc);
    PetscObject fixed = nullptr, band = nullptr;
    CELLFSI_PETSC(PetscObjectQuery(reinterpret_cast<PetscObject>(pc->pmat), kFixedKey, &fixed));
    CELLFSI_PETSC(PetscObjectQuery(reinterpret_cast<PetscObject>(pc->pmat), kBandKey, &band));
    if (!fixed || !band)
      throw std::logic_error(
          "cellfsi_band: set up on an operator without its kept part and band "
          "(solvers::pc_band_compose_split; "
          "in cellfsi the coupling loop gives them)");
    PetscObjectState state = 0;
    CELLFSI_PETSC(PetscObjectStateGet(fixed, &state));
    if (!c.band) c.band = std::make_unique<BandSchurSolver>();
    if (!c.band->factored() || reinterpret_cast<Mat>(fixed) != c.factored_fixed ||
        state != c.factored_state || reinterpret_cast<IS>(band) != c.factored_band) {
      c.factored_fixed = nullptr;  // (a factorisation that fails leaves none)
      c.band->set_fused_solve(c.options.fused_solve);
      c.band->set_blr_tolerance(c.options.blr_tolerance);
      c.band->factor(reinterpret_cast<Mat>(fixed), reinterpret_cast<IS>(band),
                     pc_impl::prefix_of(pc) + "band_");
      c.factored_fixed = reinterpret_cast<Mat>(fixed);
      // (After the factorisation: reading the kept part's entries may raise its state.)
      CELLFSI_PETSC(PetscObjectStateGet(fixed, &c.factored_state));
      c.factored_band = reinterpret_cast<IS>(band);
    }
    c.band->set_operator(pc->pmat);
  });
}

PetscErrorCode apply(PC pc, Vec r, Vec x) {
  return pc_impl::guarded(pc, [&] { context(pc).band->solve(r, x); });
}

PetscErrorCode view(PC pc, PetscViewer v) {
  const PCBand& c = context(pc);
  return pc_impl::view_ascii(
      v, "cellfsi kept part LU + band Schur complement (solvers/band_schur.hpp)", [&]() -> PetscErrorCode {
        PetscCall(PetscViewerASCIIPrintf(
            v, "  fused solve %s, block low-rank tolerance of the kept part %g\n",
            c.options.fused_solve ? "yes" : "no", static_cast<double>(c.options.blr_tolerance)));
        if (c.band && c.band->factored())
          PetscCall(PetscViewerASCIIPrintf(
              v,
              "  band: %" PetscInt_FMT " of %" PetscInt_FMT " unknowns, edge %" PetscInt_FMT
              ", Schur complement %" PetscInt_FMT " nonzeros\n",
              c.band->n_band(), c.band->n_total(), c.band->n_edge(), c.band->schur_nonzeros()));
        return 0;
      });
}

PetscErrorCode set_from_options(PC pc, PetscOptionItems* PetscOptionsObject) {
  PCBand& c = context(pc);
  PetscBool fused = c.options.fused_solve ? PETSC_TRUE : PETSC_FALSE;
  PetscReal blr = c.options.blr_tolerance;
  PetscOptionsHeadBegin(PetscOptionsObject, "cellfsi_band options");
  PetscCall(PetscOptionsBool("-pc_band_fused", "One MUMPS solve with the Schur complement's inside it",
                             "solvers/pc_band.hpp", fused, &fused, nullptr));
  PetscCall(PetscOptionsReal("-pc_band_blr_tolerance",
                             "Block low-rank threshold of the kept part's factors (0: full rank)",
                             "solvers/pc_band.hpp", blr, &blr, nullptr));
  if (!BandSchurOptions::valid_blr_tolerance(blr))
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
            "-%spc_band_blr_tolerance %g is invalid. Valid values are %s", pc_impl::prefix_of(pc).c_str(),
            static_cast<double>(blr), BandSchurOptions::kBlrToleranceRange);
  PetscOptionsHeadEnd();
  c.options.fused_solve = fused == PETSC_TRUE;  // (taking effect at the next factorisation)
  c.options.blr_tolerance = blr;
  return 0;
}

/// The factors go (the next set-up factorises again); the options stay.
PetscErrorCode reset(PC pc) {
  PCBand& c = context(pc);
  c.band.reset();
  c.factored_fixed = nullptr;
  c.factored_band = nullptr;
  return 0;
}

}  // namespace

PetscErrorCode pc_create_band(PC pc) {
  return pc_impl::create<PCBand>(pc, set_up, apply, view, set_from_options, reset);
}

void pc_band_compose_split(Mat K, Mat fixed, IS band) {
  CELLFSI_PETSC(
      PetscObjectCompose(reinterpret_cast<PetscObject>(K), kFixedKey, reinterpret_cast<PetscObject>(fixed)));
  CELLFSI_PETSC(
      PetscObjectCompose(reinterpret_cast<PetscObject>(K), kBandKey, reinterpret_cast<PetscObject>(band)));
}

const BandSchurSolver* pc_band_solver(PC pc) {
  return pc_impl::has_type(reinterpret_cast<PetscObject>(pc), kPCBand) ? context(pc).band.get() : nullptr;
}

}  // namespace cellfsi::solvers
