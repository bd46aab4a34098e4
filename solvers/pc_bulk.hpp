#pragma once
// The PETSc preconditioner type cellfsi_bulk: a fluid discretisation's own exact inverse of its bulk operator
// (the Jacobian without the cells), applied as the whole preconditioner. The divergence-conforming fluid gives
// one (fluid/div_conforming/dc_fourier.hpp: a DFT along the periodic x and one LU per wave number, built once
// per run), and its coupled solve needs nothing else: no region around the cells is factorised (issue 44;
// the cells' terms and a viscosity contrast are left to the Krylov method, FGMRES).
//
// The inverse is not in the operator's entries: the PC finds it on the operator (PetscObjectQuery, as
// cellfsi_fourier finds its bulk solver), put there by pc_bulk_compose (in cellfsi the coupling loop, with
// what fluid::ImmersedFluid::bulk_inverse returned). No options of its own.
#include <petscksp.h>

#include <functional>
#include <memory>
#include <string>

namespace cellfsi::solvers {

inline constexpr const char* kPCBulk = "cellfsi_bulk";

/// x = A_bulk^{-1} b on vectors of the operator's layout, and a line for -ksp_view.
struct BulkInverse {
  std::function<void(Vec b, Vec x)> apply;
  std::string description;
};

/// PCCreate of the type (for PCRegister: register_pc_types, solvers/pc_types.hpp).
PetscErrorCode pc_create_bulk(PC pc);

/// Gives operator A its bulk inverse (shared: A keeps it alive). Null removes it.
void pc_bulk_compose(Mat A, std::shared_ptr<BulkInverse> bulk);

}  // namespace cellfsi::solvers
