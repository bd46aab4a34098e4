#pragma once
// The paths of the coupled linear solve (coupling/coupled_linear_solver.hpp), one class per PC type family:
//   FourierSolve   cellfsi_fourier (coupling/fourier_solve.cpp): the bulk solver built once, the Jacobian
//                  re-assembled around the cells at each refresh (or, with the bulk stencil, only the rows
//                  near them), FGMRES;
//   BandSolve      cellfsi_band (coupling/band_solve.cpp): the kept part re-split when the cells leave its
//                  region, the Jacobian refreshed as for cellfsi_fourier, FGMRES;
//   BulkSolve      cellfsi_bulk (coupling/bulk_solve.cpp): the fluid's own bulk inverse built once
//                  (fluid::ImmersedFluid::bulk_inverse), the whole Jacobian re-assembled at each refresh,
//                  FGMRES; nothing factorised in a step;
//   PetscPCSolve   any PETSc PC (coupling/petsc_pc_solve.cpp): the whole Jacobian at every solve, the
//                  preconditioner rebuilt every -coupling_pc_lag solves and when the marking moves, GMRES.
// CoupledLinearSolver owns the KSP and picks the path (make_solve_path); a path that cannot go on asks it for
// a fallback, which replaces the path. Only CoupledLinearSolver uses these classes.
#include <petscksp.h>

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/petsc_error.hpp"
#include "coupling/solver_policy.hpp"
#include "fluid/immersed_fluid.hpp"

namespace cellfsi::coupling {

struct SolveCounts;

/// What every path works with (CoupledLinearSolver's; the paths may turn options.bulk_stencil off).
struct SolveContext {
  fluid::ImmersedFluid& fluid;
  LinearSolverOptions& options;
  std::function<std::vector<char>()> active_elements;  // the elements with s^h != 1 or an immersed point
  KSP ksp = nullptr;
};

/// A path's request to be replaced by another PC type (even_if_asked: also when the user asked for this one;
/// otherwise that is refused with the reason).
struct FallBack {
  std::string pc_type, why;
  bool even_if_asked = false;
};

class SolvePath {
 public:
  explicit SolvePath(SolveContext& c) : c_(c) {}
  virtual ~SolvePath() = default;
  SolvePath(const SolvePath&) = delete;
  SolvePath& operator=(const SolvePath&) = delete;

  /// The checks and set-up of the path the solver starts with (not of one it falls back to), after the KSP
  /// read its options. Throws std::invalid_argument for a PC type that cannot run here.
  virtual void start(const SolverSituation& s, bool seq_baij) = 0;
  /// The s^h marking moved.
  virtual void marking_changed() = 0;
  /// See CoupledLinearSolver::may_assemble.
  virtual bool may_assemble(bool first_iteration) const = 0;
  /// What a solve needs before the KSP's (the bulk solver, the band's split); a fallback if the path cannot
  /// go on.
  virtual std::optional<FallBack> prepare(Vec X, bool first_iteration, SolveCounts& counts) = 0;
  /// dX = K_MC(X)^{-1} F, after prepare. Returns the KSP's iterations.
  virtual int solve(Vec X, Vec F, Vec dX, bool first_iteration, SolveCounts& counts) = 0;
  /// After a failed solve: whether the path built something once from an earlier state (a bulk operator)
  /// that the next prepare() and solve() will build again from the state then, with the Jacobian refreshed.
  /// False if it has nothing to rebuild.
  virtual bool rebuild() { return false; }
  /// See CoupledLinearSolver::corrected_unknowns.
  virtual PetscInt corrected_unknowns() const { return 0; }

 protected:
  PC pc() const;
  /// The may_assemble of the paths that keep the Jacobian through a step: at its first iteration, and when
  /// this solve is the refresh_lag-th since the last refresh (solves_before: those before it).
  bool refresh_due(bool first_iteration, int solves_before) const {
    return first_iteration || (c_.options.refresh_lag > 0 && solves_before + 1 >= c_.options.refresh_lag);
  }
  SolveContext& c_;
};

/// The cellfsi types' common part: the Jacobian kept between refreshes (a chord iteration), refreshed at
/// the first iteration of a step in which the marking moved, every refresh_steps steps, and every
/// refresh_lag solves if set.
class CellfsiSolve : public SolvePath {
 public:
  using SolvePath::SolvePath;
  void marking_changed() override { marking_changed_ = true; }
  int solve(Vec X, Vec F, Vec dX, bool first_iteration, SolveCounts& counts) final;
  /// FGMRES at options.rtol, and the PC type `type`, before the options are read.
  static void configure_ksp(KSP ksp, const LinearSolverOptions& options, const std::string& type);

 protected:
  /// Whether prepare() re-split the operator (then the Jacobian is refreshed whatever the counters say).
  bool resplit_ = false;
  int solves_since_refresh_ = 0;

