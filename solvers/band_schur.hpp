#pragma once
// A direct solver for a matrix K = K_fixed + K_band whose second part changes often but only inside a fixed
// set of unknowns B (the "band"), while K_fixed stays for many solves.
//
// Why: in the coupled FSI Jacobian the s^h band of the interfaces (s_I up to 1e10) and the immersed points
// move every time step, so the LU factors of the whole Jacobian went stale every step, while everything away
// from the cells (most of the matrix) barely changes at Re ~ 1e-4. Split the unknowns into B, every unknown
// that K_band touches, and the rest I. K_band lives in the B x B block only, so
//   K = [ K_II  K_IB ; K_BI  K_fixed,BB + K_band,BB ],
// and the Schur complement of K on B is
//   S = S_fixed + K_band,BB,   S_fixed = K_fixed,BB - K_BI K_II^{-1} K_IB.
// factor(K_fixed, B): one sparse LU of K_fixed by MUMPS. K_BI K_II^{-1} K_IB is non-zero only on the band's
//   edge E (its unknowns whose rows of K_fixed are not zero, i.e. that border I); the band's inner unknowns
//   have zero rows and columns in K_fixed and get an identity, and MUMPS eliminates everything but E and
//   returns the dense S_E = K_fixed,EE - K_EI K_II^{-1} K_IE (ICNTL(19)). S_fixed is S_E on E and zero
//   elsewhere; it is stored sparse, in the block layout of the band.
// set_band(K_band): S = S_fixed + K_band,BB and a sparse LU of S (the band's size, not the domain's).
// solve(r): block elimination: z = K_II^{-1} r_I, y = S^{-1} (r_B - K_BI z), x_I = K_II^{-1} (r_I - K_IB y),
//   x_B = y. Fused (the default): one MUMPS solve with K_fixed's factors, whose forward sweep condenses the
//   right-hand side onto B (ICNTL(26) = 1) and backward sweep expands y (ICNTL(26) = 2), with S's factors
//   solving in between: the cost of one triangular solve pair plus one with S. PETSc 3.18 lets the user
//   solve the Schur system only through the factor's dense Schur matrix, so that matrix is declared factored
//   and its MatMatSolve operation is pointed at S's sparse factors (public API: MatSetFactorType,
//   MatSetOperation; checked by the unit test). Not fused: two interior solves
//   (ICNTL(26) = 0) and products with K_BI and K_IB, public API only.
// The result is the inverse of K_fixed + K_band whatever K_band,BB is: exact to round-off with full-rank
// factors (set_blr_tolerance(0)); by default K_fixed's factors are block low-rank with a 1e-10 threshold, so
// it is exact to about that.
//
// One rank only (PETSc 3.18 computes MUMPS Schur complements on one rank). Matrices are PETSc SeqBAIJ; B must
// consist of whole blocks.
#include <petscmat.h>

#include <string>
#include <vector>

namespace cellfsi::solvers {

/// The solver's options (cellfsi_band's -pc_band_fused and -pc_band_blr_tolerance, solvers/pc_band.hpp): the
/// defaults and the valid range, stated once.
struct BandSchurOptions {
  bool fused_solve = true;       // see set_fused_solve
  double blr_tolerance = 1e-10;  // see set_blr_tolerance
  static bool valid_blr_tolerance(const double& v) { return v >= 0 && v < 1; }
  static constexpr const char* kBlrToleranceRange = "in [0, 1)";
};

class BandSchurSolver {
 public:
  BandSchurSolver() = default;
  ~BandSchurSolver();
  BandSchurSolver(const BandSchurSolver&) = delete;
  BandSchurSolver& operator=(const BandSchurSolver&) = delete;

