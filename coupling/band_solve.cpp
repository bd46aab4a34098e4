// BandSolve (see solve_path.hpp): the coupled solve with cellfsi_band.
#include <algorithm>
#include <stdexcept>

#include "geometry/element_region.hpp"
#include "coupling/coupled_linear_solver.hpp"
#include "coupling/coupling_events.hpp"
#include "coupling/solve_path.hpp"
#include "solvers/pc_band.hpp"

namespace cellfsi::coupling {

using geometry::contains;  // (element masks: geometry/element_region.hpp)

BandSolve::~BandSolve() {
  try {  // the Jacobian lets the kept part go (PETSc errors are exceptions, and a destructor does not throw)
    if (Mat J = c_.fluid.jacobian_matrix_if_made()) solvers::pc_band_compose_split(J, nullptr, nullptr);
  } catch (...) {
  }
  MatDestroy(&J_fixed_);
}

void BandSolve::start(const SolverSituation& s, bool seq_baij) {
  c_.options.bulk_stencil = false;  // (given by the user, the option checks refuse it: option_inapplicable)
  if (s.fluid_ranks > 1 || !seq_baij)
    throw std::invalid_argument(
        "-coupling_pc_type cellfsi_band needs one fluid rank and a BAIJ Jacobian "
        "(-fluid_mat_type_jacobian baij); on several ranks use cellfsi_fourier or a "
        "PETSc PC such as asm");
}

std::optional<FallBack> BandSolve::prepare(Vec X, bool first_iteration, SolveCounts& counts) {
  if (first_iteration) ++steps_since_factor_;
  // The region is checked every iteration: the immersed points move with the solids. The kept part is split
  // off again when the cells leave the region (or every refactor_every steps); cellfsi_band factorises it at
  // its next set-up.
  const std::vector<char> active = c_.active_elements();
  const solvers::BandSchurSolver* band = solvers::pc_band_solver(pc());
  const bool stale = c_.options.refactor_every > 0 && steps_since_factor_ >= c_.options.refactor_every;
  if (!stale && band && band->factored() && contains(region_, active)) return std::nullopt;
  EventScope ev(coupling_events().factor);
  region_ = grow_elements(c_.fluid.patch(), active, c_.options.region_margin);
  // A region that holds most of the domain (a coarse 3D mesh around a compound capsule) leaves nothing to
  // keep: its Schur complement is the whole problem.
  in_region_ = std::count(region_.begin(), region_.end(), 1);
  if (region_holds_most(in_region_, region_.size()))
    return FallBack{kBandFallbackPCType,
                    "the band region holds " + std::to_string(in_region_) + " of " +
                        std::to_string(region_.size()) + " elements",
                    true};
  const std::vector<PetscInt> unknowns = c_.fluid.region_unknowns(region_);
  IS is;
  CELLFSI_PETSC(ISCreateGeneral(PETSC_COMM_SELF, static_cast<PetscInt>(unknowns.size()), unknowns.data(),
                                PETSC_COPY_VALUES, &is));
  const Mat J = c_.fluid.jacobian_matrix();
  if (!J_fixed_) CELLFSI_PETSC(MatDuplicate(J, MAT_DO_NOT_COPY_VALUES, &J_fixed_));
  c_.fluid.jacobian_part(X, J_fixed_, region_, false);
  solvers::pc_band_compose_split(J, J_fixed_, is);  // (J keeps a reference to both)
  CELLFSI_PETSC(ISDestroy(&is));
  steps_since_factor_ = 0;
  resplit_ = true;
  ++counts.factorizations;
  return std::nullopt;
}

void BandSolve::refresh_jacobian(Vec X) {
  EventScope ev(coupling_events().jacobian);
  Mat J = c_.fluid.jacobian_matrix();
  CELLFSI_PETSC(MatCopy(J_fixed_, J, SAME_NONZERO_PATTERN));
  c_.fluid.jacobian_add_part(X, J, region_);
}

void BandSolve::set_up_pc() {
  try {
    CELLFSI_PETSC(KSPSetUp(c_.ksp));
  } catch (...) {
    if (resplit_) region_.clear();  // the next solve splits again
    throw;
  }
}

void BandSolve::after_refresh() {
  if (!resplit_ || !c_.options.monitor) return;
  PetscLogDouble resident = 0;
  CELLFSI_PETSC(PetscMemoryGetCurrentUsage(&resident));
  const solvers::BandSchurSolver* band = solvers::pc_band_solver(pc());
  CELLFSI_PETSC(PetscPrintf(c_.fluid.comm(),
                            "  band factorisation: %ld of %zu elements, %" PetscInt_FMT " of %" PetscInt_FMT
                            " unknowns (edge %" PetscInt_FMT "), Schur complement %" PetscInt_FMT
                            " nonzeros; resident %.0f MB\n",
                            in_region_, region_.size(), band->n_band(), band->n_total(), band->n_edge(),
                            band->schur_nonzeros(), resident / 1048576.0));
}

PetscInt BandSolve::corrected_unknowns() const {
  const solvers::BandSchurSolver* b = solvers::pc_band_solver(pc());
  return b ? b->n_band() : 0;
}

}  // namespace cellfsi::coupling
