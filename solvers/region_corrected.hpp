#pragma once
// A preconditioner for a Jacobian J that equals a translation-invariant bulk operator A except in a small
// region (the cells' s^h band and immersed points): the bulk operator's exact inverse by Fourier transform
// (solvers/fourier_bulk.hpp, built once per run), corrected by a sparse LU of J restricted to the region
// where they differ, grown by a few node layers.
//
// Why: the band solver (solvers/band_schur.hpp) keeps a sparse LU of the whole bulk, which in 3D costs
// O(N^{4/3}) memory or more (32^3 quadratic: 14 GB with Debian's MUMPS), and its region's Schur complement is
// dense between the region's border unknowns, which in 3D is a surface. Here the bulk costs O(N log N) and
// O(N) memory, and the region's LU is a sparse matrix of the region's size; the price is a Krylov iteration,
// since the two pieces do not add up to J^{-1}.
//
// One application (multiplicative Schwarz; the region's solve last, so that the s_I rows, which dominate
// there, are satisfied exactly):
//   x = A^{-1} r;   x += R^T J_R^{-1} R (r - J x)
// with R the restriction to the region's unknowns (set_region_solves(2) puts a region solve first too: fewer
// Krylov iterations, each dearer). `set_operator(J)` finds the region (nodes whose rows of J differ from A by
// more than `threshold` of the row's largest entry of A, grown by `overlap` node layers in every direction)
// and factorises J_R (options prefix given at construction + "region_"): in 3D by MUMPS in single precision
// (cellfsi_lu_single, solvers/single_precision_lu.hpp; the FGMRES around this preconditioner makes up the
// precision, with the same iterations: docs/design.md §8; should it fail, in double precision from then
// on), in 2D by MUMPS in double precision.
//
// Measured on the 3D compound capsule at 32^3 quadratic (3 steps, one rank; docs/performance.md): the
// region is the 3700 nodes of the s_I band and the immersed points, 14.7 k unknowns; 6 FGMRES iterations per
// solve; the region's LU 2.5 s. Growing the region by 1 layer: 22 k unknowns, 4 iterations, an LU of 4.7 s;
// by 2 layers with two region solves per application: 31 k unknowns, 3 iterations, 9.3 s: slower overall.
//
// Ranks: as the Fourier solver (the matrix's communicator, the DMDA's AO for the natural node numbering);
// every rank finds the same region, takes the rows it owns, and the region's LU is MUMPS on all ranks.
#include <petscksp.h>

#include <array>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "solvers/fourier_bulk.hpp"

namespace cellfsi::solvers {

/// How the region is found and used (cellfsi_fourier's -pc_fourier_* options, solvers/pc_fourier.hpp): the
/// defaults and the valid ranges, stated once.
struct RegionOptions {
  double threshold = 1e-3;  // relative deviation from the bulk operator that puts a node in the region (> 0)
  int overlap = 0;          // node layers the region is grown by (0 ... kMaxOverlap)
  int region_solves = 1;    // region solves per application: 1 (bulk, region) or 2 (region, bulk, region)
  static constexpr int kMaxOverlap = 20;
};

/// The region's factorisation unless -<prefix>region_pc_type says otherwise: cellfsi_lu_single in 3D (see
/// above), lu in 2D.
const char* default_region_pc_type(bool three_d);

class RegionCorrectedSolver {
 public:
  /// n, periodic, degree, dof: the box mesh (see FourierBulkSolver).
  /// comm, natural: see FourierBulkSolver. The solver makes its own bulk solver (set_bulk builds it).
  RegionCorrectedSolver(std::array<int, 3> n, std::array<bool, 3> periodic, std::array<int, 3> degree,
                        int dof, std::string prefix, MPI_Comm comm = PETSC_COMM_SELF, AO natural = nullptr);
  /// With a bulk solver built by its owner (shared: cellfsi_fourier finds it on its operator).
  RegionCorrectedSolver(std::shared_ptr<FourierBulkSolver> bulk, std::string prefix);
  ~RegionCorrectedSolver();
  RegionCorrectedSolver(const RegionCorrectedSolver&) = delete;
  RegionCorrectedSolver& operator=(const RegionCorrectedSolver&) = delete;

