#include "solvers/band_schur.hpp"

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "common/petsc_error.hpp"

namespace cellfsi::solvers {

namespace {

/// Block CSR structure of a SeqBAIJ matrix (copied: PETSc's arrays are only lent).
struct BlockStructure {
  std::vector<PetscInt> ia, ja;
};

BlockStructure block_structure(Mat A) {
  PetscInt n = 0;
  const PetscInt *ia = nullptr, *ja = nullptr;
  PetscBool done = PETSC_FALSE;
  CELLFSI_PETSC(MatGetRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  if (!done) throw std::runtime_error("BandSchurSolver: the matrix gives no row structure");
  BlockStructure s;
  s.ia.assign(ia, ia + n + 1);
  s.ja.assign(ja, ja + ia[n]);
  CELLFSI_PETSC(MatRestoreRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  return s;
}

void require_seqbaij(Mat A, const char* what) {
  PetscBool is = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(A), MATSEQBAIJ, &is));
  if (!is) throw std::invalid_argument(std::string("BandSchurSolver: ") + what + " must be a SeqBAIJ matrix");
}

void check_factor(Mat F, const char* what) {
  MatFactorError err = MAT_FACTOR_NOERROR;
  CELLFSI_PETSC(MatFactorGetError(F, &err));
  if (err != MAT_FACTOR_NOERROR)
    throw std::runtime_error(std::string("BandSchurSolver: the LU factorisation of ") + what +
                             " failed (PETSc MatFactorError " + std::to_string(static_cast<int>(err)) + ")");
}

}  // namespace

/// MUMPS' Schur step of a fused solve: X = S^{-1} B for the one right-hand side MUMPS condensed (B and X
/// share their array).
PetscErrorCode band_schur_matsolve(Mat S, Mat B, Mat X) {
  PetscFunctionBeginUser;
  PetscContainer c = nullptr;
  PetscCall(PetscObjectQuery(reinterpret_cast<PetscObject>(S), "cellfsi_band_schur",
                             reinterpret_cast<PetscObject*>(&c)));
  PetscCheck(c, PETSC_COMM_SELF, PETSC_ERR_PLIB, "band Schur solver not attached");
  void* ctx = nullptr;
  PetscCall(PetscContainerGetPointer(c, &ctx));
  auto* self = static_cast<BandSchurSolver*>(ctx);
  PetscInt n = 0, ncol = 0;
  PetscCall(MatGetSize(B, &n, &ncol));
  PetscCheck(ncol == 1 && n == self->n_edge_, PETSC_COMM_SELF, PETSC_ERR_SUP, "one right-hand side expected");
  // The condensed right-hand side on the band: MUMPS' on the edge; the inner nodes', which do not couple to
  // I, are those of the right-hand side (already in rB_, see solve()).
  const std::vector<PetscInt>& edge = self->edge_pos_;
  const PetscScalar* b = nullptr;
  PetscScalar* v = nullptr;
  PetscCall(MatDenseGetArrayRead(B, &b));
  PetscCall(VecGetArray(self->rB_, &v));
  for (PetscInt k = 0; k < n; ++k) v[edge[k]] = b[k];
  PetscCall(VecRestoreArray(self->rB_, &v));
  PetscCall(MatDenseRestoreArrayRead(B, &b));
  try {
    self->solve_schur(self->rB_, self->yB_);
  } catch (const std::exception& e) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "%s", e.what());
  }
  PetscScalar* x = nullptr;
  const PetscScalar* y = nullptr;
  PetscCall(MatDenseGetArrayWrite(X, &x));
  PetscCall(VecGetArrayRead(self->yB_, &y));
  for (PetscInt k = 0; k < n; ++k) x[k] = y[edge[k]];
  PetscCall(VecRestoreArrayRead(self->yB_, &y));
  PetscCall(MatDenseRestoreArrayWrite(X, &x));
  PetscFunctionReturn(0);
}

BandSchurSolver::~BandSchurSolver() { release(); }

void BandSchurSolver::solve_schur(Vec g, Vec y) { CELLFSI_PETSC(MatSolve(SF_, g, y)); }

