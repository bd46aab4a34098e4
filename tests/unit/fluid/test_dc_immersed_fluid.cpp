// The divergence-conforming fluid behind the fluid interface (fluid/dc_immersed_fluid.hpp): what the coupling
// loop reads of it (samples at points, at t_{n+alpha} of an iterate, the unknowns' kinds), a step driven from
// outside against the fluid's own, its bulk inverse against the Jacobian, checkpoints and refused input.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <stdexcept>

#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkStructuredGrid.h>
#include <vtkXMLStructuredGridReader.h>

#include "common/petsc_error.hpp"
#include "fluid/dc_immersed_fluid.hpp"
#include "geometry/builders.hpp"
#include "geometry/refine.hpp"
#include "solid/material.hpp"
#include "solid/nurbs_solid.hpp"

using namespace cellfsi;
using geometry::Vec3;

namespace {

/// The paper's shear box (0.0024 x 0.0012 cm, periodic in x) at nx x ny, walls at +-gammadot H / 2.
struct ShearBox {
  double lx = 0.0024, ly = 0.0012, rate = 70;
  geometry::Patch patch;
  fluid::FluidOptions options;
  ShearBox(int nx, int ny, int degree = 2) : patch(geometry::rectangle(lx, ly, nx, ny, degree, {true, false})) {
    options.space = "div_conforming";
    options.dc_degree = 2;
    options.dt = 1e-3;
    options.wall_velocity[1][0] = Vec3(-rate * ly / 2, 0, 0);
    options.wall_velocity[1][1] = Vec3(rate * ly / 2, 0, 0);
  }
  Vec3 shear(const Vec3& x) const { return Vec3(rate * (x[1] - ly / 2), 0, 0); }
};

std::vector<Vec3> random_points(int n, double lx, double ly, unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> ux(0, lx), uy(0, ly);
  std::vector<Vec3> p;
  for (int i = 0; i < n; ++i) p.emplace_back(ux(gen), uy(gen), 0);
  return p;
}

/// This rank's share of per-point lists, as the coupler deals points to a fluid that assembles them anywhere
/// (ImmersedFluid::assembles_points_anywhere): equal contiguous runs by index.
template <class T>
std::vector<T> dealt(const std::vector<T>& all) {
  int rank = 0, size = 1;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  std::vector<T> mine;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (static_cast<int>(i * size / all.size()) == rank) mine.push_back(all[i]);
  return mine;
}

/// n immersed points on an ellipse in the box, with stress, density and stiffness, as a membrane gives.
void set_immersed_ring(fluid::ImmersedFluid& f, const ShearBox& box, int n) {
  std::vector<geometry::Index3> elements;
  std::vector<geometry::Param> xi;
  std::vector<fluid::ImmersedPoint> data;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    const geometry::Param p{0.5 + 0.2 * std::cos(a), 0.5 + 0.3 * std::sin(a), 0};
    elements.push_back(box.patch.find_element(p));
    xi.push_back(p);
    fluid::ImmersedPoint d;
    d.weight = 1e-9;
    d.beta = 0.1;
    d.stiffness_viscosity = 0.5;
    d.stress = {{{0.3, 0.1, 0}, {0.1, -0.2, 0}, {0, 0, 0}}};
    data.push_back(d);
  }
  f.set_immersed_points(dealt(elements), dealt(xi), dealt(data));
}

}  // namespace

