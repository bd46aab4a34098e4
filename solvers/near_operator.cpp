// See near_operator.hpp.
#include "solvers/near_operator.hpp"

#include <stdexcept>

#include "common/petsc_error.hpp"

namespace cellfsi::solvers {

namespace {

// The key under which the operator carries its near matrix (what marks it as one of these shells).
constexpr const char* kKey = "cellfsi_near_matrix";

PetscErrorCode near_mult(Mat A, Vec x, Vec y) {
  PetscFunctionBeginUser;
  NearOperator* op = nullptr;
  PetscCall(MatShellGetContext(A, &op));
  try {
    op->bulk->multiply(x, y);
  } catch (const std::exception& e) {
    SETERRQ(PetscObjectComm(reinterpret_cast<PetscObject>(A)), PETSC_ERR_LIB, "%s", e.what());
  }
  PetscCall(MatMult(op->near, x, op->work));
  // y = y + m (N x - y)
  PetscCall(VecAXPY(op->work, -1.0, y));
  PetscCall(VecPointwiseMult(op->work, op->work, op->mask));
  PetscCall(VecAXPY(y, 1.0, op->work));
  PetscFunctionReturn(0);
}

PetscErrorCode near_destroy(Mat A) {
  PetscFunctionBeginUser;
  NearOperator* op = nullptr;
  PetscCall(MatShellGetContext(A, &op));
  PetscCall(MatDestroy(&op->near));
  PetscCall(VecDestroy(&op->mask));
  PetscCall(VecDestroy(&op->work));
  delete op;
  PetscFunctionReturn(0);
}

}  // namespace

Mat create_near_operator(const FourierBulkSolver& bulk, Mat near, std::vector<char> near_nodes) {
  if (!bulk.built()) throw std::logic_error("create_near_operator: the bulk solver is not built");
  if (static_cast<int>(near_nodes.size()) != bulk.n_nodes())
    throw std::invalid_argument("create_near_operator: a mask of " + std::to_string(near_nodes.size()) +
                                " nodes for " + std::to_string(bulk.n_nodes()));
  auto* op = new NearOperator;
  op->bulk = &bulk;
  op->near = near;
  op->near_nodes = std::move(near_nodes);
  CELLFSI_PETSC(PetscObjectReference(reinterpret_cast<PetscObject>(near)));
  CELLFSI_PETSC(MatCreateVecs(near, &op->work, &op->mask));
  PetscInt lo = 0, hi = 0, rows = 0;
  CELLFSI_PETSC(VecGetOwnershipRange(op->mask, &lo, &hi));
  CELLFSI_PETSC(VecGetSize(op->mask, &rows));
  const PetscInt bs = rows / bulk.n_nodes();  // unknowns per node
  PetscScalar* m = nullptr;
  CELLFSI_PETSC(VecGetArray(op->mask, &m));
  for (PetscInt row = lo; row < hi; ++row)
    m[row - lo] = op->near_nodes[bulk.natural_node(static_cast<int>(row / bs))] ? 1.0 : 0.0;
  CELLFSI_PETSC(VecRestoreArray(op->mask, &m));
  PetscInt ml = 0, nl = 0, M = 0, N = 0;
  CELLFSI_PETSC(MatGetLocalSize(near, &ml, &nl));
  CELLFSI_PETSC(MatGetSize(near, &M, &N));
  Mat A = nullptr;
  CELLFSI_PETSC(MatCreateShell(PetscObjectComm(reinterpret_cast<PetscObject>(near)), ml, nl, M, N, op, &A));
  CELLFSI_PETSC(MatShellSetOperation(A, MATOP_MULT, reinterpret_cast<void (*)(void)>(near_mult)));
  CELLFSI_PETSC(MatShellSetOperation(A, MATOP_DESTROY, reinterpret_cast<void (*)(void)>(near_destroy)));
  CELLFSI_PETSC(MatSetBlockSize(A, bs));
  CELLFSI_PETSC(PetscObjectCompose(reinterpret_cast<PetscObject>(A), kKey, reinterpret_cast<PetscObject>(near)));
  return A;
}

const NearOperator* near_operator(Mat J) {
  PetscObject marker = nullptr;
  CELLFSI_PETSC(PetscObjectQuery(reinterpret_cast<PetscObject>(J), kKey, &marker));
  if (!marker) return nullptr;
  NearOperator* op = nullptr;
  CELLFSI_PETSC(MatShellGetContext(J, &op));
  return op;
}

}  // namespace cellfsi::solvers