 private:
  virtual void refresh_jacobian(Vec X) = 0;  // the Jacobian (or the near rows) at X
  virtual Mat operator_matrix() const = 0;   // the KSP's operator
  virtual void set_up_pc() { CELLFSI_PETSC(KSPSetUp(c_.ksp)); }
  virtual void after_refresh() {}  // reports, after the preconditioner's set-up
  virtual bool refresh_factorizes() const = 0;  // whether set_up_pc() factorised a matrix
  bool marking_changed_ = true;
  int steps_since_refresh_ = 0;
};

class FourierSolve final : public CellfsiSolve {
 public:
  using CellfsiSolve::CellfsiSolve;
  ~FourierSolve() override;
  void start(const SolverSituation& s, bool seq_baij) override;
  bool may_assemble(bool first_iteration) const override;
  std::optional<FallBack> prepare(Vec X, bool first_iteration, SolveCounts& counts) override;
  PetscInt corrected_unknowns() const override;
  bool rebuild() override;  // the bulk operator (not with the bulk stencil: the Jacobian was released)

 private:
  std::optional<FallBack> build_bulk(Vec X);  // once, and again after rebuild()
  void refresh_jacobian(Vec X) override;      // the region re-assembled, the rest kept
  void refresh_near_operator(Vec X);          // bulk_stencil: the near rows re-assembled
  /// bulk_stencil: the matrix of the rows of nodes on region_'s elements (the others hold one diagonal
  /// block), the operator made of it and the bulk stencil, and the nodes whose rows it holds in full.
  void make_near_operator();
  Mat operator_matrix() const override;
  void after_refresh() override;
  bool refresh_factorizes() const override;           // the region's LU, unless its PC type says otherwise
  std::shared_ptr<solvers::FourierBulkSolver> bulk_;  // made by start(), built by the first prepare()
  bool bulk_built_ = false;
  int bulk_builds_ = 0;
  std::vector<char> region_;                // elements re-assembled at every refresh
  Mat J_fixed_ = nullptr;                   // the Jacobian of the other elements
  Mat near_ = nullptr, near_op_ = nullptr;  // bulk_stencil: the near rows, and the operator
  MatNullSpace null_space_ = nullptr, transpose_null_space_ = nullptr;  // the fluid Jacobian's, for near_op_
  bool single_failure_reported_ = false;  // the region's single-precision LU failed, and the console was told
};

class BandSolve final : public CellfsiSolve {
 public:
  using CellfsiSolve::CellfsiSolve;
  ~BandSolve() override;
  void start(const SolverSituation& s, bool seq_baij) override;
  bool may_assemble(bool) const override { return true; }  // it re-splits whenever the cells leave its region
  std::optional<FallBack> prepare(Vec X, bool first_iteration, SolveCounts& counts) override;
  PetscInt corrected_unknowns() const override;

 private:
  void refresh_jacobian(Vec X) override;  // the kept part plus the band's
  Mat operator_matrix() const override { return c_.fluid.jacobian_matrix(); }
  void set_up_pc() override;  // the kept part's LU when re-split, the Schur complement
  void after_refresh() override;
  bool refresh_factorizes() const override { return true; }  // the Schur complement's LU
  std::vector<char> region_;  // the band's elements
  Mat J_fixed_ = nullptr;     // the Jacobian of the other elements
  long in_region_ = 0;        // elements in region_
  int steps_since_factor_ = 0;
};

class BulkSolve final : public CellfsiSolve {
 public:
  using CellfsiSolve::CellfsiSolve;
  ~BulkSolve() override;
  void start(const SolverSituation& s, bool seq_baij) override;
  bool may_assemble(bool first_iteration) const override;
  std::optional<FallBack> prepare(Vec X, bool first_iteration, SolveCounts& counts) override;
  bool rebuild() override;  // the fluid's bulk inverse (and its stencil)

 private:
  void refresh_jacobian(Vec X) override;
  Mat operator_matrix() const override { return op_ ? op_ : c_.fluid.jacobian_matrix(); }
  bool refresh_factorizes() const override { return false; }
  bool built_ = false;
  int builds_ = 0;
  Mat op_ = nullptr;  // bulk_stencil: the fluid's operator (its own; not destroyed here)
  Mat composed_ = nullptr;  // the operator the bulk inverse was composed on (the destructor detaches it)
};

class PetscPCSolve final : public SolvePath {
 public:
  using SolvePath::SolvePath;
  void start(const SolverSituation& s, bool seq_baij) override;
  void marking_changed() override { pc_stale_ = true; }
  /// The Jacobian at a step's first iteration, and every refresh_lag iterations inside it if that is set:
  /// the residual is exact, so the solution does not depend on it (measured on the CTC among 11 red cells
  /// on the curved narrowing, 96 x 32, 20 steps: the same 68 coupling iterations, the state to 1.1e-9, and
  /// 0.75 times the time of a Jacobian at every iteration).
  bool may_assemble(bool first_iteration) const override;
  std::optional<FallBack> prepare(Vec, bool, SolveCounts&) override { return std::nullopt; }
  int solve(Vec X, Vec F, Vec dX, bool first_iteration, SolveCounts& counts) override;
  /// GMRES at kFluidRtol, and the PC type `pc_type` (ASM with PetscPCDefaults' overlap), before the options
  /// are read.
  static void configure_ksp(KSP ksp, const std::string& pc_type);

 private:
  bool pc_stale_ = true;
  int solves_since_pc_ = 1 << 30;
  int solves_since_jacobian_ = 0;
};

}  // namespace cellfsi::coupling
