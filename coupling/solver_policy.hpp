#pragma once
// Every policy about the coupling loop's linear solve, in one place; the solver (coupling/
// coupled_linear_solver.hpp) and the executables (apps/: -help, the option checks, the memory check) ask it:
//   - the options of the solve: each one's default (LinearSolverOptions' initialisers for 2D,
//     linear_solver_defaults for a dimension; the PC types' own, solvers::RegionOptions and
//     solvers::BandSchurOptions), its valid range and its help (add_solver_options), which PC type reads it
//     (option_inapplicable), its old name (renamed_option);
//   - the PC type (default_pc_type: the automatic choice; fallback_pc_type: what replaces a cellfsi type that
//     cannot run) and the Krylov method and defaults each path sets (PetscPCDefaults, CellfsiKrylov);
//   - memory: the copies of the fluid Jacobian a PC type keeps and when cellfsi_fourier's second copy is
//   dropped
//     (plan_memory);
//   - the region's LU of cellfsi_fourier, whose options a 3D run does not read by default
//     (region_option_unread).
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/option_table.hpp"
#include "fluid/fluid_options.hpp"
#include "geometry/patch.hpp"
#include "solvers/band_schur.hpp"
#include "solvers/pc_band.hpp"
#include "solvers/pc_bulk.hpp"
#include "solvers/pc_fourier.hpp"
#include "solvers/pc_lu_single.hpp"
#include "solvers/region_corrected.hpp"

