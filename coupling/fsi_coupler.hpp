#pragma once
// The block-iterative Newton loop of the paper's Sec. 2.3, as a partitioned scheme between one FluidSolver
// and any number of SolidSolver bodies (Remark 4). Per iteration:
//   steps 1-3, per body: the fluid velocity at the body's collocation points (at t_{n+alpha_f} of the current
//   fluid iterate) -> the body's kinematic update; step 4: the bodies' quadrature data located in the
//   Eulerian mesh and handed to the fluid as immersed points, and s^h marked (s_I on the basis functions
//   around the interface points; once per step, at the first iteration) -> the fluid residual R_MC; steps
//   5-7: K_MC, a linear solve, the update of the fluid unknowns.
// It stops when the fluid residual and every body's kinematic residual have dropped by `tolerance` (paper:
// 1e-4) below the largest value each has had in the step, or are at round-off (fluid_atol, solid_atol).
#include <memory>
#include <string>
#include <vector>

#include "coupling/anderson.hpp"
#include "coupling/interface_marking.hpp"
#include "coupling/locator.hpp"
#include "fluid/band_schur.hpp"
#include "fluid/fluid_solver.hpp"
#include "fluid/region_corrected_solver.hpp"
#include "solid/solid_solver.hpp"

namespace cellfsi::coupling {

/// How the fluid's linear systems of the coupling loop are solved.
enum class CouplingSolver {
  /// `fourier` where it applies (a BAIJ Jacobian, a translation-invariant box periodic in all directions but
  /// one: fourier_inapplicable; any number of fluid ranks), else `band` (which falls back to `fluid` on
  /// several ranks). If the Jacobian away from the cells assembled in the first step is not uniform along
  /// the periodic directions after all (fourier_uniformity), `band` or `fluid` from then on. The default.
  automatic,
  /// fluid::BandSchurSolver (one fluid rank, SeqBAIJ Jacobian): the Jacobian away from the cells is
  /// factorised once and kept while the s^h band and the immersed points stay inside the region it was built
  /// for; when the s^h marking moves only that region is re-assembled and its Schur complement factorised.
  /// The default on one fluid rank where `fourier` does not apply (the narrowing channel).
  band,
  /// The fluid's own KSP and PC (prefix fluid_, every PETSc option): the preconditioner is rebuilt every
  /// `preconditioner_lag` solves and whenever the s^h marking changes (every step while a cell moves).
  fluid,
  /// fluid::RegionCorrectedSolver in FGMRES (prefix coupling_fourier_; a BAIJ Jacobian, a box periodic in
  /// all directions but one; any number of fluid ranks): the Jacobian without the cells inverted by Fourier
  /// transform once per run, corrected by an LU of the region around the cells, re-factorised when the band
  /// is refreshed. No global factorisation: the solver for 3D and for several ranks.
  fourier,
};

/// How the coupling loop's iterates are formed from its corrections.
enum class Acceleration {
  none,      // x_{k+1} = x_k - dx_k (the paper's block iteration)
  anderson,  // Anderson acceleration of that fixed-point map (coupling/anderson.hpp)
};

struct CouplerOptions {
  double s_interface = 1e10;           // s_I (paper Sec. 3.3)
  Marking marking = Marking::central;  // which functions get s_I (coupling/interface_marking.hpp)
  double tolerance = 1e-4;             // drop of every residual's L2 norm (paper: four orders of magnitude)
  double fluid_atol = 1e-16;           // or an absolute fluid residual below this
  // or an absolute kinematic residual below this [cm/s]: round-off (a body whose predictor matches the flow,
  // e.g. a tracer, has a residual of 1e-17 that cannot drop by the tolerance; converged cells have 1e-7)
  double solid_atol = 1e-14;
  int max_iterations = 30;
  int preconditioner_lag = 10;  // linear solves between rebuilds of the preconditioner (1: every iteration)
  bool monitor = false;         // print every iteration's residual norms (rank 0)
  // Measured on the default scene (160 x 80, 50 steps): 259 coupling iterations instead of 312, theta the
  // same to 4e-9 relative.
  Acceleration acceleration = Acceleration::anderson;
  int acceleration_columns = 5;  // difference pairs kept by the Anderson acceleration
  int acceleration_reuse = 0;    // previous steps whose pairs are kept (0: only this step's)
  CouplingSolver solver = CouplingSolver::automatic;
  // Band solver. Elements around the active ones in the band region (measured: margins 2 and 6 were slower).
  int band_margin = 4;
  // Steps between factorisations of the kept (fixed) part besides those the band's motion needs (0: only
  // those).
  int band_refactor_every = 0;
  // Steps between refreshes of the band's Jacobian and Schur complement while the s^h marking stays (it is
  // refreshed at the first iteration of every step in which the marking moved).
  int band_refresh_steps = 10;
  // Coupling iterations between refreshes inside a step (0: none); in between, the Newton matrix is kept (a
  // chord iteration; the residual is exact, so the answer is the same to the coupling tolerance).
  int band_schur_lag = 0;
  // Fourier solver: relative deviation of a node's rows from the bulk operator that puts it in the corrected
  // region, and the node layers the region is grown by.
  double fourier_threshold = 1e-3;
  int fourier_overlap = 0;
  // Region LU solves per preconditioner application: 2 (region, bulk, region) or 1 (bulk, region).
  int fourier_region_solves = 1;
  // Re-assemble only the elements around the cells, the rest kept in a second copy of the Jacobian (false:
  // the whole Jacobian at every refresh, one copy less: for meshes whose memory is tight).
  bool fourier_partial_jacobian = true;
  // The bulk operator's largest relative deviation between periodic positions above which the Fourier solver
  // does not run (the flow or mesh is not uniform along x): `auto` then takes the band solver (or the fluid's
  // KSP on several ranks), `fourier` is refused. No option sets it: the meshes it guards are uniform to
  // round-off (about 1e-13) or not uniform at all (the narrowing channel: order 1).
  double fourier_uniformity = 1e-2;
};

/// Whether -coupling_solver fourier can run on this patch: at most one non-periodic direction, and the patch
/// translation-invariant along the periodic ones (geometry::translation_invariant). "" if so, else why not.
std::string fourier_inapplicable(const geometry::Patch& patch);

struct CouplerStats {
  int iterations = 0, linear_iterations = 0;
  int factorizations = 0;  // factorisations of the whole fluid Jacobian (band: of its fixed part) in the step
  // Band solver: re-assemblies of the band and factorisations of its Schur complement in the step.
  int band_refreshes = 0;
  bool converged = false;
  double fluid_residual0 = 0, fluid_residual = 0;
  std::vector<double> solid_residual0, solid_residual;
  std::string reason;
};

class FsiCoupler {
 public:
  FsiCoupler(fluid::FluidSolver& fluid, std::vector<solid::SolidSolver*> bodies, CouplerOptions options = {});
  ~FsiCoupler();
  FsiCoupler(const FsiCoupler&) = delete;
  FsiCoupler& operator=(const FsiCoupler&) = delete;