TEST(DcImmersedFluid, SamplesTheShearFlowAtPointsAndAtTheIterateAlike) {
  ShearBox box(16, 8);
  std::unique_ptr<fluid::ImmersedFluid> f = fluid::create_fluid(PETSC_COMM_WORLD, box.patch, box.options);
  EXPECT_FALSE(f->block_layout().has_value());
  EXPECT_FALSE(f->uses_interface_scaling());
  f->set_initial_velocity([&](const Vec3& x) { return box.shear(x); });
  const std::vector<Vec3> pts = random_points(40, box.lx, box.ly, 7);
  const std::vector<fluid::PointSample> s = f->sample(pts);
  for (size_t i = 0; i < pts.size(); ++i) {
    ASSERT_TRUE(s[i].found);
    EXPECT_LT((s[i].v - box.shear(pts[i])).norm(), 1e-12 * box.rate * box.ly);  // the shear is in the space
  }
  // A flow that varies along x too (a divergence-free swirl over the shear), so that a point evaluated in
  // the wrong element would show.
  f->set_initial_velocity([&](const Vec3& x) {
    const double kx = 2 * M_PI / box.lx, ky = M_PI / box.ly;
    return Vec3(box.shear(x)[0] + 0.01 * std::sin(kx * x[0]) * std::cos(ky * x[1]) / kx,
                -0.01 * std::cos(kx * x[0]) * std::sin(ky * x[1]) / ky, 0);
  });
  const std::vector<fluid::PointSample> s2 = f->sample(pts);
  // The patch's parametric points of the same physical points, located as the coupler does.
  std::vector<geometry::Index3> elements;
  std::vector<geometry::Param> xi;
  const std::optional<geometry::AffineMap> map = geometry::affine_map(box.patch);
  ASSERT_TRUE(map);
  for (const Vec3& x : pts) {
    const geometry::Param p{(x[0] - map->offset[0]) / map->scale[0], (x[1] - map->offset[1]) / map->scale[1], 0};
    xi.push_back(p);
    elements.push_back(box.patch.find_element(p));
  }
  Vec X;
  CELLFSI_PETSC(VecDuplicate(f->solution(), &X));
  f->begin_step(X);
  const std::vector<fluid::PointSample> a = f->sample_alpha(X, elements, xi);
  double worst_alpha = 0;
  for (size_t i = 0; i < pts.size(); ++i)
    worst_alpha = std::max(worst_alpha, (a[i].v - s2[i].v).norm() + (a[i].grad_v - s2[i].grad_v).norm() * box.ly);
  EXPECT_LT(worst_alpha, 1e-12 * box.rate * box.ly);  // X = U_n: the alpha level is U_n
  CELLFSI_PETSC(VecDestroy(&X));
}

