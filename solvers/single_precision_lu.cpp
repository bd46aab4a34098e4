// See single_precision_lu.hpp.
#include "solvers/single_precision_lu.hpp"

#include <smumps_c.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "common/petsc_error.hpp"
#include "solvers/nested_dissection.hpp"

namespace cellfsi::solvers {

struct SinglePrecisionLU::Mumps {
  SMUMPS_STRUC_C id{};
  bool initialised = false;
};

namespace {

// MUMPS' arrays are 1-based Fortran ones: ICNTL(i) is icntl[i - 1].
constexpr int icntl(int i) { return i - 1; }

// The parts of a factorisation in -log_view: the host's ordering (SCOTCH), MUMPS' analysis (job 1), its
// numerical factorisation (job 2) and the solves (job 3).
struct LuEvents {
  PetscLogEvent order = register_log_event("cellfsi solvers", "RegionLUOrder");
  PetscLogEvent analyse = register_log_event("cellfsi solvers", "RegionLUAnalyse");
  PetscLogEvent numeric = register_log_event("cellfsi solvers", "RegionLUNumeric");
  PetscLogEvent solve = register_log_event("cellfsi solvers", "RegionLUSolve");
};

const LuEvents& lu_events() {
  static const LuEvents events;
  return events;
}

bool has_type(Mat A, const char* type) {
  PetscBool same = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(A), type, &same));
  return same;
}

}  // namespace

SinglePrecisionLU::SinglePrecisionLU(MPI_Comm comm) : mumps_(std::make_unique<Mumps>()), comm_(comm) {}

SinglePrecisionLU::~SinglePrecisionLU() {
  if (mumps_->initialised) {
    mumps_->id.job = -2;  // collective, as the PC's destruction is
    smumps_c(&mumps_->id);
  }
  VecScatterDestroy(&to_host_);
  VecDestroy(&b0_);
}

void SinglePrecisionLU::set_ordering(const std::string& ordering) {
  if (ordering != kMatOrderingNestedDissection && ordering != "mumps")
    throw std::invalid_argument("single-precision LU: ordering '" + ordering +
                                "' is invalid. Valid values are " + kMatOrderingNestedDissection +
                                " and mumps");
  if (ordering != ordering_) analysed_ = false;  // analyse anew
  ordering_ = ordering;
}

double SinglePrecisionLU::operations() const { return factored_ ? mumps_->id.rinfog[2] : 0.0; }

long long SinglePrecisionLU::factor_entries() const {
  if (!factored_) return 0;
  const long long v = mumps_->id.infog[28];
  return v >= 0 ? v : -v * 1000000LL;  // INFOG(29) < 0: millions of entries
}

void SinglePrecisionLU::call(int job) {
  SMUMPS_STRUC_C& id = mumps_->id;
  id.job = job;
  smumps_c(&id);
  if (id.infog[0] < 0)  // INFOG is the same on every rank: all throw
    throw std::runtime_error("single-precision LU (MUMPS smumps) failed in job " + std::to_string(job) +
                             " on " + std::to_string(n_) + " unknowns: INFOG(1) = " +
                             std::to_string(id.infog[0]) + ", INFOG(2) = " + std::to_string(id.infog[1]) +
                             " (see MUMPS' user guide, section on error diagnostics)");
}

