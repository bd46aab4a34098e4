// GoogleTest main for tests that use PETSc and MPI: initialises PETSc around the test run; only rank 0
// prints.
#include <gtest/gtest.h>
#include <petscsys.h>

#include "ompi_session_dir.hpp"

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  const std::string session_base = cellfsi_test::private_ompi_session_base();  // before MPI_Init
  if (PetscInitialize(&argc, &argv, nullptr, nullptr) != 0) return 1;
  PetscMPIInt rank = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  if (rank != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  int status = RUN_ALL_TESTS();
  // A failure on any rank fails the run.
  int any = status;
  MPI_Allreduce(&status, &any, 1, MPI_INT, MPI_MAX, PETSC_COMM_WORLD);
  PetscFinalize();
  cellfsi_test::remove_ompi_session_base(session_base);
  return any;
}
