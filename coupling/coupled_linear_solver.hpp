#pragma once
// The linear solves of the coupling loop (paper Sec. 2.3, steps 5-7: K_MC dX = R_MC) and every policy about
// them, in one place: which preconditioner runs, when the Jacobian and the preconditioner are refreshed,
// which part of the Jacobian is re-assembled, the fallbacks, how many copies of the Jacobian the choice
// keeps (the memory check asks) and which options apply (the option checks ask).
//
// The solve is one PETSc KSP with the options prefix coupling_: -coupling_ksp_view shows the whole solver,
// and every PETSc option under the prefix works. Its preconditioner (-coupling_pc_type) is
//   cellfsi_fourier  the Jacobian without the cells inverted by FFT, corrected by an LU of the region around
//                    them (solvers/pc_types.hpp; a BAIJ Jacobian and a box periodic and uniform in all
//                    directions but one; any number of fluid ranks). FGMRES.
//   cellfsi_band     the Jacobian away from the cells factorised once and kept while the cells stay inside
//                    the region it was built for, the band around them re-solved exactly (one fluid rank, a
//                    SeqBAIJ Jacobian). FGMRES.
//   any PETSc PC     on the whole Jacobian, rebuilt every -coupling_pc_lag solves and whenever the s^h
//                    marking moves (e.g. asm, lu, bjacobi). GMRES.
// Not given, it is chosen (default_pc_type): cellfsi_fourier where it applies, else cellfsi_band on one
// rank, else asm (overlap 4, MUMPS LU on each subdomain: the fluid's own defaults). The automatic choice
// falls back in the first step when cellfsi_fourier finds the operator away from the cells not uniform
// along the periodic directions, and cellfsi_band when its region holds most of the domain.
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
#include <string>
#include <vector>

#include "fluid/immersed_fluid.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::coupling {

inline constexpr const char* kCouplingPrefix = "coupling_";

struct LinearSolverOptions {
  std::string pc_type;  // -coupling_pc_type as given ("": the automatic choice, default_pc_type)
  // Elements around the s^h band and the immersed points in the re-assembled region (the scenes take 4 in 2D
  // and 1 in 3D, as measured: apps/scene_options.cpp).
  int region_margin = 4;
  int refresh_steps = 10;  // steps between refreshes while the s^h marking stays (cellfsi types)
  int refresh_lag = 0;     // coupling iterations between refreshes inside a step (0: none; cellfsi types)
  // cellfsi_band: steps between factorisations of the kept part besides those the cells' motion needs.
  int refactor_every = 0;
  // cellfsi_fourier: re-assemble only the region, keeping the rest in a second copy (false: the whole
  // Jacobian at every refresh, one copy less: for meshes whose memory is tight).
  bool partial_jacobian = true;
  // cellfsi_fourier: no whole Jacobian after the first step: the Krylov products use the bulk operator's
  // stencil away from the cells and an assembled matrix of the rows near them (solvers/near_operator.hpp).
  bool bulk_stencil = false;
  int preconditioner_lag = 10;  // other PCs: linear solves between rebuilds of the preconditioner
  // cellfsi types: the FGMRES's relative tolerance per coupling iteration (-coupling_ksp_rtol overrides it;
  // the scenes take 1e-2 in 3D, where the coupling loop, not the linear solve, sets the iterations:
  // docs/performance.md §14).
  double rtol = 1e-5;
  // cellfsi_fourier: the bulk operator's largest relative deviation between periodic positions above which
  // it does not run. No option sets it: the meshes it guards are uniform to round-off (about 1e-13) or not
  // at all (the narrowing channel: order 1).
  double uniformity = 1e-2;
  double fluid_atol = 1e-16;  // a residual below this is not solved for (the coupling loop's round-off)
  bool s_interface_dominates = true;  // s_I > 1: a new marking invalidates a kept preconditioner
  bool monitor = false;
};

/// Whether cellfsi_fourier can run on this patch: at most one non-periodic direction, and the patch
/// translation-invariant along the periodic ones. "" if so, else why not.
std::string fourier_inapplicable(const geometry::Patch& patch);

