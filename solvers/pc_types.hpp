#pragma once
// The coupled solvers as PETSc preconditioner types, selected and viewed by options like any PETSc PC; one
// file each, in the shape of PETSc's own types (a context and its set-up, apply, view, set-from-options,
// reset and destroy operations):
//   -coupling_pc_type cellfsi_fourier   solvers/pc_fourier.hpp: the bulk operator's inverse by FFT, corrected
//                                       by an LU of the region where the operator differs from it
//   -coupling_pc_type cellfsi_band      solvers/pc_band.hpp: the kept part's LU with the band's Schur
//                                       complement, the exact inverse of kept part + band (one rank)
//   -..._pc_type cellfsi_lu_single      solvers/pc_lu_single.hpp: a sparse LU in single precision (MUMPS
//                                       smumps) of any AIJ or BAIJ operator: the 3D default of
//                                       cellfsi_fourier's region (-coupling_fourier_region_pc_type)
// -ksp_view shows them with their sizes; their options (-pc_fourier_*, -pc_band_*, -pc_lu_single_*) are read
// by PCSetFromOptions and listed by -help. What the operator's entries do not tell cellfsi_fourier and
// cellfsi_band (the bulk solver; the kept part and the band) they find on the operator, put there by its
// owner (pc_fourier_compose_bulk, pc_band_compose_split; in cellfsi the coupling loop's linear solver,
// coupling/coupled_linear_solver.hpp).
#include <petscksp.h>

#include "solvers/pc_band.hpp"
#include "solvers/pc_fourier.hpp"
#include "solvers/pc_lu_single.hpp"

namespace cellfsi::solvers {

/// Registers the types (and the ordering cellfsi_nd) with PETSc (once; later calls do nothing). After
/// PetscInitialize.
void register_pc_types();

/// Whether pc is of the type `type`.
bool pc_is(PC pc, const char* type);

}  // namespace cellfsi::solvers
