#pragma once
// The PETSc preconditioner type cellfsi_fourier: the inverse of a translation-invariant bulk operator by FFT
// (solvers/fourier_bulk.hpp), corrected by an LU of the region where the operator differs from it
// (solvers/region_corrected.hpp). Any number of ranks; a BAIJ operator or solvers/near_operator.hpp's.
//
// What the operator's entries do not tell it, the bulk solver (built from the operator without the cells,
// once per run), it finds on the operator (PetscObjectQuery, as PetIGA's PCBBB finds its IGA), put there by
// the operator's owner with pc_fourier_compose_bulk (in cellfsi the coupling loop,
// coupling/coupled_linear_solver.hpp). PCSetUp (KSP calls it whenever the operator's entries changed) finds
// the region and factorises the operator on it.
//
// Options (under the PC's prefix, read by PCSetFromOptions, listed by -help; defaults and ranges
// RegionOptions):
//   -pc_fourier_threshold       relative deviation of a node's rows from the bulk operator that puts it in
//   the
//                               LU-corrected region
//   -pc_fourier_overlap         node layers the region is grown by
//   -pc_fourier_region_solves   region LU solves per application: 1 (bulk, region) or 2 (region, bulk,
//   region)
// The region's LU has the options prefix <PC prefix>fourier_region_ (e.g. -coupling_fourier_region_pc_type).
#include <petscksp.h>

#include <memory>

#include "solvers/fourier_bulk.hpp"
#include "solvers/region_corrected.hpp"

namespace cellfsi::solvers {

inline constexpr const char* kPCFourier = "cellfsi_fourier";

/// PCCreate of the type (for PCRegister: register_pc_types, solvers/pc_types.hpp).
PetscErrorCode pc_create_fourier(PC pc);

/// Gives operator A its bulk solver (built; shared: A keeps it alive). Null removes it.
void pc_fourier_compose_bulk(Mat A, std::shared_ptr<FourierBulkSolver> bulk);

/// The PC's solver (null for another type or before its first set-up).
const RegionCorrectedSolver* pc_fourier_solver(PC pc);

}  // namespace cellfsi::solvers
