#pragma once
// A scatter of chosen rows of a distributed PETSc vector into a vector of their own, both ways: forward
// (INSERT_VALUES) reads the rows' values, reverse writes them back (INSERT_VALUES) or adds them (ADD_VALUES).
// The divergence-conforming fluid reads so only what a rank needs of an iterate (its lines, the unknowns its
// rows touch), where gathering the whole vector to every rank does not divide by the ranks.
#include <petscvec.h>

#include <vector>

#include "common/petsc_error.hpp"

namespace cellfsi {

/// `values` (made here unless given: a sequential vector of rows.size() entries; a given one may be a
/// distributed vector whose local size is rows.size(), its own rows then being the targets) and the scatter
/// between `rows` of `from`'s layout (any rank's rows, in the order given) and it. Collective on from's
/// communicator.
inline VecScatter make_row_scatter(Vec from, const std::vector<PetscInt>& rows, Vec& values) {
  if (!values) CELLFSI_PETSC(VecCreateSeq(PETSC_COMM_SELF, static_cast<PetscInt>(rows.size()), &values));
  IS is = nullptr;
  CELLFSI_PETSC(ISCreateGeneral(PetscObjectComm(reinterpret_cast<PetscObject>(from)),
                                static_cast<PetscInt>(rows.size()), rows.data(), PETSC_USE_POINTER, &is));
  VecScatter scatter = nullptr;
  const PetscErrorCode ierr = VecScatterCreate(from, is, values, nullptr, &scatter);
  ISDestroy(&is);
  CELLFSI_PETSC(ierr);
  return scatter;
}

}  // namespace cellfsi
