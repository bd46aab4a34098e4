#pragma once
// A sparse LU in single precision (MUMPS' smumps) of a double-precision PETSc matrix, for use as a
// preconditioner: the registered PC type "cellfsi_lu_single" (solvers/pc_lu_single.hpp), in 3D the default
// for the region of cellfsi_fourier (-coupling_fourier_region_pc_type).
//
// Why: the region's LU (solvers/region_corrected.hpp) is redone at every step in 3D, and at the paper's 64^3
// it is half the step (docs/design.md §8): 1.6e12 operations at the cores' dense speed, whatever the
// ordering. In single precision the same fronts run at twice the speed (twice the SIMD lanes) and the factors
// take half the memory and half the time to read in each triangular solve. The factors are then a
// preconditioner, not an exact inverse: the region's solve is correct to about single precision times the
// region's conditioning, and the Krylov iteration around it (the coupling's FGMRES) makes up the rest; a KSP
// around this PC (-..._ksp_type richardson or fgmres) refines it further if asked.
//
// The matrix goes to MUMPS as distributed triplets (AIJ or BAIJ, any number of ranks), converted to float;
// right-hand sides and solutions pass through the host. The ordering is "cellfsi_nd" (SCOTCH's nested
// dissection of the node graph, solvers/nested_dissection.hpp, computed on the host from the gathered
// pattern, on any number of ranks) or "mumps" (MUMPS' own choice, PORD in Debian's build).
#include <petscmat.h>

#include <memory>
#include <string>
#include <vector>

namespace cellfsi::solvers {

class SinglePrecisionLU {
 public:
  explicit SinglePrecisionLU(MPI_Comm comm);
  ~SinglePrecisionLU();
  SinglePrecisionLU(const SinglePrecisionLU&) = delete;
  SinglePrecisionLU& operator=(const SinglePrecisionLU&) = delete;

  /// "cellfsi_nd" (the default) or "mumps"; anything else: std::invalid_argument.
  void set_ordering(const std::string& ordering);
  const std::string& ordering() const { return ordering_; }

  /// Factorises A (square, AIJ or BAIJ, on the communicator given at construction). The analysis (ordering
  /// and symbolic factorisation) is kept while A is the same matrix with the same nonzero pattern.
  /// Collective; throws std::runtime_error with MUMPS' error code if it fails (on every rank).
  void factor(Mat A);
  /// x = (LU)^{-1} b, in single precision. Collective.
  void solve(Vec b, Vec x);

  bool factored() const { return factored_; }
  PetscInt size() const { return n_; }
  double operations() const;         // floating-point operations of the factorisation (MUMPS' RINFOG(3))
  long long factor_entries() const;  // entries in the factors (INFOG(29))
  int analyses() const { return analyses_; }  // symbolic factorisations so far

 private:
  void extract(Mat A, bool values_only);  // this rank's triplets (1-based) and values
  void analyse();
  void call(int job);  // runs MUMPS, throws on an error
  struct Mumps;
  std::unique_ptr<Mumps> mumps_;
  MPI_Comm comm_;
  std::string ordering_ = "cellfsi_nd";
  std::vector<int> irn_, jcn_, perm_in_;
  std::vector<float> values_, rhs_;
  PetscInt n_ = 0, bs_ = 1;
  bool analysed_ = false;
  PetscObjectId analysed_id_ = 0;  // the matrix whose pattern the analysis is of, and that pattern's state
  PetscObjectState pattern_ = 0;
  bool factored_ = false;
  int analyses_ = 0;
  Vec b0_ = nullptr;  // the right-hand side on the host
  VecScatter to_host_ = nullptr;
};

}  // namespace cellfsi::solvers
