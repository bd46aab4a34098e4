// PetscPCSolve (see solve_path.hpp): the coupled solve with a PETSc PC on the whole Jacobian.
#include "coupling/coupled_linear_solver.hpp"
#include "coupling/coupling_events.hpp"
#include "coupling/solve_path.hpp"

namespace cellfsi::coupling {

void PetscPCSolve::configure_ksp(KSP ksp, const std::string& pc_type) {
  CELLFSI_PETSC(KSPSetType(ksp, KSPGMRES));
  CELLFSI_PETSC(KSPSetTolerances(ksp, kFluidRtol, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, pc_type.c_str()));
  if (pc_type == PCASM) CELLFSI_PETSC(PCASMSetOverlap(pc, PetscPCDefaults::asm_overlap));
}

void PetscPCSolve::start(const SolverSituation&, bool) {
  c_.options.bulk_stencil = false;  // (given by the user, the option checks refuse it: option_inapplicable)
  // A PETSc PC sets itself up on the Jacobian of the current state now, so that its inner solvers (ASM's
  // subdomains) read their options and misspelt ones are reported before any step; factorisations wait for
  // the first solve.
  const Mat J = c_.fluid.jacobian_matrix();
  c_.fluid.jacobian(c_.fluid.solution(), J);
  CELLFSI_PETSC(KSPSetOperators(c_.ksp, J, J));
  CELLFSI_PETSC(KSPSetUp(c_.ksp));
}

bool PetscPCSolve::may_assemble(bool first_iteration) const {
  return refresh_due(first_iteration, solves_since_jacobian_);
}

int PetscPCSolve::solve(Vec X, Vec F, Vec dX, bool first_iteration, SolveCounts& counts) {
  Mat J = c_.fluid.jacobian_matrix();
  if (may_assemble(first_iteration)) {
    EventScope ev(coupling_events().jacobian);
    c_.fluid.jacobian(X, J);
    solves_since_jacobian_ = 0;
  } else {
    ++solves_since_jacobian_;
  }
  EventScope ev(coupling_events().solve);
  CELLFSI_PETSC(KSPSetOperators(c_.ksp, J, J));
  // The preconditioner is reused for preconditioner_lag solves, and rebuilt when the marking changed: with
  // s_I >> 1 the marked rows dominate the Jacobian.
  const bool rebuild =
      solves_since_pc_ >= c_.options.preconditioner_lag || (pc_stale_ && c_.options.s_interface_dominates);
  pc_stale_ = false;
  CELLFSI_PETSC(KSPSetReusePreconditioner(c_.ksp, rebuild ? PETSC_FALSE : PETSC_TRUE));
  solves_since_pc_ = rebuild ? 1 : solves_since_pc_ + 1;
  if (rebuild) ++counts.factorizations;
  CELLFSI_PETSC(KSPSolve(c_.ksp, F, dX));
  return iterations_or_throw(c_.ksp);
}

}  // namespace cellfsi::coupling