namespace cellfsi::coupling {

inline constexpr const char* kCouplingPrefix = "coupling_";

/// The fluid's relative tolerance of a linear solve (its own default, fluid/fluid_solver.cpp): the coupled
/// solve's with a PETSc PC, and with the cellfsi types in 2D.
inline constexpr double kFluidRtol = fluid::KrylovDefaults::rtol;

/// The coupled solve's options. The initialisers are the 2D defaults; linear_solver_defaults(3) those of 3D.
struct LinearSolverOptions {
  std::string pc_type;  // -coupling_pc_type as given ("": the automatic choice, default_pc_type)
  // Elements around the s^h band and the immersed points in the re-assembled region (4 in 2D, 1 in 3D:
  // linear_solver_defaults).
  int region_margin = 4;
  int refresh_steps = 10;  // steps between refreshes while the s^h marking stays (cellfsi types)
  int refresh_lag = 0;     // coupling iterations between refreshes inside a step (0: none; every PC type)
  // cellfsi_band: steps between factorisations of the kept part besides those the cells' motion needs.
  int refactor_every = 0;
  // cellfsi_fourier: re-assemble only the region, keeping the rest in a second copy (false: the whole
  // Jacobian at every refresh, one copy less: for meshes whose memory is tight; plan_memory).
  bool partial_jacobian = true;
  // cellfsi_fourier: no whole Jacobian after the first step: the Krylov products use the bulk operator's
  // stencil away from the cells and an assembled matrix of the rows near them (solvers/near_operator.hpp;
  // true in 3D: linear_solver_defaults). cellfsi_bulk: the bulk part applied by the bulk inverse's stencil
  // and the cells' tangent by a matrix of their own (fluid::ImmersedFluid::OwnBulkInverse; true unless given:
  // pc_type_bulk_stencil).
  bool bulk_stencil = false;
  int preconditioner_lag = 10;  // other PCs: linear solves between rebuilds of the preconditioner
  // cellfsi types: the FGMRES's relative tolerance per coupling iteration (-coupling_ksp_rtol overrides it;
  // 1e-2 in 3D: linear_solver_defaults).
  double rtol = kFluidRtol;
  // cellfsi_fourier: the bulk operator's largest relative deviation between periodic positions above which
  // it does not run. No option sets it: the meshes it guards are uniform to round-off (about 1e-13) or not
  // at all (the narrowing channel: order 1).
  double uniformity = 1e-2;
  double fluid_atol = 1e-16;  // a residual below this is not solved for (the coupling loop's round-off)
  bool s_interface_dominates = true;  // s_I > 1: a new marking invalidates a kept preconditioner
  bool monitor = false;
};

/// cellfsi_bulk's FGMRES relative tolerance per coupling iteration (-coupling_ksp_rtol overrides it). Measured
/// on the 2D capsule (64 x 32, 10 steps, div_conforming): 1e-2 and 1e-5 give the same 71 coupling iterations
/// and theta to 1e-9 deg, with 520 instead of 1149 FGMRES iterations.
inline constexpr double kBulkRtol = 1e-2;

/// The defaults of a dim-dimensional run (3D differs from 2D where it was measured to pay).
LinearSolverOptions linear_solver_defaults(int dim);

/// -coupling_bulk_stencil where it is not given and the PC type sets it: true with cellfsi_bulk (the
/// divergence-conforming capsule at 256 x 128: a Krylov product 3.3x faster, the same iterations, metrics to
/// 1e-12 relative, a step 0.78-0.80 times the equal-order one instead of 1.05); nothing for the other types,
/// which keep the dimension's default (linear_solver_defaults).
std::optional<bool> pc_type_bulk_stencil(const std::string& pc_type);

/// -coupling_refresh_steps where it is not given and the PC type sets it: 1 with cellfsi_bulk, whose space
/// has no s^h marking to move (what refreshed its Jacobian at nearly every step before). Measured: the
/// default scene (2D, 128 x 64) diverges in step 2 with 3 or 10; with 1 it takes 659 coupling iterations
/// against 695 with the marking's refreshes (0.96 of the time, paired runs, within their spread);
/// nothing for the other types (10: LinearSolverOptions).
std::optional<int> pc_type_refresh_steps(const std::string& pc_type);

/// The Krylov method of the cellfsi types: FGMRES (their preconditioners change between applications only
/// through the region's LU in single precision; the true residual decides), restarted every `restart`
/// iterations, at most `max_iterations` per solve.
struct CellfsiKrylov {
  static constexpr int restart = 100;
  static constexpr int max_iterations = 500;
};

/// What the coupled solve with a PETSc PC starts from: the fluid's own defaults (fluid/fluid_solver.cpp):
/// GMRES at kFluidRtol, ASM with an overlap of 4 and MUMPS LU on each subdomain.
struct PetscPCDefaults {
  static constexpr int asm_overlap = fluid::KrylovDefaults::asm_overlap;
  /// Options set in the database unless given (the user's values win): the subdomain solves, and MUMPS'
  /// null-pivot detection for the constant pressure when it is the Jacobian's null space.
  static std::vector<std::pair<std::string, std::string>> options(bool pressure_null_space);
};

/// Whether cellfsi_fourier can run on this patch: at most one non-periodic direction, and the patch
/// translation-invariant along the periodic ones. "" if so, else why not.
std::string fourier_inapplicable(const geometry::Patch& patch);

/// What the automatic choice depends on (known before the fluid is built: the memory check asks too).
struct SolverSituation {
  bool baij = true;  // -fluid_mat_type_jacobian baij
  int fluid_ranks = 1;
  std::string fourier_inapplicable;  // fourier_inapplicable(domain)
  bool own_bulk_inverse = false;     // the fluid has its own (ImmersedFluid::has_bulk_inverse)
};
/// The PC type of the automatic choice (before any fallback): cellfsi_bulk for a fluid with its own bulk
/// inverse (the divergence-conforming one: no region factorised), else cellfsi_fourier where it applies,
/// else cellfsi_band on one rank, else asm.
std::string default_pc_type(const SolverSituation& s);
/// What replaces cellfsi_fourier when its first step finds the operator not uniform: the automatic choice
/// without it.
std::string fallback_pc_type(bool baij, int fluid_ranks);
/// What replaces cellfsi_band when its region holds most of the domain (its Schur complement is then the
/// whole problem; measured at 16^3: 25 % slower than ASM on the whole).
inline constexpr const char* kBandFallbackPCType = "asm";
/// Whether a region of `in_region` of `n_elements` elements holds most of the domain: cellfsi_band then
/// falls back, and cellfsi_fourier re-assembles the whole Jacobian instead of keeping a copy of the rest.
inline bool region_holds_most(long in_region, std::size_t n_elements) {
  return 2 * in_region > static_cast<long>(n_elements);
}

/// Copies of the fluid Jacobian a run with this PC type keeps.
int jacobian_copies(const std::string& pc_type, bool partial_jacobian, bool bulk_stencil = false);
/// The memory check's plan for a coupled run with `pc_type`.
struct MemoryPlan {
  bool partial_jacobian = true;  // LinearSolverOptions::partial_jacobian for the run
  int jacobian_copies = 1;       // jacobian_copies with it
};
/// jacobian_bytes: one fluid Jacobian per node; available: the least memory available on a node;
/// partial_given: -coupling_partial_jacobian was given (it is then kept whatever the memory).
/// cellfsi_fourier's second copy is dropped when kPartialJacobianFit Jacobians do not fit.
MemoryPlan plan_memory(const std::string& pc_type, const LinearSolverOptions& options, bool partial_given,
                       double jacobian_bytes, double available);
/// Measured at 64^3 on one rank since coupled runs no longer set up the fluid's own KSP: a peak of 14.9 GB
/// (3.4 Jacobians of 4.33 GB) with the second copy and 10.7 GB (2.5) without; on two ranks 8.5 + 8.7 GB (4.0
/// Jacobians) with it. It is kept while 4.5 Jacobians fit.
inline constexpr double kPartialJacobianFit = 4.5;

/// The options of the PC types that the types themselves read (PCSetFromOptions): listed in the coupling's
/// option table too, for -help and the range checks.
struct PCTypeOptions {
  solvers::RegionOptions fourier;
  solvers::BandSchurOptions band;
};
/// -coupling_pc_lag in the coupling's option table (its place in -help, before -coupling_acceleration).
void add_pc_lag_option(OptionTable& t, LinearSolverOptions& options);
/// The other options of the solve, from -coupling_pc_type to -coupling_refresh_lag; defaults: the values of
/// `options` and `pc` (linear_solver_defaults, PCTypeOptions{}).
void add_solver_options(OptionTable& t, LinearSolverOptions& options, PCTypeOptions& pc);

/// Why option `name` (without the dash) given by the user does not apply to a coupled run whose solve uses
/// `pc_type`, or "" if it applies.
std::string option_inapplicable(const std::string& name, const std::string& pc_type);
/// The new name of an option this release renamed ("" if `name` was not renamed).
std::string renamed_option(const std::string& name);
/// Whether the coupled solve reads option `name` (without the dash) only at its first solve: its subdomain
/// solvers' (-coupling_sub_), cellfsi_band's factors' (-coupling_band_), cellfsi_fourier's region LU's
/// (-coupling_fourier_region_).
bool read_at_first_solve(const std::string& name);
/// Whether option `name` may be one the PC type a fallback replaced would have read (then never read):
/// -coupling_pc_*, the cellfsi types' factors' and the PETSc PCs' inner solvers' options.
bool option_of_replaced_solver(const std::string& name);
/// Why option `name` of cellfsi_fourier's region LU (-coupling_fourier_region_*) is not read in a
/// dim-dimensional run (region_pc_given: -coupling_fourier_region_pc_type was given), or "" if it may be.
std::string region_option_unread(const std::string& name, int dim, bool region_pc_given);

}  // namespace cellfsi::coupling
