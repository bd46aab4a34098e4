#pragma once
// The SolidSolver interface: everything the coupling layer may ask of an immersed solid body, in plain data
// (points, weights, tensors, values). A second implementation (another membrane model, a shell) plugs in
// without touching fluid/ or coupling/.
//
// One time step of the paper's block-iterative scheme (Sec. 2.3), as the coupling layer drives it:
//   begin_step(time) -> repeat { collocation_points() -> [fluid samples v, grad v there] ->
//   kinematic_update() (steps 1-3) -> quadrature_data(), interface_points() -> [fluid assembles and solves] }
//   -> end_step().
#include <array>
#include <cstddef>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "common/generalized_alpha.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::solid {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

/// Generalized-alpha parameters shared with the fluid (docs/design.md §3), and the time t_n at the step's
/// start (for a load that changes in time: the stretching force's ramp).
struct TimeParameters : GeneralizedAlpha {
  double t_n = 0;
  TimeParameters() = default;
  TimeParameters(const GeneralizedAlpha& a, double t) : GeneralizedAlpha(a), t_n(t) {}
  static TimeParameters from_rho_inf(double rho_inf, double dt, double t = 0) {
    return {GeneralizedAlpha::from_rho_inf(rho_inf, dt), t};
  }
};

/// The fluid velocity and its gradient at one point (grad_v(i, j) = d v_i / d x_j).
struct VelocitySample {
  Vec3 v = Vec3::Zero();
  Mat3 grad_v = Mat3::Zero();
};

/// How the ranks that hold a body share its kinematic update (the coupler's fluid ranks, where the fluid
/// samples anywhere and every rank has every sample): rank `part` of `parts` updates its run of the points
/// (from n part / parts on) and solves the collocation columns c with (first_column + c) % parts == part
/// (first_column: the columns of the bodies updated before this one, so that the bodies' columns are dealt
/// out in turn). `gather` fills every rank's run of an array of `width` values per point in place from the
/// rank that holds it; `sum` adds an array over the ranks in place, the same bits on every rank.
/// `operations`, if given, gets an estimate of this rank's operations (-log_view's counts). The default: one
/// rank does all.
struct KinematicShare {
  int part = 0;
  int parts = 1;
  int first_column = 0;
  std::function<void(double* values, int width)> gather;
  std::function<void(double* values, int n)> sum;
  double* operations = nullptr;
};

/// One solid quadrature point as the fluid needs it (paper Eq. (10), and an external load on the body).
struct QuadratureData {
  Vec3 x = Vec3::Zero();       // current position (at t_{n+alpha_f})
  double weight = 0;           // quadrature weight in the reference configuration
  Mat3 stress = Mat3::Zero();  // (1/rho_1) F S F^T, symmetric
  double beta = 0;             // 1 - rho_2 / rho_1
  double shear_modulus = 0;    // of the linearised material (for the coupling's isotropic tangent)
  /// (1/rho_1) the spatial tangent of the Kirchhoff stress F S F^T in Voigt form (Material::spatial_tangent),
  /// its upper triangle row by row, for the coupling's consistent tangent (-coupling_solid_tangent
  /// consistent); a solver that leaves has_tangent false gets the isotropic one from shear_modulus.
  bool has_tangent = false;
  std::array<double, 21> tangent{};
  Vec3 force = Vec3::Zero();   // (1/rho_1) external force per unit reference volume (solid/external_load.hpp)
  /// A membrane's point: its share of the reference mid-surface area (in 2D, length), weight / thickness, so
  /// that the points through the thickness of a column sum to the column's area (the contact repulsion's
  /// weight, coupling/repulsion.hpp). 0: a bulky body's point, which takes no part in it.
  double area = 0;
};

class SolidSolver {
 public:
  virtual ~SolidSolver() = default;
  virtual std::string name() const = 0;
  virtual int dim() const = 0;

