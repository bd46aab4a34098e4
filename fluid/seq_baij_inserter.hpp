#pragma once
// SeqBaijInserter: the one-rank Jacobian's element blocks added straight into PETSc's SeqBAIJ value array
// (fluid_assembly.cpp). Measured against PETSc's public insertion (MatSetValuesBlockedLocal) and COO
// assembly in docs/performance.md, "Assembly per element"; it is kept because it is the fastest. Internal to fluid/.
#include <petscmat.h>

#include <algorithm>
#include <utility>
#include <vector>

#include "common/petsc_error.hpp"

namespace cellfsi::fluid {

/// Adds element node blocks straight into the value array of a sequential BAIJ matrix of block size dof (the
/// one-rank Jacobian), as MatSetValuesBlockedLocal(ADD_VALUES) would, without its per-block searches: the
/// element's column blocks are sorted once and located in each of its block rows (sorted in ja) by one merge.
/// Not usable (usable() false) for any other matrix: MPI, AIJ, another block size, no local-to-global map.
class SeqBaijInserter {
 public:
  SeqBaijInserter(Mat J, int bs) : J_(J), bs_(bs) {
    if (!J) return;
    PetscBool seqbaij = PETSC_FALSE;
    CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(J), MATSEQBAIJ, &seqbaij));
    PetscInt mbs = 0;
    CELLFSI_PETSC(MatGetBlockSize(J, &mbs));
    if (!seqbaij || mbs != bs) return;
    ISLocalToGlobalMapping rmap = nullptr, cmap = nullptr;
    CELLFSI_PETSC(MatGetLocalToGlobalMapping(J, &rmap, &cmap));
    if (!rmap || rmap != cmap) return;
    PetscInt lbs = 0;
    CELLFSI_PETSC(ISLocalToGlobalMappingGetBlockSize(rmap, &lbs));
    if (lbs != bs) return;
    PetscBool done = PETSC_FALSE;
    PetscInt nrows = 0;
    CELLFSI_PETSC(MatGetRowIJ(J, 0, PETSC_FALSE, PETSC_TRUE, &nrows, &ia_, &ja_, &done));
    if (!done) return;
    got_ij_ = true;
    map_ = rmap;
    CELLFSI_PETSC(ISLocalToGlobalMappingGetBlockIndices(map_, &global_));
    CELLFSI_PETSC(MatSeqBAIJGetArray(J, &a_));
  }
  SeqBaijInserter(const SeqBaijInserter&) = delete;
  SeqBaijInserter& operator=(const SeqBaijInserter&) = delete;
  ~SeqBaijInserter() {
    try {
      finish();
    } catch (...) {
    }
  }
  bool usable() const { return a_ != nullptr; }

  /// Finds the blocks of the element with local nodes lnode in the matrix. Returns false if one is not in the
  /// matrix's nonzero pattern. (Prefetching them here, before the element matrix is formed, measured no
  /// gain.)
  bool prepare(int n, const PetscInt* lnode) {
    located_ = locate(n, lnode);
    return located_;
  }

  /// Adds the (n bs) x (n bs) row-major element matrix K over the nodes given to prepare. Returns false,
  /// having added nothing, if prepare failed.
  bool add(int n, const double* K) {
    if (!located_) return false;
    switch (bs_) {
      case 3:
        add_blocks<3>(n, K);
        break;
      case 4:
        add_blocks<4>(n, K);
        break;
      default:
        add_blocks<0>(n, K);
        break;
    }
    return true;
  }

  /// Adds the element matrix in vms_tangent_element_blocks' layout (the matrix's own block layout) over the
  /// nodes given to prepare, which must have succeeded.
  void add_blocks(int n, const double* Kb) {
    if (bs_ == 3)
      add_node_blocks<3>(n, Kb);
    else if (bs_ == 4)
      add_node_blocks<4>(n, Kb);
    else
      add_node_blocks<0>(n, Kb);
  }

  /// Gives the arrays back to the matrix (before MatAssemblyBegin or any MatSetValues).
  void finish() {
    if (a_) {
      double* a = a_;
      a_ = nullptr;
      CELLFSI_PETSC(MatSeqBAIJRestoreArray(J_, &a));
    }
    if (global_) {
      const PetscInt* g = global_;
      global_ = nullptr;
      CELLFSI_PETSC(ISLocalToGlobalMappingRestoreBlockIndices(map_, &g));
    }
    if (got_ij_) {
      got_ij_ = false;
      PetscBool done = PETSC_FALSE;
      PetscInt nrows = 0;
      CELLFSI_PETSC(MatRestoreRowIJ(J_, 0, PETSC_FALSE, PETSC_TRUE, &nrows, &ia_, &ja_, &done));
    }
  }

 private:
  Mat J_;
  int bs_;
  const PetscInt *ia_ = nullptr, *ja_ = nullptr, *global_ = nullptr;
  ISLocalToGlobalMapping map_ = nullptr;
  bool got_ij_ = false;
  double* a_ = nullptr;
  bool located_ = false;
  std::vector<PetscInt> offset_;                   // pos_ - the row's start, kept from the previous element
  std::vector<PetscInt> pos_;                      // pos_[A n + B]: block index of (A, B) in a_
  std::vector<std::pair<PetscInt, int>> columns_;  // (global block column, B), sorted

  // Row by row. A block is usually where it was in the previous element, relative to its row's start (the
  // same stencil around the row's node, the same displacement between the nodes): tried first. Otherwise the
  // element's columns are sorted (insertion sort: few, mostly in order already) and found by one pass over
  // the row, where the next sorted column is usually the next entry (runs of consecutive nodes) or else
  // searched.
  bool locate(int n, const PetscInt* lnode) {
    columns_.clear();
    const std::size_t nn = static_cast<std::size_t>(n) * n;
    pos_.resize(nn);
    if (offset_.size() != nn) offset_.assign(nn, -1);
    for (int A = 0; A < n; ++A) {
      const PetscInt r = global_[lnode[A]], lo = ia_[r], hi = ia_[r + 1];
      PetscInt* pa = pos_.data() + static_cast<std::size_t>(A) * n;
      PetscInt* oa = offset_.data() + static_cast<std::size_t>(A) * n;
      bool same = true;
      for (int B = 0; B < n && same; ++B) {
        const PetscInt k = lo + oa[B];
        same = oa[B] >= 0 && k < hi && ja_[k] == global_[lnode[B]];
        pa[B] = k;
      }
      if (same) continue;
      if (columns_.empty()) {
        columns_.resize(n);
        for (int B = 0; B < n; ++B) {
          const std::pair<PetscInt, int> c{global_[lnode[B]], B};
          int i = B;
          for (; i > 0 && columns_[i - 1] > c; --i) columns_[i] = columns_[i - 1];
          columns_[i] = c;
        }
      }
      PetscInt k = lo, found = -1, previous = -1;
      for (const auto& [g, B] : columns_) {
        if (g != previous) {  // (a node twice in the element: a periodic direction shorter than it)
          if (k == hi || ja_[k] != g) k = std::lower_bound(ja_ + k, ja_ + hi, g) - ja_;
          if (k == hi || ja_[k] != g) return false;
          found = k++;
          previous = g;
        }
        pa[B] = found;
        oa[B] = found - lo;
      }
    }
    return true;
  }

  template <int BS>
  void add_node_blocks(int n, const double* Kb) {
    const int bs2 = BS > 0 ? BS * BS : bs_ * bs_;
    // Two doubles at a time (the compiler kept this scalar).
    typedef double Pair __attribute__((vector_size(16), aligned(8), may_alias));
    for (std::size_t k = 0; k < static_cast<std::size_t>(n) * n; ++k) {
      double* blk = a_ + pos_[k] * bs2;
      const double* kb = Kb + k * bs2;
      int i = 0;
      for (; i + 2 <= bs2; i += 2)
        *reinterpret_cast<Pair*>(blk + i) += *reinterpret_cast<const Pair*>(kb + i);
      if (i < bs2) blk[i] += kb[i];
    }
  }

  // SeqBAIJ blocks are column-major: entry (c, e) of block k is a_[k bs^2 + e bs + c].
  template <int BS>
  void add_blocks(int n, const double* K) {
    const int bs = BS > 0 ? BS : bs_, bs2 = bs * bs;
    const std::size_t ld = static_cast<std::size_t>(n) * bs;
    for (int A = 0; A < n; ++A)
      for (int B = 0; B < n; ++B) {
        double* blk = a_ + pos_[static_cast<std::size_t>(A) * n + B] * bs2;
        const double* k = K + static_cast<std::size_t>(A) * bs * ld + static_cast<std::size_t>(B) * bs;
        for (int e = 0; e < bs; ++e)
          for (int c = 0; c < bs; ++c) blk[e * bs + c] += k[c * ld + e];
      }
  }
};

}  // namespace cellfsi::fluid