TEST(DcImmersedFluid, AStepDrivenFromOutsideEqualsItsOwnStep) {
  // A disturbed start (a divergence-free swirl over the shear), three steps either way: the fluid's own
  // Newton with MUMPS, or begin_step / residual / jacobian / a direct solve / end_step, as the coupling loop.
  ShearBox box(16, 8);
  auto v0 = [&](const Vec3& x) {
    const double kx = 2 * M_PI / box.lx, ky = M_PI / box.ly;
    return Vec3(box.shear(x)[0] + 0.01 * std::sin(kx * x[0]) * std::cos(ky * x[1]) / kx,
                -0.01 * std::cos(kx * x[0]) * std::sin(ky * x[1]) / ky, 0);
  };
  std::unique_ptr<fluid::ImmersedFluid> own = fluid::create_fluid(PETSC_COMM_WORLD, box.patch, box.options);
  std::unique_ptr<fluid::ImmersedFluid> driven = fluid::create_fluid(PETSC_COMM_WORLD, box.patch, box.options);
  own->set_initial_velocity(v0);
  driven->set_initial_velocity(v0);
  Vec X, F, dX;
  CELLFSI_PETSC(VecDuplicate(driven->solution(), &X));
  CELLFSI_PETSC(VecDuplicate(X, &F));
  CELLFSI_PETSC(VecDuplicate(X, &dX));
  KSP ksp;
  CELLFSI_PETSC(KSPCreate(PETSC_COMM_WORLD, &ksp));
  CELLFSI_PETSC(KSPSetType(ksp, KSPGMRES));
  CELLFSI_PETSC(KSPSetTolerances(ksp, 1e-13, 1e-30, PETSC_DEFAULT, 200));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, PCLU));
  CELLFSI_PETSC(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
  // The driven Jacobian leaves the pressure's constant free (no pin: the coupled solve's bulk inverse handles
  // it), so the solves are told its null space: an LU of the singular matrix alone puts round-off over its
  // smallest pivot into that constant, and from there into the velocity (1e-7 of the largest with OpenBLAS's
  // AVX-512 kernels on two threads, where the three steps then differed by 3.9e-9 cm/s).
  MatNullSpace constant_pressure;
  {
    Vec c;
    CELLFSI_PETSC(VecDuplicate(X, &c));
    const std::vector<int> kinds = driven->unknown_kinds();
    PetscInt lo = 0, hi = 0;
    CELLFSI_PETSC(VecGetOwnershipRange(c, &lo, &hi));
    PetscScalar* cp;
    CELLFSI_PETSC(VecGetArray(c, &cp));
    for (PetscInt i = lo; i < hi; ++i) cp[i - lo] = kinds[i - lo] == driven->dim() ? 1.0 : 0.0;
    CELLFSI_PETSC(VecRestoreArray(c, &cp));
    CELLFSI_PETSC(VecNormalize(c, nullptr));
    CELLFSI_PETSC(MatNullSpaceCreate(PETSC_COMM_WORLD, PETSC_FALSE, 1, &c, &constant_pressure));
    VecDestroy(&c);
  }
  for (int s = 0; s < 3; ++s) {
    ASSERT_TRUE(own->step().converged);
    driven->begin_step(X);
    for (int it = 0; it < 4; ++it) {
      driven->residual(X, F);
      driven->jacobian(X, driven->jacobian_matrix());
      CELLFSI_PETSC(MatSetNullSpace(driven->jacobian_matrix(), constant_pressure));
      CELLFSI_PETSC(KSPSetOperators(ksp, driven->jacobian_matrix(), driven->jacobian_matrix()));
      CELLFSI_PETSC(KSPSolve(ksp, F, dX));
      CELLFSI_PETSC(VecAXPY(X, -1.0, dX));
    }
    driven->end_step(X);
  }
  const std::vector<Vec3> pts = random_points(30, box.lx, box.ly, 3);
  const auto a = own->sample(pts), b = driven->sample(pts);
  double worst = 0, vmax = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    worst = std::max(worst, (a[i].v - b[i].v).norm());
    vmax = std::max(vmax, a[i].v.norm());
  }
  // Both solve the same equations; the fluid's own Newton stops when its update is 1e-10 of the state
  // (DcFluidOptions::newton_stol), so three steps agree to about 1e-9.
  EXPECT_LT(worst, 1e-8 * vmax);
  EXPECT_NEAR(own->time(), driven->time(), 1e-15);
  // Divergence-free to the linear solves' round-off (tests/support/tolerances.hpp: eps times the Jacobian's
  // condition, 1e6-1e8 on the test meshes): measured below 1e-12 with OpenBLAS's Haswell kernels and 5.7e-12
  // with its AVX-512 ones; bounded by issue 44's 1e-9.
  ASSERT_TRUE(driven->max_divergence_ratio().has_value());
  EXPECT_LT(*driven->max_divergence_ratio(), 1e-9);
  MatNullSpaceDestroy(&constant_pressure);
  KSPDestroy(&ksp);
  VecDestroy(&X);
  VecDestroy(&F);
  VecDestroy(&dX);
}

