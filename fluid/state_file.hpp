#pragma once
// The fluid state as a checkpoint holds it, shared by the discretisations behind fluid::ImmersedFluid.
#include <petscviewer.h>
#include <petscvec.h>

#include <string>

namespace cellfsi::fluid {

/// A vector as a PETSc binary file holds it (VecLoad reads it back): the class id and the length as
/// big-endian 32-bit integers, then the values as big-endian doubles, in the DMDA's natural ordering if the
/// vector has a DMDA, else in its own (any number of ranks can read it). Collective; the bytes on rank 0,
/// empty elsewhere.
std::string vec_binary_on_rank_zero(Vec v);

/// Whether every entry of v is finite (collective).
bool all_finite(Vec v);

/// Reads two vectors (the state, then its rate) from a PETSc binary viewer into u and udot (sized already):
/// ok, does_not_fit (a file of another size: the caller reports it, no PETSc traceback) or not_finite.
/// Collective.
enum class StateRead { ok, does_not_fit, not_finite };
StateRead read_state_pair(PetscViewer viewer, Vec u, Vec udot);

}  // namespace cellfsi::fluid
