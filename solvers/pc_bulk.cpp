#include "solvers/pc_bulk.hpp"

#include <stdexcept>

#include "solvers/pc_impl.hpp"

namespace cellfsi::solvers {

namespace {

constexpr const char* kBulkKey = "cellfsi_bulk_inverse";

struct PCBulk {
  std::shared_ptr<BulkInverse> bulk;  // found on the operator at set-up
};

PCBulk& context(PC pc) { return *static_cast<PCBulk*>(pc->data); }

PetscErrorCode set_up(PC pc) {
  return pc_impl::guarded(pc, [&] {
    PCBulk& c = context(pc);
    c.bulk = pc_impl::composed_shared<BulkInverse>(pc->pmat, kBulkKey);
    if (!c.bulk || !c.bulk->apply)
      throw std::logic_error(
          "cellfsi_bulk: set up on an operator without its bulk inverse (solvers::pc_bulk_compose; in cellfsi "
          "the coupling loop gives it, from a fluid that has one: -fluid_space div_conforming)");
  });
}

PetscErrorCode apply(PC pc, Vec r, Vec x) {
  return pc_impl::guarded(pc, [&] {
    context(pc).bulk->apply(r, x);
  });
}

PetscErrorCode view(PC pc, PetscViewer v) {
  const PCBulk& c = context(pc);
  return pc_impl::view_ascii(v, "cellfsi: the fluid's own bulk inverse (solvers/pc_bulk.hpp)",
                             [&]() -> PetscErrorCode {
                               if (c.bulk)
                                 PetscCall(PetscViewerASCIIPrintf(v, "  %s\n", c.bulk->description.c_str()));
                               return 0;
                             });
}

PetscErrorCode set_from_options(PC, PetscOptionItems*) { return 0; }

PetscErrorCode reset(PC pc) {
  context(pc).bulk.reset();
  return 0;
}

}  // namespace

PetscErrorCode pc_create_bulk(PC pc) {
  return pc_impl::create<PCBulk>(pc, set_up, apply, view, set_from_options, reset);
}

void pc_bulk_compose(Mat A, std::shared_ptr<BulkInverse> bulk) {
  pc_impl::compose_shared(A, kBulkKey, std::move(bulk));
}

}  // namespace cellfsi::solvers
