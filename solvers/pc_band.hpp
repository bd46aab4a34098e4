#pragma once
// The PETSc preconditioner type cellfsi_band: the exact inverse of an operator K = K_fixed + K_band whose
// second part lives on a set of unknowns B (solvers/band_schur.hpp): K_fixed's LU with B kept for the Schur
// complement, and per set-up only the band's Schur complement. One rank, SeqBAIJ.
//
// What the operator's entries do not tell it, the split, it finds on the operator (PetscObjectQuery, as
// PetIGA's PCBBB finds its IGA), put there by the operator's owner with pc_band_compose_split (in cellfsi the
// coupling loop, coupling/coupled_linear_solver.hpp). PCSetUp (KSP calls it whenever the operator's entries
// changed) factorises K_fixed again when the split changed (another kept part or band, or the kept part's
// entries: its state rose) and then the band's Schur complement of K - K_fixed.
//
// Options (under the PC's prefix, read by PCSetFromOptions, listed by -help; defaults BandSchurOptions):
//   -pc_band_fused           one MUMPS solve with the Schur complement's inside it (false: two interior
//   solves) -pc_band_blr_tolerance   block low-rank threshold of the kept part's factors (0: full rank)
// The kept part's MUMPS factors have the options prefix <PC prefix>band_ (e.g. -coupling_band_mat_mumps_*).
#include <petscksp.h>

#include "solvers/band_schur.hpp"

namespace cellfsi::solvers {

inline constexpr const char* kPCBand = "cellfsi_band";

/// PCCreate of the type (for PCRegister: register_pc_types, solvers/pc_types.hpp).
PetscErrorCode pc_create_band(PC pc);

/// Gives operator K its split: the kept part `fixed` (K's layout) and the band's unknowns `band` (sorted
/// global indices, whole blocks). References are taken; the PC set up on K factorises `fixed` when it is new
/// or its entries changed. Null for both removes the split.
void pc_band_compose_split(Mat K, Mat fixed, IS band);

/// The PC's solver (null for another type).
const BandSchurSolver* pc_band_solver(PC pc);

}  // namespace cellfsi::solvers
