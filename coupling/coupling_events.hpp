#pragma once
// The PETSc log events of a coupled step (-log_view shows where a step goes), shared by the coupling loop
// (coupling/fsi_coupler.cpp) and its linear solves (coupling/coupled_linear_solver.cpp).
#include <petscksp.h>

#include <stdexcept>
#include <string>

#include "common/petsc_error.hpp"
#include "fluid/linear_solve_failure.hpp"

namespace cellfsi::coupling {

struct CouplingEvents {
  // The fluid's velocity at the bodies' collocation points (each rank its share, where the fluid samples
  // anywhere) and the bodies' kinematic updates (FsiKinematic: every body on every rank).
  PetscLogEvent solid = register_log_event("cellfsi coupling", "FsiSolidUpdate");
  PetscLogEvent kinematic = register_log_event("cellfsi coupling", "FsiKinematic");
  // The step's start and end: the fluid's and the bodies' begin_step and end_step (the fluid's end of a step
  // gathers the solution to every rank and takes its divergence diagnostic).
  PetscLogEvent step_ends = register_log_event("cellfsi coupling", "FsiStepEnds");
  PetscLogEvent locate = register_log_event("cellfsi coupling", "FsiLocate");
  // Inside FsiLocate's immersed update: the bodies' quadrature points located and their data (stress,
  // tangent: this rank's points only), and the repulsion.
  PetscLogEvent quadrature = register_log_event("cellfsi coupling", "FsiQuadrature");
  PetscLogEvent repulsion = register_log_event("cellfsi coupling", "FsiRepulsion");
  // Inside FsiLocate at a run's first call (once per run): every body's points formed and located on every
  // rank to deal them out, and the collocation points located.
  PetscLogEvent locate_setup = register_log_event("cellfsi coupling", "FsiLocateSetUp");
  // Inside FsiRepulsion at the first call: the repulsion's construction (its bins and walls), once per run.
  PetscLogEvent repulsion_setup = register_log_event("cellfsi coupling", "FsiRepulsionSetUp");
  PetscLogEvent residual = register_log_event("cellfsi coupling", "FsiResidual");
  PetscLogEvent jacobian = register_log_event("cellfsi coupling", "FsiJacobian");
  // The kept part's factorisation (cellfsi_band) or the bulk solver's set-up (cellfsi_fourier).
  PetscLogEvent factor = register_log_event("cellfsi coupling", "FsiFactor");
  // The preconditioner's set-up at a refresh: the band's Schur complement or the region's LU.
  PetscLogEvent pc_setup = register_log_event("cellfsi coupling", "FsiPCSetUp");
  PetscLogEvent solve = register_log_event("cellfsi coupling", "FsiLinearSolve");
  // Inside the Krylov products of the stencil operator (-coupling_solid_tangent collocation): the bodies'
  // control increments (each body's columns dealt out to the ranks, one collocation solve each, the results
  // summed over the ranks).
  PetscLogEvent solid_control = register_log_event("cellfsi coupling", "FsiSolidControl");
  // The viscosity field from the membranes' insides (with an inner viscosity; once per step).
  PetscLogEvent viscosity = register_log_event("cellfsi coupling", "FsiViscosity");
};

inline const CouplingEvents& coupling_events() {
  static const CouplingEvents e;
  return e;
}

/// A KSP solve that ended with a negative converged reason (not a PETSc error): what CoupledLinearSolver may
/// repeat with a rebuilt bulk operator. iterations: the failed solve's.
struct LinearSolveFailed : std::runtime_error {
  LinearSolveFailed(const std::string& what, int its) : std::runtime_error(what), iterations(its) {}
  int iterations;
};

/// The iterations of the KSP's last solve; throws LinearSolveFailed if it failed.
inline int iterations_or_throw(KSP ksp) {
  KSPConvergedReason kr;
  CELLFSI_PETSC(KSPGetConvergedReason(ksp, &kr));
  PetscInt lits = 0;
  CELLFSI_PETSC(KSPGetIterationNumber(ksp, &lits));
  if (kr < 0)
    throw LinearSolveFailed("linear solve failed: " + fluid::linear_solve_failure(ksp),
                            static_cast<int>(lits));
  return static_cast<int>(lits);
}

}  // namespace cellfsi::coupling
