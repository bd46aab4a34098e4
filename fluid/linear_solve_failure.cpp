// See linear_solve_failure.hpp.
#include "fluid/linear_solve_failure.hpp"

#include "common/petsc_error.hpp"

namespace cellfsi::fluid {

namespace {

/// Why a preconditioner failed, looking into the subdomain solvers of ASM and block Jacobi (where a
/// factorisation that ran out of memory is reported as a subdomain error).
std::string pc_failure(PC pc) {
  PCFailedReason reason = PC_NOERROR;
  CELLFSI_PETSC(PCGetFailedReasonRank(pc, &reason));
  if (reason == PC_SUBPC_ERROR) {
    PetscBool asm_pc = PETSC_FALSE, bjacobi = PETSC_FALSE;
    CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(pc), PCASM, &asm_pc));
    CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(pc), PCBJACOBI, &bjacobi));
    KSP* sub = nullptr;
    PetscInt n = 0;
    if (asm_pc) CELLFSI_PETSC(PCASMGetSubKSP(pc, &n, nullptr, &sub));
    if (bjacobi) CELLFSI_PETSC(PCBJacobiGetSubKSP(pc, &n, nullptr, &sub));
    for (PetscInt i = 0; i < n; ++i) {
      PC sub_pc;
      CELLFSI_PETSC(KSPGetPC(sub[i], &sub_pc));
      const std::string why = pc_failure(sub_pc);
      if (!why.empty()) return why;
    }
  }
  switch (reason) {
    case PC_NOERROR:
      return "";
    case PC_FACTOR_OUTMEMORY:
      return "the LU factorisation ran out of memory (use fewer elements; the direct factors of a 3D mesh "
             "grow "
             "fastest: docs/performance.md)";
    case PC_FACTOR_NUMERIC_ZEROPIVOT:
    case PC_FACTOR_STRUCT_ZEROPIVOT:
      return std::string("the factorisation met a zero pivot (") + PCFailedReasons[reason] + ")";
    default:
      return PCFailedReasons[reason];
  }
}

}  // namespace

std::string linear_solve_failure(KSP ksp) {
  KSPConvergedReason kr;
  CELLFSI_PETSC(KSPGetConvergedReason(ksp, &kr));
  std::string why = KSPConvergedReasons[kr];
  if (kr == KSP_DIVERGED_PC_FAILED) {
    PC pc;
    CELLFSI_PETSC(KSPGetPC(ksp, &pc));
    const std::string pc_why = pc_failure(pc);
    if (!pc_why.empty()) why += ": " + pc_why;
  }
  return why;
}

}  // namespace cellfsi::fluid