  /// Before the first step: the bodies' rates from the fluid velocity at their points, and the immersed
  /// points and s^h of the initial configuration.
  void initialize();
  /// After the fluid's and the bodies' states were restored (a restart): the immersed points and s^h of
  /// that configuration, the bodies' rates left as restored.
  void restart();
  /// One time step of the coupled problem.
  CouplerStats step();
  /// The solver in use (CouplingSolver::fluid when `band` was asked for but cannot run: several fluid ranks,
  /// a non-BAIJ Jacobian, or a band region holding most of the domain). It can change in the first step:
  /// `band` falls back to `fluid` when its region holds most of the domain, and `fourier` chosen by `auto`
  /// falls back to `band` or `fluid` when the Jacobian away from the cells is not uniform along the periodic
  /// directions (both reported on the console); fell_back() then says so.
  CouplingSolver solver() const { return solver_; }
  /// Whether a step (in practice the first) replaced the solver chosen at set-up (the options of the solver
  /// it replaced were then never read).
  bool fell_back() const { return fell_back_; }
  /// Unknowns of the current band (0 before the first step or with CouplingSolver::fluid).
  PetscInt band_unknowns() const { return band_.n_band(); }

 private:
  void update_immersed(bool mark);  // mark: also rebuild s^h from the interface points
  /// Band solver: the fallback to the fluid's solver, freeing the band solver's matrices.
  void use_fluid_solver();
  void setup_band();  // the band solver's matrices and KSP
  /// Band solver: elements with s^h != 1 or an immersed point.
  std::vector<char> active_elements() const;
  /// Band solver: (re)builds the region and the factorisation of the fixed part if there is none yet, the
  /// active elements left the region, or band_refactor_every steps passed; returns whether it did.
  bool ensure_band_factorization();
  /// One linear solve dX = K^{-1} F of the coupling loop; returns the KSP's iterations, or throws.
  int solve_band(CouplerStats& st, bool first_iteration);
  int solve_fluid(CouplerStats& st);
  int solve_fourier(CouplerStats& st, bool first_iteration);
  fluid::FluidSolver& fluid_;
  std::vector<solid::SolidSolver*> bodies_;
  CouplerOptions opt_;
  Locator locator_;
  std::vector<std::vector<Location>> collocation_loc_, quadrature_loc_;  // warm starts, per body
  Vec X_ = nullptr, dX_ = nullptr, F_ = nullptr;
  int solves_since_pc_ = 1 << 30;
  solid::TimeParameters tp_;
  std::vector<int> marked_;  // basis functions carrying s_I
  bool marking_changed_ = true;
  // Band solver (see CouplingSolver::band).
  CouplingSolver solver_ = CouplingSolver::band;
  bool fell_back_ = false;  // see fell_back()
  fluid::BandSchurSolver band_;
  Mat J_fixed_ = nullptr, J_band_ = nullptr;  // the two parts of K_MC; their sum goes into the fluid's matrix
  KSP band_ksp_ = nullptr;                    // FGMRES (prefix coupling_band_) preconditioned by band_
  std::vector<char> region_;                  // elements whose Jacobian is re-assembled at every refresh
  int steps_since_factor_ = 0, solves_since_schur_ = 0, steps_since_refresh_ = 0;
  bool band_marking_changed_ = true;                // the marking moved since the band was last refreshed
  std::unique_ptr<AndersonAcceleration> anderson_;  // with Acceleration::anderson
  // Fourier solver (see CouplingSolver::fourier).
  std::unique_ptr<fluid::RegionCorrectedSolver> fourier_;
  KSP fourier_ksp_ = nullptr;  // FGMRES (prefix coupling_fourier_) preconditioned by fourier_
};

}  // namespace cellfsi::coupling
