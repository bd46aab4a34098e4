#pragma once
// The divergence-conforming fluid (fluid/div_conforming/: Evans-Hughes B-splines, Galerkin, pointwise
// divergence-free velocity) behind the fluid interface (fluid/immersed_fluid.hpp): what create_fluid makes
// for -fluid_space div_conforming.
//
// What it maps, and how:
//   * the patch: an axis-aligned box (geometry::affine_map), whose elements are the space's, numbered alike,
//     the coupler's parametric points becoming physical ones through the affine map; or any other patch
//     with uniform elements (the narrowing channel) through the contravariant Piola map
//     (DivConformingSpace::mapped): the coupler's parametric points are then the space's own (scaled)
//     coordinates, physical points are found by NURBS inversion, and the coupled solve assembles the whole
//     tangent with the pressure pinned (no bulk inverse: the domain is not translation-invariant; the
//     default PC is then PETSc's ASM with MUMPS on its blocks, one exact LU on one rank).
//   * the unknowns: the space's (velocity components, then pressure), in DivConformingFluid's PETSc
//     numbering; no node blocks (block_layout() is empty, so cellfsi_fourier and cellfsi_band do not apply).
//     The coupled solve uses PC type cellfsi_bulk with bulk_inverse(): the DFT inverse of the operator
//     without the cells (periodic in x, and in 3D in z).
//   * s^h: none. The velocity is divergence-free pointwise, so a cell keeps its volume without the interface
//     scaling; set_scaling is ignored and uses_interface_scaling() is false (the app refuses -s_interface).
//   * the viscosity field by the patch's control points: the pressure space (degree k', C^(k'-1)) is the
//     patch's own spline space when the patch has degree k' (-fluid_degree = -fluid_dc_degree), and the
//     field's values are then its coefficients; other degrees are refused where a field is set.
//   * the pressure: one pressure unknown is pinned during a step (a unit row) and the pressure is shifted to
//     zero mean after it, so options().pressure_null_space is false.
//   * the coupled Jacobian: its bulk part kept from the first iterate, the immersed points' tangent added at
//     each refresh (bulk_matrix_ below); or, as bulk_inverse()'s stencil_operator (-coupling_bulk_stencil),
//     a MATSHELL named cellfsi_dc_stencil: the bulk part applied by the bulk inverse's own stencil
//     (DcFourierSolver::multiply, no matrix) plus an assembled matrix of the immersed points' tangent alone
//     (over the unknowns of the elements that hold points alone, its rows dealt out evenly among the ranks,
//     its pattern counted exactly by DivConformingFluid::create_immersed_matrix whenever those elements
//     change).
//   * the region hooks of the equal-order solvers (jacobian_part, jacobian_add_part, region_unknowns) do
//     not apply: they throw std::logic_error.
// State: replicated on every rank (DivConformingFluid's; fluid/div_conforming/README.md says what a real
// partition needs). Output: one .vts per time written by rank 0.
#include <memory>

#include "fluid/div_conforming/dc_fluid.hpp"
#include "fluid/div_conforming/dc_fourier.hpp"
#include "fluid/immersed_fluid.hpp"
#include "geometry/inversion.hpp"

namespace cellfsi::fluid {

class DcImmersedFluid final : public ImmersedFluid {
 public:
  /// Throws std::invalid_argument (naming -fluid_space) for a patch the space cannot take (elements not
  /// uniform in the parameters).
  DcImmersedFluid(MPI_Comm comm, const geometry::Patch& patch, const FluidOptions& options);
  ~DcImmersedFluid() override;

  MPI_Comm comm() const override { return comm_; }
  int dim() const override { return space_->dim(); }
  const geometry::Patch& patch() const override { return patch_; }
  const FluidOptions& options() const override { return options_; }
  std::optional<BlockLayout> block_layout() const override { return std::nullopt; }
  std::vector<int> unknown_kinds() const override;

  void set_initial_velocity(const std::function<Vec3(const Vec3&)>& v0) override;
  void project_initial_velocity(const std::function<Vec3(const Vec3&)>& v0) override {
    set_initial_velocity(v0);  // (the space's interpolant is already its L2 projection)
  }
  void setup() override {}
  StepStats step() override;
  double time() const override { return fluid_->time(); }
  int steps_taken() const override { return fluid_->steps_taken(); }
  Vec solution() const override { return U_; }