void SinglePrecisionLU::extract(Mat A, bool values_only) {
  const bool mpi = has_type(A, MATMPIAIJ) || has_type(A, MATMPIBAIJ);
  const bool blocked = has_type(A, MATSEQBAIJ) || has_type(A, MATMPIBAIJ);
  if (!mpi && !blocked && !has_type(A, MATSEQAIJ))
    throw std::invalid_argument("single-precision LU: the matrix must be AIJ or BAIJ (sequential or MPI)");
  PetscInt row_begin = 0, row_end = 0, col_begin = 0, col_end = 0;
  CELLFSI_PETSC(MatGetOwnershipRange(A, &row_begin, &row_end));
  CELLFSI_PETSC(MatGetOwnershipRangeColumn(A, &col_begin, &col_end));
  Mat parts[2] = {A, nullptr};
  const PetscInt* garray = nullptr;  // the off-diagonal part's (block) columns
  if (has_type(A, MATMPIAIJ)) CELLFSI_PETSC(MatMPIAIJGetSeqAIJ(A, &parts[0], &parts[1], &garray));
  if (has_type(A, MATMPIBAIJ)) CELLFSI_PETSC(MatMPIBAIJGetSeqBAIJ(A, &parts[0], &parts[1], &garray));
  const PetscInt bs = blocked ? bs_ : 1, bs2 = bs * bs;
  if (!values_only) {
    irn_.clear();
    jcn_.clear();
  }
  values_.clear();
  for (int part = 0; part < 2; ++part) {
    Mat P = parts[part];
    if (!P) continue;
    PetscInt n_rows = 0;
    const PetscInt *ia = nullptr, *ja = nullptr;
    PetscBool done = PETSC_FALSE;
    CELLFSI_PETSC(
        MatGetRowIJ(P, 0, PETSC_FALSE, blocked ? PETSC_TRUE : PETSC_FALSE, &n_rows, &ia, &ja, &done));
    if (!done) throw std::runtime_error("single-precision LU: MatGetRowIJ gave no pattern");
    const auto entries = static_cast<std::size_t>(ia[n_rows] * bs2);
    values_.reserve(values_.size() + entries);
    if (!values_only) {
      irn_.reserve(irn_.size() + entries);
      jcn_.reserve(jcn_.size() + entries);
    }
    const PetscScalar* a = nullptr;
    PetscScalar* ab = nullptr;
    if (blocked)
      CELLFSI_PETSC(MatSeqBAIJGetArray(P, &ab));
    else
      CELLFSI_PETSC(MatSeqAIJGetArrayRead(P, &a));
    for (PetscInt i = 0; i < n_rows; ++i)
      for (PetscInt k = ia[i]; k < ia[i + 1]; ++k) {
        const PetscInt col = part == 0 ? col_begin / bs + ja[k] : garray[ja[k]];
        for (PetscInt r = 0; r < bs; ++r)
          for (PetscInt c = 0; c < bs; ++c) {
            // BAIJ stores each block by columns.
            values_.push_back(static_cast<float>(blocked ? ab[k * bs2 + c * bs + r] : a[k]));
            if (!values_only) {
              irn_.push_back(static_cast<int>(row_begin + i * bs + r + 1));
              jcn_.push_back(static_cast<int>(col * bs + c + 1));
            }
          }
      }
    if (blocked)
      CELLFSI_PETSC(MatSeqBAIJRestoreArray(P, &ab));
    else
      CELLFSI_PETSC(MatSeqAIJRestoreArrayRead(P, &a));
    CELLFSI_PETSC(
        MatRestoreRowIJ(P, 0, PETSC_FALSE, blocked ? PETSC_TRUE : PETSC_FALSE, &n_rows, &ia, &ja, &done));
  }
}

void SinglePrecisionLU::analyse() {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm_, &rank);
  MPI_Comm_size(comm_, &size);
  SMUMPS_STRUC_C& id = mumps_->id;
  id.n = static_cast<int>(n_);
  if (size == 1) {
    id.nnz = static_cast<MUMPS_INT8>(irn_.size());
    id.irn = irn_.data();
    id.jcn = jcn_.data();
  } else {
    id.icntl[icntl(18)] = 3;  // distributed triplets
    id.nnz_loc = static_cast<MUMPS_INT8>(irn_.size());
    id.irn_loc = irn_.data();
    id.jcn_loc = jcn_.data();
  }
  id.icntl[icntl(28)] = 1;  // sequential analysis on the host
  if (ordering_ == kMatOrderingNestedDissection) {
    // The pattern as a graph of nodes (bs_ unknowns each), ordered on the host. Each rank sends the node
    // pairs of the first row of each of its nodes, once per block: 1 / bs^2 of its triplets (the rows of a
    // node have the same blocks, those of a BAIJ Jacobian; were one missing, the ordering would be worse, not
    // wrong).
    const int bs = static_cast<int>(bs_);
    std::vector<int> pairs;  // (a, b), (a, b), ...
    for (std::size_t k = 0; k < irn_.size(); ++k) {
      const int row = irn_[k] - 1;
      if (row % bs != 0) continue;
      const int a = row / bs, b = (jcn_[k] - 1) / bs;
      if (a == b) continue;
      const std::size_t m = pairs.size();
      if (m >= 2 && pairs[m - 2] == a && pairs[m - 1] == b) continue;  // the block's other columns
      pairs.push_back(a);
      pairs.push_back(b);
    }
    const int n_local = static_cast<int>(pairs.size());
    std::vector<int> counts(size), offsets(size + 1, 0);
    MPI_Gather(&n_local, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm_);
    for (int r = 0; r < size; ++r) offsets[r + 1] = offsets[r] + counts[r];
    std::vector<int> all(rank == 0 ? offsets[size] : 0);
    MPI_Gatherv(pairs.data(), n_local, MPI_INT, all.data(), counts.data(), offsets.data(), MPI_INT, 0, comm_);
    std::vector<int>().swap(pairs);
    std::string failure;  // the host's, told to every rank: all throw, or none waits in MUMPS alone
    if (rank == 0) {
      EventScope ev(lu_events().order);
      try {
        std::vector<std::vector<int>> neighbours(n_ / bs_);
        for (std::size_t k = 0; k + 1 < all.size(); k += 2) {  // A + A^T
          neighbours[all[k]].push_back(all[k + 1]);
          neighbours[all[k + 1]].push_back(all[k]);
        }
        std::vector<int>().swap(all);
        const std::vector<int> position = nested_dissection(std::move(neighbours));
        perm_in_.resize(n_);
        for (PetscInt i = 0; i < n_; ++i)
          perm_in_[i] = static_cast<int>(position[i / bs_] * bs_ + i % bs_ + 1);
        id.perm_in = perm_in_.data();
      } catch (const std::exception& e) {
        failure = e.what();
      }
    }
    int length = static_cast<int>(failure.size());
    MPI_Bcast(&length, 1, MPI_INT, 0, comm_);
    if (length > 0) {
      failure.resize(length);
      MPI_Bcast(failure.data(), length, MPI_CHAR, 0, comm_);
      throw std::runtime_error("single-precision LU: the ordering failed: " + failure);
    }
    id.icntl[icntl(7)] = 1;  // the ordering given in PERM_IN
  } else {
    id.icntl[icntl(7)] = 7;  // MUMPS' own choice
  }
  {
    EventScope ev(lu_events().analyse);
    call(1);
  }
  ++analyses_;
}

