#include "fluid/region_corrected_solver.hpp"

#include <algorithm>
#include <stdexcept>

#include "common/petsc_error.hpp"

namespace cellfsi::fluid {

RegionCorrectedSolver::RegionCorrectedSolver(std::array<int, 3> n, std::array<bool, 3> periodic,
                                             std::array<int, 3> degree, int dof, std::string prefix)
    : bulk_(n, periodic, degree, dof),
      n_(n),
      degree_(degree),
      periodic_(periodic),
      dof_(dof),
      prefix_(std::move(prefix)) {}

RegionCorrectedSolver::~RegionCorrectedSolver() {
  release_region();
  VecDestroy(&res_);
  VecDestroy(&t_);
}

void RegionCorrectedSolver::release_region() {
  ISDestroy(&is_);
  MatDestroy(&JR_);
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
  // The nodes where J is not the bulk operator, grown by overlap_ layers (periodic directions wrap).
  const std::vector<double> dev = bulk_.node_deviation(J);
  const int n_nodes = static_cast<int>(dev.size());
  std::vector<char> in(n_nodes, 0), grown(n_nodes, 0);
  n_differing_ = 0;
  for (int i = 0; i < n_nodes; ++i)
    if (dev[i] > threshold_) {
      in[i] = 1;
      ++n_differing_;
    }
  for (int i = 0; i < n_nodes; ++i) {
    if (!in[i]) continue;
    const std::array<int, 3> c{i % n_[0], (i / n_[0]) % n_[1], i / (n_[0] * n_[1])};
    std::array<int, 3> lo{}, hi{};
    for (int d = 0; d < 3; ++d) {
      const int g = n_[d] > 1 ? overlap_ : 0;
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
  std::vector<PetscInt> region;
  for (int i = 0; i < n_nodes; ++i)
    if (grown[i])
      for (int c = 0; c < dof_; ++c) region.push_back(static_cast<PetscInt>(i) * dof_ + c);
  if (region != region_ || (n_region_ > 0 && !JR_)) {
    release_region();  // (also after a build that failed half-way)
    n_region_ = static_cast<PetscInt>(region.size());
    if (n_region_ == 0) return;
    CELLFSI_PETSC(ISCreateGeneral(PETSC_COMM_SELF, n_region_, region.data(), PETSC_COPY_VALUES, &is_));
    CELLFSI_PETSC(ISSetBlockSize(is_, dof_));
    CELLFSI_PETSC(MatCreateSubMatrix(J, is_, is_, MAT_INITIAL_MATRIX, &JR_));
    PetscInt n_all = 0;
    CELLFSI_PETSC(MatGetSize(J, &n_all, nullptr));
    CELLFSI_PETSC(ISCreateStride(PETSC_COMM_SELF, n_all, 0, 1, &all_));
    CELLFSI_PETSC(ISSetBlockSize(all_, dof_));
    CELLFSI_PETSC(MatCreateSubMatrix(J, is_, all_, MAT_INITIAL_MATRIX, &J_rows_));
    CELLFSI_PETSC(VecCreateSeq(PETSC_COMM_SELF, n_region_, &rR_));
    CELLFSI_PETSC(VecDuplicate(rR_, &xR_));
    CELLFSI_PETSC(VecScatterCreate(res_, is_, rR_, nullptr, &to_region_));
    CELLFSI_PETSC(KSPCreate(PETSC_COMM_SELF, &region_ksp_));
    CELLFSI_PETSC(KSPSetOptionsPrefix(region_ksp_, (prefix_ + "region_").c_str()));
    CELLFSI_PETSC(KSPSetType(region_ksp_, KSPPREONLY));
    PC pc;
    CELLFSI_PETSC(KSPGetPC(region_ksp_, &pc));
    CELLFSI_PETSC(PCSetType(pc, PCLU));
    CELLFSI_PETSC(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
    CELLFSI_PETSC(KSPSetFromOptions(region_ksp_));
    region_ = std::move(region);
  } else if (n_region_ > 0) {
    CELLFSI_PETSC(MatCreateSubMatrix(J, is_, is_, MAT_REUSE_MATRIX, &JR_));
    CELLFSI_PETSC(MatCreateSubMatrix(J, is_, all_, MAT_REUSE_MATRIX, &J_rows_));
  }
  if (n_region_ == 0) return;
  CELLFSI_PETSC(KSPSetOperators(region_ksp_, JR_, JR_));
  CELLFSI_PETSC(KSPSetUp(region_ksp_));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(region_ksp_, &pc));
  PCFailedReason reason = PC_NOERROR;
  CELLFSI_PETSC(PCGetFailedReason(pc, &reason));
  if (reason != PC_NOERROR)
    throw std::runtime_error("RegionCorrectedSolver: the LU factorisation of the region (" +
                             std::to_string(n_region_) + " unknowns) failed: " + PCFailedReasons[reason]);
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
  if (region_solves_ == 2) {
    region_solve(r, x);
    CELLFSI_PETSC(MatMult(J_, x, res_));
    CELLFSI_PETSC(VecAYPX(res_, -1.0, r));
    bulk_.solve(res_, t_);
    CELLFSI_PETSC(VecAXPY(x, 1.0, t_));
  } else {
    bulk_.solve(r, x);
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

}  // namespace cellfsi::fluid