TEST(DcImmersedFluid, ItsBulkInverseInvertsTheJacobianWithoutCells) {
  ShearBox box(32, 16);
  std::unique_ptr<fluid::ImmersedFluid> f = fluid::create_fluid(PETSC_COMM_WORLD, box.patch, box.options);
  f->set_initial_velocity([&](const Vec3& x) { return box.shear(x); });
  ASSERT_TRUE(f->has_bulk_inverse());
  Vec X, b, x, r;
  CELLFSI_PETSC(VecDuplicate(f->solution(), &X));
  CELLFSI_PETSC(VecDuplicate(X, &b));
  CELLFSI_PETSC(VecDuplicate(X, &x));
  CELLFSI_PETSC(VecDuplicate(X, &r));
  f->begin_step(X);
  std::optional<fluid::ImmersedFluid::OwnBulkInverse> inv = f->bulk_inverse(X);
  ASSERT_TRUE(inv);
  EXPECT_LT(inv->deviation, 1e-12);
  // A right-hand side as the coupled solve sees one: the residual of an iterate off the solution. Only v_x
  // is disturbed (x is periodic: no wall-normal unknown moves), so the continuity rows sum to zero, as every
  // residual of the coupling loop does.
  const std::vector<int> kinds = f->unknown_kinds();
  Vec X0;  // the state the inverse was built at (its operator; the disturbed one differs by Re ~ 1e-4 terms)
  CELLFSI_PETSC(VecDuplicate(X, &X0));
  CELLFSI_PETSC(VecCopy(X, X0));
  PetscScalar* px;
  CELLFSI_PETSC(VecGetArray(X, &px));
  for (size_t i = 0; i < kinds.size(); ++i)
    if (kinds[i] == 0) px[i] += 0.01 * std::sin(0.37 * static_cast<double>(i));
  CELLFSI_PETSC(VecRestoreArray(X, &px));
  f->residual(X, b);
  inv->apply(b, x);
  f->bulk_jacobian(X0, f->jacobian_matrix());
  CELLFSI_PETSC(MatMult(f->jacobian_matrix(), x, r));
  CELLFSI_PETSC(VecAXPY(r, -1.0, b));
  // The fixed rows (walls' normal velocities) are unit rows in both; compare the rest.
  PetscReal rn = 0, bn = 0;
  CELLFSI_PETSC(VecNorm(r, NORM_INFINITY, &rn));
  CELLFSI_PETSC(VecNorm(b, NORM_INFINITY, &bn));
  EXPECT_LT(rn, 1e-10 * bn);
  VecDestroy(&X);
  VecDestroy(&X0);
  VecDestroy(&b);
  VecDestroy(&x);
  VecDestroy(&r);
}

TEST(DcImmersedFluid, ItsStencilOperatorMultipliesAsTheAssembledJacobian) {
  // The coupled Jacobian two ways (-coupling_bulk_stencil): assembled (the bulk part kept, the immersed
  // points' tangent added) and as the stencil operator (the bulk part by the bulk inverse's stencil, the
  // points' tangent a matrix of its own). With the bulk uniform along x to round-off (the shear flow), their
  // products agree to round-off; asserted 1e-12 of max|y|, with immersed points (a ring of them with stress,
  // density and stiffness, as a membrane gives) and, after the points are gone, without.
  ShearBox box(32, 16);
  std::unique_ptr<fluid::ImmersedFluid> f = fluid::create_fluid(PETSC_COMM_WORLD, box.patch, box.options);
  f->set_initial_velocity([&](const Vec3& x) { return box.shear(x); });
  Vec X, x, y_op, y_mat;
  CELLFSI_PETSC(VecDuplicate(f->solution(), &X));
  CELLFSI_PETSC(VecDuplicate(X, &x));
  CELLFSI_PETSC(VecDuplicate(X, &y_op));
  CELLFSI_PETSC(VecDuplicate(X, &y_mat));
  f->begin_step(X);
  std::optional<fluid::ImmersedFluid::OwnBulkInverse> inv = f->bulk_inverse(X);
  ASSERT_TRUE(inv);
  ASSERT_NE(inv->stencil_operator, nullptr);
  // Neither the bulk inverse's build nor the stencil operator makes the whole matrix (at 64^3 8 GB that a
  // run with the stencil never uses); the assembled path below makes it when it first asks.
  const auto& dc = dynamic_cast<const fluid::DcImmersedFluid&>(*f);
  f->jacobian(X, inv->stencil_operator);
  EXPECT_FALSE(dc.discretisation().matrix_made());
  EXPECT_FALSE(f->jacobian_is_blocked());
  EXPECT_FALSE(dc.discretisation().matrix_made());
  auto set_ring = [&](int n) { set_immersed_ring(*f, box, n); };
  PetscInt lo = 0, hi = 0;
  CELLFSI_PETSC(VecGetOwnershipRange(x, &lo, &hi));
  PetscScalar* px;
  CELLFSI_PETSC(VecGetArray(x, &px));
  for (PetscInt i = lo; i < hi; ++i) px[i - lo] = std::sin(0.37 * static_cast<double>(i)) + 0.1;
  CELLFSI_PETSC(VecRestoreArray(x, &px));
  Vec y_points;  // the product with the points, to check that they matter
  CELLFSI_PETSC(VecDuplicate(X, &y_points));
  for (int n : {200, 200, 0}) {  // (the second time the pattern of the elements with points is kept)
    set_ring(n);
    f->jacobian(X, inv->stencil_operator);
    f->jacobian(X, f->jacobian_matrix());
    CELLFSI_PETSC(MatMult(inv->stencil_operator, x, y_op));
    CELLFSI_PETSC(MatMult(f->jacobian_matrix(), x, y_mat));
    PetscReal scale = 0, diff = 0;
    CELLFSI_PETSC(VecNorm(y_mat, NORM_INFINITY, &scale));
    CELLFSI_PETSC(VecAXPY(y_op, -1.0, y_mat));
    CELLFSI_PETSC(VecNorm(y_op, NORM_INFINITY, &diff));
    EXPECT_LT(diff, 1e-12 * scale) << n << " points";
    EXPECT_GT(scale, 0) << n << " points";
    if (n > 0) {
      CELLFSI_PETSC(VecCopy(y_mat, y_points));
    } else {  // the points' part is more than round-off
      CELLFSI_PETSC(VecAXPY(y_points, -1.0, y_mat));
      CELLFSI_PETSC(VecNorm(y_points, NORM_INFINITY, &diff));
      EXPECT_GT(diff, 1e-6 * scale);
    }
  }
  EXPECT_TRUE(dc.discretisation().matrix_made());
  f->release_jacobian_matrix();
  EXPECT_FALSE(dc.discretisation().matrix_made());
  VecDestroy(&y_points);
  VecDestroy(&X);
  VecDestroy(&x);
  VecDestroy(&y_op);
  VecDestroy(&y_mat);
}

