#include "coupling/anderson.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "common/petsc_error.hpp"

namespace cellfsi::coupling {

namespace {

/// Kind i mod block_size for each of this rank's entries of `like`.
std::vector<int> interleaved_kinds(Vec like, int block_size) {
  if (block_size < 1) throw std::invalid_argument("Anderson acceleration: block size must be >= 1");
  PetscInt lo = 0, hi = 0;
  CELLFSI_PETSC(VecGetOwnershipRange(like, &lo, &hi));
  std::vector<int> kinds(static_cast<std::size_t>(hi - lo));
  for (PetscInt i = lo; i < hi; ++i) kinds[i - lo] = static_cast<int>(i % block_size);
  return kinds;
}

}  // namespace

AndersonAcceleration::AndersonAcceleration(Vec like, int block_size, int columns, int reuse_steps)
    : AndersonAcceleration(like, interleaved_kinds(like, block_size), columns, reuse_steps) {}

AndersonAcceleration::AndersonAcceleration(Vec like, std::vector<int> kinds, int columns, int reuse_steps)
    : kinds_(std::move(kinds)), max_columns_(columns), reuse_steps_(reuse_steps) {
  if (columns < 1) throw std::invalid_argument("Anderson acceleration: columns must be >= 1");
  if (reuse_steps < 0) throw std::invalid_argument("Anderson acceleration: reuse steps must be >= 0");
  PetscInt n_local = 0;
  CELLFSI_PETSC(VecGetLocalSize(like, &n_local));
  if (static_cast<PetscInt>(kinds_.size()) != n_local)
    throw std::invalid_argument("Anderson acceleration: one kind per local entry of the iterate");
  int n_kinds = 0;
  for (int k : kinds_) {
    if (k < 0) throw std::invalid_argument("Anderson acceleration: kinds must be >= 0");
    n_kinds = std::max(n_kinds, k + 1);
  }
  MPI_Comm comm = MPI_COMM_NULL;
  CELLFSI_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(like), &comm));
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &n_kinds, 1, MPI_INT, MPI_MAX, comm));
  std::vector<long long> count(n_kinds, 0);
  for (int k : kinds_) ++count[k];
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, count.data(), n_kinds, MPI_LONG_LONG, MPI_SUM, comm));
  per_kind_.assign(count.begin(), count.end());
  for (Vec* v : {&f_prev_, &g_prev_, &f_, &g_, &w_, &wf_}) CELLFSI_PETSC(VecDuplicate(like, v));
}

AndersonAcceleration::~AndersonAcceleration() {
  reset();
  for (Vec& v : spare_) VecDestroy(&v);
  for (Vec& v : q_) VecDestroy(&v);
  for (Vec* v : {&f_prev_, &g_prev_, &f_, &g_, &w_, &wf_}) VecDestroy(v);
}

void AndersonAcceleration::reset() {
  while (!cols_.empty()) drop_oldest();
  have_previous_ = false;
}

void AndersonAcceleration::drop_oldest() {
  spare_.push_back(cols_.front().df);
  spare_.push_back(cols_.front().dg);
  cols_.pop_front();
}

void AndersonAcceleration::begin_step() {
  ++step_;
  have_previous_ = false;
  while (!cols_.empty() && step_ - cols_.front().step > reuse_steps_) drop_oldest();
}

