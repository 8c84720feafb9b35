// GoogleTest entry point for tests that use MPI and PETSc. PetscInitialize also
// initializes MPI; non-zero ranks keep quiet so ctest logs stay readable, but every
// rank's failures still fail the process (gtest's exit code is reduced with MPI_MAX).
// hexcut's error handler is installed as in the app, so that a test that expects a
// solver failure (SolverError through the boundary) sees no PETSc traceback.
#include <gtest/gtest.h>
#include <mpi.h>
#include <petscsys.h>

#include "common/petsc_check.hpp"

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  if (PetscInitialize(&argc, &argv, nullptr, nullptr) != 0) return 1;
  if (hexcut::push_error_handler() != 0) return 1;
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  int local = RUN_ALL_TESTS();
  int global = 0;
  MPI_Allreduce(&local, &global, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  PetscFinalize();
  return global;
}
