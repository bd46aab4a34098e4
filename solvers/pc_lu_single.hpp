#pragma once
// The PETSc preconditioner type cellfsi_lu_single: a sparse LU in single precision (MUMPS' smumps) of any AIJ
// or BAIJ operator, on any number of ranks (solvers/single_precision_lu.hpp). In 3D the default of
// cellfsi_fourier's region (-coupling_fourier_region_pc_type; solvers/region_corrected.hpp).
//
// Needs nothing but its operator. Option (under the PC's prefix, read by PCSetFromOptions, listed by -help):
//   -pc_lu_single_ordering cellfsi_nd|mumps   the fill-reducing ordering (default cellfsi_nd: SCOTCH's nested
//                                             dissection of the node graph, solvers/nested_dissection.hpp)
// -ksp_view shows the ordering and, once factored, the size, operations and entries of the factors.
#include <petscksp.h>

#include "solvers/single_precision_lu.hpp"

namespace cellfsi::solvers {

inline constexpr const char* kPCLUSingle = "cellfsi_lu_single";

/// Registers the type and the ordering cellfsi_nd with PETSc (once; later calls do nothing). After
/// PetscInitialize. (register_pc_types, solvers/pc_types.hpp, registers every cellfsi type.)
void register_pc_lu_single();

/// The PC's solver (null for another type or before the first set-up).
const SinglePrecisionLU* pc_lu_single_solver(PC pc);

}  // namespace cellfsi::solvers