void BandSchurSolver::release() {
  MatDestroy(&F_);
  MatDestroy(&K_);
  MatDestroy(&K_BI_);
  MatDestroy(&K_IB_);
  MatDestroy(&S_);
  MatDestroy(&SF_);
  MatDestroy(&band_sub_);
  ISDestroy(&band_);
  ISDestroy(&interior_);
  for (Vec* v : {&w1_, &w2_, &rB_, &yB_, &tB_, &zI_, &tI_}) VecDestroy(v);
  VecScatterDestroy(&to_band_);
  VecScatterDestroy(&to_interior_);
  s_fixed_.clear();
  s_fixed_minus_bb_.clear();
  band_pos_.clear();
  edge_pos_.clear();
  s_ia_.clear();
  s_ja_.clear();
  prefix_.clear();
  n_band_ = n_total_ = n_edge_ = schur_nonzeros_ = 0;
}

void BandSchurSolver::factor(Mat fixed, IS band, const std::string& prefix) {
  try {
    factor_impl(fixed, band, prefix);
  } catch (...) {
    release();  // nothing half-built stays: factored() is false again
    throw;
  }
}

void BandSchurSolver::factor_impl(Mat fixed, IS band, const std::string& prefix) {
  release();
#ifdef __GLIBC__
  // MUMPS' many allocations stay in glibc's heap after its factors are freed: without this the resident size
  // grew by the size of a factorisation every few refactorisations (256 x 128: 2.7 -> 4.3 GB in 4).
  malloc_trim(0);
#endif
  require_seqbaij(fixed, "K_fixed");
  CELLFSI_PETSC(MatGetBlockSize(fixed, &bs_));
  CELLFSI_PETSC(MatGetSize(fixed, &n_total_, nullptr));
  CELLFSI_PETSC(ISDuplicate(band, &band_));
  CELLFSI_PETSC(ISSort(band_));
  CELLFSI_PETSC(ISGetLocalSize(band_, &n_band_));
  if (n_band_ == 0 || n_band_ % bs_ != 0)
    throw std::invalid_argument("BandSchurSolver: the band must hold whole blocks (" +
                                std::to_string(n_band_) + " unknowns, block size " + std::to_string(bs_) +
                                ")");
  CELLFSI_PETSC(ISComplement(band_, 0, n_total_, &interior_));
  const PetscInt nb = n_band_ / bs_, bs = bs_, bs2 = bs * bs;

  // The band's edge: its nodes whose rows of K_fixed are not zero (they border I). Only they enter
  // K_BI K_II^{-1} K_IB; the band's inner nodes have zero rows and columns in K_fixed.
  const PetscInt* band_idx = nullptr;
  CELLFSI_PETSC(ISGetIndices(band_, &band_idx));
  std::vector<PetscInt> band_nodes(nb);
  bool whole = true;
  for (PetscInt I = 0; I < nb; ++I) {
    band_nodes[I] = band_idx[I * bs] / bs;
    for (PetscInt c = 0; c < bs; ++c) whole = whole && band_idx[I * bs + c] == band_nodes[I] * bs + c;
  }
  CELLFSI_PETSC(ISRestoreIndices(band_, &band_idx));
  if (!whole)
    throw std::invalid_argument("BandSchurSolver: the band must hold whole blocks of " + std::to_string(bs) +
                                " unknowns");
  std::vector<PetscInt> inner_nodes;  // block rows of the band's inner nodes
  {
    const BlockStructure k = block_structure(fixed);
    PetscScalar* a = nullptr;
    CELLFSI_PETSC(MatSeqBAIJGetArray(fixed, &a));
    for (PetscInt I = 0; I < nb; ++I) {
      const PetscInt row = band_nodes[I];
      const bool nonzero =
          std::any_of(a + k.ia[row] * bs2, a + k.ia[row + 1] * bs2, [](PetscScalar v) { return v != 0.0; });
      if (nonzero)
        for (PetscInt c = 0; c < bs; ++c) edge_pos_.push_back(I * bs + c);
      else
        inner_nodes.push_back(row);
    }
    CELLFSI_PETSC(MatSeqBAIJRestoreArray(fixed, &a));
  }
  n_edge_ = static_cast<PetscInt>(edge_pos_.size());
  if (n_edge_ == 0) throw std::invalid_argument("BandSchurSolver: the band does not border the rest");

  // K_fixed with an identity on the band's inner nodes (which then decouple) is factorised by MUMPS with the
  // edge kept for the Schur complement: MUMPS returns S_edge = K_fixed,EE - K_EI K_II^{-1} K_IE.
  Mat K = nullptr;
  CELLFSI_PETSC(MatDuplicate(fixed, MAT_COPY_VALUES, &K));
  {
    std::vector<PetscScalar> identity(bs2, 0.0);
    for (PetscInt c = 0; c < bs; ++c) identity[c * bs + c] = 1.0;
    for (PetscInt n : inner_nodes)
      CELLFSI_PETSC(MatSetValuesBlocked(K, 1, &n, 1, &n, identity.data(), INSERT_VALUES));
    CELLFSI_PETSC(MatAssemblyBegin(K, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(K, MAT_FINAL_ASSEMBLY));
  }
  IS edge = nullptr;
  {
    std::vector<PetscInt> idx(n_edge_);
    const PetscInt* b = nullptr;
    CELLFSI_PETSC(ISGetIndices(band_, &b));
    for (PetscInt k = 0; k < n_edge_; ++k) idx[k] = b[edge_pos_[k]];
    CELLFSI_PETSC(ISRestoreIndices(band_, &b));
    CELLFSI_PETSC(ISCreateGeneral(PETSC_COMM_SELF, n_edge_, idx.data(), PETSC_COPY_VALUES, &edge));
  }
  MatFactorInfo info;
  CELLFSI_PETSC(MatFactorInfoInitialize(&info));
  CELLFSI_PETSC(MatGetFactor(K, MATSOLVERMUMPS, MAT_FACTOR_LU, &F_));
  if (!prefix.empty()) CELLFSI_PETSC(MatSetOptionsPrefix(F_, prefix.c_str()));
  if (blr_tolerance_ > 0) {
    // Block low-rank factors (MUMPS ICNTL(35) = 2: compressed in the factorisation and the solves) dropping
    // below blr_tolerance_: measured at 256 x 128, the factorisation 32 % and each solve 26 % faster, 13 %
    // less memory, and still one FGMRES iteration per solve with 1e-10 (1e-7: 1.5 iterations). Options under
    // the prefix (-<prefix>mat_mumps_icntl_35 0) override this default.
    CELLFSI_PETSC(MatMumpsSetIcntl(F_, 35, 2));
    CELLFSI_PETSC(MatMumpsSetCntl(F_, 7, blr_tolerance_));
  }
  CELLFSI_PETSC(MatFactorSetSchurIS(F_, edge));
  CELLFSI_PETSC(MatLUFactorSymbolic(F_, K, nullptr, nullptr, &info));
  CELLFSI_PETSC(MatLUFactorNumeric(F_, K, &info));
  CELLFSI_PETSC(ISDestroy(&edge));
  // MUMPS points into K's entries (PETSc passes a SeqBAIJ matrix's value array as the triples' values).
  K_ = K;
  check_factor(F_, "the fixed part");
  Mat Sd = nullptr;
  CELLFSI_PETSC(MatFactorCreateSchurComplement(F_, &Sd, nullptr));
  fused_active_ = fused_;
  if (fused_active_) {
    // MUMPS' own Schur matrix is declared factored, and its solve is ours (see the header).
    Mat S = nullptr;
    CELLFSI_PETSC(MatFactorGetSchurComplement(F_, &S, nullptr));
    PetscContainer c = nullptr;
    CELLFSI_PETSC(PetscContainerCreate(PETSC_COMM_SELF, &c));
    CELLFSI_PETSC(PetscContainerSetPointer(c, this));
    CELLFSI_PETSC(PetscObjectCompose(reinterpret_cast<PetscObject>(S), "cellfsi_band_schur",
                                     reinterpret_cast<PetscObject>(c)));
    CELLFSI_PETSC(PetscContainerDestroy(&c));
    CELLFSI_PETSC(MatSetOperation(S, MATOP_MAT_SOLVE, reinterpret_cast<void (*)(void)>(band_schur_matsolve)));
    CELLFSI_PETSC(MatSetFactorType(S, MAT_FACTOR_LU));  // MatMatSolve refuses an unfactored matrix
    CELLFSI_PETSC(MatFactorRestoreSchurComplement(F_, &S, MAT_FACTOR_SCHUR_FACTORED));
  } else {
    CELLFSI_PETSC(MatMumpsSetIcntl(F_, 26, 0));  // MatSolve: the interior problem only
  }

  CELLFSI_PETSC(MatCreateSubMatrix(fixed, band_, interior_, MAT_INITIAL_MATRIX, &K_BI_));
  CELLFSI_PETSC(MatCreateSubMatrix(fixed, interior_, band_, MAT_INITIAL_MATRIX, &K_IB_));

  // The Schur complement's block pattern: K_fixed,BB's structure (where K_band will add) and every block of
  // S_edge that is not zero (the dense coupling of the edge through I). S_fixed is S_edge on the edge and
  // zero elsewhere (the inner nodes' rows and columns of K_fixed are zero).
  Mat K_BB = nullptr;
  CELLFSI_PETSC(MatCreateSubMatrix(fixed, band_, band_, MAT_INITIAL_MATRIX, &K_BB));
  const BlockStructure kbb = block_structure(K_BB);
  const PetscScalar* sd = nullptr;
  PetscInt lda = 0;
  CELLFSI_PETSC(MatDenseGetLDA(Sd, &lda));
  CELLFSI_PETSC(MatDenseGetArrayRead(Sd, &sd));
  const PetscInt ne = n_edge_ / bs;
  std::vector<PetscInt> edge_of(nb, -1);  // band node -> edge node, or -1
  for (PetscInt k = 0; k < ne; ++k) edge_of[edge_pos_[k * bs] / bs] = k;
  std::vector<std::vector<PetscInt>> cols(nb);
  for (PetscInt I = 0; I < nb; ++I)
    cols[I].assign(kbb.ja.begin() + kbb.ia[I], kbb.ja.begin() + kbb.ia[I + 1]);
  auto edge_block_nonzero = [&](PetscInt ei, PetscInt ej) {
    for (PetscInt e = 0; e < bs; ++e)
      for (PetscInt c = 0; c < bs; ++c)
        if (sd[(ei * bs + c) + (ej * bs + e) * lda] != 0.0) return true;
    return false;
  };
  for (PetscInt ej = 0; ej < ne; ++ej)
    for (PetscInt ei = 0; ei < ne; ++ei)
      if (edge_block_nonzero(ei, ej)) cols[edge_pos_[ei * bs] / bs].push_back(edge_pos_[ej * bs] / bs);
  std::vector<PetscInt> nnz(nb);
  for (PetscInt I = 0; I < nb; ++I) {
    std::sort(cols[I].begin(), cols[I].end());
    cols[I].erase(std::unique(cols[I].begin(), cols[I].end()), cols[I].end());
    nnz[I] = static_cast<PetscInt>(cols[I].size());
  }
  CELLFSI_PETSC(MatCreateSeqBAIJ(PETSC_COMM_SELF, bs, n_band_, n_band_, 0, nnz.data(), &S_));
  CELLFSI_PETSC(MatSetOption(S_, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
  std::vector<PetscScalar> zeros;
  for (PetscInt I = 0; I < nb; ++I) {
    zeros.assign(cols[I].size() * bs2, 0.0);
    CELLFSI_PETSC(MatSetValuesBlocked(S_, 1, &I, nnz[I], cols[I].data(), zeros.data(), INSERT_VALUES));
  }
  CELLFSI_PETSC(MatAssemblyBegin(S_, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(S_, MAT_FINAL_ASSEMBLY));
  const BlockStructure s = block_structure(S_);
  s_fixed_.assign(s.ja.size() * bs2, 0.0);
  for (PetscInt I = 0; I < nb; ++I)
    for (PetscInt k = s.ia[I]; k < s.ia[I + 1]; ++k) {
      const PetscInt ei = edge_of[I], ej = edge_of[s.ja[k]];
      if (ei < 0 || ej < 0) continue;
      for (PetscInt e = 0; e < bs; ++e)  // SeqBAIJ blocks are column-major
        for (PetscInt c = 0; c < bs; ++c)
          s_fixed_[k * bs2 + e * bs + c] = sd[(ei * bs + c) + (ej * bs + e) * lda];
    }
  // S_fixed - K_fixed,BB in the same layout, for set_operator (which is given K_BB = K_fixed,BB + K_band,BB).
  s_fixed_minus_bb_ = s_fixed_;
  {
    PetscScalar* kv = nullptr;
    CELLFSI_PETSC(MatSeqBAIJGetArray(K_BB, &kv));
    for (PetscInt I = 0; I < nb; ++I)
      for (PetscInt k = kbb.ia[I]; k < kbb.ia[I + 1]; ++k) {
        const PetscInt* lo = s.ja.data() + s.ia[I];
        const PetscInt* hi = s.ja.data() + s.ia[I + 1];
        const PetscInt pos = static_cast<PetscInt>(std::lower_bound(lo, hi, kbb.ja[k]) - s.ja.data());
        for (PetscInt i = 0; i < bs2; ++i) s_fixed_minus_bb_[pos * bs2 + i] -= kv[k * bs2 + i];
      }
    CELLFSI_PETSC(MatSeqBAIJRestoreArray(K_BB, &kv));
  }
  CELLFSI_PETSC(MatDestroy(&K_BB));
  schur_nonzeros_ = static_cast<PetscInt>(s.ja.size()) * bs2;
  CELLFSI_PETSC(MatDenseRestoreArrayRead(Sd, &sd));
  CELLFSI_PETSC(MatDestroy(&Sd));
  s_ia_ = s.ia;
  s_ja_ = s.ja;
  if (!prefix.empty()) prefix_ = prefix;

  CELLFSI_PETSC(MatCreateVecs(fixed, &w1_, &w2_));
  CELLFSI_PETSC(VecCreateSeq(PETSC_COMM_SELF, n_band_, &rB_));
  CELLFSI_PETSC(VecDuplicate(rB_, &yB_));
  CELLFSI_PETSC(VecDuplicate(rB_, &tB_));
  CELLFSI_PETSC(VecCreateSeq(PETSC_COMM_SELF, n_total_ - n_band_, &zI_));
  CELLFSI_PETSC(VecDuplicate(zI_, &tI_));
  CELLFSI_PETSC(VecScatterCreate(w1_, band_, rB_, nullptr, &to_band_));
  CELLFSI_PETSC(VecScatterCreate(w1_, interior_, zI_, nullptr, &to_interior_));
}

void BandSchurSolver::set_band(Mat band) { factor_schur(band, s_fixed_, "K_band"); }

void BandSchurSolver::set_operator(Mat K) { factor_schur(K, s_fixed_minus_bb_, "K"); }

void BandSchurSolver::factor_schur(Mat band, const std::vector<double>& base, const char* what) {
  if (!F_) throw std::logic_error("BandSchurSolver: the band's Schur complement before factor()");
  require_seqbaij(band, what);
  CELLFSI_PETSC(
      MatCreateSubMatrix(band, band_, band_, band_sub_ ? MAT_REUSE_MATRIX : MAT_INITIAL_MATRIX, &band_sub_));
  const PetscInt bs2 = bs_ * bs_;
  if (band_pos_.empty()) {
    const BlockStructure b = block_structure(band_sub_);
    std::vector<PetscInt> pos(b.ja.size());
    for (std::size_t I = 0; I + 1 < b.ia.size(); ++I) {
      const PetscInt* lo = s_ja_.data() + s_ia_[I];
      const PetscInt* hi = s_ja_.data() + s_ia_[I + 1];
      for (PetscInt k = b.ia[I]; k < b.ia[I + 1]; ++k) {
        const PetscInt* p = std::lower_bound(lo, hi, b.ja[k]);
        if (p == hi || *p != b.ja[k])
          throw std::invalid_argument("BandSchurSolver: K_band has a block outside K_fixed's structure");
        pos[k] = static_cast<PetscInt>(p - s_ja_.data());
      }
    }
    band_pos_ = std::move(pos);
  }
  PetscScalar* a = nullptr;
  PetscScalar* b = nullptr;
  CELLFSI_PETSC(MatSeqBAIJGetArray(S_, &a));
  CELLFSI_PETSC(MatSeqBAIJGetArray(band_sub_, &b));
  std::copy(base.begin(), base.end(), a);
  for (std::size_t k = 0; k < band_pos_.size(); ++k) {
    PetscScalar* dst = a + band_pos_[k] * bs2;
    const PetscScalar* src = b + k * bs2;
    for (PetscInt i = 0; i < bs2; ++i) dst[i] += src[i];
  }
  CELLFSI_PETSC(MatSeqBAIJRestoreArray(band_sub_, &b));
  CELLFSI_PETSC(MatSeqBAIJRestoreArray(S_, &a));

  MatFactorInfo info;
  CELLFSI_PETSC(MatFactorInfoInitialize(&info));
  if (!SF_) {
    CELLFSI_PETSC(MatGetFactor(S_, MATSOLVERMUMPS, MAT_FACTOR_LU, &SF_));
    if (!prefix_.empty()) CELLFSI_PETSC(MatSetOptionsPrefix(SF_, (prefix_ + "schur_").c_str()));
    CELLFSI_PETSC(MatLUFactorSymbolic(SF_, S_, nullptr, nullptr, &info));
  }
  CELLFSI_PETSC(MatLUFactorNumeric(SF_, S_, &info));
  check_factor(SF_, "the band's Schur complement");
}

void BandSchurSolver::solve(Vec r, Vec x) {
  if (!SF_) throw std::logic_error("BandSchurSolver::solve before set_band");
  auto scatter = [](VecScatter sc, Vec from, Vec to, ScatterMode mode) {
    CELLFSI_PETSC(VecScatterBegin(sc, from, to, INSERT_VALUES, mode));
    CELLFSI_PETSC(VecScatterEnd(sc, from, to, INSERT_VALUES, mode));
  };
  if (fused_active_) {
    // MUMPS condenses onto the edge and calls band_schur_matsolve, which completes rB_ and leaves y in yB_;
    // MUMPS' values on the inner nodes (its identity) are replaced by y.
    scatter(to_band_, r, rB_, SCATTER_FORWARD);
    CELLFSI_PETSC(MatSolve(F_, r, x));
    scatter(to_band_, yB_, x, SCATTER_REVERSE);
    return;
  }
  // z = K_II^{-1} r_I (w1: r_I and zero on B; MUMPS solves the interior problem only)
  scatter(to_band_, r, rB_, SCATTER_FORWARD);
  scatter(to_interior_, r, zI_, SCATTER_FORWARD);
  CELLFSI_PETSC(VecSet(w1_, 0.0));
  scatter(to_interior_, zI_, w1_, SCATTER_REVERSE);
  CELLFSI_PETSC(MatSolve(F_, w1_, w2_));
  // y = S^{-1} (r_B - K_BI z)
  scatter(to_interior_, w2_, zI_, SCATTER_FORWARD);
  CELLFSI_PETSC(MatMult(K_BI_, zI_, tB_));
  CELLFSI_PETSC(VecAXPY(rB_, -1.0, tB_));
  solve_schur(rB_, yB_);
  // x_I = K_II^{-1} (r_I - K_IB y), x_B = y
  CELLFSI_PETSC(MatMult(K_IB_, yB_, tI_));
  scatter(to_interior_, r, zI_, SCATTER_FORWARD);
  CELLFSI_PETSC(VecAXPY(zI_, -1.0, tI_));
  CELLFSI_PETSC(VecSet(w1_, 0.0));
  scatter(to_interior_, zI_, w1_, SCATTER_REVERSE);
  CELLFSI_PETSC(MatSolve(F_, w1_, x));
  scatter(to_band_, yB_, x, SCATTER_REVERSE);
}

}  // namespace cellfsi::solvers
