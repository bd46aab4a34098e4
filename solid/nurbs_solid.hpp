#pragma once
// The paper's immersed solid (Sec. 2.2-2.3): a Lagrangian NURBS patch whose displacement, in the patch's own
// (rational) basis, satisfies the kinematic equation (19) by collocation at the Greville points.
//
// The state lives at the collocation points (displacement and its rate, advanced by generalized-alpha point
// by point, steps 1-2: one d x d Newton solve per point); the control variables follow from them through the
// collocation matrix, solved direction by direction (step 3, solid/collocation_solver.hpp). In a closed
// direction (a membrane around a cell: first and last control layers coincide) those two layers are one
// unknown, and the duplicate Greville point is dropped, so the system stays square. Degenerate points (a
// disk's centre, a sphere's poles) need nothing special: their Greville points coincide in space, receive the
// same velocity, and so move together.
#include <functional>
#include <memory>

#include <Eigen/Sparse>

#include "geometry/patch.hpp"
#include "solid/collocation_solver.hpp"
#include "solid/external_load.hpp"
#include "solid/material.hpp"
#include "solid/solid_solver.hpp"

namespace cellfsi::solid {

class NurbsSolid final : public SolidSolver {
 public:
  /// `reference`: the body in its reference (stress-free) configuration, parametric dimension == physical
  /// dimension; direction 0 runs through a membrane's thickness or from a bulky body's centre (the geometry
  /// builders' convention), which is where interface points are taken. density: rho_2 [g/cm^3].
  NurbsSolid(std::string name, geometry::Patch reference, std::shared_ptr<const Material> material,
             double density);
  /// A thin shell (Kirchhoff-Love, solid/shell_kinematics.hpp) of thickness h [cm] about `mid_surface`, a
  /// surface patch (parametric dimension 2 in 3D): collocated at the mid-surface's Greville points, its
  /// quadrature points at three Gauss heights through the thickness above each of the surface's, where the
  /// law sees the F of shell_point (a membrane surface law in the shell's frame). A membrane; the thickness
  /// is not an unknown. Its parameters for cauchy_stress are those of reference_patch() (direction 0 across
  /// the thickness, over [0, 1]).
  ///
  /// The fluid receives the shell's internal force, not its stress: f_A = -dE / dx_A on the mid-surface's
  /// control points (the energy through the thickness, E = sum W(F) dV), spread as a force density on the
  /// mid-surface, sum_A R_A ftilde_A with M ftilde = f (M the reference mid-surface's mass matrix, factored
  /// once), carried by the middle layer's points as QuadratureData::force (stress zero at every point). The
  /// fluid's power against a velocity in the shell's space is then the energy's rate exactly. A stress at
  /// the points off the mid-surface would pair the bending moment with the fluid's shear across the shell,
  /// which does not turn the shell's normal: the bending would resist nothing the mid-surface does
  /// (measured: the rim creased within 3-5 ms). Every rank evaluates the whole shell (the force at a point
  /// depends on all of its functions' points). The coupling's tangent: the law's at each point
  /// (QuadratureData::tangent; no geometric term). Not yet available: the collocation tangent's basis
  /// gradients (basis_gradients says so: false).
  NurbsSolid(std::string name, geometry::Patch mid_surface, double thickness,
             std::shared_ptr<const Material> material, double density);
  /// The thin shell's thickness [cm] (0: a solid body, the first constructor's).
  double shell_thickness() const { return shell_thickness_; }
  /// The elastic energy at t_n, sum W(F) dV over the quadrature points [erg] (a thin shell's through its
  /// thickness, the energy whose gradient is its internal force).
  double strain_energy() const;

  std::string name() const override { return name_; }
  int dim() const override { return dim_; }
  void begin_step(const TimeParameters& time) override;
  std::vector<Vec3> collocation_points() const override;
  double kinematic_update(const std::vector<VelocitySample>& samples) override;
  double kinematic_update(const std::vector<VelocitySample>& samples, const KinematicShare& share) override;
  std::vector<QuadratureData> quadrature_data(double fluid_density, bool with_tangent) const override;
  using SolidSolver::quadrature_data;
  void quadrature_data(double fluid_density, bool with_tangent,
                       const std::function<bool(std::size_t, const Vec3&)>& wanted,
                       std::vector<QuadratureData>& out,
                       const std::vector<char>* only = nullptr) const override;
  std::vector<Vec3> interface_points() const override;
  using SolidSolver::control_increment;
  bool control_increment(const std::vector<Vec3>& dv, Eigen::MatrixXd& dc, int column) const override;
  double control_increment_operations() const override;
  int n_control() const override { return n_reduced_; }
  bool basis_gradients(std::vector<int>& begin, std::vector<int>& unknown, std::vector<double>& grad,
                       const std::vector<char>* wanted = nullptr) const override;
  /// quadrature_data() into out[0, n_quadrature_points()) (`only`: null, or n_quadrature_points() flags), and
  /// basis_gradients() appended to begin (not empty: its last entry is where this body's list starts),
  /// unknown (each plus unknown_offset) and grad; listed_entries: what that appends to unknown. For a body of
  /// several patches (CompositeSolid), which writes its parts' runs in place: at a 3D red cell of six patches
  /// copying them through buffers of their own, made at each call, was an eighth of the run (perf).
  void quadrature_data_into(double fluid_density, bool with_tangent,
                            const std::function<bool(std::size_t, const Vec3&)>& wanted, QuadratureData* out,
                            const char* only) const;
  bool append_basis_gradients(std::vector<int>& begin, std::vector<int>& unknown, std::vector<double>& grad,
                              const char* wanted, int unknown_offset) const;
  std::size_t listed_entries(const char* wanted) const;
  void end_step() override;

