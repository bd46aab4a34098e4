// See immersed_fluid.hpp.
#include "fluid/immersed_fluid.hpp"

#include "fluid/dc_immersed_fluid.hpp"
#include "fluid/fluid_solver.hpp"

#include "common/petsc_error.hpp"

namespace cellfsi::fluid {

bool ImmersedFluid::jacobian_is_blocked() const {
  const Mat J = jacobian_matrix();
  if (!J) return false;
  PetscBool seq = PETSC_FALSE, mpi = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(J), MATSEQBAIJ, &seq));
  CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(J), MATMPIBAIJ, &mpi));
  return seq || mpi;
}

std::unique_ptr<ImmersedFluid> create_fluid(MPI_Comm comm, const geometry::Patch& patch,
                                            const FluidOptions& options) {
  if (options.space == "div_conforming") return std::make_unique<DcImmersedFluid>(comm, patch, options);
  return std::make_unique<FluidSolver>(comm, patch, options);
}

}  // namespace cellfsi::fluid
