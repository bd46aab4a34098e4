#pragma once
// LAPACK's banded LU, declared once for the two Fourier bulk solvers (solvers/fourier_bulk.cpp,
// fluid/div_conforming/dc_fourier.cpp): PETSc's petscblaslapack.h has no banded LU. Fortran calling convention
// (the trailing length is that of the character argument), PETSc's BLAS integer for the integer arguments (64
// bits when PETSc is configured for a 64-bit-integer BLAS/LAPACK; the LAPACK CMake links,
// find_package(LAPACK), must then be that same library).
#include <petscsys.h>

#include <complex>
#include <cstddef>

extern "C" {
void zgbtrf_(const PetscBLASInt* m, const PetscBLASInt* n, const PetscBLASInt* kl, const PetscBLASInt* ku,
             std::complex<double>* ab, const PetscBLASInt* ldab, PetscBLASInt* ipiv, PetscBLASInt* info);
void zgbtrs_(const char* trans, const PetscBLASInt* n, const PetscBLASInt* kl, const PetscBLASInt* ku,
             const PetscBLASInt* nrhs, const std::complex<double>* ab, const PetscBLASInt* ldab,
             const PetscBLASInt* ipiv, std::complex<double>* b, const PetscBLASInt* ldb, PetscBLASInt* info,
             std::size_t trans_len);
}