  /// Sets the displacement rate at the collocation points (e.g. the fluid velocity there at t = 0, so the
  /// first step starts consistent); the displacement stays as it is.
  void set_rate(const std::vector<Vec3>& rate) override;
  /// u_n, rate_n (collocation points) and the control variables at t_n, row by row.
  std::vector<double> state() const override;
  void set_state(const std::vector<double>& state) override;

  bool is_membrane() const override { return membrane_; }
  /// A thin shell's: the shell as a solid shell's patch (direction 0 linear across the thickness over [0, 1],
  /// its two control layers the mid-surface's control points -+ h/2 lambda3 n at their Greville points),
  /// whose mid-surface is the shell's exactly and whose faces only approximate the offset surfaces, so that
  /// the metrics and the output read it as they read a solid shell.
  geometry::Patch reference_patch() const override;
  geometry::Patch current_patch() const override;
  std::vector<Mat3> cauchy_stress(const std::vector<geometry::Param>& xi) const override;

  /// External loads (solid/external_load.hpp), replacing any earlier ones: each force spread over the
  /// quadrature points of its patch, carried by quadrature_data() as QuadratureData::force. ramp > 0: the
  /// forces grow linearly from 0 at t = 0 to their full size at t = ramp [s], evaluated at the step's
  /// t_{n+alpha_f} (TimeParameters::t_n); 0: in full from the start. Throws std::invalid_argument when a
  /// patch holds no quadrature point, two patches overlap or ramp < 0.
  void set_loads(const std::vector<PatchLoad>& loads, double ramp = 0);
  /// The loads as densities per unit reference volume at the quadrature points, in quadrature_data()'s order
  /// (empty: none), and their ramp (set_loads'); a body of several patches spreads its loads over all of its
  /// parts' points (CompositeSolid::set_loads). Throws std::invalid_argument for another count or ramp < 0.
  void set_load_densities(std::vector<Vec3> density, double ramp);
  /// The quadrature points in the reference configuration and their reference volume weights, in
  /// quadrature_data()'s order.
  void reference_quadrature(std::vector<Vec3>& X, std::vector<double>& w) const;
  /// The loads' share of their full size in the current step (1 without a ramp; with one, 0 before the first
  /// step).
  double load_factor() const;
  /// The external force per unit reference volume at each quadrature point, in quadrature_data()'s order
  /// [dyn/cm^3] (empty: no load).
  const std::vector<Vec3>& load_densities() const { return load_density_; }

  int n_points() const { return static_cast<int>(reference_points_.size()); }
  /// The quadrature points' count (quadrature_data()'s size).
  int n_quadrature_points() const { return static_cast<int>(q_X_.size()); }
  /// Step 3's solver (whether it goes direction by direction, or why not).
  const CollocationSolver& collocation_solver() const { return *collocation_solver_; }
  const std::vector<Vec3>& reference_points() const { return reference_points_; }
  const geometry::Patch& reference() const { return reference_; }

  /// Step 3 and its inverse, on values at the collocation points (n_points x dim): control variables (one row
  /// per reduced control point) and back.
  Eigen::MatrixXd control_from_points(const Eigen::MatrixXd& point_values) const;
  Eigen::MatrixXd points_from_control(const Eigen::MatrixXd& control) const;

  /// The kinematic residual at one collocation point, R = udot_{n+alpha_m} - v(x_{n+alpha_f}), as a function
  /// of the point's displacement u at t_{n+1}; and its tangent (alpha_m / (gamma dt)) I - alpha_f grad v
  /// (docs/design.md §3). Pure functions, tested against finite differences.
  static Vec3 kinematic_residual(const Vec3& u, const Vec3& u_n, const Vec3& rate_n, const TimeParameters& t,
                                 const Vec3& v);
  static Mat3 kinematic_tangent(const TimeParameters& t, const Mat3& grad_v, int dim);

