#pragma once
// The exact inverse of a translation-invariant operator on the divergence-conforming space of a 2D box that
// is periodic in x (walls or periodic in y): the first step of generalising solvers/fourier_bulk.hpp to this
// space (issue 44).
//
// Why it works: in a periodic direction every component's knot vector is uniform and periodic with one
// function per element, so shifting all x indices by one maps the space onto itself for the velocity
// components and the pressure alike (their degrees along x differ, k + 1 for v_x and k for v_y and p, which
// only widens the stencil to half-width k + 1). An operator assembled from data uniform in x (the bulk flow
// of the paper's channels) is then a block-circulant matrix: A[(c,i,j),(c',i',j')] = S_{i'-i mod
// n}[(c,j),(c',j')], with c the component, i the x index, j the y index. A discrete Fourier transform in x
// splits it into one system per wave number m over the "line" of all y unknowns of all components (size
// sum_c n_y(c), the zero pressure block included), A_m = sum_s S_s e^{2 pi i m s / n}. The operator is real,
// so A_{n-m} = conj(A_m): only m = 0 .. n/2 are factorised, and the transforms are real-to-half-complex FFTs
// (FFTW's, planned once) of each line's n_x values, which are contiguous in the natural numbering.
//
// Banded systems: the line's unknowns are ordered by y index, the components of one y index together
// (interleaved), so that A_m is banded: every y function couples only to those whose supports overlap (within
// k + 1 y indices on either side). In y periodic the order is folded (j = 0, n-1, 1, n-2, ...) so that the
// wrap-around coupling is banded too, at twice the width. The half-bandwidths are read from the stencil's
// nonzeros, and each A_m is factorised by LAPACK's banded LU with partial pivoting (zgbtrf; the pivots are
// those of a dense partial-pivoting LU, since below the band the columns are zero anyway).
//
// Wave number 0 of a box without outflow has the constant pressure as null vector: with pin_pressure its
// first pressure unknown is pinned, so solve() returns one solution of the consistent part, with its own
// pressure constant (the fluid shifts its pressure to zero mean after each step). A singular A_m (zgbtrf's
// info > 0, e.g. wave 0 without the pin) throws std::runtime_error naming the wave number.
//
// Ranks: the wave numbers 0 .. n/2 are dealt out to the ranks (m mod size); every rank reads the stencil rows
// (those at x index 0, MatCreateSubMatrices) and checks deviation() on its own rows; b and x are whole on
// every rank (the fluid's state is replicated, dc_fluid.hpp); a solve transforms every line on every rank,
// solves its own wave numbers and ends in one MPI_Allreduce of the half spectra before the inverse FFTs.
//
// Cost: per solve 2 n_line real FFTs of length n_x and n_x/2 + 1 banded substitutions of size n_line
// (O(n log n_x) in all); build O(nonzeros) plus the banded LUs. Measured (bench/dc_fourier_solve: the
// Navier-Stokes step tangent at a Couette state, k = 2, one rank, shared 2-core machine): 64 x 32 elements
// (6.6 k unknowns) 0.22 ms per solve and 0.014 s to build; 256 x 128 (100 k unknowns) 2.7 ms per solve (4.1-4.2
// with Eigen's kissfft and LAPACK's zgbtrs; the substitutions, written out, are now four fifths of it) and 0.3 s
// to build; equal to MUMPS to 2.5e-13 of max|x| (fluid/div_conforming/README.md).
//
// Limits (next steps, README): 2D only (3D: transforms in x and z, lines in y); b and x whole on every rank,
// and every rank transforms all lines (only the banded solves are divided among the ranks).
#include <petscmat.h>

#include <complex>
#include <memory>
#include <vector>

#include "fluid/div_conforming/dc_space.hpp"

namespace cellfsi::fluid::dc {

class DcFourierSolver {
 public:
  /// Throws std::invalid_argument unless the space is 2D and periodic in x. comm: the matrix's; petsc_index:
  /// the matrix's numbering of each natural unknown (DivConformingFluid::petsc_numbering(); empty: natural).
  explicit DcFourierSolver(const DivConformingSpace& space, MPI_Comm comm = PETSC_COMM_SELF,
                           std::vector<PetscInt> petsc_index = {});
  ~DcFourierSolver();
  DcFourierSolver(const DcFourierSolver&) = delete;
  DcFourierSolver& operator=(const DcFourierSolver&) = delete;