/// What the automatic choice depends on (known before the fluid is built: the memory check asks too).
struct SolverSituation {
  bool baij = true;                  // -fluid_mat_type_jacobian baij
  int fluid_ranks = 1;
  std::string fourier_inapplicable;  // fourier_inapplicable(domain)
};
/// The PC type of the automatic choice (before any fallback).
std::string default_pc_type(const SolverSituation& s);
/// Copies of the fluid Jacobian a run with this PC type keeps (the memory check).
int jacobian_copies(const std::string& pc_type, bool partial_jacobian, bool bulk_stencil = false);
/// Why option `name` (without the dash) given by the user does not apply to a coupled run whose solve uses
/// `pc_type`, or "" if it applies.
std::string option_inapplicable(const std::string& name, const std::string& pc_type);
/// The new name of an option this release renamed ("" if `name` was not renamed).
std::string renamed_option(const std::string& name);

/// What a solve cost (added to the step's statistics).
struct SolveCounts {
  int factorizations = 0;  // of the whole Jacobian, its kept part (cellfsi_band) or the bulk (cellfsi_fourier)
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
  void marking_changed() { marking_changed_ = pc_stale_ = true; }
  /// Whether the next solve may assemble the Jacobian, whose immersed terms read the solids' tangents (so the
  /// coupler asks the solids for them only then): a step's first iteration; with the cellfsi types, an
  /// iteration -coupling_refresh_lag refreshes at, and any of cellfsi_band's (it refactorises whenever the
  /// cells leave its region); any iteration of a PETSc PC (the Jacobian at every solve).
  bool may_assemble(bool first_iteration) const;
  /// dX = K_MC(X)^{-1} F. first_iteration: the step's first. Returns the KSP's iterations; throws if the
  /// solve failed (std::invalid_argument for bad input found at the first solve).
  int solve(Vec X, Vec F, Vec dX, bool first_iteration, SolveCounts& counts);

  /// The PC type in use (it can change in the first step, see fell_back()).
  std::string pc_type() const;
  /// Whether a step replaced the automatic choice (the options of the type it replaced were then never read).
  bool fell_back() const { return fell_back_; }
  /// Unknowns of cellfsi_band's band or cellfsi_fourier's region (0 otherwise or before the first step).
  PetscInt corrected_unknowns() const;
  KSP ksp() const { return ksp_; }

 private:
  void configure(const std::string& type);  // the KSP's and PC's types and defaults for `type`
  /// Replaces the PC type in the first step (even_if_asked: also one the user asked for; otherwise that is
  /// refused with the reason).
  void fall_back(const std::string& type, const std::string& why, bool even_if_asked = false);
  bool ensure_band_factorization(Vec X);   // cellfsi_band; returns whether it factorised
  bool build_bulk(Vec X);                  // cellfsi_fourier, once; false if it fell back
  void refresh_jacobian(Vec X);            // the region re-assembled, the rest kept
  void refresh_near_operator(Vec X);       // bulk_stencil: the near rows re-assembled
  /// bulk_stencil: the matrix of the rows of nodes on region_'s elements (the others hold one diagonal
  /// block), the operator made of it and the bulk stencil, and the nodes whose rows it holds in full.
  void make_near_operator();
  int solve_generic(Vec X, Vec F, Vec dX, SolveCounts& counts);
  fluid::ImmersedFluid& fluid_;
  LinearSolverOptions opt_;
  std::function<std::vector<char>()> active_elements_;
  KSP ksp_ = nullptr;
  bool cellfsi_type_ = false, fell_back_ = false, marking_changed_ = true, pc_stale_ = true;
  std::vector<char> region_;  // elements re-assembled at every refresh
  Mat J_fixed_ = nullptr;     // the Jacobian of the other elements
  Mat near_ = nullptr, near_op_ = nullptr;  // bulk_stencil: the near rows, and the operator
  MatNullSpace null_space_ = nullptr, transpose_null_space_ = nullptr;  // the fluid Jacobian's, for near_op_
  int steps_since_refresh_ = 0, solves_since_refresh_ = 0, steps_since_factor_ = 0, solves_since_pc_ = 1 << 30;
  bool bulk_built_ = false;
  bool single_failure_reported_ = false;  // the region's single-precision LU failed, and the console was told
};

}  // namespace cellfsi::coupling
