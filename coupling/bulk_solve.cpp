// BulkSolve (see solve_path.hpp): the coupled solve with cellfsi_bulk, the fluid's own bulk inverse.
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "coupling/coupled_linear_solver.hpp"
#include "coupling/coupling_events.hpp"
#include "coupling/solve_path.hpp"
#include "solvers/pc_bulk.hpp"

namespace cellfsi::coupling {

BulkSolve::~BulkSolve() {
  try {  // the operator lets the inverse go (a destructor does not throw; nor does it make a matrix the
         // stencil path never needed)
    if (composed_) solvers::pc_bulk_compose(composed_, nullptr);
  } catch (...) {
  }
}

void BulkSolve::start(const SolverSituation& s, bool) {
  if (!s.own_bulk_inverse)
    throw std::invalid_argument(
        "-coupling_pc_type cellfsi_bulk needs a fluid with its own bulk inverse: -fluid_space div_conforming "
        "on a box periodic in x (and in 3D in z)");
}

bool BulkSolve::may_assemble(bool first_iteration) const {
  return refresh_due(first_iteration, solves_since_refresh_);
}

bool BulkSolve::rebuild() {
  if (!built_) return false;
  built_ = false;
  resplit_ = true;  // the next solve refreshes the Jacobian
  return true;
}

std::optional<FallBack> BulkSolve::prepare(Vec X, bool, SolveCounts& counts) {
  if (built_) return std::nullopt;
  // Once per run, at the first iterate (the initial state: the undisturbed flow, uniform along x), as
  // cellfsi_fourier's bulk solver; counted as the bulk's factorisation (its per-wave-number LUs). Again after
  // a failed solve (rebuild()), at the flow then: its average along x (see FourierSolve::build_bulk), the
  // cells' disturbance a deviation that the first build's check of the mesh does not apply to.
  EventScope ev(coupling_events().factor);
  std::optional<fluid::ImmersedFluid::OwnBulkInverse> inv = c_.fluid.bulk_inverse(X);
  if (!inv) throw std::logic_error("cellfsi_bulk: the fluid gave no bulk inverse");
  ++counts.bulk_factorizations;
  built_ = true;
  if (++builds_ > 1)
    inv->description += " (built again, build " + std::to_string(builds_) + ", at the flow averaged along x)";
  else if (!(inv->deviation <= c_.options.uniformity)) {
    char amount[32];
    std::snprintf(amount, sizeof amount, "%.2e", inv->deviation);
    throw std::invalid_argument(std::string("-coupling_pc_type cellfsi_bulk: the fluid operator without the cells "
                                            "differs by ") +
                                amount + " of a row's largest entry between periodic positions");
  }
  auto bulk = std::make_shared<solvers::BulkInverse>();
  bulk->apply = std::move(inv->apply);
  bulk->description = inv->description;
  // With the bulk stencil the operator is the fluid's: its bulk part the inverse's own stencil, no assembled
  // bulk (fluid::ImmersedFluid::OwnBulkInverse::stencil_operator).
  if (c_.options.bulk_stencil) op_ = inv->stencil_operator;
  composed_ = operator_matrix();
  solvers::pc_bulk_compose(composed_, std::move(bulk));
  CELLFSI_PETSC(PetscPrintf(c_.fluid.comm(), "cellfsi: %s%s\n", inv->description.c_str(),
                            op_ ? "; the Jacobian's bulk part applied by its stencil" : ""));
  marking_changed();  // the first solve assembles the coupled Jacobian
  return std::nullopt;
}

void BulkSolve::refresh_jacobian(Vec X) {
  EventScope ev(coupling_events().jacobian);
  c_.fluid.jacobian(X, operator_matrix());
}

}  // namespace cellfsi::coupling