void AndersonAcceleration::update(Vec x, Vec dx) {
  // f_k = -dx, g_k = x - dx.
  CELLFSI_PETSC(VecAXPBY(f_, -1.0, 0.0, dx));
  CELLFSI_PETSC(VecWAXPY(g_, -1.0, dx, x));
  if (have_previous_) {
    if (static_cast<int>(cols_.size()) == max_columns_) drop_oldest();
    Column c;
    c.step = step_;
    auto take = [this]() {
      Vec v = nullptr;
      if (spare_.empty()) {
        CELLFSI_PETSC(VecDuplicate(f_, &v));
      } else {
        v = spare_.back();
        spare_.pop_back();
      }
      return v;
    };
    c.df = take();
    c.dg = take();
    CELLFSI_PETSC(VecWAXPY(c.df, -1.0, f_prev_, f_));
    CELLFSI_PETSC(VecWAXPY(c.dg, -1.0, g_prev_, g_));
    cols_.push_back(c);
  }
  CELLFSI_PETSC(VecCopy(f_, f_prev_));
  CELLFSI_PETSC(VecCopy(g_, g_prev_));
  have_previous_ = true;
  CELLFSI_PETSC(VecCopy(g_, x));
  const int m = static_cast<int>(cols_.size());
  if (m == 0) return;

  // Weights: 1 / (mean square of each unknown kind in f_k), so every kind counts alike in the norm; the
  // least-squares problem is solved in the scaled space (sqrt(W) dF, sqrt(W) f_k).
  // (By hand, not VecStrideNormAll: the vector's own block size need not be set.)
  const int n_kinds = static_cast<int>(per_kind_.size());
  const std::size_t n_local = kinds_.size();
  std::vector<double> squares(n_kinds, 0.0);
  {
    const PetscScalar* a = nullptr;
    CELLFSI_PETSC(VecGetArrayRead(f_, &a));
    for (std::size_t i = 0; i < n_local; ++i) squares[kinds_[i]] += a[i] * a[i];
    CELLFSI_PETSC(VecRestoreArrayRead(f_, &a));
  }
  MPI_Comm comm = MPI_COMM_NULL;
  CELLFSI_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(f_), &comm));
  MPI_Allreduce(MPI_IN_PLACE, squares.data(), n_kinds, MPI_DOUBLE, MPI_SUM, comm);
  std::vector<PetscReal> root_weight(n_kinds, 0.0);
  for (int c = 0; c < n_kinds; ++c)
    if (squares[c] > 0) root_weight[c] = std::sqrt(per_kind_[c] / squares[c]);
  {
    PetscScalar* w = nullptr;
    CELLFSI_PETSC(VecGetArrayWrite(w_, &w));
    for (std::size_t i = 0; i < n_local; ++i) w[i] = root_weight[kinds_[i]];
    CELLFSI_PETSC(VecRestoreArrayWrite(w_, &w));
  }
  // QR of the scaled columns by classical Gram-Schmidt with reorthogonalisation (the normal equations lose
  // the accuracy of nearly dependent columns); a column whose new direction is below 1e-10 of its norm is
  // left out.
  while (static_cast<int>(q_.size()) < m) {
    Vec v = nullptr;
    CELLFSI_PETSC(VecDuplicate(f_, &v));
    q_.push_back(v);
  }
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(m, m);
  std::vector<int> kept;  // columns in the basis, in order
  std::vector<Vec> basis;
  std::vector<PetscScalar> r(m);
  for (int j = 0; j < m; ++j) {
    Vec q = q_[kept.size()];
    CELLFSI_PETSC(VecPointwiseMult(q, w_, cols_[j].df));
    PetscReal norm0 = 0;
    CELLFSI_PETSC(VecNorm(q, NORM_2, &norm0));
    if (!(norm0 > 0)) continue;
    const int k = static_cast<int>(basis.size());
    for (int pass = 0; pass < 2 && k > 0; ++pass) {
      CELLFSI_PETSC(VecMDot(q, k, basis.data(), r.data()));
      for (int i = 0; i < k; ++i) R(i, j) += r[i], r[i] = -r[i];
      CELLFSI_PETSC(VecMAXPY(q, k, r.data(), basis.data()));
    }
    PetscReal norm = 0;
    CELLFSI_PETSC(VecNorm(q, NORM_2, &norm));
    if (norm <= 1e-10 * norm0) {
      R.col(j).setZero();
      continue;
    }
    CELLFSI_PETSC(VecScale(q, 1.0 / norm));
    R(k, j) = norm;
    kept.push_back(j);
    basis.push_back(q);
  }
  const int k = static_cast<int>(kept.size());
  Eigen::VectorXd gamma = Eigen::VectorXd::Zero(m);
  if (k > 0) {
    CELLFSI_PETSC(VecPointwiseMult(wf_, w_, f_));
    CELLFSI_PETSC(VecMDot(wf_, k, basis.data(), r.data()));
    // R restricted to the kept columns is upper triangular (row i belongs to basis vector i).
    Eigen::MatrixXd Rk(k, k);
    Eigen::VectorXd c(k);
    for (int i = 0; i < k; ++i) {
      c[i] = r[i];
      for (int jj = 0; jj < k; ++jj) Rk(i, jj) = R(i, kept[jj]);
    }
    const Eigen::VectorXd g = Rk.triangularView<Eigen::Upper>().solve(c);
    for (int jj = 0; jj < k; ++jj) gamma[kept[jj]] = g[jj];
  }
  std::vector<Vec> dg(m);
  for (int j = 0; j < m; ++j) dg[j] = cols_[j].dg;
  std::vector<PetscScalar> minus_gamma(m);
  for (int j = 0; j < m; ++j) minus_gamma[j] = -gamma[j];
  CELLFSI_PETSC(VecMAXPY(x, m, minus_gamma.data(), dg.data()));
}

}  // namespace cellfsi::coupling