  std::vector<PointSample> sample(const std::vector<Vec3>& points) const override;
  std::vector<PointSample> sample_alpha(Vec X, const std::vector<geometry::Index3>& elements,
                                        const std::vector<geometry::Param>& xi) const override;
  SectionData section(double u, int n_profile = 33) const override;

  bool owns_element(const geometry::Index3& e) const override;
  /// True: DivConformingFluid assembles a point in any element (the state is on every rank).
  bool assembles_points_anywhere() const override { return true; }
  bool samples_anywhere() const override { return true; }
  void set_immersed_points(const std::vector<geometry::Index3>& elements, const std::vector<geometry::Param>& xi,
                           const std::vector<ImmersedPoint>& data) override;
  bool set_solid_linearization(SolidLinearization& lin) override;
  void set_scaling(const std::function<double(int node)>&) override {}  // no s^h on this space
  void set_viscosity(const std::function<double(int node)>& mu) override;
  void begin_step(Vec X) override;
  void residual(Vec X, Vec F) override;
  void jacobian(Vec X, Mat J) override;
  void jacobian_part(Vec, Mat, const std::vector<char>&, bool) override;
  void jacobian_add_part(Vec, Mat, const std::vector<char>&) override;
  void bulk_jacobian(Vec X, Mat J) override;
  void end_step(Vec X) override;
  std::vector<PetscInt> region_unknowns(const std::vector<char>&) const override;
  /// The fluid's matrix, made at the first call (DivConformingFluid::matrix): a run with the bulk stencil
  /// (-coupling_bulk_stencil, the default of cellfsi_bulk) never asks for it.
  Mat jacobian_matrix() const override { return fluid_->matrix(); }
  void release_jacobian_matrix() override { fluid_->release_matrix(); }
  Mat jacobian_matrix_if_made() const override { return fluid_->matrix_made() ? fluid_->matrix() : nullptr; }
  bool jacobian_is_blocked() const override { return false; }  // (AIJ; asked without making the matrix)
  std::optional<OwnBulkInverse> bulk_inverse(Vec X) override;
  bool has_bulk_inverse() const override {
    return !space_->is_mapped() && space_->periodic(0) && (dim() == 2 || space_->periodic(2));
  }
  bool uses_interface_scaling() const override { return false; }
  std::optional<double> max_divergence_ratio() const override;

  std::string write_fields(const std::string& dir, const std::string& stem, int samples_per_element,
                           const std::function<Vec3(const Vec3&)>& undisturbed) const override;
  std::string state_bytes() const override;
  LoadedState load_state(PetscViewer viewer, int steps) override;

  /// The discretisation behind the face (tests, the divergence history for summary.json).
  const dc::DivConformingFluid& discretisation() const { return *fluid_; }
  /// How many stencil products were taken from the bulk inverse's last right-hand side (stencil_mult).
  long stencil_products_skipped() const { return products_skipped_; }

 private:
  /// The space's point of the patch's parametric point xi: physical on a box, the scaled parameters on a
  /// mapped space (DivConformingSpace::from_patch_parameters).
  Vec3 space_point(const geometry::Param& xi) const;
  /// Where a physical point lies: found, and the space's point (by the affine map or by inversion, started
  /// from *warm's element if it was found, and set to this point's result).
  bool locate(const Vec3& x, Vec3& s, geometry::InversionResult* warm = nullptr) const;
  /// section() on a mapped space.
  SectionData section_mapped(double u, int n_profile) const;
  /// The fields of coefficients c at a point in the space's coordinates (inside; in `element` as it is if
  /// given, else in the element that holds it, periodic coordinates wrapped); eb then holds its basis,
  /// eb.x[0] the physical point.
  PointSample at_space_point(const std::vector<double>& c, const std::vector<double>* rate, const Vec3& at,
                             dc::ElementBasis& eb, const geometry::Index3* element = nullptr) const;
  /// The fields of coefficients c (natural numbering) at physical points (found false outside the box).
  std::vector<PointSample> evaluate(const std::vector<double>& c, const std::vector<double>* rate,
                                    const std::vector<Vec3>& points) const;
  void sync_solution();  // U_ from the discretisation's state

