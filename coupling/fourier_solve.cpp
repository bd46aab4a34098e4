// FourierSolve (see solve_path.hpp): the coupled solve with cellfsi_fourier.
#include <petscdmda.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <stdexcept>

#include "geometry/element_region.hpp"
#include "coupling/coupled_linear_solver.hpp"
#include "coupling/coupling_events.hpp"
#include "coupling/solve_path.hpp"
#include "solvers/near_operator.hpp"
#include "solvers/pc_fourier.hpp"

namespace cellfsi::coupling {

using geometry::contains;  // (element masks: geometry/element_region.hpp)

FourierSolve::~FourierSolve() {
  try {  // the Jacobian lets the bulk solver go (PETSc errors are exceptions, and a destructor does not
         // throw)
    if (Mat J = c_.fluid.jacobian_matrix_if_made()) solvers::pc_fourier_compose_bulk(J, nullptr);
  } catch (...) {
  }
  MatDestroy(&J_fixed_);
  MatDestroy(&near_op_);
  MatDestroy(&near_);
  MatNullSpaceDestroy(&null_space_);
  MatNullSpaceDestroy(&transpose_null_space_);
}

void FourierSolve::start(const SolverSituation& s, bool) {
  // What cellfsi_fourier needs of the Jacobian, refused here with the reason.
  if (!s.baij)
    throw std::invalid_argument(
        "-coupling_pc_type cellfsi_fourier needs a BAIJ fluid Jacobian "
        "(-fluid_mat_type_jacobian baij)");
  if (!s.fourier_inapplicable.empty())
    throw std::invalid_argument("-coupling_pc_type cellfsi_fourier does not apply: " +
                                s.fourier_inapplicable);
  // The bulk solver's box: the fluid's control points, periodicity and degree per direction, unknowns per
  // node and their natural ordering (fluid::ImmersedFluid::block_layout; a fluid whose unknowns are not node
  // blocks has none, and the Fourier solver does not apply to it).
  const std::optional<fluid::BlockLayout> layout = c_.fluid.block_layout();
  if (!layout)
    throw std::invalid_argument("-coupling_pc_type cellfsi_fourier needs the fluid's unknowns in node blocks "
                                "on the control net");
  bulk_ = std::make_shared<solvers::FourierBulkSolver>(layout->n, layout->periodic, layout->degree, layout->dof,
                                                       c_.fluid.comm(), layout->natural);
  if (c_.options.bulk_stencil && !c_.fluid.options().pressure_null_space) {
    // (The default in 3D gives way; asked for, it is refused.)
    PetscBool given = PETSC_FALSE;
    CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-coupling_bulk_stencil", &given));
    if (given)
      throw std::invalid_argument(
          "-coupling_bulk_stencil needs the constant pressure as the Jacobian's null "
          "space (-fluid_pressure_null_space true): a pinned pressure row is not "
          "part of the bulk stencil");
    c_.options.bulk_stencil = false;
  }
  if (c_.options.bulk_stencil) {
    // The operator that replaces the Jacobian carries its null spaces.
    const Mat J = c_.fluid.jacobian_matrix();
    CELLFSI_PETSC(MatGetNullSpace(J, &null_space_));
    CELLFSI_PETSC(MatGetTransposeNullSpace(J, &transpose_null_space_));
    if (null_space_) CELLFSI_PETSC(PetscObjectReference(reinterpret_cast<PetscObject>(null_space_)));
    if (transpose_null_space_)
      CELLFSI_PETSC(PetscObjectReference(reinterpret_cast<PetscObject>(transpose_null_space_)));
  }
}

bool FourierSolve::may_assemble(bool first_iteration) const {
  return refresh_due(first_iteration, solves_since_refresh_);
}

std::optional<FallBack> FourierSolve::prepare(Vec X, bool, SolveCounts& counts) {
  if (bulk_built_) return std::nullopt;
  ++counts.bulk_factorizations;
  return build_bulk(X);
}

bool FourierSolve::rebuild() {
  if (!bulk_built_ || c_.options.bulk_stencil) return false;
  bulk_built_ = false;
  region_.clear();  // the Jacobian away from the cells (J_fixed_) was assembled at an earlier state too
  resplit_ = true;  // the next solve refreshes the Jacobian and the preconditioner
  return true;
}

std::optional<FallBack> FourierSolve::build_bulk(Vec X) {
  // Once per run: the bulk operator at the first iterate (from the initial state, the undisturbed flow,
  // uniform along the periodic directions to the projection's round-off; after a restart, the restored
  // state, whose disturbance by the cells changes the Jacobian by about Re ~ 1e-4 of its entries). The
  // Jacobian's matrix holds it meanwhile: the refresh that follows re-assembles it.
  // Again after a failed solve (rebuild()): at finite Re the flow's convective Jacobian drifts from the first
  // state's (a flow started from rest develops). build() averages the operator over the periodic positions,
  // which for the convective term, linear in the velocity, is the operator of the velocity averaged along the
  // periodic directions (up to the stabilisation's own dependence on the velocity): the cells' disturbance
  // then shows as a deviation, which is not a reason to fall back (the first build checked the mesh's
  // uniformity).
  EventScope ev(coupling_events().factor);
  Mat J = c_.fluid.jacobian_matrix();
  c_.fluid.bulk_jacobian(X, J);
  bulk_->build(J, true);
  const double dev = bulk_->deviation();
  bulk_built_ = true;
  if (++bulk_builds_ > 1) {
    CELLFSI_PETSC(
        PetscPrintf(c_.fluid.comm(),
                    "cellfsi: Fourier bulk solver rebuilt at the current flow (build %d; the operator "
                    "averaged along the periodic directions, %.2e from it)\n",
                    bulk_builds_, dev));
    return std::nullopt;
  }
  if (!(dev <= c_.options.uniformity)) {  // NaN (a broken operator) counts as not uniform
    char amount[32];
    std::snprintf(amount, sizeof amount, "%.2e", dev);
    int ranks = 1;
    CELLFSI_PETSC(MPI_Comm_size(c_.fluid.comm(), &ranks));
    PetscBool seq_baij = PETSC_FALSE;
    CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(J), MATSEQBAIJ, &seq_baij));
    return FallBack{
        fallback_pc_type(seq_baij == PETSC_TRUE, ranks),
        std::string("the fluid Jacobian away from the cells differs by ") + amount +
            " of a row's largest entry between periodic positions (the mesh or the flow is not uniform "
            "along the periodic directions)"};
  }
  double factor_mb = bulk_->factor_bytes() / 1048576.0;  // this rank's; summed over the ranks
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &factor_mb, 1, MPI_DOUBLE, MPI_SUM, c_.fluid.comm()));
  CELLFSI_PETSC(
      PetscPrintf(c_.fluid.comm(),
                  "cellfsi: Fourier bulk solver: %d wave vectors, %.1f MB of banded factors, operator "
                  "uniform to %.2e\n",
                  bulk_->n_modes(), factor_mb, dev));
  marking_changed();
  if (c_.options.bulk_stencil) {  // from here on the stencil and the near rows
    PetscLogDouble before = 0, after = 0;
    CELLFSI_PETSC(PetscMemoryGetCurrentUsage(&before));
    c_.fluid.release_jacobian_matrix();
    CELLFSI_PETSC(PetscMemoryGetCurrentUsage(&after));
    if (c_.options.monitor)
      CELLFSI_PETSC(PetscPrintf(c_.fluid.comm(), "  the whole Jacobian released: resident %.0f -> %.0f MB\n",
                                before / 1048576.0, after / 1048576.0));
  } else {
    solvers::pc_fourier_compose_bulk(J, bulk_);  // what cellfsi_fourier set up on the Jacobian inverts
  }
  return std::nullopt;
}

