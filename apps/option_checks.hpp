#pragma once
// Checks of the options a run was given, beyond each option table's own: options nobody read (misspelt),
// solver options that would be silently ignored, and (in a job of two executables) differences between the
// two sides' options that shape the bodies or the time stepping.
#include <string>
#include <vector>

#include "coupling/fsi_coupler.hpp"

namespace cellfsi::app {

/// When the unknown-option check runs: before the coupling loop exists, once it is set up, after the first
/// step (after_fallback: after a first step in which the coupling loop replaced its solver, see
/// coupling::CoupledLinearSolver::fell_back(), so that the options of the one it replaced were never read).
enum class OptionCheck { before_coupling, before_first_step, after_first_step, after_fallback };

/// Fails on options nobody read (a misspelt key must not be silently ignored), skipping those PETSc may read
/// later than `when`.
void reject_unknown_options(OptionCheck when);

/// Names (without the dash) of the options in the database now: the user's command line and scene file.
std::vector<std::string> option_names();

/// Solver options that would be silently ignored in a coupled run whose solve uses `pc_type`
/// (coupling::option_inapplicable decides: e.g. -fluid_ksp_* act only on runs without cells, -coupling_pc_band_*
/// only with cellfsi_band).
void reject_inapplicable_solver_options(const std::vector<std::string>& user_options,
                                        const std::string& pc_type);

/// In a split job (two executables, or -solid_ranks), the options both sides read must be the same on both:
/// the solid side builds and steps the bodies from its own, and a time step or final time given to it alone
/// would be silently ignored (the fluid side leads the steps). Those are the -solid_* options, the domain and
/// mesh the bodies are checked against, -dt and -final_time. Returns the differences ("name: fluid side ->
/// solid side"), the same list on both sides.
std::string split_option_differences(const std::string& fluid_side, const std::string& solid_side);

}  // namespace cellfsi::app
