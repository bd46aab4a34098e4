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
// splits it into one dense system per wave number m, of size sum_c n_y(c) (all y unknowns of all components,
// the zero pressure block included), A_m = sum_s S_s e^{2 pi i m s / n}.
//
// Wave number 0 of a box without outflow has the constant pressure as null vector: with pin_pressure its
// first pressure unknown is pinned, so solve() returns one solution of the consistent part, with its own
// pressure constant (the fluid shifts its pressure to zero mean after each step).
//
// Ranks: the wave numbers are dealt out to the ranks (m mod size); every rank reads the whole operator (a
// sequential copy, MatCreateSubMatrices) and holds b and x whole (the fluid's state is replicated,
// dc_fluid.hpp); a solve ends in one MPI_Allreduce of the partial inverse transforms.
//
// Limits (next steps, fluid/div_conforming/README.md): the transform is a plain DFT, O(n_x^2) per line, not
// an FFT; the per-mode systems are dense LU, not banded; the operator is copied whole to every rank; 2D only
// (3D: transforms in x and z, lines in y).
#include <petscmat.h>

#include <Eigen/Dense>
#include <complex>
#include <vector>

#include "fluid/div_conforming/dc_space.hpp"

namespace cellfsi::fluid::dc {

class DcFourierSolver {
 public:
  /// Throws std::invalid_argument unless the space is 2D and periodic in x. comm: the matrix's; petsc_index:
  /// the matrix's numbering of each natural unknown (DivConformingFluid::petsc_numbering(); empty: natural).
  explicit DcFourierSolver(const DivConformingSpace& space, MPI_Comm comm = PETSC_COMM_SELF,
                           std::vector<PetscInt> petsc_index = {});

  /// Reads the stencil from the rows at x index 0 of A (the operator must not carry a pressure pin, which is
  /// not translation-invariant) and factorises this rank's wave numbers. deviation(): the largest difference
  /// between A and the circulant matrix of that stencil, relative to the largest entry of its row.
  /// Collective.
  void build(Mat A, bool pin_pressure);
  /// x = A^{-1} b (natural numbering, size n_dofs, the same b on every rank; x on every rank). Collective.
  void solve(const std::vector<double>& b, std::vector<double>& x) const;
  double deviation() const { return deviation_; }

 private:
  using Complex = std::complex<double>;
  const DivConformingSpace& space_;
  MPI_Comm comm_;
  std::vector<PetscInt> petsc_index_, natural_index_;  // natural <-> the matrix's numbering (empty: the same)
  int nx_ = 0, n_line_ = 0;
  std::vector<int> modes_;        // this rank's wave numbers
  std::vector<int> line_offset_;  // per component: its first line index (c, j) -> line_offset_[c] + j
  std::vector<Eigen::PartialPivLU<Eigen::MatrixXcd>> lu_;  // per wave number of modes_: the LU of A_m
  double deviation_ = 0;
  bool pinned_ = false, built_ = false;
};

}  // namespace cellfsi::fluid::dc