  /// Builds the bulk solver from the bulk operator A (J without the cells).
  void set_bulk(Mat A, bool pin_pressure) { bulk_->build(A, pin_pressure); }
  /// All of the options at once (defaults: RegionOptions).
  void set_options(const RegionOptions& o) {
    set_region(o.threshold, o.overlap);
    set_region_solves(o.region_solves);
  }
  const RegionOptions& options() const { return options_; }
  /// Region thresholds: relative deviation from A and growth in node layers.
  void set_region(double threshold, int overlap) {
    options_.threshold = threshold;
    options_.overlap = overlap;
  }
  /// Region solves per application: 2 (region, bulk, region) or 1 (bulk, region).
  void set_region_solves(int n) {
    if (n != 1 && n != 2) throw std::invalid_argument("RegionCorrectedSolver: 1 or 2 region solves");
    options_.region_solves = n;
  }
  /// Sets J (kept by reference: J's entries must not change until the next call), finds the region and
  /// factorises J on it. Collective.
  void set_operator(Mat J);
  /// x = P^{-1} r (see above). Collective.
  void apply(Vec r, Vec x);

  const FourierBulkSolver& bulk() const { return *bulk_; }
  PetscInt n_region() const { return n_region_; }  // unknowns in the region
  /// Whether the last set_operator factorised the region (a non-empty region, and its PC an LU, a Cholesky or
  /// cellfsi_lu_single rather than one chosen by options that does not factorise).
  bool region_factorized() const;
  /// The region's solver (null before the first set_operator): its view is part of the PC's.
  KSP region_ksp() const { return region_ksp_; }
  /// Nodes whose rows of J differ from the bulk operator by more than the threshold (before the growth).
  int n_differing_nodes() const { return n_differing_; }
  /// Why the region's LU in single precision failed, if it did (it is then in double precision for the rest
  /// of the run); empty otherwise.
  const std::string& single_precision_failure() const { return single_failure_; }

 private:
  void region_solve(Vec r, Vec x);  // x += R^T J_R^{-1} R r
  // The region's KSP with its default factorisation (in 3D in single precision until that fails once), then
  // the options; sets aij_.
  void create_region_ksp(int size);
  // Whether the region's factorisation (as the options chose it) needs J_R as AIJ: a solver without BAIJ
  // (SuperLU_DIST), or MUMPS on one rank with an ordering from PETSc, which it reads from AIJ only.
  bool needs_aij(PC pc, int size) const;
  void release_region();
  std::shared_ptr<FourierBulkSolver> bulk_;
  std::array<int, 3> n_{}, degree_{};
  std::array<bool, 3> periodic_{};
  int dof_ = 1;
  std::string prefix_;
  MPI_Comm comm_ = PETSC_COMM_SELF;
  RegionOptions options_;
  Mat J_ = nullptr;
  std::vector<int> region_;  // the region's nodes (natural numbering, sorted; the same on every rank)
  PetscInt n_region_ = 0;
  int n_differing_ = 0;
  IS is_ = nullptr;
  Mat JR_ = nullptr;      // J on region x region
  Mat JR_aij_ = nullptr;  // JR_ as AIJ, when the factorisation needs it (aij_)
  bool aij_ = false;
  std::string single_failure_;  // the single-precision LU's failure, if any
  Mat J_rows_ = nullptr;  // J's rows of the region, every column
  IS all_ = nullptr;
  KSP region_ksp_ = nullptr;
  VecScatter to_region_ = nullptr;
  Vec rR_ = nullptr, xR_ = nullptr, res_ = nullptr, t_ = nullptr;
};

}  // namespace cellfsi::solvers
