#include "solvers/region_corrected.hpp"

#include <algorithm>
#include <stdexcept>

#include "common/petsc_error.hpp"
#include "solvers/near_operator.hpp"
#include "solvers/nested_dissection.hpp"
#include "solvers/pc_lu_single.hpp"

namespace cellfsi::solvers {

RegionCorrectedSolver::RegionCorrectedSolver(std::array<int, 3> n, std::array<bool, 3> periodic,
                                             std::array<int, 3> degree, int dof, std::string prefix,
                                             MPI_Comm comm, AO natural)
    : RegionCorrectedSolver(std::make_shared<FourierBulkSolver>(n, periodic, degree, dof, comm, natural),
                            std::move(prefix)) {}

RegionCorrectedSolver::RegionCorrectedSolver(std::shared_ptr<FourierBulkSolver> bulk, std::string prefix)
    : bulk_(std::move(bulk)),
      n_(bulk_->shape()),
      degree_(bulk_->degree()),
      periodic_(bulk_->periodic()),
      dof_(bulk_->dof()),
      prefix_(std::move(prefix)),
      comm_(bulk_->comm()) {
  register_pc_lu_single();  // the region's default solver in 3D and its ordering (cellfsi_nd)
}

const char* default_region_pc_type(bool three_d) { return three_d ? kPCLUSingle : PCLU; }

RegionCorrectedSolver::~RegionCorrectedSolver() {
  release_region();
  VecDestroy(&res_);
  VecDestroy(&t_);
}

void RegionCorrectedSolver::release_region() {
  ISDestroy(&is_);
  MatDestroy(&JR_);
  MatDestroy(&JR_aij_);
  MatDestroy(&J_rows_);
  ISDestroy(&all_);
  KSPDestroy(&region_ksp_);
  VecScatterDestroy(&to_region_);
  VecDestroy(&rR_);
  VecDestroy(&xR_);
  region_.clear();
  n_region_ = 0;
}

void RegionCorrectedSolver::set_operator(Mat J) {
  J_ = J;
  if (!res_) {
    CELLFSI_PETSC(MatCreateVecs(J, &res_, &t_));
  }
  // An operator of solvers/near_operator.hpp: its rows away from the cells are the bulk operator itself, and
  // the region is read from its assembled near rows.
  const NearOperator* near = near_operator(J);
  const Mat rows_of = near ? near->near : J;
  // The nodes where J is not the bulk operator, grown by options_.overlap layers (periodic directions wrap).
  std::vector<double> dev = bulk_->node_deviation(rows_of);
  const int n_nodes = static_cast<int>(dev.size());
  if (near)
    for (int i = 0; i < n_nodes; ++i)
      if (!near->near_nodes[i]) dev[i] = 0;
  std::vector<char> in(n_nodes, 0), grown(n_nodes, 0);
  n_differing_ = 0;
  for (int i = 0; i < n_nodes; ++i)
    if (dev[i] > options_.threshold) {
      in[i] = 1;
      ++n_differing_;
    }
  for (int i = 0; i < n_nodes; ++i) {
    if (!in[i]) continue;
    const std::array<int, 3> c{i % n_[0], (i / n_[0]) % n_[1], i / (n_[0] * n_[1])};
    std::array<int, 3> lo{}, hi{};
    for (int d = 0; d < 3; ++d) {
      const int g = n_[d] > 1 ? options_.overlap : 0;
      lo[d] = c[d] - g;
      hi[d] = c[d] + g;
      if (!periodic_[d]) {
        lo[d] = std::max(lo[d], 0);
        hi[d] = std::min(hi[d], n_[d] - 1);
      } else if (2 * g + 1 >= n_[d]) {
        lo[d] = 0;
        hi[d] = n_[d] - 1;
      }
    }
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x) {
          const int wx = (x % n_[0] + n_[0]) % n_[0], wy = (y % n_[1] + n_[1]) % n_[1],
                    wz = (z % n_[2] + n_[2]) % n_[2];
          grown[wx + n_[0] * (wy + n_[1] * wz)] = 1;
        }
  }
  std::vector<int> region;
  for (int i = 0; i < n_nodes; ++i)
    if (grown[i]) region.push_back(i);
  if (near)
    for (int node : region)
      if (!near->near_nodes[node])
        throw std::runtime_error("RegionCorrectedSolver: the region reaches node " + std::to_string(node) +
                                 ", whose rows the operator's assembled part does not hold (a larger margin "
                                 "of assembled elements around the cells is needed)");
  if (region != region_ || (!region.empty() && !JR_)) {
    release_region();  // (also after a build that failed half-way)
    n_region_ = static_cast<PetscInt>(region.size()) * dof_;
    if (n_region_ == 0) return;
    // This rank's rows of the region, in the global ordering.
    PetscInt row_begin = 0, row_end = 0;
    CELLFSI_PETSC(MatGetOwnershipRange(rows_of, &row_begin, &row_end));
    std::vector<PetscInt> rows;
    for (int node : region) {
      const PetscInt g = static_cast<PetscInt>(bulk_->global_node(node)) * dof_;
      if (g >= row_begin && g < row_end)
        for (int c = 0; c < dof_; ++c) rows.push_back(g + c);
    }
    std::sort(rows.begin(), rows.end());
    const auto n_rows = static_cast<PetscInt>(rows.size());
    CELLFSI_PETSC(ISCreateGeneral(comm_, n_rows, rows.data(), PETSC_COPY_VALUES, &is_));
    CELLFSI_PETSC(ISSetBlockSize(is_, dof_));
    CELLFSI_PETSC(MatCreateSubMatrix(rows_of, is_, is_, MAT_INITIAL_MATRIX, &JR_));
    CELLFSI_PETSC(ISCreateStride(comm_, row_end - row_begin, row_begin, 1, &all_));
    CELLFSI_PETSC(ISSetBlockSize(all_, dof_));
    CELLFSI_PETSC(MatCreateSubMatrix(rows_of, is_, all_, MAT_INITIAL_MATRIX, &J_rows_));
    CELLFSI_PETSC(VecCreate(comm_, &rR_));
    CELLFSI_PETSC(VecSetSizes(rR_, n_rows, PETSC_DECIDE));
    CELLFSI_PETSC(VecSetType(rR_, VECSTANDARD));
    CELLFSI_PETSC(VecDuplicate(rR_, &xR_));
    CELLFSI_PETSC(VecScatterCreate(res_, is_, rR_, nullptr, &to_region_));
    PetscMPIInt size = 1;
    CELLFSI_PETSC(MPI_Comm_size(comm_, &size));
    create_region_ksp(size);
    region_ = std::move(region);
  } else if (n_region_ > 0) {
    PetscMPIInt size = 1;
    CELLFSI_PETSC(MPI_Comm_size(comm_, &size));
    // PETSc 3.18 refuses to refill an MPIBAIJ submatrix of the same index sets ("Previous matrix must be same
    // size/layout as request", measured): on several ranks the submatrices are extracted anew.
    const MatReuse reuse = size == 1 ? MAT_REUSE_MATRIX : MAT_INITIAL_MATRIX;
    if (size > 1) {
      MatDestroy(&JR_);
      MatDestroy(&J_rows_);
    }
    CELLFSI_PETSC(MatCreateSubMatrix(rows_of, is_, is_, reuse, &JR_));
    CELLFSI_PETSC(MatCreateSubMatrix(rows_of, is_, all_, reuse, &J_rows_));
  }
  if (n_region_ == 0) return;
  if (aij_) {
    MatDestroy(&JR_aij_);
    CELLFSI_PETSC(MatConvert(JR_, MATAIJ, MAT_INITIAL_MATRIX, &JR_aij_));
  }
  Mat factored = aij_ ? JR_aij_ : JR_;
  CELLFSI_PETSC(KSPSetOperators(region_ksp_, factored, factored));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(region_ksp_, &pc));
  try {
    CELLFSI_PETSC(KSPSetUp(region_ksp_));
  } catch (const std::runtime_error& e) {
    // The LU in single precision failed (MUMPS' error on every rank, so every rank is here): a region
    // singular to single precision but not to double. From now on the region is factorised in double
    // precision.
    PetscBool single = PETSC_FALSE;
    CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(pc), kPCLUSingle, &single));
    if (!single) throw;
    single_failure_ = e.what();
    PetscMPIInt size = 1;
    CELLFSI_PETSC(MPI_Comm_size(comm_, &size));
    KSPDestroy(&region_ksp_);
    create_region_ksp(size);
    MatDestroy(&JR_aij_);
    if (aij_) CELLFSI_PETSC(MatConvert(JR_, MATAIJ, MAT_INITIAL_MATRIX, &JR_aij_));
    factored = aij_ ? JR_aij_ : JR_;
    CELLFSI_PETSC(KSPSetOperators(region_ksp_, factored, factored));
    CELLFSI_PETSC(KSPSetUp(region_ksp_));
    CELLFSI_PETSC(KSPGetPC(region_ksp_, &pc));
  }
  // This rank's reason, and whether any rank failed: every rank throws, or none does (one alone would leave
  // the others waiting in the next collective call).
  PCFailedReason reason = PC_NOERROR;
  CELLFSI_PETSC(PCGetFailedReasonRank(pc, &reason));
  int failed = reason != PC_NOERROR;
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &failed, 1, MPI_INT, MPI_MAX, comm_));
  if (failed)
    throw std::runtime_error(
        "RegionCorrectedSolver: the LU factorisation of the region (" + std::to_string(n_region_) +
        " unknowns) failed: " + (reason != PC_NOERROR ? PCFailedReasons[reason] : "on another rank"));
}