  MPI_Comm comm_;
  const geometry::Patch& patch_;
  FluidOptions options_;
  Vec3 offset_ = Vec3::Zero(), scale_ = Vec3::Zero();  // the patch's affine map x = offset + scale xi
  std::unique_ptr<geometry::PointInverter> inverter_;  // (a mapped space)
  std::unique_ptr<dc::DivConformingSpace> space_;
  std::unique_ptr<dc::DivConformingFluid> fluid_;
  Vec U_ = nullptr;
  mutable std::vector<double> work_;       // an iterate in the natural numbering (gather_iterate*)
  mutable PetscObjectId gathered_id_ = 0;  // work_'s vector and its state (PETSc's ids start at 1)
  mutable PetscObjectState gathered_state_ = -1;
  /// What work_ holds of that iterate: every unknown, or the parts of DivConformingFluid::gather_part
  /// gathered for it (with their elements).
  mutable bool gathered_whole_ = false;
  mutable std::array<bool, 2> gathered_part_{false, false};
  mutable std::array<std::vector<int>, 2> gathered_elements_;
  /// Every unknown of X into work_, unless it holds them already. (Every rank decides alone whether to skip
  /// the gather, which is collective: every write to an iterate must happen on every rank, as the coupling
  /// loop's do.)
  void gather_iterate(Vec X) const;
  /// A part of X into work_ (DivConformingFluid::gather_part): the unknowns this rank reads for its residual
  /// and points' tangent (kAssemblyPart, its points' elements) or for its samples (kSamplePart), unless work_
  /// holds them already on every rank. What a coupling iteration gathers: a share of the unknowns per rank,
  /// where gather_iterate moves every unknown to every rank. Collective.
  void gather_iterate_part(Vec X, int part, const std::vector<int>& elements) const;
  std::vector<dc::DivConformingFluid::ImmersedAt> points_;  // set_immersed_points' (kept storage)
  std::unique_ptr<dc::DcFourierSolver> bulk_;
  /// The coupled Jacobian's bulk part (no immersed points), assembled at the first jacobian() and kept: each
  /// jacobian() copies it and adds the immersed points' tangent (DivConformingFluid::step_tangent_from).
  /// Newton's direction then misses the bulk's change with the flow (terms of the order of Re ~ 1e-4 in the
  /// paper's flows); the residual, and so the solution, is exact. With a viscosity field (a contrast, which
  /// moves with the cells) the whole tangent is assembled instead.
  Mat bulk_matrix_ = nullptr;
  /// bulk_inverse()'s stencil_operator (see the header comment), its immersed part, and whether it applies
  /// the whole assembled tangent instead (a viscosity field: the bulk is not the stencil's).
  Mat stencil_op_ = nullptr;
  /// The immersed points' tangent, over the unknowns it touches, its rows dealt out evenly.
  dc::DivConformingFluid::ImmersedMatrix immersed_;
  std::vector<int> pattern_elements_;  // this rank's elements with points when immersed_'s pattern was made
  bool op_assembled_ = false;
  std::vector<double> x_nat_, y_nat_;  // the operator's product in the natural numbering
  /// The bulk inverse's last application, z = S^{-1} v: v (a copy), z's id and z's state then. stencil_mult
  /// takes v for S z when it multiplies that z unchanged (right preconditioning: FGMRES's every product).
  Vec applied_rhs_ = nullptr;
  PetscObjectId applied_id_ = 0;  // (PETSc's object ids start at 1)
  PetscObjectState applied_state_ = -1;
  long products_skipped_ = 0;
  static PetscErrorCode stencil_mult(Mat A, Vec x, Vec y);
  void refresh_stencil_operator(Vec X);
  /// The solids' stiffness through their collocation (set_solid_linearization), in the stencil operator
  /// only: the velocity at the collocation points from the natural-numbered iterate (rows 3 per point,
  /// coefficients times alpha_f), the bodies' control increments from it (solid_.control), and each element's
  /// block of DivConformingFluid::solid_blocks. Empty: the points carry their own consistent tangent.
  SolidLinearization solid_;
  bool solid_given_ = false;
  // this rank's run of the rows (colloc_displs_[rank] on); colloc_index_: places in colloc_x_
  std::vector<int> colloc_begin_, colloc_index_;
  std::vector<int> colloc_counts_, colloc_displs_;  // each rank's run of the rows
  std::size_t colloc_rows_ = 0;                     // every rank's (3 per collocation point)
  std::vector<double> colloc_value_;
  std::vector<dc::DivConformingFluid::SolidBlock> solid_blocks_;
  std::vector<double> dv_, dc_, block_x_, block_y_;
  void build_solid_operator();
  void add_solid_product(Vec x, Vec y);
  VecScatter colloc_scatter_ = nullptr;  // the fluid's vectors at the unknowns the collocation rows read
  Vec colloc_x_ = nullptr;
};

}  // namespace cellfsi::fluid
