#pragma once
// The block-iterative Newton loop of the paper's Sec. 2.3, as a partitioned scheme between one FluidSolver
// and any number of SolidSolver bodies (Remark 4). Per iteration:
//   steps 1-3, per body: the fluid velocity at the body's collocation points (at t_{n+alpha_f} of the current
//   fluid iterate) -> the body's kinematic update; step 4: the bodies' quadrature data located in the
//   Eulerian mesh and handed to the fluid as immersed points, and s^h marked (s_I on the basis functions
//   around the interface points; once per step, at the first iteration) -> the fluid residual R_MC; steps
//   5-7: K_MC, a linear solve, the update of the fluid unknowns.
// It stops when the fluid residual and every body's kinematic residual have dropped by `tolerance` (paper:
// 1e-4) below the largest value each has had in the step.
#include <string>
#include <vector>

#include "coupling/locator.hpp"
#include "fluid/fluid_solver.hpp"
#include "solid/solid_solver.hpp"

namespace cellfsi::coupling {

struct CouplerOptions {
  double s_interface = 1e10;  // s_I (paper Sec. 3.3)
  double tolerance = 1e-4;    // drop of every residual's L2 norm (paper: four orders of magnitude)
  double fluid_atol = 1e-16;  // or an absolute fluid residual below this
  int max_iterations = 30;
  int preconditioner_lag = 10;  // linear solves between rebuilds of the preconditioner (1: every iteration)
  bool monitor = false;         // print every iteration's residual norms (rank 0)
};

struct CouplerStats {
  int iterations = 0, linear_iterations = 0;
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
  /// One time step of the coupled problem.
  CouplerStats step();

 private:
  void update_immersed(bool mark);  // mark: also rebuild s^h from the interface points
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
};

}  // namespace cellfsi::coupling