bool RegionCorrectedSolver::region_factorized() const {
  if (n_region_ == 0 || !region_ksp_) return false;
  PC pc;
  CELLFSI_PETSC(KSPGetPC(region_ksp_, &pc));
  PetscBool factor = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompareAny(reinterpret_cast<PetscObject>(pc), &factor, PCLU, PCCHOLESKY,
                                          kPCLUSingle, ""));
  return factor == PETSC_TRUE;
}

void RegionCorrectedSolver::create_region_ksp(int size) {
  CELLFSI_PETSC(KSPCreate(comm_, &region_ksp_));
  CELLFSI_PETSC(KSPSetOptionsPrefix(region_ksp_, (prefix_ + "region_").c_str()));
  CELLFSI_PETSC(KSPSetType(region_ksp_, KSPPREONLY));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(region_ksp_, &pc));
  // In 3D the region's LU is half of a step at 64^3, redone every step: in single precision it costs half
  // (solvers/single_precision_lu.hpp, SCOTCH's nested dissection on any number of ranks), and the outer
  // FGMRES makes up the precision (docs/design.md §8). In 2D the region is small: MUMPS in double
  // precision with its own ordering (SCOTCH's ordering and the AIJ copy cost 3 % of the default scene, §12).
  // After a failure of the single-precision LU (set_operator), double precision whatever the options say.
  CELLFSI_PETSC(PCSetType(pc, single_failure_.empty() ? default_region_pc_type(n_[2] > 1) : PCLU));
  CELLFSI_PETSC(KSPSetFromOptions(region_ksp_));
  PetscBool single = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(pc), kPCLUSingle, &single));
  if (!single_failure_.empty() && single) CELLFSI_PETSC(PCSetType(pc, PCLU));
  PetscBool factor = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompareAny(reinterpret_cast<PetscObject>(pc), &factor, PCLU, PCCHOLESKY, ""));
  if (factor) {
    // A factorisation chosen by options (-..._pc_type lu): MUMPS unless another package is named, and in 3D
    // on one rank SCOTCH's ordering handed to it by PETSc (11 % off the LU at 64^3, §12) unless another
    // ordering is named (external: MUMPS' own).
    const std::string region_prefix = prefix_ + "region_";
    PetscBool package = PETSC_FALSE, ordering = PETSC_FALSE;
    CELLFSI_PETSC(
        PetscOptionsHasName(nullptr, region_prefix.c_str(), "-pc_factor_mat_solver_type", &package));
    CELLFSI_PETSC(
        PetscOptionsHasName(nullptr, region_prefix.c_str(), "-pc_factor_mat_ordering_type", &ordering));
    if (!package) CELLFSI_PETSC(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
    if (!ordering && size == 1 && n_[2] > 1)
      CELLFSI_PETSC(PCFactorSetMatOrderingType(pc, kMatOrderingNestedDissection));
  }
  aij_ = needs_aij(pc, size);
}

