// The coupling loop through fluid::ImmersedFluid alone, as preCICE's solver dummies drive its adapters: a fake
// fluid (no discretisation behind it, no header of one included: tests/check_fluid_interface.cmake checks)
// whose flow is a uniform velocity U everywhere and whose residual is X - X* with the identity as Jacobian.
// A stiff disk in it must translate rigidly with U, and the coupler must hand the fake everything the
// interface promises: the immersed points, the s^h marking, a predicted iterate and the accepted one.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "common/petsc_error.hpp"
#include "coupling/fsi_coupler.hpp"
#include "fluid/immersed_fluid.hpp"
#include "geometry/builders.hpp"
#include "solid/nurbs_solid.hpp"

using namespace cellfsi;
using geometry::Vec3;

namespace {

/// A fluid that flows at `velocity` everywhere and whose coupled residual is X - X* (X*: every unknown
/// `target`), with an identity Jacobian; it counts what the coupler hands it.
class FakeFluid final : public fluid::ImmersedFluid {
 public:
  FakeFluid(const geometry::Patch& patch, double dt, Vec3 velocity, double target)
      : patch_(patch), velocity_(velocity) {
    opt_.dt = dt;
    const PetscInt n = 3 * patch.n_control();
    CELLFSI_PETSC(VecCreateMPI(PETSC_COMM_WORLD, PETSC_DECIDE, n, &U_));
    CELLFSI_PETSC(VecSet(U_, 0.0));
    CELLFSI_PETSC(VecDuplicate(U_, &target_));
    CELLFSI_PETSC(VecSet(target_, target));
    CELLFSI_PETSC(MatCreateAIJ(PETSC_COMM_WORLD, PETSC_DECIDE, PETSC_DECIDE, n, n, 1, nullptr, 0, nullptr, &J_));
  }
  ~FakeFluid() override {
    VecDestroy(&U_);
    VecDestroy(&target_);
    MatDestroy(&J_);
  }

  MPI_Comm comm() const override { return PETSC_COMM_WORLD; }
  int dim() const override { return 2; }
  const geometry::Patch& patch() const override { return patch_; }
  const fluid::FluidOptions& options() const override { return opt_; }
  std::optional<fluid::BlockLayout> block_layout() const override { return std::nullopt; }
  std::vector<int> unknown_kinds() const override {
    PetscInt lo = 0, hi = 0;
    CELLFSI_PETSC(VecGetOwnershipRange(U_, &lo, &hi));
    std::vector<int> k;
    for (PetscInt i = lo; i < hi; ++i) k.push_back(static_cast<int>(i % 3));
    return k;
  }

  void set_initial_velocity(const std::function<Vec3(const Vec3&)>&) override {}
  void project_initial_velocity(const std::function<Vec3(const Vec3&)>&) override {}
  void setup() override {}
  fluid::StepStats step() override { throw std::logic_error("FakeFluid: no steps of its own"); }
  double time() const override { return steps_ * opt_.dt; }
  int steps_taken() const override { return steps_; }
  Vec solution() const override { return U_; }

  std::vector<fluid::PointSample> sample(const std::vector<Vec3>& points) const override {
    std::vector<fluid::PointSample> s(points.size());
    for (auto& p : s) p.found = true, p.v = velocity_;
    return s;
  }
  std::vector<fluid::PointSample> sample_alpha(Vec, const std::vector<geometry::Index3>& elements,
                                               const std::vector<geometry::Param>&) const override {
    std::vector<fluid::PointSample> s(elements.size());
    for (auto& p : s) p.found = true, p.v = velocity_;
    return s;
  }
  fluid::SectionData section(double, int) const override { return {}; }

  bool owns_element(const geometry::Index3&) const override { return true; }
  void set_immersed_points(const std::vector<geometry::Index3>& elements, const std::vector<geometry::Param>&,
                           const std::vector<fluid::ImmersedPoint>&) override {
    immersed_points = static_cast<int>(elements.size());
  }
  void set_scaling(const std::function<double(int)>& s) override {
    scaled_nodes = 0;
    for (int k = 0; k < patch_.n_control(); ++k) scaled_nodes += s(k) != 1.0;
  }
  void set_viscosity(const std::function<double(int)>&) override { ++viscosity_fields; }
  void begin_step(Vec X) override {
    ++begun;
    CELLFSI_PETSC(VecCopy(U_, X));
  }
  void residual(Vec X, Vec F) override { CELLFSI_PETSC(VecWAXPY(F, -1.0, target_, X)); }
  void jacobian(Vec, Mat J) override {
    PetscInt lo = 0, hi = 0;
    CELLFSI_PETSC(MatGetOwnershipRange(J, &lo, &hi));
    for (PetscInt i = lo; i < hi; ++i) CELLFSI_PETSC(MatSetValue(J, i, i, 1.0, INSERT_VALUES));
    CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  }
  // (A PETSc PC on the whole Jacobian asks for none of the parts.)
  void jacobian_part(Vec, Mat, const std::vector<char>&, bool) override { throw std::logic_error("unused"); }
  void jacobian_add_part(Vec, Mat, const std::vector<char>&) override { throw std::logic_error("unused"); }
  void bulk_jacobian(Vec, Mat) override { throw std::logic_error("unused"); }
  void end_step(Vec X) override {
    CELLFSI_PETSC(VecCopy(X, U_));
    ++steps_;
  }
  std::vector<PetscInt> region_unknowns(const std::vector<char>&) const override { return {}; }
  Mat jacobian_matrix() const override { return J_; }
  void release_jacobian_matrix() override { MatDestroy(&J_); }