TEST(DcImmersedFluid, ItsStencilOperatorTakesTheBulkInversesRightHandSideForItsOutput) {
  // Right preconditioning multiplies the operator by z = S^{-1} v, and S z = v: the stencil operator takes v
  // for S z when z is the bulk inverse's last output, unchanged. Its product then equals the full one (the
  // stencil's on a copy of z) to the banded solves' round-off, asserted 1e-10 of max|y|, for v a coupling
  // residual (its continuity rows sum to zero), with immersed points; a changed z (scaled) is multiplied in
  // full.
  ShearBox box(32, 16);
  std::unique_ptr<fluid::ImmersedFluid> f = fluid::create_fluid(PETSC_COMM_WORLD, box.patch, box.options);
  f->set_initial_velocity([&](const Vec3& x) { return box.shear(x); });
  const auto& dc = dynamic_cast<const fluid::DcImmersedFluid&>(*f);
  Vec X, v, z, w, y_short, y_full;
  CELLFSI_PETSC(VecDuplicate(f->solution(), &X));
  for (Vec* p : {&v, &z, &w, &y_short, &y_full}) CELLFSI_PETSC(VecDuplicate(X, p));
  f->begin_step(X);
  std::optional<fluid::ImmersedFluid::OwnBulkInverse> inv = f->bulk_inverse(X);
  ASSERT_TRUE(inv);
  set_immersed_ring(*f, box, 200);
  f->jacobian(X, inv->stencil_operator);
  // v: the residual of an iterate with v_x disturbed (a coupling loop's residual).
  const std::vector<int> kinds = f->unknown_kinds();
  PetscScalar* px;
  CELLFSI_PETSC(VecGetArray(X, &px));
  for (size_t i = 0; i < kinds.size(); ++i)
    if (kinds[i] == 0) px[i] += 0.01 * std::sin(0.37 * static_cast<double>(i));
  CELLFSI_PETSC(VecRestoreArray(X, &px));
  f->residual(X, v);
  inv->apply(v, z);
  const long before = dc.stencil_products_skipped();
  CELLFSI_PETSC(MatMult(inv->stencil_operator, z, y_short));
  EXPECT_EQ(dc.stencil_products_skipped(), before + 1);
  CELLFSI_PETSC(VecCopy(z, w));  // (another object: multiplied in full)
  CELLFSI_PETSC(MatMult(inv->stencil_operator, w, y_full));
  EXPECT_EQ(dc.stencil_products_skipped(), before + 1);
  PetscReal scale = 0, diff = 0;
  CELLFSI_PETSC(VecNorm(y_full, NORM_INFINITY, &scale));
  CELLFSI_PETSC(VecAXPY(y_short, -1.0, y_full));
  CELLFSI_PETSC(VecNorm(y_short, NORM_INFINITY, &diff));
  EXPECT_GT(scale, 0);
  EXPECT_LT(diff, 1e-10 * scale);
  CELLFSI_PETSC(VecScale(z, 2.0));  // z changed: its state moved on
  CELLFSI_PETSC(MatMult(inv->stencil_operator, z, y_short));
  EXPECT_EQ(dc.stencil_products_skipped(), before + 1);
  CELLFSI_PETSC(VecAXPY(y_short, -2.0, y_full));
  CELLFSI_PETSC(VecNorm(y_short, NORM_INFINITY, &diff));
  EXPECT_LT(diff, 1e-12 * scale);
  for (Vec* p : {&X, &v, &z, &w, &y_short, &y_full}) VecDestroy(p);
}

