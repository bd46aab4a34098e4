#pragma once
// The exact inverse of a translation-invariant operator on the divergence-conforming space of a box periodic
// in x (2D), or in x and z (3D), with walls or periodic in y: solvers/fourier_bulk.hpp generalised to this
// space (issues 44 and 45).
//
// Why it works: in a periodic direction every component's knot vector is uniform and periodic with one
// function per element, so shifting all x (or z) indices by one maps the space onto itself for the velocity
// components and the pressure alike (their degrees along x differ, k + 1 for v_x and k for the others, which
// only widens the stencil to half-width k + 1). An operator assembled from data uniform in x and z (the bulk
// flow of the paper's shear boxes and channels) is then block-circulant: A[(c,i,j,l),(c',i',j',l')] =
// S_{i'-i mod n_x, l'-l mod n_z}[(c,j),(c',j')], with c the component, i, j, l the x, y, z indices. A
// discrete Fourier transform in x and z splits it into one system per wave vector (m, q) over the "line" of
// all y unknowns of all components (size sum_c n_y(c), the zero pressure block included), A_mq = sum_s S_s
// e^{2 pi i (m s_x / n_x + q s_z / n_z)}. The operator is real, so A_{-m,-q} = conj(A_mq): only m = 0 ..
// n_x/2 are factorised (every q), and the transforms are real-to-half-complex FFTs (FFTW's, planned once per
// component) of each line's n_z x n_x values (a plane of the natural numbering in 3D, a contiguous run in
// 2D).
//
// Banded systems: the line's unknowns are ordered by y index, the components of one y index together
// (interleaved), so that A_mq is banded: every y function couples only to those whose supports overlap
// (within k + 1 y indices on either side). In y periodic the order is folded (j = 0, n-1, 1, n-2, ...) so
// that the wrap-around coupling is banded too, at twice the width. The half-bandwidths are read from the
// stencil's nonzeros, and each A_mq is factorised by LAPACK's banded LU with partial pivoting (zgbtrf; the
// pivots are those of a dense partial-pivoting LU, since below the band the columns are zero anyway).
//
// Wave vector 0 of a box without outflow has the constant pressure as null vector: with pin_pressure its
// first pressure unknown is pinned, so solve() returns one solution of the consistent part, with its own
// pressure constant (the fluid shifts its pressure to zero mean after each step). A singular A_mq (zgbtrf's
// info > 0, e.g. wave 0 without the pin) throws std::runtime_error naming the wave vector.
//
// Ranks: the wave vectors are dealt out to the ranks (index mod size); every rank reads the stencil rows
// (those at x and z index 0, MatCreateSubMatrices) and checks deviation() on its own rows (those A holds); b
// and x are whole on every rank (the fluid's state is replicated, dc_fluid.hpp); a solve transforms each
// rank's run of lines on that rank, sends each wave vector's values to the rank that solves it and back (two
// MPI_Alltoallv), inverts its lines and gathers every rank's into x (MPI_Allgatherv).
//
// Cost: per solve 2 n_line real FFTs of n_x n_z values (2 n_line / size on each rank) and n_z (n_x/2 + 1)
// banded substitutions of size n_line (dealt out likewise) (O(n log(n_x n_z)) in all); build O(nonzeros) plus
// the banded LUs. Measured (bench/dc_fourier_solve: the Navier-Stokes step tangent at a Couette state, k = 2,
// one rank, shared 2-core machine): 64 x 32 elements (6.6 k unknowns) 0.22 ms per solve and 0.014 s to build;
// 256 x 128 (100 k unknowns) 2.7 ms per solve (4.1-4.2 with Eigen's kissfft and LAPACK's zgbtrs; the
// substitutions, written out, are now four fifths of it) and 0.3 s to build; equal to MUMPS to 2.5e-13 of
// max|x| (fluid/div_conforming/README.md).
//
// Limits (next steps, README): b and x whole on every rank (a rank reads only its lines of b, and needs only
// its rows of x).
#include <petscmat.h>

#include <array>
#include <complex>
#include <memory>
#include <vector>

#include "fluid/div_conforming/dc_space.hpp"

namespace cellfsi::fluid::dc {

class DcFourierSolver {
 public:
  /// Throws std::invalid_argument unless the space is periodic in x and, in 3D, in z. comm: the matrix's;
  /// petsc_index: the matrix's numbering of each natural unknown (DivConformingFluid::petsc_numbering();
  /// empty: natural).
  explicit DcFourierSolver(const DivConformingSpace& space, MPI_Comm comm = PETSC_COMM_SELF,
                           std::vector<PetscInt> petsc_index = {});
  ~DcFourierSolver();
  DcFourierSolver(const DcFourierSolver&) = delete;
  DcFourierSolver& operator=(const DcFourierSolver&) = delete;