  std::string write_fields(const std::string&, const std::string&, int,
                           const std::function<Vec3(const Vec3&)>&) const override {
    return "";
  }
  std::string state_bytes() const override { return ""; }
  LoadedState load_state(PetscViewer, int) override { return LoadedState::does_not_fit; }

  int immersed_points = -1, scaled_nodes = -1, viscosity_fields = 0, begun = 0;

 private:
  const geometry::Patch& patch_;
  fluid::FluidOptions opt_;
  Vec3 velocity_;
  Vec U_ = nullptr, target_ = nullptr;
  Mat J_ = nullptr;
  int steps_ = 0;
};

}  // namespace

// Two steps of a stiff disk (radius 1e-4 cm, 4 x 32 quadratic elements) in the fake's uniform flow of
// 0.01 cm/s on a 24 x 12 cubic box: every control point moves by U dt per step (a rigid translation, no
// stress: the flow has no gradient), and the fluid's iterate ends at X* (one identity solve, then round-off).
TEST(FluidInterface, CouplingLoopDrivesAFakeFluidAndTheDiskTranslatesWithItsFlow) {
  const double dt = 1e-3, target = 0.25;
  const Vec3 U(0.01, 0.0, 0.0);
  const geometry::Patch box = geometry::rectangle(0.0024, 0.0012, 24, 12, 3, {true, false});
  FakeFluid fake(box, dt, U, target);
  const Vec3 c(0.0012, 0.0006, 0);
  solid::NurbsSolid disk("disk", geometry::bulky_ellipse(1e-4, 1e-4, 4, 32, 2, c),
                         std::make_shared<solid::DeviatoricNeoHookean>(7500.0), fake.options().density);
  const geometry::Patch reference = disk.current_patch();
  coupling::CouplerOptions co;
  co.linear.pc_type = "jacobi";  // a PETSc PC: the whole Jacobian, no element regions
  coupling::FsiCoupler fsi(fake, {&disk}, co);
  fsi.initialize();
  EXPECT_EQ(fake.immersed_points, static_cast<int>(disk.quadrature_data(fake.options().density, false).size()));
  EXPECT_GT(fake.scaled_nodes, 0);  // the marking around the disk's rim reached the fluid as s^h
  EXPECT_EQ(fake.viscosity_fields, 0);  // no inner viscosity: no field
  for (int s = 0; s < 2; ++s) {
    const coupling::CouplerStats st = fsi.step();
    ASSERT_TRUE(st.converged) << "step " << s + 1 << ": " << st.reason;
    EXPECT_LE(st.fluid_residual, 1e-4 * st.fluid_residual0);
  }
  EXPECT_EQ(fake.begun, 2);
  EXPECT_EQ(fake.steps_taken(), 2);
  // The accepted iterate is X*: the identity solve's answer up to the Krylov round-off (|X*| ~ 0.25 sqrt(n)).
  Vec diff;
  CELLFSI_PETSC(VecDuplicate(fake.solution(), &diff));
  CELLFSI_PETSC(VecSet(diff, target));
  CELLFSI_PETSC(VecAXPY(diff, -1.0, fake.solution()));
  PetscReal err = 0;
  CELLFSI_PETSC(VecNorm(diff, NORM_INFINITY, &err));
  CELLFSI_PETSC(VecDestroy(&diff));
  EXPECT_LT(err, 1e-12);
  // Rigid translation by 2 U dt (2e-5 cm), to 1e-9 of it: the kinematic equation integrates a constant
  // velocity exactly, and the converged kinematic residual leaves round-off.
  const geometry::Patch moved = disk.current_patch();
  const auto& x0 = reference.control_points();
  const auto& x1 = moved.control_points();
  ASSERT_EQ(x0.size(), x1.size());
  double worst = 0;
  for (std::size_t k = 0; k < x0.size(); ++k) worst = std::max(worst, (x1[k] - x0[k] - 2 * dt * U).norm());
  EXPECT_LT(worst, 1e-9 * 2 * dt * U.norm());
}