TEST(DcImmersedFluid, TheSolidTangentThroughTheCollocationEqualsTheConsistentOneOnLinearFields) {
  // The solids' stiffness two ways (-coupling_solid_tangent): consistent (each point's tangent applied to
  // the fluid's gradient there) and through the body's collocation (fluid::SolidLinearization: the velocity
  // at the collocation points, the body's own interpolation, its functions' gradients at the points). For a
  // velocity that is linear in x, the body interpolates it exactly (isoparametric NURBS), so the two products
  // agree to round-off; asserted 1e-10 of max|y| with a deformed, stressed membrane (relative to the size of
  // its stiffness part, the difference of the two products with the points and without), on one rank or
  // two. For a velocity that is not linear they differ: what the other tangent is for.
  ShearBox box(32, 16);
  std::unique_ptr<fluid::ImmersedFluid> f = fluid::create_fluid(PETSC_COMM_WORLD, box.patch, box.options);
  f->set_initial_velocity([&](const Vec3& x) { return box.shear(x); });
  const std::optional<geometry::AffineMap> map = geometry::affine_map(box.patch);
  ASSERT_TRUE(map);
  auto locate = [&](const Vec3& x, geometry::Index3& e, geometry::Param& xi) {
    for (int d = 0; d < 3; ++d) xi[d] = d < 2 ? (x[d] - map->offset[d]) / map->scale[d] : 0.0;
    e = box.patch.find_element(xi);
  };
  // A membrane deformed by one kinematic update, the last with grad v = 0 (its tangent is then the scalar
  // alpha_m / (gamma dt), as the consistent tangent assumes).
  const double rho1 = 1.025;
  const solid::TimeParameters tp = solid::TimeParameters::from_rho_inf(0.5, box.options.dt);
  solid::NurbsSolid body("m", geometry::hollow_ellipse(2e-4, 1e-4, 5e-7, 24, 2, Vec3(1.2e-3, 6e-4, 0), 0.5),
                         std::make_shared<solid::DeviatoricNeoHookean>(7500.0), 1.1);
  body.begin_step(tp);
  {
    std::vector<solid::VelocitySample> vs(body.n_points());
    const std::vector<Vec3> x = body.collocation_points();
    for (int i = 0; i < body.n_points(); ++i)
      vs[i].v = Vec3(30 * (x[i][1] - 6e-4), 20 * (x[i][0] - 1.2e-3), 0);
    body.kinematic_update(vs);
  }
  const std::vector<solid::QuadratureData> q = body.quadrature_data(rho1, true);
  std::vector<int> q_begin, q_unknown;
  std::vector<double> q_grad;
  ASSERT_TRUE(body.basis_gradients(q_begin, q_unknown, q_grad));
  ASSERT_EQ(q_begin.size(), q.size() + 1);
  const double stiffness_time = tp.gamma * tp.dt * tp.alpha_f / tp.alpha_m;
  std::vector<geometry::Index3> elements(q.size());
  std::vector<geometry::Param> xi(q.size());
  std::vector<fluid::ImmersedPoint> data(q.size());
  fluid::SolidLinearization lin;
  for (size_t i = 0; i < q.size(); ++i) {
    locate(q[i].x, elements[i], xi[i]);
    fluid::ImmersedPoint& d = data[i];
    d.weight = q[i].weight;
    d.beta = q[i].beta;
    d.stiffness_time = stiffness_time;
    d.stiffness = q[i].tangent;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) d.stress[r][c] = q[i].stress(r, c);
    d.solid_begin = static_cast<int>(lin.column.size());
    for (int k = q_begin[i]; k < q_begin[i + 1]; ++k) {
      lin.column.push_back(3 * q_unknown[k]);
      lin.grad.insert(lin.grad.end(), q_grad.begin() + 3 * k, q_grad.begin() + 3 * k + 3);
    }
    d.solid_end = static_cast<int>(lin.column.size());
  }
  const std::vector<Vec3> colloc = body.collocation_points();
  lin.elements.resize(colloc.size());
  lin.xi.resize(colloc.size());
  for (size_t i = 0; i < colloc.size(); ++i) locate(colloc[i], lin.elements[i], lin.xi[i]);
  lin.n_columns = 3 * body.n_control();
  lin.control = [&body](const std::vector<double>& dv, std::vector<double>& dc) {
    std::vector<Vec3> v(dv.size() / 3);
    for (size_t i = 0; i < v.size(); ++i) v[i] = Vec3(dv[3 * i], dv[3 * i + 1], dv[3 * i + 2]);
    Eigen::MatrixXd c;
    ASSERT_TRUE(body.control_increment(v, c));
    for (Eigen::Index r = 0; r < c.rows(); ++r)
      for (Eigen::Index k = 0; k < c.cols(); ++k) dc[3 * r + k] = c(r, k);
  };

  Vec X, x, y_col, y_cons, y_none;
  CELLFSI_PETSC(VecDuplicate(f->solution(), &X));
  CELLFSI_PETSC(VecDuplicate(X, &y_col));
  CELLFSI_PETSC(VecDuplicate(X, &y_cons));
  CELLFSI_PETSC(VecDuplicate(X, &y_none));
  f->begin_step(X);
  std::optional<fluid::ImmersedFluid::OwnBulkInverse> inv = f->bulk_inverse(X);
  ASSERT_TRUE(inv && inv->stencil_operator);
  Mat op = inv->stencil_operator;
  // The velocities: linear (another shear and a uniform flow), and one that is not.
  std::unique_ptr<fluid::ImmersedFluid> g = fluid::create_fluid(PETSC_COMM_WORLD, box.patch, box.options);
  for (int field = 0; field < 2; ++field) {
    g->set_initial_velocity([&](const Vec3& p) {
      return field == 0 ? Vec3(-45 * p[1] + 0.02, 0, 0)
                        : Vec3(0.01 * std::sin(16 * M_PI * p[1] / box.ly), 0, 0);
    });
    CELLFSI_PETSC(VecDuplicate(g->solution(), &x));
    CELLFSI_PETSC(VecCopy(g->solution(), x));
    fluid::SolidLinearization given = lin;  // (the fluid takes its contents)
    EXPECT_TRUE(f->set_solid_linearization(given));
    f->set_immersed_points(dealt(elements), dealt(xi), dealt(data));
    f->jacobian(X, op);
    CELLFSI_PETSC(MatMult(op, x, y_col));
    std::vector<fluid::ImmersedPoint> plain = data;
    for (fluid::ImmersedPoint& d : plain) d.solid_begin = d.solid_end = -1;
    f->set_immersed_points(dealt(elements), dealt(xi), dealt(plain));
    f->jacobian(X, op);
    CELLFSI_PETSC(MatMult(op, x, y_cons));
    for (fluid::ImmersedPoint& d : plain) d.stiffness_time = 0;  // no stiffness at all
    f->set_immersed_points(dealt(elements), dealt(xi), dealt(plain));
    f->jacobian(X, op);
    CELLFSI_PETSC(MatMult(op, x, y_none));
    PetscReal stiff = 0, diff = 0;
    CELLFSI_PETSC(VecAXPY(y_none, -1.0, y_cons));
    CELLFSI_PETSC(VecNorm(y_none, NORM_INFINITY, &stiff));
    CELLFSI_PETSC(VecAXPY(y_col, -1.0, y_cons));
    CELLFSI_PETSC(VecNorm(y_col, NORM_INFINITY, &diff));
    EXPECT_GT(stiff, 0) << "field " << field;
    if (field == 0)
      EXPECT_LT(diff, 1e-10 * stiff) << "a linear field";
    else
      EXPECT_GT(diff, 1e-2 * stiff) << "a field the membrane does not interpolate exactly";
    VecDestroy(&x);
  }
  VecDestroy(&X);
  VecDestroy(&y_col);
  VecDestroy(&y_cons);
  VecDestroy(&y_none);
}