  /// Reads the stencil from the rows at x (and z) index 0 of A (the operator must not carry a pressure pin,
  /// which is not translation-invariant) and factorises this rank's wave numbers. deviation(): the largest
  /// difference between A and the circulant matrix of that stencil, relative to the largest entry of its row,
  /// over the rows A holds (a row without entries is skipped: A may hold only the stencil's rows and a few
  /// others to check, DivConformingFluid::bulk_stencil_tangent).
  /// Collective. Throws std::runtime_error if a wave number's system is singular.
  void build(Mat A, bool pin_pressure);
  /// x = A^{-1} b (natural numbering, size n_dofs, the same b on every rank; x on every rank). Collective.
  /// Not thread-safe (a work buffer).
  void solve(const std::vector<double>& b, std::vector<double>& x) const;
  /// The same with b and x PETSc vectors in the matrix's numbering (the layout of the first b given): each
  /// rank reads only its lines' entries of b and writes only theirs of x (one VecScatter each way), where the
  /// vector solve() needs b whole on every rank and gathers every line into x on every rank, which does not
  /// divide by the ranks. Collective.
  void solve(Vec b, Vec x) const;
  /// y = S x, S the circulant matrix of the stencil build() read (A itself to deviation(); without the pin
  /// build() adds to its own factors). Natural numbering, size n_dofs, every entry on every rank; local (no
  /// communication). How: x's lines copied with a periodic halo, then per (row line, column line) pair and z
  /// offset one loop over each run of n_x values, each a short fixed-width dot product with the pair's x
  /// offsets: at 256 x 128, k' = 2, about 7 M multiply-adds from cache, where the assembled matrix's product
  /// reads 7 M entries and their column indices from memory. owned_only: only the runs of n_x rows that hold
  /// a row of this rank's (the build matrix's ownership range); the other entries of y are 0. Not thread-safe
  /// (a work buffer).
  void multiply(const std::vector<double>& x, std::vector<double>& y, bool owned_only = false) const;
  double deviation() const { return deviation_; }

 private:
  using Complex = std::complex<double>;
  /// One entry of the stencil: row and column lines (component-major line indices, line_offset_[c] + j),
  /// x shift i' - i mod n_x, z shift l' - l mod n_z (0 in 2D), value.
  struct StencilEntry {
    int row, col, shift, shift_z;
    double value;
  };
  const DivConformingSpace& space_;
  MPI_Comm comm_;
  std::vector<PetscInt> petsc_index_, natural_index_;  // natural <-> the matrix's numbering (empty: the same)
  // n_half_ = n_x / 2 + 1 x wave numbers 0 .. n_x / 2; n_z 1 in 2D; wave vector index mz n_half_ + mx
  int nx_ = 0, nz_ = 1, n_half_ = 0, n_modes_ = 0, n_line_ = 0;
  std::vector<int> modes_;        // this rank's wave vectors (of 0 .. n_modes_ - 1)
  std::vector<int> line_offset_;  // per component: its first line index (c, j) -> line_offset_[c] + j
  std::vector<int> line_component_, line_y_;  // per line index: c and j
  std::vector<int> line_first_,
      plane_stride_;                // per line: its (i, l) = (0, 0) unknown; per component: l's stride
  std::vector<int> position_;       // per line index: its row in the banded systems
  int kl_ = 0, ku_ = 0, ldab_ = 1;  // half-bandwidths below and above, leading dimension 2 kl + ku + 1
  std::vector<Complex> ab_;         // per wave number of modes_: the banded LU of A_m (zgbtrf)
  /// solve()'s steps: the forward transform of this rank's lines of b, their values sent to the wave numbers'
  /// ranks, f on each of this rank's wave numbers (k: its slot in modes_, the wave number's values by banded
  /// position, in place), the values sent back, the inverse transform of this rank's lines, every rank's
  /// lines gathered into x.
  /// whole: every rank's lines gathered into x on every rank (else x holds this rank's lines only).
  template <class PerMode>
  void transform(const std::vector<double>& b, std::vector<double>& x, PerMode&& f, bool whole = true) const;
  void solve_lines(const std::vector<double>& b, std::vector<double>& x, bool whole) const;
  /// solve(Vec, Vec)'s move of this rank's lines between the PETSc vectors and the natural-numbered buffers
  /// (made at its first call): lines_values_ holds them line by line, z-major.
  mutable VecScatter lines_scatter_ = nullptr;
  mutable Vec lines_values_ = nullptr;
  mutable std::vector<double> lines_b_, lines_x_;
  /// Calls visit(k, natural) for this rank's lines' unknowns, k their place in lines_values_.
  template <class Visit>
  void for_each_line_unknown(Visit&& visit) const;
  std::vector<PetscBLASInt> ipiv_;         // and its pivots
  std::vector<Complex> inverse_diagonal_;  // 1 / U's diagonal, per wave number and position
  /// zgbtrs('N') of one right-hand side in place, with the factors of one wave number (see solve()).
  void banded_substitution(const Complex* ab, const PetscBLASInt* ipiv, const Complex* inv_diag,
                           Complex* rhs) const;
  /// The stencil regrouped for multiply(): per (row line, column line) pair, the values at the signed z and
  /// x offsets -halo_z_ .. halo_z_, -halo_ .. halo_ (zeros where the stencil has none), (2 halo_z_ + 1)
  /// (2 halo_ + 1) per pair (z-major), the pairs by row line.
  int halo_ = 0, halo_z_ = 0;
  std::vector<int> pair_row_, pair_col_;
  std::vector<double> pair_taps_;
  mutable std::vector<double> padded_;  // multiply()'s lines of x with halo_ periodic values at both ends
  mutable std::vector<Complex> spectrum_;  // transform()'s half spectra
  // transform()'s exchanges (kept between solves): counts and displacements, the wave vectors' values both
  // ways, the lines gathered into x.
  mutable std::array<std::vector<int>, 4> exchange_counts_;
  mutable std::vector<Complex> exchange_send_, exchange_recv_;
  mutable std::vector<double> exchange_lines_;
  mutable std::vector<std::size_t> exchange_base_;
  /// The first of rank r's lines (equal runs of the line indices; r = size: n_line_).
  int line_begin(int r) const { return static_cast<int>(static_cast<long long>(r) * n_line_ / comm_size_); }
  int comm_size_ = 1;
  std::vector<char> owned_runs_;        // per (line, l): whether it holds a row of this rank's (build())
  double deviation_ = 0;
  bool pinned_ = false, built_ = false;
  struct Plans;                                // FFTW's plans of one line's transforms (dc_fourier.cpp)
  std::vector<std::unique_ptr<Plans>> plans_;  // per component (its plane stride), made by build()
};

}  // namespace cellfsi::fluid::dc
