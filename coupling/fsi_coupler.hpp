#pragma once
// The block-iterative Newton loop of the paper's Sec. 2.3, as a partitioned scheme between one fluid
// (fluid::ImmersedFluid, whichever discretisation) and any number of SolidSolver bodies (Remark 4). Per
// iteration:
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
#include "coupling/coupled_linear_solver.hpp"
#include "coupling/interface_marking.hpp"
#include "coupling/locator.hpp"
#include "coupling/repulsion.hpp"
#include "fluid/immersed_fluid.hpp"
#include "solid/solid_solver.hpp"

namespace cellfsi::coupling {

/// How the coupling loop's iterates are formed from its corrections.
enum class Acceleration {
  none,      // x_{k+1} = x_k - dx_k (the paper's block iteration)
  anderson,  // Anderson acceleration of that fixed-point map (coupling/anderson.hpp)
};

/// The solids' stiffness in the fluid tangent (fluid::ImmersedPoint): the residual, and so the solution, does
/// not depend on it; the coupling iterations do.
enum class SolidTangent {
  isotropic,   // a viscosity from the small-strain shear modulus G (ImmersedPoint::stiffness_viscosity)
  consistent,  // the material's spatial tangent and the stress at the point (ImmersedPoint::stiffness)
  // the consistent tangent through the body's own interpolation of the fluid velocity at its collocation
  // points (fluid::SolidLinearization), where the fluid and the body take it; consistent elsewhere
  collocation,
};

/// The default per dimension, measured (docs/notes/2026-11-28-solid-tangent.md): in 3D, where a scene's
/// bodies are about as coarse as the fluid, collocation (the compound capsule at 64^3 on the
/// divergence-conforming space: 4 coupling iterations per step instead of 8.5, 19.9-27.0 s per step
/// on two ranks instead of 36.8); in 2D, where they are several times finer, consistent (the capsule at 256 x
/// 128: the same iterations, 10 % slower with collocation).
inline SolidTangent default_solid_tangent(int dim) {
  return dim == 3 ? SolidTangent::collocation : SolidTangent::consistent;
}

/// The contact repulsion between membranes and from the walls (coupling/repulsion.hpp).
struct RepulsionOptions {
  bool enabled = true;
  double cutoff = 0;  // r_c [cm]; 0: the fluid mesh's smallest element extent
  double scale = 0;   // P0 [dyn/cm^2]; 0: the largest G h / R of the membranes (R: of a circle or sphere of
                      // the membrane's reference perimeter or area)
  bool walls = true;  // also between membranes and the walls
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
  bool monitor = false;  // print every iteration's residual norms (rank 0)
  // Measured on the default scene (160 x 80, 50 steps): 259 coupling iterations instead of 312, theta the
  // same to 4e-9 relative.
  Acceleration acceleration = Acceleration::anderson;
  int acceleration_columns = 5;  // difference pairs kept by the Anderson acceleration
  int acceleration_reuse = 0;    // previous steps whose pairs are kept (0: only this step's)
  // Consistent: the same coupling iterations where the cells barely deform (the 3D compound capsule at
  // 16^3, 537 in 120 steps either way), fewer where they deform much (the optical-tweezers test: 98 instead
  // of 123); docs/design.md §8.
  SolidTangent solid_tangent = SolidTangent::consistent;
  // Per body (in the order of the bodies; missing or 0: none): the dynamic viscosity mu_in [g/(cm s)] of the
  // fluid inside a membrane (coupling/inner_viscosity.hpp). Only membranes take one. A value equal to the
  // fluid's adds nothing: with no contrast the fluid never gets a viscosity field, and runs are unchanged.
  std::vector<double> inner_viscosity;
  RepulsionOptions repulsion;
  // The linear solves (coupling/coupled_linear_solver.hpp); its fluid_atol and s_I are set from the above.
  LinearSolverOptions linear;
};

struct CouplerStats {
  int iterations = 0, linear_iterations = 0;
  // In the step: LU factorisations (coupling::SolveCounts::factorizations), the bulk operator's (the run's
  // first step only), and refreshes of the Jacobian with the preconditioner's set-up.
  int factorizations = 0, bulk_factorizations = 0, refreshes = 0;
  bool converged = false;
  double fluid_residual0 = 0, fluid_residual = 0;
  std::vector<double> solid_residual0, solid_residual;
  std::string reason;
  RepulsionStats repulsion;  // at the step's last iteration (none found: infinite gaps)
};

class FsiCoupler {
 public:
  FsiCoupler(fluid::ImmersedFluid& fluid, std::vector<solid::SolidSolver*> bodies, CouplerOptions options = {});
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
  /// s_I from now on (checked by check_interface_scaling): s^h of the current marking at once, and the
  /// coupled preconditioner refreshed at the next step, as for a new marking.
  void set_interface_scaling(double s_interface);
  double interface_scaling() const { return opt_.s_interface; }
  /// The linear solver (its PC type, whether it fell back, its KSP).
  const CoupledLinearSolver& linear_solver() const { return *linear_; }
  /// The contact repulsion (null while off, or before the first configuration, or without membranes).
  const Repulsion* repulsion() const { return repulsion_.get(); }

