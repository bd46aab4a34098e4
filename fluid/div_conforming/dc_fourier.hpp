#pragma once
// The exact inverse of a translation-invariant operator on the divergence-conforming space of a 2D box that
// is periodic in x (walls or periodic in y): the first step of generalising solvers/fourier_bulk.hpp to this
// space (issue 44).
//
// Why it works: in a periodic direction every component's knot vector is uniform and periodic with one
// function per element, so shifting all x indices by one maps the space onto itself for the velocity
// components and the pressure alike (their degrees along x differ, k + 1 for v_x and k for v_y and p, which
// only widens the stencil to half-width k + 1). An operator assembled from data uniform in x (the bulk flow of
// the paper's channels) is then a block-circulant matrix: A[(c,i,j),(c',i',j')] = S_{i'-i mod n}[(c,j),(c',j')],
// with c the component, i the x index, j the y index. A discrete Fourier transform in x splits it into one dense
// system per wave number m, of size sum_c n_y(c) (all y unknowns of all components, the zero pressure block
// included), A_m = sum_s S_s e^{2 pi i m s / n}.
//
// Wave number 0 of a box without outflow has the constant pressure as null vector: with pin_pressure its first
// pressure unknown is pinned, so solve() returns one solution of the consistent part, with its own pressure
// constant (the fluid shifts its pressure to zero mean after each step).
//
// Limits (next steps, fluid/div_conforming/README.md): one rank (the matrix in the natural numbering of
// dc_space.hpp); the transform is a plain DFT, O(n_x^2) per line, not an FFT; the per-mode systems are dense LU,
// not banded; 2D only (3D: transforms in x and z, lines in y).
#include <petscmat.h>

#include <Eigen/Dense>
#include <complex>
#include <vector>

#include "fluid/div_conforming/dc_space.hpp"

namespace cellfsi::fluid::dc {

class DcFourierSolver {
 public:
  /// Throws std::invalid_argument unless the space is 2D and periodic in x.
  explicit DcFourierSolver(const DivConformingSpace& space);

  /// Reads the stencil from the rows at x index 0 of A (sequential, natural numbering; the operator must not
  /// carry a pressure pin, which is not translation-invariant) and factorises every wave number's system.
  /// deviation(): the largest difference between A and the circulant matrix of that stencil, relative to the
  /// largest entry of its row.
  void build(Mat A, bool pin_pressure);
  /// x = A^{-1} b (natural numbering, size n_dofs).
  void solve(const std::vector<double>& b, std::vector<double>& x) const;
  double deviation() const { return deviation_; }

 private:
  using Complex = std::complex<double>;
  const DivConformingSpace& space_;
  int nx_ = 0, n_line_ = 0;
  std::vector<int> line_offset_;  // per component: its first line index (c, j) -> line_offset_[c] + j
  std::vector<Eigen::PartialPivLU<Eigen::MatrixXcd>> lu_;  // per wave number: the LU of A_m
  double deviation_ = 0;
  bool pinned_ = false;
};

}  // namespace cellfsi::fluid::dc
