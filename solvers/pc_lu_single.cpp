// See pc_lu_single.hpp. The shape of PETSc's own types (src/ksp/pc/impls/jacobi/jacobi.c): a context, and
// set-up, apply, view, set-from-options, reset and destroy operations.
#include "solvers/pc_lu_single.hpp"

#include <memory>

#include "solvers/nested_dissection.hpp"
#include "solvers/pc_impl.hpp"

namespace cellfsi::solvers {

namespace {

const char* const kOrderings[] = {kMatOrderingNestedDissection, "mumps"};  // the first is the default

/// The type's context (pc->data).
struct PCLUSingle {
  std::unique_ptr<SinglePrecisionLU> lu;  // made at the first set-up
  PetscInt ordering = 0;                  // index in kOrderings
};

PCLUSingle& context(PC pc) { return *static_cast<PCLUSingle*>(pc->data); }

PetscErrorCode set_up(PC pc) {
  return pc_impl::guarded(pc, [&] {
    PCLUSingle& c = context(pc);
    if (!c.lu) c.lu = std::make_unique<SinglePrecisionLU>(PetscObjectComm(reinterpret_cast<PetscObject>(pc)));
    c.lu->set_ordering(kOrderings[c.ordering]);
    c.lu->factor(pc->pmat);
  });
}

PetscErrorCode apply(PC pc, Vec r, Vec x) {
  return pc_impl::guarded(pc, [&] { context(pc).lu->solve(r, x); });
}

PetscErrorCode view(PC pc, PetscViewer v) {
  const PCLUSingle& c = context(pc);
  return pc_impl::view_ascii(
      v, "cellfsi LU in single precision (solvers/single_precision_lu.hpp)", [&]() -> PetscErrorCode {
        PetscCall(PetscViewerASCIIPrintf(v, "  MUMPS LU in single precision, ordering %s\n",
                                         kOrderings[c.ordering]));
        if (c.lu && c.lu->factored())
          PetscCall(PetscViewerASCIIPrintf(v,
                                           "  %" PetscInt_FMT
                                           " unknowns, %.3e operations, %lld entries in the factors "
                                           "(%.1f MB), %d analyses\n",
                                           c.lu->size(), c.lu->operations(), c.lu->factor_entries(),
                                           4.0 * static_cast<double>(c.lu->factor_entries()) / 1048576.0,
                                           c.lu->analyses()));
        return 0;
      });
}

PetscErrorCode set_from_options(PC pc, PetscOptionItems* PetscOptionsObject) {
  PCLUSingle& c = context(pc);
  PetscOptionsHeadBegin(PetscOptionsObject, "cellfsi_lu_single options");
  PetscCall(PetscOptionsEList(
      "-pc_lu_single_ordering",
      "Fill-reducing ordering: SCOTCH's nested dissection of the node graph, or MUMPS' own "
      "choice",
      "solvers/single_precision_lu.hpp", kOrderings, 2, kOrderings[c.ordering], &c.ordering, nullptr));
  PetscOptionsHeadEnd();
  return 0;
}

/// The factors go; the ordering stays (as PCReset of PETSc's LU keeps its options).
PetscErrorCode reset(PC pc) {
  context(pc).lu.reset();
  return 0;
}

PetscErrorCode create(PC pc) {
  return pc_impl::create<PCLUSingle>(pc, set_up, apply, view, set_from_options, reset);
}

}  // namespace

void register_pc_lu_single() {
  static bool done = false;
  if (done) return;
  CELLFSI_PETSC(PCRegister(kPCLUSingle, create));
  register_orderings();  // its default ordering, and the region's LU's -..._pc_factor_mat_ordering_type
                         // cellfsi_nd
  done = true;
}

const SinglePrecisionLU* pc_lu_single_solver(PC pc) {
  return pc_impl::has_type(reinterpret_cast<PetscObject>(pc), kPCLUSingle) ? context(pc).lu.get() : nullptr;
}

}  // namespace cellfsi::solvers