 private:
  // The solids' data at the immersed points. first_iteration (a step's first, or before any step): s^h is
  // marked again from the interface points. The solids' tangents are formed only for a solve that may
  // assemble the Jacobian (CoupledLinearSolver::may_assemble).
  void update_immersed(bool first_iteration);
  void apply_scaling();             // s^h on the fluid: s_I on the marked functions, 1 elsewhere
  /// The repulsion's force [dyn] on every body's points (q: their data, located in quadrature_loc_), or null
  /// where none acts; built at the first call (its defaults come from the membranes' points).
  const std::vector<std::vector<geometry::Vec3>>* repulsion_forces(
      const std::vector<std::vector<solid::QuadratureData>>& q);
  /// The fluid's viscosity field from the membranes' current insides (with a contrast; between steps, from
  /// the accepted configuration, like the bodies' current_patch()).
  void update_viscosity();
  /// Elements with s^h != 1, an immersed point, or a viscosity other than the fluid's.
  std::vector<char> active_elements() const;
  fluid::ImmersedFluid& fluid_;
  std::vector<solid::SolidSolver*> bodies_;
  CouplerOptions opt_;
  Locator locator_;
  std::vector<std::vector<Location>> collocation_loc_, quadrature_loc_;  // warm starts, per body
  std::vector<std::vector<char>> quadrature_owned_;  // per body and point: this rank's (update_immersed)
  std::vector<char> scratch_mine_;                   // (update_immersed's dealing: kept storage)
  std::vector<int> scratch_order_, scratch_start_;   // (the counting sort's order and bucket starts)
  std::vector<int> scratch_counts_, scratch_displs_;  // (the exchange of the runs' elements and positions)
  std::vector<double> scratch_send_, scratch_recv_;
  // update_immersed's buffers of this rank's points (kept between calls).
  std::vector<geometry::Index3> scratch_elements_;
  std::vector<geometry::Param> scratch_xi_;
  std::vector<fluid::ImmersedPoint> scratch_data_;
  std::vector<std::vector<solid::QuadratureData>> scratch_q_;
  std::vector<int> scratch_q_begin_, scratch_q_unknown_;
  std::vector<double> scratch_q_grad_;
  fluid::SolidLinearization scratch_lin_;  // (given to the fluid, which gives its old one back)
  std::unique_ptr<Repulsion> repulsion_;
  bool repulsion_checked_ = false;  // repulsion_ built, or found not to apply
  std::vector<std::vector<geometry::Vec3>> contact_x_, contact_force_;
  std::vector<std::vector<double>> contact_area_;
  RepulsionStats repulsion_stats_;
  Vec X_ = nullptr, dX_ = nullptr, F_ = nullptr;
  solid::TimeParameters tp_;
  bool linearization_refused_ = false;  // the fluid takes no SolidLinearization (SolidTangent::collocation)
  std::vector<int> marked_;  // basis functions carrying s_I
  bool contrast_ = false;    // some membrane has an inner viscosity other than the fluid's
  std::vector<int> viscous_;  // basis functions whose viscosity is not the fluid's
  std::unique_ptr<AndersonAcceleration> anderson_;  // with Acceleration::anderson
  std::unique_ptr<CoupledLinearSolver> linear_;
};

}  // namespace cellfsi::coupling
