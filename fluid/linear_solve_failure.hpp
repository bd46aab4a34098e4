#pragma once
// Why a linear solve failed, in words: shared by the fluid's own SNES and the coupling loop's KSP.
#include <petscksp.h>

#include <string>

namespace cellfsi::fluid {

/// Why the last solve of ksp failed: its converged reason and, for a failed preconditioner, why it failed
/// (looking into ASM and block-Jacobi subdomains; e.g. an LU factorisation that ran out of memory).
std::string linear_solve_failure(KSP ksp);

}  // namespace cellfsi::fluid
