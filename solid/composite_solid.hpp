#pragma once
// A body made of several NURBS patches (a membrane without poles: geometry::biconcave_rbc_3d_faces), one
// NurbsSolid per patch, presented to the coupling as one body: its points, quadrature data and control
// unknowns are the parts' in turn. The parts need no gluing: where two parts share an edge their collocation
// points coincide, get the same fluid velocity and so move together (as the points at a polar patch's pole
// do), and a part's control points on its boundary follow from its points there alone (open knot vectors), so
// the parts stay joined to round-off. As one body, the contact repulsion and the placement checks treat the
// parts as one membrane.
#include <memory>
#include <vector>

#include "solid/nurbs_solid.hpp"

namespace cellfsi::solid {

class CompositeSolid final : public SolidSolver {
 public:
  /// parts: at least one, all of one dimension and all membranes or all bulky.
  CompositeSolid(std::string name, std::vector<std::unique_ptr<NurbsSolid>> parts);

  std::string name() const override { return name_; }
  int dim() const override { return parts_[0]->dim(); }
  void begin_step(const TimeParameters& time) override;
  std::vector<Vec3> collocation_points() const override;
  double kinematic_update(const std::vector<VelocitySample>& samples) override;
  /// Every rank that holds the body updates every part (the share's split is not used).
  double kinematic_update(const std::vector<VelocitySample>& samples, const KinematicShare& share) override;
  std::vector<QuadratureData> quadrature_data(double fluid_density, bool with_tangent) const override;
  using SolidSolver::quadrature_data;
  void quadrature_data(double fluid_density, bool with_tangent,
                       const std::function<bool(std::size_t, const Vec3&)>& wanted,
                       std::vector<QuadratureData>& out,
                       const std::vector<char>* only = nullptr) const override;
  using SolidSolver::control_increment;
  bool control_increment(const std::vector<Vec3>& dv, Eigen::MatrixXd& dc, int column) const override;
  double control_increment_operations() const override;
  int n_control() const override { return control_begin_.back(); }
  bool basis_gradients(std::vector<int>& begin, std::vector<int>& unknown, std::vector<double>& grad,
                       const std::vector<char>* wanted = nullptr) const override;
  std::vector<Vec3> interface_points() const override;
  void end_step() override;
  void set_rate(const std::vector<Vec3>& rate) override;
  std::vector<double> state() const override;
  void set_state(const std::vector<double>& state) override;
  bool is_membrane() const override { return parts_[0]->is_membrane(); }
  /// One patch cannot describe the body: these throw std::logic_error (use the parts' patches).
  geometry::Patch reference_patch() const override;
  geometry::Patch current_patch() const override;
  std::vector<geometry::Patch> reference_patches() const override;
  std::vector<geometry::Patch> current_patches() const override;
  /// At parametric points of the first part (the output asks each part: part(k).cauchy_stress).
  std::vector<Mat3> cauchy_stress(const std::vector<geometry::Param>& xi) const override;

  /// External loads over the whole body (NurbsSolid::set_loads, each force spread over the points of all
  /// parts within its radius, so a contact patch may straddle a seam). Throws as NurbsSolid::set_loads.
  void set_loads(const std::vector<PatchLoad>& loads, double ramp = 0);
  int n_parts() const { return static_cast<int>(parts_.size()); }
  const NurbsSolid& part(int k) const { return *parts_[k]; }
  NurbsSolid& part(int k) { return *parts_[k]; }

 private:
  /// Splits a per-point vector (collocation points) into the parts' runs.
  template <class T>
  std::vector<T> run(const std::vector<T>& all, int k) const {
    return std::vector<T>(all.begin() + point_begin_[k], all.begin() + point_begin_[k + 1]);
  }
  std::string name_;
  std::vector<std::unique_ptr<NurbsSolid>> parts_;
  std::vector<int> point_begin_, quadrature_begin_, control_begin_;  // each part's first index, and the total
};

}  // namespace cellfsi::solid