bool RegionCorrectedSolver::needs_aij(PC pc, int size) const {
  PetscBool factor = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompareAny(reinterpret_cast<PetscObject>(pc), &factor, PCLU, PCCHOLESKY, ""));
  if (!factor) return false;  // another PC chosen by options: it gets the region as extracted (BAIJ)
  MatSolverType type = nullptr;
  CELLFSI_PETSC(PCFactorGetMatSolverType(pc, &type));
  PetscBool available = PETSC_TRUE;
  if (type) CELLFSI_PETSC(MatGetFactorAvailable(JR_, type, MAT_FACTOR_LU, &available));
  if (!available) return true;  // e.g. SuperLU_DIST, which factorises AIJ only
  PetscBool mumps = PETSC_FALSE;
  if (type) CELLFSI_PETSC(PetscStrcmp(type, MATSOLVERMUMPS, &mumps));
  if (!mumps || size > 1) return false;
  // PETSc passes an ordering to MUMPS from an AIJ matrix only: convert unless MUMPS orders by itself.
  char ordering[64] = "";
  PetscBool set = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsGetString(nullptr, (prefix_ + "region_").c_str(), "-pc_factor_mat_ordering_type",
                                      ordering, sizeof ordering, &set));
  if (!set) return n_[2] > 1;  // the default above
  PetscBool external = PETSC_FALSE;
  CELLFSI_PETSC(PetscStrcmp(ordering, MATORDERINGEXTERNAL, &external));
  return !external;
}

