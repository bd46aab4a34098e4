#pragma once
// The linear solves of the coupling loop (paper Sec. 2.3, steps 5-7: K_MC dX = R_MC): one PETSc KSP with the
// options prefix coupling_ (-coupling_ksp_view shows the whole solver, and every PETSc option under the
// prefix works), and the path that runs it for its preconditioner (-coupling_pc_type;
// coupling/solve_path.hpp):
//   cellfsi_fourier  the Jacobian without the cells inverted by FFT, corrected by an LU of the region around
//                    them (solvers/pc_fourier.hpp; a BAIJ Jacobian and a box periodic and uniform in all
//                    directions but one; any number of fluid ranks). FGMRES.
//   cellfsi_band     the Jacobian away from the cells factorised once and kept while the cells stay inside
//                    the region it was built for, the band around them re-solved exactly
//                    (solvers/pc_band.hpp; one fluid rank, a SeqBAIJ Jacobian). FGMRES.
//   any PETSc PC     on the whole Jacobian, rebuilt every -coupling_pc_lag solves and whenever the s^h
//                    marking moves (e.g. asm, lu, bjacobi). GMRES.
// Not given, it is chosen (coupling/solver_policy.hpp, default_pc_type): cellfsi_fourier where it applies,
// else cellfsi_band on one rank, else asm (the fluid's own defaults). The automatic choice falls back in the
// first step when cellfsi_fourier finds the operator away from the cells not uniform along the periodic
// directions, and cellfsi_band when its region holds most of the domain. Every default and range of the
// solve's options, and which options apply to which type, are the policy's (coupling/solver_policy.hpp).
//
// With both cellfsi types the Jacobian is refreshed at the first iteration of a step in which the s^h
// marking moved, and every -coupling_refresh_steps steps; in between the previous Newton matrix is kept (a
// chord iteration; the residual is exact, so the answer is the same to the coupling tolerance). A refresh
// re-assembles only the elements around the cells (-coupling_region_margin elements around the active
// ones); the rest is kept in a second copy of the Jacobian, re-assembled when the cells leave that region.
// With -coupling_bulk_stencil (cellfsi_fourier) there is no whole Jacobian after the bulk solver is built:
// the operator is solvers/near_operator.hpp's, the bulk stencil away from the cells and a matrix of the rows
// near them (the active elements grown by the spline degree and the margin), re-assembled at each refresh.
#include <petscksp.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "coupling/solve_path.hpp"
#include "coupling/solver_policy.hpp"
#include "fluid/immersed_fluid.hpp"

namespace cellfsi::coupling {

/// What a solve cost (added to the step's statistics).
struct SolveCounts {
  // LU factorisations made in steps: of the whole Jacobian (a PETSc PC's rebuild), of cellfsi_band's kept
  // part and its Schur complement, of cellfsi_fourier's region.
  int factorizations = 0;
  // The bulk operator's banded LUs (cellfsi_fourier, cellfsi_bulk), once per run and after a failed solve.
  int bulk_factorizations = 0;
  int refreshes = 0;       // re-assemblies of the Jacobian with a new preconditioner set-up (cellfsi types)
};

class CoupledLinearSolver {
 public:
  /// active_elements: the elements with s^h != 1 or an immersed point (asked when the region is checked).
  CoupledLinearSolver(fluid::ImmersedFluid& fluid, LinearSolverOptions options,
                      std::function<std::vector<char>()> active_elements);
  ~CoupledLinearSolver();
  CoupledLinearSolver(const CoupledLinearSolver&) = delete;
  CoupledLinearSolver& operator=(const CoupledLinearSolver&) = delete;

  /// The s^h marking moved: its s_I rows dominate the Jacobian.
  void marking_changed() { path_->marking_changed(); }
  /// Whether the next solve may assemble the Jacobian, whose immersed terms read the solids' tangents (so the
  /// coupler asks the solids for them only then): a step's first iteration; with the cellfsi types, an
  /// iteration -coupling_refresh_lag refreshes at, and any of cellfsi_band's (it refactorises whenever the
  /// cells leave its region); any iteration of a PETSc PC (the Jacobian at every solve).
  bool may_assemble(bool first_iteration) const { return path_->may_assemble(first_iteration); }
  /// dX = K_MC(X)^{-1} F. first_iteration: the step's first. Returns the KSP's iterations; throws if the
  /// solve failed (std::invalid_argument for bad input found at the first solve). A KSP that did not converge
  /// (LinearSolveFailed; not a PETSc error) on a path with a bulk operator built once (cellfsi_fourier,
  /// cellfsi_bulk) is repeated once with the operator built again from X (SolvePath::rebuild), and throws if
  /// it fails again.
  int solve(Vec X, Vec F, Vec dX, bool first_iteration, SolveCounts& counts);

  /// The PC type in use (it can change in the first step, see fell_back()).
  std::string pc_type() const;
  /// Whether a step replaced the automatic choice (the options of the type it replaced were then never read).
  bool fell_back() const { return fell_back_; }
  /// Unknowns of cellfsi_band's band or cellfsi_fourier's region (0 otherwise or before the first step).
  PetscInt corrected_unknowns() const { return path_->corrected_unknowns(); }
  KSP ksp() const { return ksp_; }

 private:
  /// Replaces the path (the KSP keeps its options, monitors and prefix).
  void fall_back(const FallBack& f);
  LinearSolverOptions opt_;
  SolveContext context_;
  KSP ksp_ = nullptr;
  std::unique_ptr<SolvePath> path_;
  bool fell_back_ = false;
};

}  // namespace cellfsi::coupling