void FourierSolve::make_near_operator() {
  MatDestroy(&near_op_);
  MatDestroy(&near_);
  const solvers::FourierBulkSolver& bulk = *bulk_;
  const geometry::Patch& patch = c_.fluid.patch();
  const int dim = c_.fluid.dim(), dof = dim + 1;
  // The rows the region's elements touch, and those they hold in full (every element of the node's support
  // in the region).
  std::vector<char> touched(bulk.n_nodes(), 0), outside(region_.size(), 0);
  for (int f : functions_on_elements(patch, region_)) touched[f] = 1;
  for (std::size_t e = 0; e < region_.size(); ++e) outside[e] = !region_[e];
  std::vector<char> near_nodes = touched;
  for (int f : functions_on_elements(patch, outside)) near_nodes[f] = 0;
  // Preallocation: a touched row's block columns are its stencil's nodes (+-degree per direction, wrapped in
  // the periodic ones), split between this rank's columns and the others'; any other row, its diagonal (the
  // unit rows of the walls).
  PetscInt lo = 0, hi = 0;
  CELLFSI_PETSC(VecGetOwnershipRange(c_.fluid.solution(), &lo, &hi));
  const PetscInt b0 = lo / dof, b1 = hi / dof;
  std::array<int, 3> n{1, 1, 1}, p{0, 0, 0};
  std::array<bool, 3> periodic{false, false, false};
  for (int d = 0; d < dim; ++d) {
    n[d] = patch.n_control(d);
    p[d] = patch.degree(d);
    periodic[d] = patch.knots(d).periodic();
  }
  std::vector<PetscInt> d_nnz(b1 - b0, 1), o_nnz(b1 - b0, 0);
  std::array<std::vector<int>, 3> cols;
  for (PetscInt gb = b0; gb < b1; ++gb) {
    const int node = bulk.natural_node(static_cast<int>(gb));
    if (!touched[node]) continue;
    const std::array<int, 3> c{node % n[0], (node / n[0]) % n[1], node / (n[0] * n[1])};
    for (int d = 0; d < 3; ++d) {
      cols[d].clear();
      for (int o = -p[d]; o <= p[d]; ++o) {
        int x = c[d] + o;
        if (periodic[d])
          x = (x % n[d] + n[d]) % n[d];
        else if (x < 0 || x >= n[d])
          continue;
        if (std::find(cols[d].begin(), cols[d].end(), x) == cols[d].end()) cols[d].push_back(x);
      }
    }
    PetscInt in = 0, out = 0;
    for (int z : cols[2])
      for (int y : cols[1])
        for (int x : cols[0]) {
          const PetscInt g = bulk.global_node(x + n[0] * (y + n[1] * z));
          (g >= b0 && g < b1 ? in : out) += 1;
        }
    d_nnz[gb - b0] = in;
    o_nnz[gb - b0] = out;
  }
  CELLFSI_PETSC(MatCreateBAIJ(c_.fluid.comm(), dof, hi - lo, hi - lo, PETSC_DETERMINE, PETSC_DETERMINE, 0,
                              d_nnz.data(), 0, o_nnz.data(), &near_));
  // Every row's diagonal block in the pattern (an assembly squeezes out what was not set): the assembly's
  // Dirichlet rows become unit rows there.
  const std::vector<PetscScalar> zero(static_cast<std::size_t>(dof) * dof, 0.0);
  for (PetscInt gb = b0; gb < b1; ++gb)
    CELLFSI_PETSC(MatSetValuesBlocked(near_, 1, &gb, 1, &gb, zero.data(), INSERT_VALUES));
  CELLFSI_PETSC(MatAssemblyBegin(near_, MAT_FLUSH_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(near_, MAT_FLUSH_ASSEMBLY));
  const ISLocalToGlobalMapping ltog = c_.fluid.block_layout()->local_to_global;
  CELLFSI_PETSC(MatSetLocalToGlobalMapping(near_, ltog, ltog));
  near_op_ = solvers::create_near_operator(bulk, near_, std::move(near_nodes));
  if (null_space_) CELLFSI_PETSC(MatSetNullSpace(near_op_, null_space_));
  if (transpose_null_space_) CELLFSI_PETSC(MatSetTransposeNullSpace(near_op_, transpose_null_space_));
  solvers::pc_fourier_compose_bulk(near_op_, bulk_);  // what cellfsi_fourier set up on it inverts
}

void FourierSolve::refresh_near_operator(Vec X) {
  // The region: the elements around the cells, `degree` elements beyond the active ones at least, so that
  // every row the cells change (a node whose support meets an active element) is held in full; grown by
  // the margin so that it is kept for a while as the cells move.
  const std::vector<char> active = c_.active_elements();
  const geometry::Patch& patch = c_.fluid.patch();
  int reach = 0;
  for (int d = 0; d < c_.fluid.dim(); ++d) reach = std::max(reach, patch.degree(d));
  const bool fresh = !near_ || !contains(region_, grow_elements(patch, active, reach));
  if (fresh) {
    region_ = grow_elements(patch, active, reach + c_.options.region_margin);
    make_near_operator();
  } else {
    CELLFSI_PETSC(MatZeroEntries(near_));
  }
  c_.fluid.jacobian_add_part(X, near_, region_);
  // (An assembly of the operator raises its state: KSP then sets the preconditioner up again.)
  CELLFSI_PETSC(MatAssemblyBegin(near_op_, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(near_op_, MAT_FINAL_ASSEMBLY));
}

void FourierSolve::refresh_jacobian(Vec X) {
  EventScope ev(coupling_events().jacobian);
  if (c_.options.bulk_stencil) {
    refresh_near_operator(X);
    return;
  }
  // Only the elements around the cells are re-assembled: the rest, kept in J_fixed_, is rebuilt when the
  // cells leave the region it was assembled for; a region of most of the domain is not worth the matrix.
  Mat J = c_.fluid.jacobian_matrix();
  const std::vector<char> active = c_.active_elements();
  if (region_.empty() || !contains(region_, active)) {
    region_ = grow_elements(c_.fluid.patch(), active, c_.options.region_margin);
    const auto in_region = std::count(region_.begin(), region_.end(), 1);
    if (!c_.options.partial_jacobian || region_holds_most(in_region, region_.size())) {
      region_.assign(region_.size(), 1);
      MatDestroy(&J_fixed_);
    } else {
      if (!J_fixed_) CELLFSI_PETSC(MatDuplicate(J, MAT_DO_NOT_COPY_VALUES, &J_fixed_));
      c_.fluid.jacobian_part(X, J_fixed_, region_, false);
    }
  }
  if (J_fixed_) {
    CELLFSI_PETSC(MatCopy(J_fixed_, J, SAME_NONZERO_PATTERN));
    c_.fluid.jacobian_add_part(X, J, region_);
  } else {
    c_.fluid.jacobian(X, J);
  }
}

Mat FourierSolve::operator_matrix() const { return near_op_ ? near_op_ : c_.fluid.jacobian_matrix(); }

void FourierSolve::after_refresh() {
  const solvers::RegionCorrectedSolver* fourier = solvers::pc_fourier_solver(pc());
  if (fourier && !fourier->single_precision_failure().empty() && !single_failure_reported_) {
    single_failure_reported_ = true;
    CELLFSI_PETSC(
        PetscPrintf(c_.fluid.comm(),
                    "cellfsi: the region's LU in single precision failed (%s); the region is factorised "
                    "in double precision from now on (-coupling_fourier_region_pc_type lu)\n",
                    fourier->single_precision_failure().c_str()));
  }
  if (c_.options.monitor && fourier)
    CELLFSI_PETSC(PetscPrintf(c_.fluid.comm(),
                              "  Fourier solver: %d nodes differ from the bulk, region %" PetscInt_FMT
                              " unknowns\n",
                              fourier->n_differing_nodes(), corrected_unknowns()));
}

bool FourierSolve::refresh_factorizes() const {
  const solvers::RegionCorrectedSolver* f = solvers::pc_fourier_solver(pc());
  return f && f->region_factorized();
}

PetscInt FourierSolve::corrected_unknowns() const {
  const solvers::RegionCorrectedSolver* f = solvers::pc_fourier_solver(pc());
  return f ? f->n_region() : 0;
}

}  // namespace cellfsi::coupling
