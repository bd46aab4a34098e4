// FluidSolver::project_initial_state and project_viscosity (L2 projections onto the spline space) and
// velocity_l2_error.
#include <cmath>
#include <stdexcept>

#include "common/petsc_error.hpp"
#include "fluid/fluid_solver.hpp"
#include "fluid/point_evaluation.hpp"
#include "geometry/quadrature.hpp"

namespace cellfsi::fluid {

using geometry::BasisValues;
using geometry::Index3;
using geometry::MapValues;

std::vector<Vec> FluidSolver::l2_project(int count,
                                         const std::function<void(const Vec3&, double*)>& f) const {
  const int D = dim_;
  Mat M;
  CELLFSI_PETSC(DMCreateMatrix(da_scalar_, &M));
  std::vector<Vec> rhs(count);
  for (auto& b : rhs) CELLFSI_PETSC(DMCreateGlobalVector(da_scalar_, &b));
  std::vector<Vec> rhs_loc(count);
  for (int c = 0; c < count; ++c) {
    CELLFSI_PETSC(DMCreateLocalVector(da_scalar_, &rhs_loc[c]));
    CELLFSI_PETSC(VecSet(rhs_loc[c], 0.0));
  }
  std::vector<PetscScalar*> r(count);
  for (int c = 0; c < count; ++c) CELLFSI_PETSC(VecGetArray(rhs_loc[c], &r[c]));
  const Index3 ng = geometry::default_gauss(patch_, 2);
  std::vector<geometry::QuadraturePoint> qp;
  BasisValues bv;
  MapValues mv;
  std::vector<PetscInt> lidx;
  std::vector<double> Me, fx(count);
  for (const Index3& e : owned_elements()) {
    geometry::element_quadrature(patch_, e, ng, qp);
    bool first_point = true;
    for (const auto& q : qp) {
      patch_.basis(q.xi, 1, bv, &e);
      patch_.map(bv, mv);
      const double w = q.weight * std::abs(mv.dx.topLeftCorner(D, D).determinant());
      const int n = bv.n;
      if (first_point) {
        lidx.resize(n);
        int first[3];
        first_functions(patch_, bv, first);
        for_each_element_node(patch_, first, gxs_, gxm_, [&](int k, PetscInt node) { lidx[k] = node; });
        Me.assign(n * n, 0.0);
        first_point = false;
      }
      f(mv.x, fx.data());
      for (int a = 0; a < n; ++a) {
        for (int c = 0; c < count; ++c) r[c][lidx[a]] += w * bv.value[a] * fx[c];
        for (int b = 0; b < n; ++b) Me[a * n + b] += w * bv.value[a] * bv.value[b];
      }
    }
    CELLFSI_PETSC(MatSetValuesLocal(M, static_cast<PetscInt>(lidx.size()), lidx.data(),
                                    static_cast<PetscInt>(lidx.size()), lidx.data(), Me.data(), ADD_VALUES));
  }
  CELLFSI_PETSC(MatAssemblyBegin(M, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(M, MAT_FINAL_ASSEMBLY));
  for (int c = 0; c < count; ++c) {
    CELLFSI_PETSC(VecRestoreArray(rhs_loc[c], &r[c]));
    CELLFSI_PETSC(VecSet(rhs[c], 0.0));
    CELLFSI_PETSC(DMLocalToGlobal(da_scalar_, rhs_loc[c], ADD_VALUES, rhs[c]));
    CELLFSI_PETSC(VecDestroy(&rhs_loc[c]));
  }
  KSP ksp;
  CELLFSI_PETSC(KSPCreate(comm_, &ksp));
  CELLFSI_PETSC(KSPSetOptionsPrefix(ksp, "fluid_projection_"));
  CELLFSI_PETSC(KSPSetOperators(ksp, M, M));
  CELLFSI_PETSC(KSPSetType(ksp, KSPCG));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, PCJACOBI));
  CELLFSI_PETSC(KSPSetTolerances(ksp, 1e-14, 1e-30, PETSC_DEFAULT, 2000));
  CELLFSI_PETSC(KSPSetFromOptions(ksp));
  std::vector<Vec> out(count);
  for (int c = 0; c < count; ++c) {
    CELLFSI_PETSC(VecDuplicate(rhs[c], &out[c]));
    CELLFSI_PETSC(KSPSolve(ksp, rhs[c], out[c]));
    KSPConvergedReason reason;
    CELLFSI_PETSC(KSPGetConvergedReason(ksp, &reason));
    if (reason < 0)
      throw std::runtime_error("an L2 projection onto the fluid's spline space did not converge");
    CELLFSI_PETSC(VecDestroy(&rhs[c]));
  }
  CELLFSI_PETSC(KSPDestroy(&ksp));
  CELLFSI_PETSC(MatDestroy(&M));
  return out;
}