  /// Starts a step: the state at t_n is kept, the unknown displacement at t_{n+1} predicted (same velocity).
  virtual void begin_step(const TimeParameters& time) = 0;
  /// Where the fluid velocity is needed: the collocation points at t_{n+alpha_f}.
  virtual std::vector<Vec3> collocation_points() const = 0;
  /// Steps 1-3: one Newton update of the kinematic equation (19) from the velocity at the collocation points.
  /// Returns the L2 norm of the kinematic residual R_K before the update.
  virtual double kinematic_update(const std::vector<VelocitySample>& samples) = 0;
  /// The same, shared among the ranks that hold the body (collective over them when parts > 1; every rank
  /// ends with the same state). The default does it all on every rank.
  virtual double kinematic_update(const std::vector<VelocitySample>& samples, const KinematicShare& share) {
    (void)share;
    return kinematic_update(samples);
  }
  /// The Eq. (10) data at the solid's quadrature points (configuration at t_{n+alpha_f}). with_tangent: also
  /// the spatial tangent (QuadratureData::has_tangent and tangent), which only an assembly of the coupling's
  /// Jacobian reads; the coupler asks for it at the iterations that may assemble one (a step's first).
  virtual std::vector<QuadratureData> quadrature_data(double fluid_density, bool with_tangent) const = 0;
  /// quadrature_data() with the material only where it is wanted, into `out` (resized to every point; its
  /// storage is kept between calls: at 64^3 the bodies' data are about 90 MB, and a fresh vector at every
  /// coupling iteration was that many page faults). `wanted(q, x)` is called once per evaluated point, in
  /// order, with its index and current position (the coupler locates the point there and answers whether
  /// this fluid rank owns it). A wanted point gets everything; the others carry x, weight, beta and area
  /// alone (stress, tangent and load zero, has_tangent false), and are still checked for an inverted
  /// element, so that every rank that evaluates a point refuses the same configuration. only (if not null,
  /// one flag per point): the points not flagged are not evaluated at all (out[q] keeps what it held; the
  /// caller makes a refusal collective). The default computes every point in full (a solver that cannot skip
  /// one, e.g. a remote body).
  virtual void quadrature_data(double fluid_density, bool with_tangent,
                               const std::function<bool(std::size_t, const Vec3&)>& wanted,
                               std::vector<QuadratureData>& out,
                               const std::vector<char>* only = nullptr) const {
    out = quadrature_data(fluid_density, with_tangent);
    if (only && only->size() != out.size())
      throw std::logic_error("body '" + name() + "': " + std::to_string(only->size()) + " point flags for " +
                             std::to_string(out.size()) + " quadrature points");
    for (std::size_t i = 0; i < out.size(); ++i)
      if (!only || (*only)[i]) wanted(i, out[i].x);
  }
  /// The same, returned.
  std::vector<QuadratureData> quadrature_data(
      double fluid_density, bool with_tangent,
      const std::function<bool(std::size_t, const Vec3&)>& wanted) const {
    std::vector<QuadratureData> q;
    quadrature_data(fluid_density, with_tangent, wanted, q);
    return q;
  }
  /// The linearised steps 2-3, for a coupled Jacobian that follows the body's own interpolation
  /// (-coupling_solid_tangent collocation): the displacement control at t_{n+alpha_f} changes by dc
  /// (n_control() rows, one per control unknown, dim() columns) when the velocity at the collocation points
  /// (their order) changes by dv, through the last kinematic_update()'s tangent. False: this solver cannot
  /// say (the coupling then uses the consistent tangent for it).
  /// column >= 0: that column of dc alone (each column is a collocation solve of its own; the others are
  /// zero), so that the coupler can deal the columns out among the ranks.
  virtual bool control_increment(const std::vector<Vec3>& dv, Eigen::MatrixXd& dc, int column) const {
    (void)dv, (void)dc, (void)column;
    return false;
  }
  bool control_increment(const std::vector<Vec3>& dv, Eigen::MatrixXd& dc) const {
    return control_increment(dv, dc, -1);
  }
  /// An estimate of the operations of control_increment for one column (-log_view's counts; 0: not known).
  virtual double control_increment_operations() const { return 0; }
  /// The control unknowns behind control_increment (0 where it is not available).
  virtual int n_control() const { return 0; }
  /// Each quadrature point's functions, in quadrature_data()'s order, at t_{n+alpha_f}: point q's are
  /// [begin[q], begin[q + 1]) of `unknown` (the control unknown, a row of control_increment's dc) and `grad`
  /// (3 values each: the spatial gradient d N / d x, zero beyond dim()). `wanted` (if not null, one flag per
  /// point): only the flagged points are listed, in order (begin then has one entry per flagged point, and
  /// one more). False: not available.
  virtual bool basis_gradients(std::vector<int>& begin, std::vector<int>& unknown, std::vector<double>& grad,
                               const std::vector<char>* wanted = nullptr) const {
    (void)begin, (void)unknown, (void)grad, (void)wanted;
    return false;
  }
  /// Points on the fluid-solid interface (both faces of a membrane, the boundary of a bulky body) at
  /// t_{n+alpha_f}, for marking s^h.
  virtual std::vector<Vec3> interface_points() const = 0;
  /// Accepts the displacement at t_{n+1}.
  virtual void end_step() = 0;
  /// Sets the displacement rate at the collocation points (before the first step: the fluid velocity there,
  /// so the first step starts consistent).
  virtual void set_rate(const std::vector<Vec3>& rate) = 0;
  /// The accepted state at t_n as plain numbers (for a checkpoint; valid between steps), and its restoration
  /// into a body built from the same scene (throws std::invalid_argument if the numbers do not fit it).
  virtual std::vector<double> state() const = 0;
  virtual void set_state(const std::vector<double>& state) = 0;

  // Measures and output (plain data; valid between steps).
  /// True for a membrane (direction 0 runs through a thin wall around an enclosed fluid), false for a bulky
  /// body.
  virtual bool is_membrane() const = 0;
  /// The body in its reference configuration and at t_{n+1} (after end_step: the accepted state), as patches
  /// with the same knots.
  virtual geometry::Patch reference_patch() const = 0;
  virtual geometry::Patch current_patch() const = 0;
  /// The same as a list: one patch, or a body's parts (solid/composite_solid.hpp), in their order.
  virtual std::vector<geometry::Patch> reference_patches() const { return {reference_patch()}; }
  virtual std::vector<geometry::Patch> current_patches() const { return {current_patch()}; }
  /// Cauchy stress sigma = J^{-1} F S F^T [dyn/cm^2] of the accepted state at parametric points (for output:
  /// NaN where F is undefined or inverted).
  virtual std::vector<Mat3> cauchy_stress(const std::vector<geometry::Param>& xi) const = 0;
};

}  // namespace cellfsi::solid
