#pragma once
// printf on rank 0 of PETSC_COMM_WORLD only, for tests that also run inside multi-rank jobs.
#include <petscsys.h>

#include <cstdarg>
#include <cstdio>

namespace cellfsi::test_support {

inline void print0(const char* format, ...) {
  int rank = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  if (rank != 0) return;
  va_list args;
  va_start(args, format);
  std::vprintf(format, args);
  va_end(args);
}

}  // namespace cellfsi::test_support