  /// Factorises K_fixed with the band unknowns `band` (sorted global indices, whole blocks) kept for the
  /// Schur complement. `prefix` is the options prefix of the MUMPS factor (its -<prefix>mat_mumps_* options
  /// apply). Replaces any previous factorisation.
  void factor(Mat fixed, IS band, const std::string& prefix = "");
  /// Fused solve (see above; default: BandSchurOptions). Takes effect at the next factor().
  void set_fused_solve(bool fused) { fused_ = fused; }
  /// Block low-rank compression of K_fixed's factors (MUMPS BLR, CNTL(7)): entries dropped below this
  /// relative size; 0: full-rank LU. The default (BandSchurOptions) keeps the solve exact far below any
  /// linear tolerance. Takes effect at the next factor().
  void set_blr_tolerance(double tol) { blr_tolerance_ = tol; }
  /// Sets K_band (a matrix of K_fixed's size and layout whose entries lie in band x band; entries outside are
  /// ignored) and factorises the band's Schur complement.
  void set_band(Mat band);
  /// The same from the whole operator K = K_fixed + K_band (K_fixed's layout; only K's band x band block is
  /// read): K_band,BB = K_BB - K_fixed,BB. For a caller that keeps K and K_fixed but not K_band (the
  /// cellfsi_band preconditioner, solvers/pc_band.hpp); agrees with set_band to round-off in K_fixed,BB.
  void set_operator(Mat K);
  /// x = (K_fixed + K_band)^{-1} r.
  void solve(Vec r, Vec x);

  /// Frees the factorisations and everything built for them (factored() is false afterwards).
  void release();
  bool factored() const { return F_ != nullptr; }
  PetscInt n_band() const { return n_band_; }    // unknowns in B
  PetscInt n_total() const { return n_total_; }  // all unknowns
  /// Unknowns of the band's edge (those bordering the rest): the size of MUMPS' dense Schur complement.
  PetscInt n_edge() const { return n_edge_; }
  /// Nonzero entries of the sparse Schur complement (its blocks times the block size squared).
  PetscInt schur_nonzeros() const { return schur_nonzeros_; }

 private:
  void factor_impl(Mat fixed, IS band, const std::string& prefix);
  friend PetscErrorCode band_schur_matsolve(Mat, Mat, Mat);
  void solve_schur(Vec g, Vec y);            // y = S^{-1} g
  /// S = base + sub's band x band block (in S_'s layout), and its LU.
  void factor_schur(Mat sub, const std::vector<double>& base, const char* what);
  bool fused_ = BandSchurOptions{}.fused_solve, fused_active_ = fused_;  // asked for; in use since factor()
  double blr_tolerance_ = BandSchurOptions{}.blr_tolerance;
  PetscInt bs_ = 1, n_band_ = 0, n_total_ = 0, schur_nonzeros_ = 0;
  Mat F_ = nullptr;  // MUMPS factors of K_fixed (inner band nodes: identity) keeping the edge for the Schur
  Mat K_ = nullptr;  // that matrix: MUMPS reads its entries in place
  Mat K_BI_ = nullptr, K_IB_ = nullptr;
  Mat S_ = nullptr, SF_ = nullptr;  // Schur complement (SeqBAIJ) and its factors
  Mat band_sub_ = nullptr;          // K_band,BB, reused
  IS band_ = nullptr, interior_ = nullptr;
  std::vector<PetscInt> s_ia_, s_ja_;  // S_'s block structure
  PetscInt n_edge_ = 0;                // unknowns of the band's edge (the MUMPS Schur complement's size)
  std::vector<PetscInt> edge_pos_;     // positions in B of the edge's unknowns
  std::string prefix_;
  std::vector<double> s_fixed_;     // S_fixed in S_'s value array layout
  std::vector<double> s_fixed_minus_bb_;  // S_fixed - K_fixed,BB, the same layout
  std::vector<PetscInt> band_pos_;  // block k of band_sub_ -> block of S_
  Vec w1_ = nullptr, w2_ = nullptr, rB_ = nullptr, yB_ = nullptr, tB_ = nullptr, zI_ = nullptr, tI_ = nullptr;
  VecScatter to_band_ = nullptr, to_interior_ = nullptr;  // full vector -> its B or I part
};

}  // namespace cellfsi::solvers