TEST(DcImmersedFluid, WritesTheNarrowingOnItsMappedGrid) {
  // The .vts of a run on the narrowing (a mapped space): the grid's points are the channel's, x from 0 to its
  // length 0.006 cm along the periodic direction (the last column at x = L, not folded back onto x = 0), y
  // between the curved walls.
  const geometry::Patch channel = geometry::narrowing_channel(geometry::NarrowingChannel{}, 24, 8, 3);
  fluid::FluidOptions o;
  o.space = "div_conforming";
  std::unique_ptr<fluid::ImmersedFluid> f = fluid::create_fluid(PETSC_COMM_WORLD, channel, o);
  f->set_initial_velocity([](const Vec3& x) { return Vec3(1e-3 * (1e-6 - x[1] * x[1]) / 1e-6, 0, 0); });
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "cellfsi_dc_narrowing_vts";
  std::filesystem::create_directories(dir);
  const std::string name = f->write_fields(dir.string(), "fluid", 2, nullptr);
  vtkNew<vtkXMLStructuredGridReader> reader;
  reader->SetFileName((dir / name).string().c_str());
  reader->Update();
  std::filesystem::remove_all(dir);  // (read: the grid is in memory)
  vtkStructuredGrid* grid = reader->GetOutput();
  int n[3];
  grid->GetDimensions(n);
  ASSERT_EQ(n[0], 24 * 2 + 1);
  ASSERT_EQ(n[1], 8 * 2 + 1);
  double first[3], last[3], top[3];
  grid->GetPoint(0, first);
  grid->GetPoint(n[0] - 1, last);
  grid->GetPoint(static_cast<vtkIdType>(n[0]) * (n[1] - 1), top);
  EXPECT_NEAR(first[0], 0.0, 1e-15);
  EXPECT_NEAR(last[0], 0.006, 1e-15);
  EXPECT_NEAR(first[1], -0.001, 1e-7);  // (the wall is an L2 projection of the profile: 1e-7 of it)
  EXPECT_NEAR(top[1], 0.001, 1e-7);
}

TEST(DcImmersedFluid, RefusesADomainWhoseElementsAreNotUniform) {
  // The narrowing channel is taken (through the Piola map, tests/unit/fluid/test_dc_mapped_fluid.cpp); one
  // with a knot inserted across the channel is not: the space's elements are uniform in the parameters.
  const geometry::Patch channel =
      geometry::insert_knots(geometry::narrowing_channel(geometry::NarrowingChannel{}, 32, 16, 3), 1, {0.51});
  fluid::FluidOptions o;
  o.space = "div_conforming";
  EXPECT_NO_THROW(fluid::create_fluid(
      PETSC_COMM_WORLD, geometry::narrowing_channel(geometry::NarrowingChannel{}, 32, 16, 3), o));
  try {
    fluid::create_fluid(PETSC_COMM_WORLD, channel, o);
    FAIL() << "a domain of unequal elements was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("-fluid_space"), std::string::npos) << e.what();
  }
}