void FluidSolver::project_initial_state(const std::function<Vec3(const Vec3&)>& v0,
                                        const std::function<Vec3(const Vec3&)>& vdot0) {
  const int D = dim_;
  std::vector<Vec> x = l2_project(2 * D, [&](const Vec3& p, double* values) {
    const Vec3 f0 = v0(p), f1 = vdot0(p);
    for (int c = 0; c < D; ++c) values[c] = f0[c], values[D + c] = f1[c];
  });
  for (int c = 0; c < 2 * D; ++c) {
    CELLFSI_PETSC(VecStrideScatter(x[c], c % D, c < D ? U_ : Udot_, INSERT_VALUES));
    CELLFSI_PETSC(VecDestroy(&x[c]));
  }
  CELLFSI_PETSC(VecStrideSet(U_, D, 0.0));
  CELLFSI_PETSC(VecStrideSet(Udot_, D, 0.0));
  apply_dirichlet_values(U_, time_);
}

void FluidSolver::project_viscosity(const std::function<double(const Vec3&)>& mu) {
  std::vector<Vec> x =
      l2_project(1, [&](const Vec3& p, double* values) { values[0] = mu(p) / opt_.density; });
  clear_viscosity();
  Nu_ = x[0];
  CELLFSI_PETSC(DMCreateLocalVector(da_scalar_, &Nu_loc_));
}

FluidSolver::L2Error FluidSolver::velocity_l2_error(const std::function<Vec3(const Vec3&)>& v_exact) const {
  const int D = dim_, nd = dof_;
  Vec U_loc;
  CELLFSI_PETSC(DMGetLocalVector(da_, &U_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_, U_, INSERT_VALUES, U_loc));
  const PetscScalar* u;
  CELLFSI_PETSC(VecGetArrayRead(U_loc, &u));
  const Index3 ng = geometry::default_gauss(patch_, 3);
  std::vector<geometry::QuadraturePoint> qp;
  BasisValues bv;
  MapValues mv;
  double sums[2] = {0, 0};
  for (const Index3& e : owned_elements()) {
    geometry::element_quadrature(patch_, e, ng, qp);
    for (const auto& q : qp) {
      patch_.basis(q.xi, 1, bv, &e);
      patch_.map(bv, mv);
      const double w = q.weight * std::abs(mv.dx.topLeftCorner(D, D).determinant());
      int first[3];
      first_functions(patch_, bv, first);
      Vec3 vh = Vec3::Zero();
      for_each_element_node(patch_, first, gxs_, gxm_, [&](int k, PetscInt node) {
        for (int c = 0; c < D; ++c) vh[c] += bv.value[k] * u[node * nd + c];
      });
      const Vec3 ve = v_exact(mv.x);
      sums[0] += w * (vh - ve).squaredNorm();
      sums[1] += w * ve.squaredNorm();
    }
  }
  CELLFSI_PETSC(VecRestoreArrayRead(U_loc, &u));
  CELLFSI_PETSC(DMRestoreLocalVector(da_, &U_loc));
  double all[2];
  CELLFSI_PETSC(MPI_Allreduce(sums, all, 2, MPI_DOUBLE, MPI_SUM, comm_));
  return {std::sqrt(all[0]), std::sqrt(all[1])};
}

}  // namespace cellfsi::fluid
