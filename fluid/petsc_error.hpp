#pragma once
// Checking PETSc calls from C++ code that reports errors by exception. Debian's PETSc is built for C, so
// PETSc's own PetscCallThrow is not available.
#include <petscsys.h>

#include <stdexcept>
#include <string>

#define CELLFSI_PETSC(...)                                                                                \
  do {                                                                                                    \
    const PetscErrorCode cellfsi_ierr_ = __VA_ARGS__;                                                     \
    if (PetscUnlikely(cellfsi_ierr_))                                                                     \
      throw std::runtime_error("PETSc error " + std::to_string(cellfsi_ierr_) + " at " + __FILE__ + ":" + \
                               std::to_string(__LINE__));                                                 \
  } while (0)
