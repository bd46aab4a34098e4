#pragma once
// The exact inverse of a translation-invariant operator on a box mesh that is periodic in all directions but
// at most one: the bulk solver of fluid/region_corrected_solver.hpp.
//
// Why: away from the cells the fluid Jacobian of the paper's boxes (shear, channels; uniform periodic knot
// vectors in x (and z), walls in y) is the same stencil at every periodic position, because at Re ~ 1e-4 it
// depends on the flow only through terms 1e-4 smaller than the viscous ones, and the undisturbed flows
// depend on y only. A discrete Fourier transform in the periodic directions splits such an operator into one
// small banded system per wave vector across the non-periodic direction (size n_y x dof, bandwidth
// (degree + 1) dof - 1): setup is a banded LU per pair of wave vectors +-k (the operator is real), a solve is
// two FFTs and the banded solves, O(N log N) with memory O(N dof (degree + 1) dof) instead of the
// O(N^{4/3})-O(N^{5/3}) of a sparse LU in 3D.
//
// build(A): the stencil is the average of A's rows over the periodic positions (A need not be exactly
// invariant: e.g. a state whose flow varies a little along x); `deviation()` reports the largest entry of A
// minus that average, relative to the largest entry of its row. Wave vector 0 of a box with a constant
// pressure null space (every wall direction no-slip, no outflow) is singular: its first pressure unknown is
// pinned, so the solver returns one solution of the consistent part, with an arbitrary pressure constant (the
// fluid shifts its pressure to one gauge after each step).
//
// One rank; the matrix in the DMDA's natural ordering (node-major, direction 0 fastest, dof-minor), which
// is its global ordering on one rank.
#include <petscmat.h>

#include <array>
#include <complex>
#include <vector>

namespace cellfsi::fluid {

class FourierBulkSolver {
 public:
  /// n: control points per direction (1 for unused ones); periodic: per direction; dof: unknowns per node;
  /// degree: stencil half-width per direction (the spline degree). At most one direction may be non-periodic
  /// (with n > 1). Throws std::invalid_argument otherwise.
  FourierBulkSolver(std::array<int, 3> n, std::array<bool, 3> periodic, std::array<int, 3> degree, int dof);

  /// Averages A over the periodic positions and factorises every wave vector's banded system. pin_pressure:
  /// the wave-0 system is singular in the last dof (the constant pressure) and gets its first such unknown
  /// pinned.
  void build(Mat A, bool pin_pressure);
  /// x = A_avg^{-1} r (r, x: sequential vectors of the matrix's size).
  void solve(Vec r, Vec x) const;

  /// Largest |A_ij - A_avg,ij| / max_j |A_ij| over the rows of the last build() (unit rows, i.e. walls and a
  /// pinned pressure, skipped).
  double deviation() const { return deviation_; }
  /// Per node: the largest |J_ij - A_avg,ij| / max_j |A_avg,ij| of its rows (J: same size, natural
  /// ordering; entries outside the stencil count in full).
  std::vector<double> node_deviation(Mat J) const;
  /// Whether build() has completed (a failed build leaves it false).
  bool built() const { return built_; }
  /// Bytes held by the factors.
  std::size_t factor_bytes() const { return ab_.size() * sizeof(std::complex<double>); }
  int n_modes() const { return n_modes_; }

 private:
  using cplx = std::complex<double>;
  /// Index of a stencil entry: row (j, c), column (j + dj, c2), periodic offsets o[.] in [-degree, degree].
  long stencil_index(int j, int c, const std::array<int, 3>& o, int dj, int c2) const;
  /// Node's coordinates and the stencil offset between two nodes (wrapped in the periodic directions);
  /// false if the column lies outside the stencil.
  bool offset(int row_node, int col_node, std::array<int, 3>& o, int& j, int& dj) const;
  void fft(std::vector<cplx>& z, bool inverse) const;
  int mirror(int mode) const;             // the mode of wave vector -k
  int across_coordinate(int node) const;  // the node's index across (0 without a wall direction)

  std::array<int, 3> n_{}, degree_{};
  std::array<bool, 3> periodic_{};
  int dof_ = 1, across_ = -1;                                      // the non-periodic direction (-1: none)
  int n_across_ = 1, n_nodes_ = 1, n_modes_ = 1, m_ = 1, kl_ = 0;  // banded systems: size m, kl = ku
  std::array<int, 3> width_{};                                     // stencil extent per periodic direction
  std::vector<double> stencil_;                                    // averaged stencil
  std::vector<int> slot_;  // per mode: its factors' index, or -1 (its mirror's conjugate)
  std::vector<cplx> ab_;   // LAPACK band storage, per slot
  std::vector<int> ipiv_;
  double deviation_ = 0;
  bool pinned_ = false, built_ = false;
};

}  // namespace cellfsi::fluid