void RegionCorrectedSolver::region_solve(Vec r, Vec x) {
  if (n_region_ == 0) return;
  CELLFSI_PETSC(VecScatterBegin(to_region_, r, rR_, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(to_region_, r, rR_, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(KSPSolve(region_ksp_, rR_, xR_));
  CELLFSI_PETSC(VecScatterBegin(to_region_, xR_, x, ADD_VALUES, SCATTER_REVERSE));
  CELLFSI_PETSC(VecScatterEnd(to_region_, xR_, x, ADD_VALUES, SCATTER_REVERSE));
}

void RegionCorrectedSolver::apply(Vec r, Vec x) {
  if (!J_) throw std::logic_error("RegionCorrectedSolver: apply before set_operator");
  // (Region,) bulk, region; the residual r - J x between the pieces.
  CELLFSI_PETSC(VecSet(x, 0.0));
  if (options_.region_solves == 2) {
    region_solve(r, x);
    CELLFSI_PETSC(MatMult(J_, x, res_));
    CELLFSI_PETSC(VecAYPX(res_, -1.0, r));
    bulk_->solve(res_, t_);
    CELLFSI_PETSC(VecAXPY(x, 1.0, t_));
  } else {
    bulk_->solve(r, x);
  }
  if (n_region_ == 0) return;
  // The region's solve needs the residual on the region's rows only: R (r - J x) = R r - (R J) x, a product
  // with the region's rows of J (a full product cost as much as the bulk solve at 256 x 128).
  CELLFSI_PETSC(VecScatterBegin(to_region_, r, rR_, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(to_region_, r, rR_, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(MatMult(J_rows_, x, xR_));
  CELLFSI_PETSC(VecAXPY(rR_, -1.0, xR_));
  CELLFSI_PETSC(KSPSolve(region_ksp_, rR_, xR_));
  CELLFSI_PETSC(VecScatterBegin(to_region_, xR_, x, ADD_VALUES, SCATTER_REVERSE));
  CELLFSI_PETSC(VecScatterEnd(to_region_, xR_, x, ADD_VALUES, SCATTER_REVERSE));
}

}  // namespace cellfsi::solvers