  /// Reads the stencil from the rows at x index 0 of A (the operator must not carry a pressure pin, which is
  /// not translation-invariant) and factorises this rank's wave numbers. deviation(): the largest difference
  /// between A and the circulant matrix of that stencil, relative to the largest entry of its row.
  /// Collective. Throws std::runtime_error if a wave number's system is singular.
  void build(Mat A, bool pin_pressure);
  /// x = A^{-1} b (natural numbering, size n_dofs, the same b on every rank; x on every rank). Collective.
  void solve(const std::vector<double>& b, std::vector<double>& x) const;
  /// y = S x, S the circulant matrix of the stencil build() read (A itself to deviation(); without the pin
  /// build() adds to its own factors). Natural numbering, size n_dofs, every entry on every rank; local (no
  /// communication). How: x's lines copied with a periodic halo, then per (row line, column line) pair one
  /// loop over the line's n_x values, each a short fixed-width dot product with the pair's x offsets: at
  /// 256 x 128, k' = 2, about 7 M multiply-adds from cache, where the assembled matrix's product reads 7 M
  /// entries and their column indices from memory. Not thread-safe (a work buffer).
  void multiply(const std::vector<double>& x, std::vector<double>& y) const;
  double deviation() const { return deviation_; }

 private:
  using Complex = std::complex<double>;
  /// One entry of the stencil: row and column lines (component-major line indices, line_offset_[c] + j),
  /// x shift s = i' - i mod n_x, value.
  struct StencilEntry {
    int row, col, shift;
    double value;
  };
  const DivConformingSpace& space_;
  MPI_Comm comm_;
  std::vector<PetscInt> petsc_index_, natural_index_;  // natural <-> the matrix's numbering (empty: the same)
  int nx_ = 0, n_half_ = 0, n_line_ = 0;               // n_half_ = n_x / 2 + 1 wave numbers 0 .. n_x / 2
  std::vector<int> modes_;                             // this rank's wave numbers (of 0 .. n_x / 2)
  std::vector<int> line_offset_;  // per component: its first line index (c, j) -> line_offset_[c] + j
  std::vector<int> line_component_, line_y_;  // per line index: c and j
  std::vector<int> position_;                 // per line index: its row in the banded systems
  int kl_ = 0, ku_ = 0, ldab_ = 1;  // half-bandwidths below and above, leading dimension 2 kl + ku + 1
  std::vector<Complex> ab_;         // per wave number of modes_: the banded LU of A_m (zgbtrf)
  /// solve()'s steps: the forward transform of b's lines, f on each of this rank's wave numbers (k: its slot
  /// in modes_, the wave number's values by banded position, in place), the ranks' spectra summed, the
  /// inverse transform.
  template <class PerMode>
  void transform(const std::vector<double>& b, std::vector<double>& x, PerMode&& f) const;
  std::vector<PetscBLASInt> ipiv_;  // and its pivots
  std::vector<Complex> inverse_diagonal_;  // 1 / U's diagonal, per wave number and position
  /// zgbtrs('N') of one right-hand side in place, with the factors of one wave number (see solve()).
  void banded_substitution(const Complex* ab, const PetscBLASInt* ipiv, const Complex* inv_diag,
                           Complex* rhs) const;
  /// The stencil regrouped for multiply(): per (row line, column line) pair, the values at the signed x
  /// offsets -halo_ .. halo_ (zeros where the stencil has none), 2 halo_ + 1 per pair, the pairs by row line.
  int halo_ = 0;
  std::vector<int> pair_row_, pair_col_;
  std::vector<double> pair_taps_;
  mutable std::vector<double> padded_;  // multiply()'s lines of x with halo_ periodic values at both ends
  double deviation_ = 0;
  bool pinned_ = false, built_ = false;
  struct Plans;                   // FFTW's plans of one line's transforms (dc_fourier.cpp)
  std::unique_ptr<Plans> plans_;  // made by build()
};

}  // namespace cellfsi::fluid::dc
