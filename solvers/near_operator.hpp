#pragma once
// The coupled Jacobian without a whole matrix: the bulk operator's stencil (FourierBulkSolver::multiply) on
// every row except the rows near the cells, which an assembled matrix holds.
//
// Why: away from the cells the Jacobian is the bulk operator that cellfsi_fourier already keeps as a stencil
// (at Re ~ 1e-4 the flow's disturbance changes it by about 1e-4 of its entries), so a whole assembled
// Jacobian (4.3 GB at the paper's 64^3 in 3D) is needed neither for the Krylov products nor for the
// region's LU, which reads only rows near the cells. A Newton iteration with this operator is a slightly
// inexact Newton iteration; the residual stays exact, so the answer is the same to the coupling tolerance.
//
// The operator is a MATSHELL: y = (1 - m) (A_bulk x) + m (N x), with N the assembled matrix and m the mask
// of the near rows (the rows N holds in full). cellfsi_fourier (solvers/region_corrected.hpp) finds N
// through near_operator() and reads the region from it. Whoever re-assembles N then assembles
// the operator too (MatAssemblyBegin/End: its state rises), so that KSP sets its preconditioner up again.
#include <petscmat.h>

#include <vector>

#include "solvers/fourier_bulk.hpp"

namespace cellfsi::solvers {

/// What the operator is made of.
struct NearOperator {
  const FourierBulkSolver* bulk = nullptr;  // its stencil (kept by reference: it must outlive the operator)
  Mat near = nullptr;                       // the assembled rows (a reference is held)
  std::vector<char> near_nodes;             // by natural node index: whether N holds that node's rows
  Vec mask = nullptr, work = nullptr;       // m, and a vector for N x
};

/// Creates the operator (sizes and layout of `near`). bulk must be built. Collective.
Mat create_near_operator(const FourierBulkSolver& bulk, Mat near, std::vector<char> near_nodes);
/// The parts of an operator made by create_near_operator; null for any other matrix.
const NearOperator* near_operator(Mat J);

}  // namespace cellfsi::solvers
