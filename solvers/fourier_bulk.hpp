#pragma once
// The exact inverse of a translation-invariant operator on a box mesh that is periodic in all directions but
// at most one: the bulk solver of solvers/region_corrected.hpp.
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
// Ranks: the solver runs on the matrix's communicator. The DMDA's natural ordering (node-major, direction 0
// fastest, dof-minor) defines the nodes; `natural` (the DMDA's AO, DMDAGetAO) maps it to the matrix's and the
// vectors' global ordering (none: the two are the same, as on one rank). A solve moves the data twice between
// two layouts: "lines", where a rank holds a slab of layers across (all periodic positions of its layers j,
// so the FFTs are local), and "modes", where a rank holds every layer of its share of the wave vectors (so
// the banded solves are local); each move is one MPI_Alltoallv of N / ranks values per rank. The set-up
// factorises only a rank's own wave vectors. Measured on the capsule at 256 x 128 cubic
// (docs/performance.md).
#include <petscao.h>
#include <petscmat.h>

#include <array>
#include <complex>
#include <vector>

namespace cellfsi::solvers {

class FourierBulkSolver {
 public:
  /// n: control points per direction (1 for unused ones); periodic: per direction; dof: unknowns per node;
  /// degree: stencil half-width per direction (the spline degree). At most one direction may be non-periodic
  /// (with n > 1). Throws std::invalid_argument otherwise.
  /// comm: the matrix's communicator; natural: the DMDA's AO (natural to global ordering; null: the same).
  FourierBulkSolver(std::array<int, 3> n, std::array<bool, 3> periodic, std::array<int, 3> degree, int dof,
                    MPI_Comm comm = PETSC_COMM_SELF, AO natural = nullptr);
  ~FourierBulkSolver();
  FourierBulkSolver(const FourierBulkSolver&) = delete;
  FourierBulkSolver& operator=(const FourierBulkSolver&) = delete;

  /// Averages A over the periodic positions and factorises every wave vector's banded system. pin_pressure:
  /// the wave-0 system is singular in the last dof (the constant pressure) and gets its first such unknown
  /// pinned. Collective.
  void build(Mat A, bool pin_pressure);
  /// x = A_avg^{-1} r (r, x: vectors of the matrix's layout). Collective.
  void solve(Vec r, Vec x) const;
  /// y = A_avg x, the averaged stencil applied without a matrix (x, y: vectors of the matrix's layout): each
  /// rank applies it on its slab of layers, with the degree's layers across on either side brought in.
  /// Collective.
  void multiply(Vec x, Vec y) const;

  /// Largest |A_ij - A_avg,ij| / max_j |A_ij| over the rows of the last build(). Rows of a (layer, component)
  /// class of which any row is a unit row (walls, a pinned pressure) are skipped, the whole class: its
  /// average mixes unit and assembled rows.
  double deviation() const { return deviation_; }
  /// Per node: the largest |J_ij - A_avg,ij| / max_j |A_avg,ij| of its rows (J: the matrix build() took, in
  /// its PETSc global ordering; entries outside the stencil count in full), by natural node index, on every
  /// rank. Only after build(). Collective.
  std::vector<double> node_deviation(Mat J) const;
  /// A node's index in the global (PETSc) ordering, and back.
  int global_node(int natural_node) const {
    return to_global_.empty() ? natural_node : to_global_[natural_node];
  }
  int natural_node(int global_node) const {
    return to_natural_.empty() ? global_node : to_natural_[global_node];
  }
  int n_nodes() const { return n_nodes_; }
  /// The box: control points, periodicity and stencil half-width per direction, unknowns per node, the
  /// communicator.
  const std::array<int, 3>& shape() const { return n_; }
  const std::array<bool, 3>& periodic() const { return periodic_; }
  const std::array<int, 3>& degree() const { return degree_; }
  int dof() const { return dof_; }
  MPI_Comm comm() const { return comm_; }
  /// Whether build() has completed (a failed build leaves it false).
  bool built() const { return built_; }
  /// Bytes held by this rank's factors.
  std::size_t factor_bytes() const { return ab_.size() * sizeof(std::complex<double>); }
  int n_modes() const { return n_modes_; }