void SinglePrecisionLU::factor(Mat A) {
  PetscInt rows = 0, cols = 0;
  CELLFSI_PETSC(MatGetSize(A, &rows, &cols));
  if (rows != cols) throw std::invalid_argument("single-precision LU: the matrix is not square");
  PetscInt bs = 1;
  CELLFSI_PETSC(MatGetBlockSize(A, &bs));
  if (bs < 1 || rows % bs != 0) bs = 1;
  PetscObjectState pattern = 0;
  CELLFSI_PETSC(MatGetNonzeroState(A, &pattern));
  PetscObjectId id_of_A = 0;
  CELLFSI_PETSC(PetscObjectGetId(reinterpret_cast<PetscObject>(A), &id_of_A));
  const bool same = analysed_ && analysed_id_ == id_of_A && pattern == pattern_ && rows == n_ && bs == bs_;
  if (!mumps_->initialised) {
    SMUMPS_STRUC_C& id = mumps_->id;
    id.comm_fortran = static_cast<MUMPS_INT>(MPI_Comm_c2f(comm_));
    id.par = 1;  // the host takes part in the factorisation
    id.sym = 0;  // unsymmetric
    call(-1);
    mumps_->initialised = true;
    id.icntl[icntl(1)] = -1;  // no printing: errors are thrown with INFOG
    id.icntl[icntl(2)] = -1;
    id.icntl[icntl(3)] = -1;
    id.icntl[icntl(4)] = 0;
  }
  factored_ = false;
  n_ = rows;
  bs_ = bs;
  extract(A, same);
  SMUMPS_STRUC_C& id = mumps_->id;
  if (!same) {
    VecScatterDestroy(&to_host_);
    VecDestroy(&b0_);
    analyse();
    analysed_ = true;
    analysed_id_ = id_of_A;
    pattern_ = pattern;
  }
  int size = 1;
  MPI_Comm_size(comm_, &size);
  if (size == 1)
    id.a = values_.data();
  else
    id.a_loc = values_.data();
  // Too little workspace (the estimate of the analysis exceeded by pivoting): more, up to 3 times.
  EventScope ev(lu_events().numeric);
  for (int attempt = 0;; ++attempt) {
    try {
      call(2);
      break;
    } catch (const std::runtime_error&) {
      const int e = id.infog[0];
      if (attempt >= 3 || (e != -8 && e != -9 && e != -14 && e != -15 && e != -17 && e != -20)) throw;
      id.icntl[icntl(14)] = std::max(2 * id.icntl[icntl(14)], 40);
    }
  }
  factored_ = true;
}

void SinglePrecisionLU::solve(Vec b, Vec x) {
  if (!factored_) throw std::logic_error("single-precision LU: solve before factor");
  EventScope ev(lu_events().solve);
  if (!to_host_) CELLFSI_PETSC(VecScatterCreateToZero(b, &to_host_, &b0_));
  CELLFSI_PETSC(VecScatterBegin(to_host_, b, b0_, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(to_host_, b, b0_, INSERT_VALUES, SCATTER_FORWARD));
  PetscInt n_host = 0;
  CELLFSI_PETSC(VecGetLocalSize(b0_, &n_host));
  PetscScalar* v = nullptr;
  CELLFSI_PETSC(VecGetArray(b0_, &v));
  rhs_.resize(n_host);
  for (PetscInt i = 0; i < n_host; ++i) rhs_[i] = static_cast<float>(v[i]);
  SMUMPS_STRUC_C& id = mumps_->id;
  id.rhs = rhs_.data();
  id.nrhs = 1;
  id.lrhs = static_cast<int>(n_);
  try {
    call(3);
  } catch (...) {
    VecRestoreArray(b0_, &v);
    throw;
  }
  for (PetscInt i = 0; i < n_host; ++i) v[i] = rhs_[i];
  CELLFSI_PETSC(VecRestoreArray(b0_, &v));
  CELLFSI_PETSC(VecScatterBegin(to_host_, b0_, x, INSERT_VALUES, SCATTER_REVERSE));
  CELLFSI_PETSC(VecScatterEnd(to_host_, b0_, x, INSERT_VALUES, SCATTER_REVERSE));
}

}  // namespace cellfsi::solvers