 private:
  Eigen::MatrixXd displacement_control_alpha() const;  // control variables at t_{n+alpha_f}
  /// The text appended to an inverted element's error: the body, the element, the point and the stretches.
  std::string where_inverted(const geometry::Index3& element, const geometry::Param& xi, const Vec3& x,
                             const Mat3& F) const;
  /// Position and deformation gradient at xi for displacement control variables c; frame (if given): a 3D
  /// membrane's reference frame there (T1, T2, N, for a membrane surface law), else the identity.
  void kinematics(const Eigen::MatrixXd& c, const geometry::Param& xi, const geometry::Index3* element,
                  Vec3& x, Mat3& F, double& ref_jacobian, Mat3* frame = nullptr) const;
  /// The quadrature points in their fixed order (elements in turn, Gauss points within each): index,
  /// position, deformation gradient for displacement control variables c, and reference volume weight.
  /// only (if not null, one flag per point): the points not flagged are not evaluated.
  void for_each_quadrature_point(const Eigen::MatrixXd& c,
                                 const std::function<void(int, const Vec3&, const Mat3&, double)>& visit,
                                 const std::vector<char>* only = nullptr) const;
  void for_each_quadrature_point(const Eigen::MatrixXd& c,
                                 const std::function<void(int, const Vec3&, const Mat3&, double)>& visit,
                                 const char* only) const;  // (only: null or n_quadrature_points() flags)
  std::string name_;
  geometry::Patch reference_;
  std::shared_ptr<const Material> material_;
  double density_;
  int dim_;
  bool membrane_ = false;  // both faces of direction 0 are interfaces
  TimeParameters time_;
  std::vector<int> reduced_;  // control index -> reduced unknown
  int n_reduced_ = 0;
  std::vector<Vec3> reference_points_;  // collocation points in the reference configuration
  std::vector<geometry::Param> point_xi_;
  std::vector<int> face_points_;  // collocation points on interface faces
  std::unique_ptr<const CollocationSolver> collocation_solver_;  // step 3 (its own file says how)
  Eigen::MatrixXd u_, u_n_, rate_n_;  // at the collocation points (n_points x dim)
  Eigen::MatrixXd c_, c_n_;           // control variables (n_reduced x dim)
  // The inverse of the last kinematic_update()'s tangent at each collocation point (control_increment, which
  // runs at every product of the coupled Krylov solve).
  std::vector<Mat3> kinematic_inverse_;
  std::vector<double> kinematic_packed_;  // kinematic_update's exchange of a share's points
  std::vector<Vec3> load_density_;    // external force per reference volume at the quadrature points
  double load_ramp_ = 0;              // [s]: the loads grow from 0 to full over it (0: full at once)
  bool stepping_ = false;  // a step has begun (time_ is a step's, not the constructor's placeholder)
  // The quadrature points' reference data, tabulated once (the basis at a fixed parametric point does not
  // change, only the control variables do), so that for_each_quadrature_point, at every coupling iteration,
  // only sums: point q's functions are [q_begin_[q], q_begin_[q + 1]) of q_unknown_ (reduced unknown), q_N_
  // (value) and q_dN_ (d / dX, dim_ per function, in the reference configuration).
  std::vector<int> q_begin_, q_unknown_;
  std::vector<double> q_N_, q_dN_, q_weight_;  // q_weight_: Gauss weight times |det dX / dxi|
  std::vector<double> q_area_;  // a membrane's: q_weight_ over the thickness there (QuadratureData::area)
  std::vector<Vec3> q_X_;                      // reference position
  std::vector<Mat3> q_frame_;  // a membrane surface law's reference frame (T1, T2, N; else empty)
  void tabulate_quadrature();
  void set_up();  // (both constructors' common part, after the members are set)
  // A thin shell's tables (shell_thickness_ > 0): per surface quadrature point s, its functions [s_begin_[s],
  // s_begin_[s + 1]) of s_unknown_ and s_basis_ (6 values each: R, dR / dtheta_0, dR / dtheta_1 and the
  // second derivatives 00, 01, 11) and the reference mid-surface's map values; quadrature point q = s *
  // layers + l at height s_zeta_[l].
  double shell_thickness_ = 0;
  std::vector<int> s_begin_, s_unknown_;
  std::vector<double> s_basis_, s_zeta_;
  std::vector<geometry::MapValues> s_ref_;
  std::vector<double> s_area_;  // the reference mid-surface's area element times the Gauss weight
  std::unique_ptr<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>> s_mass_;  // M, factored
  void tabulate_shell_quadrature();
  /// The text appended to a thin shell's inverted point's error: surface point s, layer l, at x.
  std::string shell_where(int s, int l, const Vec3& x) const;
  /// The thin shell's quadrature_data_into (the force-based coupling above).
  void shell_quadrature_data(double fluid_density, bool with_tangent,
                             const std::function<bool(std::size_t, const Vec3&)>& wanted, QuadratureData* out,
                             const char* only) const;
  geometry::Patch shell_as_thick_patch(const Eigen::MatrixXd& c) const;  // (c: control displacements)
  void for_each_shell_point(const double* rows,
                            const std::function<void(int, const Vec3&, const Mat3&, double)>& visit,
                            const char* only) const;
};

}  // namespace cellfsi::solid
