// See pc_types.hpp.
#include "solvers/pc_types.hpp"

#include "solvers/pc_bulk.hpp"

#include "common/petsc_error.hpp"

namespace cellfsi::solvers {

void register_pc_types() {
  static bool done = false;
  if (done) return;
  CELLFSI_PETSC(PCRegister(kPCFourier, pc_create_fourier));
  CELLFSI_PETSC(PCRegister(kPCBand, pc_create_band));
  CELLFSI_PETSC(PCRegister(kPCBulk, pc_create_bulk));
  register_pc_lu_single();  // (and the ordering cellfsi_nd)
  done = true;
}

bool pc_is(PC pc, const char* type) {
  PetscBool same = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(pc), type, &same));
  return same;
}

}  // namespace cellfsi::solvers
