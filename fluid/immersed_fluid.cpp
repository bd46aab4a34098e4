// See immersed_fluid.hpp.
#include "fluid/immersed_fluid.hpp"

#include "fluid/dc_immersed_fluid.hpp"
#include "fluid/fluid_solver.hpp"

namespace cellfsi::fluid {

std::unique_ptr<ImmersedFluid> create_fluid(MPI_Comm comm, const geometry::Patch& patch,
                                            const FluidOptions& options) {
  if (options.space == "div_conforming") return std::make_unique<DcImmersedFluid>(comm, patch, options);
  return std::make_unique<FluidSolver>(comm, patch, options);
}

}  // namespace cellfsi::fluid