 private:
  using cplx = std::complex<double>;
  /// Index of a stencil entry: row (j, c), column (j + dj, c2), periodic offsets o[.] in [-degree, degree].
  long stencil_index(int j, int c, const std::array<int, 3>& o, int dj, int c2) const;
  /// Node's coordinates and the stencil offset between two nodes (wrapped in the periodic directions);
  /// false if the column lies outside the stencil.
  bool offset(int row_node, int col_node, std::array<int, 3>& o, int& j, int& dj) const;
  /// FFTs along the periodic directions of a box of nl[d] nodes (the local slab).
  void fft(std::vector<cplx>& z, bool inverse, const std::array<int, 3>& nl) const;
  /// Index in the local slab of the node with the periodic coordinates of `mode` and local layer jl.
  std::size_t slab_node(int mode, int jl) const;
  int first_layer(int rank) const { return static_cast<int>(static_cast<long>(rank) * n_across_ / size_); }
  int first_slot(int rank) const { return static_cast<int>(static_cast<long>(rank) * n_slots_ / size_); }
  int mirror(int mode) const;             // the mode of wave vector -k
  /// A scatter of a global vector like r to the nodes of layers [first, last) across, and its values.
  void make_layer_scatter(Vec r, int first, int last, VecScatter* scatter, Vec* values) const;
  /// The stencil regrouped for multiply(): per layer across, its nonzero (offset, dof x dof block) pairs.
  struct StencilTerm {
    std::array<int, 3> shift{};  // the column node's offset per direction (periodic: wrapped later)
    std::array<double, 64> block{};  // row-major dof x dof (dof <= 8)
  };
  int across_coordinate(int node) const;  // the node's index across (0 without a wall direction)

  std::array<int, 3> n_{}, degree_{};
  std::array<bool, 3> periodic_{};
  int dof_ = 1, across_ = -1;                                      // the non-periodic direction (-1: none)
  int n_across_ = 1, n_nodes_ = 1, n_modes_ = 1, m_ = 1, kl_ = 0;  // banded systems: size m, kl = ku
  std::array<int, 3> width_{};                                     // stencil extent per periodic direction
  std::vector<double> stencil_;                                    // averaged stencil
  std::vector<int> slot_;  // per mode: its slot (an index among the factorised modes), or -1 (its mirror)
  std::vector<int> slot_mode_;  // per slot: its mode
  int n_slots_ = 0;
  std::vector<cplx> ab_;  // LAPACK band storage, per slot of this rank
  std::vector<PetscBLASInt> ipiv_;  // LAPACK's pivots, per slot of this rank
  // Ranks.
  MPI_Comm comm_ = PETSC_COMM_SELF;
  int rank_ = 0, size_ = 1;
  std::vector<int> to_global_, to_natural_;  // node maps (empty: the identity)
  std::array<int, 3> slab_{};                // this rank's slab: n_ with its own layers across
  int j0_ = 0, j1_ = 0;                      // its layers
  std::vector<int> send_counts_, send_offsets_, recv_counts_, recv_offsets_;  // lines -> modes, in doubles
  mutable VecScatter to_slab_ = nullptr;                                      // global vector -> slab
  mutable Vec slab_vec_ = nullptr;
  mutable VecScatter to_ghosted_ = nullptr;  // global vector -> slab with `degree` layers either side
  mutable Vec ghosted_vec_ = nullptr;
  std::vector<std::vector<StencilTerm>> terms_;  // per layer across (multiply)
  double deviation_ = 0;
  bool pinned_ = false, built_ = false;
};

}  // namespace cellfsi::solvers
