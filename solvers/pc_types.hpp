#pragma once
// The coupled solvers as PETSc preconditioner types, selected and viewed by options like any PETSc PC:
//   -coupling_pc_type cellfsi_fourier   the bulk operator's inverse by FFT, corrected by an LU of the region
//                                       where the operator differs from it (solvers/region_corrected.hpp)
//   -coupling_pc_type cellfsi_band      the kept part's LU with the band's Schur complement: the exact
//                                       inverse of kept part + band (solvers/band_schur.hpp; one rank)
//   -..._pc_type cellfsi_lu_single      a sparse LU in single precision (MUMPS smumps) of any AIJ or BAIJ
//                                       operator, as a preconditioner (solvers/single_precision_lu.hpp): the
//                                       3D default of cellfsi_fourier's region (-coupling_fourier_region_pc_type)
// -ksp_view shows them with their sizes; their options (-pc_fourier_*, -pc_band_*, -pc_lu_single_*) are read by
// PCSetFromOptions and listed by -help.
//
// What the operator's entries do not tell them comes from the owner of the operator (in cellfsi the coupling
// loop's linear solver, coupling/coupled_linear_solver.hpp), through the functions below, as PCFieldSplitSetIS
// gives a field split its fields:
//   cellfsi_fourier: the box of the unknowns (pc_fourier_set_box) and, once, the bulk operator
//                    (pc_fourier_set_bulk, which builds the FFT solver at once and reports its uniformity);
//   cellfsi_band:    the kept part and the band's unknowns (pc_band_set_split, which factorises at once).
// PCSetUp (KSP calls it whenever the operator's entries changed) then factorises only what depends on the
// whole operator: the region's LU, or the band's Schur complement. cellfsi_lu_single needs nothing but its
// operator.
//
// Implementation: each type is a PCSHELL underneath, renamed (public PETSc API only: PCSetType,
// PetscObjectChangeTypeName, PetscObjectCompose, PetscObjectAddOptionsHandler); the solver object is
// composed on the PC.
#include <petscao.h>
#include <petscksp.h>

#include <array>

#include "solvers/band_schur.hpp"
#include "solvers/region_corrected.hpp"
#include "solvers/single_precision_lu.hpp"

namespace cellfsi::solvers {

inline constexpr const char* kPCFourier = "cellfsi_fourier";
inline constexpr const char* kPCBand = "cellfsi_band";
inline constexpr const char* kPCLUSingle = "cellfsi_lu_single";

/// Registers the types with PETSc (once; later calls do nothing). After PetscInitialize.
void register_pc_types();

/// Whether pc is of the type `type`.
bool pc_is(PC pc, const char* type);

/// A structured box of unknowns (see FourierBulkSolver): control points, periodicity and spline degree per
/// direction, unknowns per node, and the DMDA's natural-to-global ordering (null: the same).
struct BoxMesh {
  std::array<int, 3> n{1, 1, 1}, degree{0, 0, 0};
  std::array<bool, 3> periodic{false, false, false};
  int dof = 1;
  AO natural = nullptr;
};

/// cellfsi_fourier: the box of the operator's unknowns. Collective; after the PC's prefix is set.
void pc_fourier_set_box(PC pc, const BoxMesh& box);
/// cellfsi_fourier: builds the bulk solver from the bulk operator A now (A is not kept) and returns its
/// deviation from translation invariance (FourierBulkSolver::deviation). Collective.
double pc_fourier_set_bulk(PC pc, Mat A, bool pin_pressure);
/// cellfsi_fourier: its solver (null for another type or before pc_fourier_set_box).
const RegionCorrectedSolver* pc_fourier_solver(PC pc);

/// cellfsi_band: factorises the kept part `fixed` with the band `band` (sorted global indices, whole blocks)
/// kept for the Schur complement (BandSchurSolver::factor); PCSetUp then treats the operator as fixed + a
/// part inside band x band. One rank, SeqBAIJ.
void pc_band_set_split(PC pc, Mat fixed, IS band);
/// cellfsi_band: its solver (null for another type).
const BandSchurSolver* pc_band_solver(PC pc);

/// cellfsi_lu_single: its solver (null for another type or before the first set-up).
const SinglePrecisionLU* pc_lu_single_solver(PC pc);

}  // namespace cellfsi::solvers
