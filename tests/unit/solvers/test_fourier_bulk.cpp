// FourierBulkSolver: the exact inverse of translation-invariant operators (random stencils in 2D and 3D, the
// fluid's own Jacobian without cells with its constant-pressure null space); the deviation it reports.
// RegionCorrectedSolver: FGMRES with it solves the fluid Jacobian with an s_I = 1e10 band and immersed points
// in a few iterations.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <string>

#include "common/petsc_error.hpp"
#include "fluid/fluid_solver.hpp"
#include "geometry/builders.hpp"
#include "solvers/fourier_bulk.hpp"
#include "solvers/near_operator.hpp"
#include "solvers/nested_dissection.hpp"
#include "solvers/pc_fourier.hpp"
#include "solvers/region_corrected.hpp"
#include "test_operators.hpp"

#include <petscdmda.h>

using namespace cellfsi;
using solvers::create_near_operator;
using solvers::FourierBulkSolver;
using solvers::near_operator;
using solvers::RegionCorrectedSolver;
using geometry::Vec3;

using cellfsi::test::relative_difference;
using cellfsi::test::relative_residual;

namespace {

/// A random operator on an n[0] x n[1] x n[2] node grid with `dof` unknowns per node, the same stencil at
/// every position along the periodic directions (couplings within +-degree nodes; the non-periodic direction
/// truncates them at its ends, where the rows differ by their j). Diagonally dominant, hence invertible.
Mat invariant_operator(std::array<int, 3> n, std::array<bool, 3> periodic, int degree, int dof,
                       unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int N = n[0] * n[1] * n[2];
  // Stencil values by (j across, row dof, offsets, column dof); the across direction is the non-periodic one.
  int across = -1;
  for (int d = 0; d < 3; ++d)
    if (n[d] > 1 && !periodic[d]) across = d;
  const int w = 2 * degree + 1, nj = across >= 0 ? n[across] : 1;
  std::vector<double> st(static_cast<std::size_t>(nj) * dof * w * w * w * dof);
  for (double& v : st) v = u(rng);
  Mat A;
  CELLFSI_PETSC(MatCreateSeqAIJ(PETSC_COMM_SELF, N * dof, N * dof, w * w * w * dof, nullptr, &A));
  for (int node = 0; node < N; ++node) {
    const std::array<int, 3> c{node % n[0], (node / n[0]) % n[1], node / (n[0] * n[1])};
    const int j = across >= 0 ? c[across] : 0;
    for (int o0 = 0; o0 < w; ++o0)
      for (int o1 = 0; o1 < w; ++o1)
        for (int o2 = 0; o2 < w; ++o2) {
          const std::array<int, 3> o{o0 - degree, o1 - degree, o2 - degree};
          std::array<int, 3> cc{};
          bool inside = true;
          for (int d = 0; d < 3; ++d) {
            if (n[d] == 1) {
              inside = inside && o[d] == 0;
              cc[d] = 0;
            } else if (periodic[d]) {
              cc[d] = ((c[d] + o[d]) % n[d] + n[d]) % n[d];
            } else {
              cc[d] = c[d] + o[d];
              inside = inside && cc[d] >= 0 && cc[d] < n[d];
            }
          }
          if (!inside) continue;
          const int col_node = cc[0] + n[0] * (cc[1] + n[1] * cc[2]);
          for (int r = 0; r < dof; ++r)
            for (int k = 0; k < dof; ++k) {
              double v =
                  st[((((static_cast<std::size_t>(j) * dof + r) * w + o0) * w + o1) * w + o2) * dof + k];
              if (col_node == node && r == k) v += 8.0 * w * w * dof;
              CELLFSI_PETSC(MatSetValue(A, node * dof + r, col_node * dof + k, v, ADD_VALUES));
            }
        }
  }
  CELLFSI_PETSC(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  return A;
}

Vec random_vector(Mat A, unsigned seed) {
  Vec v;
  CELLFSI_PETSC(MatCreateVecs(A, &v, nullptr));
  PetscRandom rnd;
  CELLFSI_PETSC(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
  CELLFSI_PETSC(PetscRandomSetSeed(rnd, seed));
  CELLFSI_PETSC(PetscRandomSeed(rnd));
  CELLFSI_PETSC(VecSetRandom(v, rnd));
  PetscRandomDestroy(&rnd);
  return v;
}

/// The paper's shear box as a fluid on PETSC_COMM_WORLD (walls in y moving at -+ shear ly / 2, the linear
/// shear as its state) and its bulk Jacobian in *J (a new matrix; the caller destroys it).
std::unique_ptr<fluid::FluidSolver> shear_box_fluid(const geometry::Patch& box, double ly, double shear, Mat* J) {
  fluid::FluidOptions opt;
  opt.wall_velocity[1][0] = Vec3(-shear * ly / 2, 0, 0);
  opt.wall_velocity[1][1] = Vec3(shear * ly / 2, 0, 0);
  auto fs = std::make_unique<fluid::FluidSolver>(PETSC_COMM_WORLD, box, opt);
  fs->set_initial_velocity([&](const Vec3& x) { return Vec3(shear * x[1], 0, 0); });
  CELLFSI_PETSC(MatDuplicate(fs->jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, J));
  fs->bulk_jacobian(fs->solution(), *J);
  return fs;
}

struct Case {
  std::array<int, 3> n;
  std::array<bool, 3> periodic;
  int degree, dof;
};

}  // namespace

TEST(FourierBulkSolver, InvertsRandomTranslationInvariantOperators) {
  for (const Case& c : {Case{{12, 7, 1}, {true, false, false}, 2, 3},   // 2D channel, quadratic
                        Case{{6, 5, 4}, {true, false, true}, 1, 4},     // 3D box, walls in y
                        Case{{5, 4, 1}, {true, true, false}, 3, 3},     // doubly periodic, short (wraps)
                        Case{{4, 6, 3}, {false, true, true}, 2, 2}}) {  // walls in x
    Mat A = invariant_operator(c.n, c.periodic, c.degree, c.dof, 7);
    FourierBulkSolver s(c.n, c.periodic, {c.degree, c.degree, c.degree}, c.dof);
    s.build(A, false);
    EXPECT_LT(s.deviation(), 1e-14);
    Vec r = random_vector(A, 3), x;
    CELLFSI_PETSC(VecDuplicate(r, &x));
    s.solve(r, x);
    EXPECT_LT(relative_residual(A, x, r), 1e-12) << "n = " << c.n[0] << "x" << c.n[1] << "x" << c.n[2];
    // The stencil applied without the matrix is the matrix's product.
    Vec y, z;
    CELLFSI_PETSC(VecDuplicate(r, &y));
    CELLFSI_PETSC(VecDuplicate(r, &z));
    CELLFSI_PETSC(MatMult(A, r, y));
    s.multiply(r, z);
    EXPECT_LT(relative_difference(y, z), 1e-14) << "n = " << c.n[0] << "x" << c.n[1] << "x" << c.n[2];
    VecDestroy(&y);
    VecDestroy(&z);
    // One entry off the stencil's average: the deviation and the node that carries it show it.
    CELLFSI_PETSC(MatSetValue(A, 5 * c.dof + 1, 5 * c.dof + 1, 100.0, ADD_VALUES));
    CELLFSI_PETSC(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
    std::vector<double> dev = s.node_deviation(A);
    EXPECT_GT(dev[5], 1e-2);
    dev[5] = 0;
    EXPECT_LT(*std::max_element(dev.begin(), dev.end()), 1e-14);
    s.build(A, false);
    EXPECT_GT(s.deviation(), 1e-2);
    // A NaN entry (a broken operator) makes the deviation NaN, whether or not LAPACK then sees a singular
    // system.
    CELLFSI_PETSC(MatSetValue(A, 5 * c.dof + 1, 5 * c.dof + 1, std::numeric_limits<double>::quiet_NaN(),
                              INSERT_VALUES));
    CELLFSI_PETSC(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
    try {
      s.build(A, false);
    } catch (const std::runtime_error&) {
    }
    EXPECT_TRUE(std::isnan(s.deviation()));
    VecDestroy(&r);
    VecDestroy(&x);
    MatDestroy(&A);
  }
  EXPECT_THROW(FourierBulkSolver({4, 4, 4}, {true, false, false}, {1, 1, 1}, 2), std::invalid_argument);
}

TEST(FourierBulkSolver, InvertsTheFluidJacobianWithoutCells) {
  // The paper's shear box (2D, cubic; 3D, quadratic): the constant pressure is the Jacobian's null space,
  // the solver returns a solution of every consistent system.
  const double lx = 0.0024, ly = 0.0012, shear = 70.0;
  for (int dim : {2, 3}) {
    const geometry::Patch box =
        dim == 2 ? geometry::rectangle(lx, ly, 12, 6, 3, {true, false}, Vec3(0, -ly / 2, 0))
                 : geometry::box(ly, ly, ly, 6, 5, 4, 2, {true, false, true}, Vec3(0, -ly / 2, 0));
    Mat J;
    const std::unique_ptr<fluid::FluidSolver> solver = shear_box_fluid(box, ly, shear, &J);
    std::array<int, 3> n{1, 1, 1}, p{0, 0, 0};
    std::array<bool, 3> periodic{false, false, false};
    for (int d = 0; d < dim; ++d) {
      n[d] = box.n_control(d);
      p[d] = box.degree(d);
      periodic[d] = box.knots(d).periodic();
    }
    FourierBulkSolver s(n, periodic, p, dim + 1);
    s.build(J, true);
    EXPECT_LT(s.deviation(), 1e-12) << dim << "D";
    Vec y = random_vector(J, 11), r, x;
    CELLFSI_PETSC(VecDuplicate(y, &r));
    CELLFSI_PETSC(VecDuplicate(y, &x));
    CELLFSI_PETSC(MatMult(J, y, r));
    s.solve(r, x);
    EXPECT_LT(relative_residual(J, x, r), 1e-10) << dim << "D";
    // The node deviations read from the BAIJ blocks are those of the same matrix as AIJ (MatGetRow).
    const PetscInt row = 7 * (dim + 1) + 1;
    CELLFSI_PETSC(MatSetValue(J, row, row + 1, 1e3, ADD_VALUES));
    CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
    Mat Jaij;
    CELLFSI_PETSC(MatConvert(J, MATAIJ, MAT_INITIAL_MATRIX, &Jaij));
    const std::vector<double> from_blocks = s.node_deviation(J), from_rows = s.node_deviation(Jaij);
    ASSERT_EQ(from_blocks.size(), from_rows.size());
    for (std::size_t i = 0; i < from_rows.size(); ++i) EXPECT_NEAR(from_blocks[i], from_rows[i], 1e-14);
    EXPECT_GT(from_blocks[7], 1e-3);
    MatDestroy(&Jaij);
    // With the pressure pinned instead of the null space (-fluid_pressure_null_space false) one row is a unit
    // row, averaged in with the others of its layer: the bottom layer's nodes differ from the bulk operator
    // (and join the region), no others.
    if (dim == 2) {
      fluid::FluidOptions pinned = solver->options();
      pinned.pressure_null_space = false;
      fluid::FluidSolver fp(PETSC_COMM_WORLD, box, pinned);
      fp.set_initial_velocity([&](const Vec3& x) { return Vec3(shear * x[1], 0, 0); });
      Mat Jp;
      CELLFSI_PETSC(MatDuplicate(fp.jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, &Jp));
      fp.bulk_jacobian(fp.solution(), Jp);
      FourierBulkSolver sp(n, periodic, p, dim + 1);
      sp.build(Jp, true);
      EXPECT_LT(sp.deviation(), 1e-12);
      std::vector<double> dev = sp.node_deviation(Jp);
      int differing = 0;
      for (double d : dev) differing += d > 1e-3;
      EXPECT_EQ(differing, n[0]) << "nodes off the bulk operator by more than 1e-3";
      MatDestroy(&Jp);
    }
    VecDestroy(&y);
    VecDestroy(&r);
    VecDestroy(&x);
    MatDestroy(&J);
  }
}

namespace {

/// A vector of the fluid's global layout whose value at natural unknown i is sin(1 + 0.37 i): the same
/// vector on any number of ranks.
Vec natural_pattern(const fluid::FluidSolver& fs) {
  Vec natural, g;
  CELLFSI_PETSC(DMDACreateNaturalVector(fs.dm(), &natural));
  PetscInt lo = 0, hi = 0;
  CELLFSI_PETSC(VecGetOwnershipRange(natural, &lo, &hi));
  PetscScalar* a = nullptr;
  CELLFSI_PETSC(VecGetArray(natural, &a));
  for (PetscInt i = lo; i < hi; ++i) a[i - lo] = std::sin(1.0 + 0.37 * static_cast<double>(i));
  CELLFSI_PETSC(VecRestoreArray(natural, &a));
  CELLFSI_PETSC(DMCreateGlobalVector(fs.dm(), &g));
  CELLFSI_PETSC(DMDANaturalToGlobalBegin(fs.dm(), natural, INSERT_VALUES, g));
  CELLFSI_PETSC(DMDANaturalToGlobalEnd(fs.dm(), natural, INSERT_VALUES, g));
  VecDestroy(&natural);
  return g;
}

/// FGMRES on M x = b (rtol 1e-10) preconditioned by `solver` (a PCSHELL around RegionCorrectedSolver::apply).
struct FgmresResult {
  int iterations = 0;
  KSPConvergedReason reason = KSP_CONVERGED_ITERATING;
};
FgmresResult fgmres_with(solvers::RegionCorrectedSolver& solver, Mat M, Vec b, Vec x, int max_iterations) {
  KSP ksp;
  CELLFSI_PETSC(KSPCreate(PetscObjectComm(reinterpret_cast<PetscObject>(M)), &ksp));
  CELLFSI_PETSC(KSPSetType(ksp, KSPFGMRES));
  CELLFSI_PETSC(KSPSetOperators(ksp, M, M));
  CELLFSI_PETSC(KSPSetTolerances(ksp, 1e-10, 1e-50, PETSC_DEFAULT, max_iterations));
  CELLFSI_PETSC(KSPGMRESSetRestart(ksp, max_iterations));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, PCSHELL));
  CELLFSI_PETSC(PCShellSetContext(pc, &solver));
  CELLFSI_PETSC(PCShellSetApply(pc, [](PC p, Vec a, Vec c) -> PetscErrorCode {
    void* ctx = nullptr;
    PetscCall(PCShellGetContext(p, &ctx));
    static_cast<solvers::RegionCorrectedSolver*>(ctx)->apply(a, c);
    return 0;
  }));
  CELLFSI_PETSC(KSPSolve(ksp, b, x));
  FgmresResult out;
  PetscInt its = 0;
  CELLFSI_PETSC(KSPGetIterationNumber(ksp, &its));
  out.iterations = static_cast<int>(its);
  CELLFSI_PETSC(KSPGetConvergedReason(ksp, &out.reason));
  KSPDestroy(&ksp);
  return out;
}

struct RegionSolve {
  int iterations = 0;
  KSPConvergedReason reason = KSP_CONVERGED_ITERATING;
  PetscInt region = 0;
  double residual = 1;
  std::vector<double> x;  // natural ordering, on rank 0
  std::string region_type;  // the factorised region's matrix type
  PetscInt mumps_ordering = -1;  // MUMPS' INFOG(7): the ordering it used (1: the one PETSc gave)
  double mumps_operations = 0;   // MUMPS' RINFOG(1): operations of the elimination
};

/// The 2D shear box (32 x 16 cubic) with s_I = 1e10 on a ring of control values and 40 immersed points on
/// it, on the ranks of comm: J x = J y solved by FGMRES (rtol 1e-10) preconditioned by the region-corrected
/// Fourier solver (corrected = false: a threshold no row reaches, i.e. the bulk solver alone).
RegionSolve solve_ring(MPI_Comm comm, bool corrected) {
  const double lx = 0.0024, ly = 0.0012, shear = 70.0;
  const geometry::Patch box = geometry::rectangle(lx, ly, 32, 16, 3, {true, false}, Vec3(0, -ly / 2, 0));
  fluid::FluidOptions opt;
  opt.wall_velocity[1][0] = Vec3(-shear * ly / 2, 0, 0);
  opt.wall_velocity[1][1] = Vec3(shear * ly / 2, 0, 0);
  fluid::FluidSolver fs(comm, box, opt);
  fs.set_initial_velocity([&](const Vec3& x) { return Vec3(shear * x[1], 0, 0); });
  const int n0 = box.n_control(0), n1 = box.n_control(1);
  fs.set_scaling([&](int node) {
    const double x = (node % n0 + 0.5) / n0 - 0.5, y = (node / n0 + 0.5) / n1 - 0.5;
    const double r = std::hypot(x / 0.25, y / 0.4);
    return std::abs(r - 1) < 0.12 ? 1e10 : 1.0;
  });
  std::vector<fluid::ImmersedPointData> pts;
  for (int i = 0; i < 40; ++i) {
    fluid::ImmersedPointData d;
    const double a = 2 * M_PI * i / 40;
    d.x = Vec3(lx / 2 + 0.25 * lx * std::cos(a), 0.4 * ly * std::sin(a), 0);
    d.data.weight = 1e-9;
    d.data.stiffness_viscosity = 0.5;
    pts.push_back(d);
  }
  fs.set_immersed_points(pts);
  Mat J, Jb;
  CELLFSI_PETSC(MatDuplicate(fs.jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, &J));
  CELLFSI_PETSC(MatDuplicate(fs.jacobian_matrix(), MAT_DO_NOT_COPY_VALUES, &Jb));
  fs.bulk_jacobian(fs.solution(), Jb);
  fs.evaluate_jacobian(fs.solution(), J);
  MatNullSpace nsp;
  CELLFSI_PETSC(MatGetNullSpace(fs.jacobian_matrix(), &nsp));
  CELLFSI_PETSC(MatSetNullSpace(J, nsp));
  Vec y = natural_pattern(fs), r, x;
  CELLFSI_PETSC(VecDuplicate(y, &r));
  CELLFSI_PETSC(VecDuplicate(y, &x));
  CELLFSI_PETSC(MatMult(J, y, r));
  AO natural = nullptr;
  CELLFSI_PETSC(DMDAGetAO(fs.dm(), &natural));
  RegionSolve out;
  {
    solvers::RegionCorrectedSolver pc_solver({n0, n1, 1}, {true, false, false}, {3, 3, 0}, 3, "test_region_",
                                           comm, natural);
    pc_solver.set_bulk(Jb, true);
    if (!corrected) pc_solver.set_region(1e300, 0);
    pc_solver.set_operator(J);
    out.region = pc_solver.n_region();
    if (KSP region_ksp = pc_solver.region_ksp()) {
      Mat op, factor;
      PC pc;
      MatType type;
      CELLFSI_PETSC(KSPGetOperators(region_ksp, &op, nullptr));
      CELLFSI_PETSC(MatGetType(op, &type));
      out.region_type = type;
      CELLFSI_PETSC(KSPGetPC(region_ksp, &pc));
      CELLFSI_PETSC(PCFactorGetMatrix(pc, &factor));
      CELLFSI_PETSC(MatMumpsGetInfog(factor, 7, &out.mumps_ordering));
      CELLFSI_PETSC(MatMumpsGetRinfog(factor, 1, &out.mumps_operations));
    }
    const FgmresResult f = fgmres_with(pc_solver, J, r, x, 200);
    out.iterations = f.iterations;
    out.reason = f.reason;
    out.residual = relative_residual(J, x, r);
  }
  out.x = fs.gather_to_zero(x);
  VecDestroy(&y);
  VecDestroy(&r);
  VecDestroy(&x);
  MatDestroy(&J);
  MatDestroy(&Jb);
  return out;
}

}  // namespace

TEST(RegionCorrectedSolver, SolvesTheJacobianWithAnInterfaceBandInAFewIterations) {
  // FGMRES with the Fourier bulk solver and the region's LU reaches rtol 1e-10 in a few iterations
  // (measured: 11); without the region correction it does not get there in 200.
  for (const bool corrected : {true, false}) {
    const RegionSolve s = solve_ring(PETSC_COMM_SELF, corrected);
    if (corrected) {
      EXPECT_GT(s.region, 0);
      EXPECT_GT(s.reason, 0);
      EXPECT_LE(s.iterations, 14);
      EXPECT_LT(s.residual, 1e-9);
    } else {
      EXPECT_EQ(s.region, 0);
      EXPECT_TRUE(s.reason < 0 || s.iterations > 50) << "without the region correction: " << s.iterations;
    }
  }
}

TEST(RegionCorrectedSolver, OrdersTheRegionByNestedDissectionWhenAskedWithTheSameAnswer) {
  // In 2D the region stays BAIJ and MUMPS orders it itself (its default; in 3D on one rank the default is
  // cellfsi_nd). With -..._pc_factor_mat_ordering_type cellfsi_nd it goes to MUMPS as AIJ with SCOTCH's
  // nested dissection (solvers/nested_dissection.hpp). Either way the LU is exact, so FGMRES takes the same
  // iterations to the same solution.
  const RegionSolve own = solve_ring(PETSC_COMM_SELF, true);
  RegionSolve nd;
  {
    const char* name = "-test_region_region_pc_factor_mat_ordering_type";
    CELLFSI_PETSC(PetscOptionsSetValue(nullptr, name, solvers::kMatOrderingNestedDissection));
    nd = solve_ring(PETSC_COMM_SELF, true);
    PetscOptionsClearValue(nullptr, name);
  }
  EXPECT_EQ(own.region_type, MATSEQBAIJ);
  EXPECT_NE(own.mumps_ordering, 1);
  EXPECT_EQ(nd.region_type, MATSEQAIJ);
  EXPECT_EQ(nd.mumps_ordering, 1);
  EXPECT_GT(nd.mumps_operations, 0);
  EXPECT_LT(nd.mumps_operations, 2 * own.mumps_operations);  // not a bad order (2D ring: similar counts)
  EXPECT_EQ(nd.iterations, own.iterations);
  EXPECT_LT(nd.residual, 1e-9);
  ASSERT_EQ(nd.x.size(), own.x.size());
  double diff = 0, norm = 0;
  for (std::size_t i = 0; i < nd.x.size(); ++i) {
    diff = std::max(diff, std::abs(nd.x[i] - own.x[i]));
    norm = std::max(norm, std::abs(own.x[i]));
  }
  EXPECT_LT(diff, 1e-8 * norm);
}

TEST(RegionCorrectedSolver, FactorisesInDoublePrecisionWhenTheSingleOneFails) {
  // In 3D the region's LU is in single precision (cellfsi_lu_single). A region singular to single precision but
  // not to double: one node's two rows replaced by c [1 1; 1 1 + 1e-9] (float rounds 1 + 1e-9 to 1, so MUMPS'
  // smumps meets a zero pivot). The solver then factorises it in double precision, for this and every later
  // region, says why, and FGMRES solves J as it would have.
  cellfsi::test::set_up_pc_types_once();
  const std::array<int, 3> n{6, 5, 6};
  const std::array<bool, 3> periodic{true, false, true};
  const int dof = 2;
  Mat A = invariant_operator(n, periodic, 1, dof, 17);
  for (const double gap : {1e-3, 1e-9}) {
    SCOPED_TRACE(gap);
    Mat J;
    CELLFSI_PETSC(MatDuplicate(A, MAT_COPY_VALUES, &J));
    const PetscInt node = 2 + n[0] * (2 + n[1] * 3), rows[2] = {node * dof, node * dof + 1};
    CELLFSI_PETSC(MatSetOption(J, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));
    CELLFSI_PETSC(MatZeroRows(J, 2, rows, 0.0, nullptr, nullptr));
    const double c = 1e6, block[4] = {c, c, c, c * (1 + gap)};
    CELLFSI_PETSC(MatSetValues(J, 2, rows, 2, rows, block, INSERT_VALUES));
    CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
    RegionCorrectedSolver solver(n, periodic, {1, 1, 1}, dof, "test_fallback_");
    solver.set_bulk(A, false);
    solver.set_operator(J);
    EXPECT_EQ(solver.n_region(), dof);
    PC pc;
    CELLFSI_PETSC(KSPGetPC(solver.region_ksp(), &pc));
    const bool single = solvers::pc_is(pc, solvers::kPCLUSingle);
    if (gap == 1e-3) {
      EXPECT_TRUE(single);
      EXPECT_TRUE(solver.single_precision_failure().empty());
    } else {
      EXPECT_FALSE(single);
      EXPECT_NE(solver.single_precision_failure().find("INFOG(1) = -10"), std::string::npos)
          << solver.single_precision_failure();
      // A later region stays in double precision.
      solver.set_operator(A);
      solver.set_operator(J);
      CELLFSI_PETSC(KSPGetPC(solver.region_ksp(), &pc));
      EXPECT_FALSE(solvers::pc_is(pc, solvers::kPCLUSingle));
    }
    Vec b = random_vector(J, 3), x;
    CELLFSI_PETSC(VecDuplicate(b, &x));
    const FgmresResult f = fgmres_with(solver, J, b, x, 100);
    EXPECT_GT(f.reason, 0);
    // To the attainable accuracy: the near-singular block has a condition number of 4e9 (measured: 8e-8).
    EXPECT_LT(relative_residual(J, x, b), gap == 1e-3 ? 1e-9 : 1e-6);
    VecDestroy(&b);
    VecDestroy(&x);
    MatDestroy(&J);
  }
  MatDestroy(&A);
}

TEST(NearOperator, IsTheAssembledRowsNearTheCellsAndTheStencilElsewhere) {
  // A bulk operator A (a quadratic-like stencil in a channel, walls across) and J = A changed on a patch of
  // nodes, as the cells change the Jacobian. The operator from J's rows on a set of nodes around the patch
  // (the other rows of that matrix deliberately wrong: they must not count) is J; the region-corrected
  // solver reads the same region from it and FGMRES takes the same iterations.
  const std::array<int, 3> n{10, 7, 1};
  const int dof = 3;
  Mat A = invariant_operator(n, {true, false, false}, 2, dof, 5);
  Mat J, near;
  CELLFSI_PETSC(MatDuplicate(A, MAT_COPY_VALUES, &J));
  auto node = [&](int i, int j) { return i + n[0] * j; };
  std::vector<char> near_nodes(n[0] * n[1], 0);
  for (int j = 2; j <= 4; ++j)
    for (int i = 3; i <= 5; ++i)
      for (int c = 0; c < dof; ++c) {
        const PetscInt row = node(i, j) * dof + c;
        CELLFSI_PETSC(MatSetValue(J, row, row, 40.0, ADD_VALUES));
        CELLFSI_PETSC(MatSetValue(J, row, node(i + 1, j) * dof + (c + 1) % dof, -3.0, ADD_VALUES));
      }
  CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  for (int j = 1; j <= 5; ++j)
    for (int i = 2; i <= 6; ++i) near_nodes[node(i, j)] = 1;
  CELLFSI_PETSC(MatDuplicate(J, MAT_COPY_VALUES, &near));
  std::vector<PetscInt> other_rows;
  for (int k = 0; k < n[0] * n[1]; ++k)
    if (!near_nodes[k])
      for (int c = 0; c < dof; ++c) other_rows.push_back(k * dof + c);
  CELLFSI_PETSC(MatZeroRows(near, static_cast<PetscInt>(other_rows.size()), other_rows.data(), 7.0, nullptr,
                            nullptr));
  FourierBulkSolver bulk(n, {true, false, false}, {2, 2, 0}, dof);
  bulk.build(A, false);
  Mat op = create_near_operator(bulk, near, near_nodes);
  ASSERT_NE(near_operator(op), nullptr);
  EXPECT_EQ(near_operator(J), nullptr);
  Vec x = random_vector(A, 9), y, z;
  CELLFSI_PETSC(VecDuplicate(x, &y));
  CELLFSI_PETSC(VecDuplicate(x, &z));
  CELLFSI_PETSC(MatMult(J, x, y));
  CELLFSI_PETSC(MatMult(op, x, z));
  EXPECT_LT(relative_difference(y, z), 1e-14);
  // The same region and iterations with the operator as with J.
  int iterations[2] = {0, 0};
  PetscInt region[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    const Mat M = k == 0 ? J : op;
    RegionCorrectedSolver rc(n, {true, false, false}, {2, 2, 0}, dof, "test_near_");
    rc.set_bulk(A, false);
    rc.set_operator(M);
    region[k] = rc.n_region();
    iterations[k] = fgmres_with(rc, M, y, z, 100).iterations;
    EXPECT_LT(relative_residual(J, z, y), 1e-9);
  }
  EXPECT_EQ(region[0], 9 * dof);  // the changed patch, 3 x 3 nodes
  EXPECT_EQ(region[1], region[0]);
  EXPECT_EQ(iterations[1], iterations[0]);
  // A region grown beyond the held rows is refused.
  RegionCorrectedSolver wide(n, {true, false, false}, {2, 2, 0}, dof, "test_near_");
  wide.set_bulk(A, false);
  wide.set_region(1e-3, 2);
  EXPECT_THROW(wide.set_operator(op), std::runtime_error);
  VecDestroy(&x);
  VecDestroy(&y);
  VecDestroy(&z);
  MatDestroy(&op);
  MatDestroy(&near);
  MatDestroy(&J);
  MatDestroy(&A);
}

TEST(FourierPCType, FindsItsBulkSolverOnTheOperatorAndSolvesAsTheSolverItHolds) {
  // cellfsi_fourier (solvers/pc_fourier.hpp) on J = a bulk operator A changed on a 3 x 3 patch of nodes: set
  // up without a bulk solver on J it says what is missing; with A's composed on J (pc_fourier_compose_bulk)
  // it finds the same region as a RegionCorrectedSolver of that bulk solver and FGMRES takes the same
  // iterations (the same operations in the same order: exactly).
  cellfsi::test::set_up_pc_types_once();
  const std::array<int, 3> n{10, 7, 1};
  const int dof = 3;
  Mat A = invariant_operator(n, {true, false, false}, 2, dof, 5), J;
  CELLFSI_PETSC(MatDuplicate(A, MAT_COPY_VALUES, &J));
  for (int j = 2; j <= 4; ++j)
    for (int i = 3; i <= 5; ++i)
      for (int c = 0; c < dof; ++c) {
        const PetscInt row = (i + n[0] * j) * dof + c;
        CELLFSI_PETSC(MatSetValue(J, row, row, 40.0, ADD_VALUES));
      }
  CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  auto bulk = std::make_shared<FourierBulkSolver>(n, std::array<bool, 3>{true, false, false},
                                                  std::array<int, 3>{2, 2, 0}, dof);
  bulk->build(A, false);
  Vec x = random_vector(A, 9), b, reference;
  CELLFSI_PETSC(VecDuplicate(x, &b));
  CELLFSI_PETSC(VecDuplicate(x, &reference));
  CELLFSI_PETSC(MatMult(J, x, b));
  RegionCorrectedSolver rc(bulk, "test_pc_fourier_");
  rc.set_operator(J);
  const FgmresResult expected = fgmres_with(rc, J, b, reference, 100);

  KSP ksp;
  CELLFSI_PETSC(KSPCreate(PETSC_COMM_SELF, &ksp));
  CELLFSI_PETSC(KSPSetOptionsPrefix(ksp, "test_pc_"));
  CELLFSI_PETSC(KSPSetType(ksp, KSPFGMRES));
  CELLFSI_PETSC(KSPSetTolerances(ksp, 1e-10, 1e-50, PETSC_DEFAULT, 100));
  CELLFSI_PETSC(KSPGMRESSetRestart(ksp, 100));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, solvers::kPCFourier));
  CELLFSI_PETSC(KSPSetOperators(ksp, J, J));
  try {
    CELLFSI_PETSC(KSPSetUp(ksp));
    ADD_FAILURE() << "no error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("pc_fourier_compose_bulk"), std::string::npos) << e.what();
  }
  KSPDestroy(&ksp);  // (a new KSP: this one is left as its set-up failed)
  CELLFSI_PETSC(KSPCreate(PETSC_COMM_SELF, &ksp));
  CELLFSI_PETSC(KSPSetOptionsPrefix(ksp, "test_pc_"));
  CELLFSI_PETSC(KSPSetType(ksp, KSPFGMRES));
  CELLFSI_PETSC(KSPSetTolerances(ksp, 1e-10, 1e-50, PETSC_DEFAULT, 100));
  CELLFSI_PETSC(KSPGMRESSetRestart(ksp, 100));
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, solvers::kPCFourier));
  CELLFSI_PETSC(KSPSetOperators(ksp, J, J));
  solvers::pc_fourier_compose_bulk(J, bulk);
  CELLFSI_PETSC(KSPSolve(ksp, b, x));
  PetscInt its = 0;
  CELLFSI_PETSC(KSPGetIterationNumber(ksp, &its));
  EXPECT_EQ(static_cast<int>(its), expected.iterations);
  const solvers::RegionCorrectedSolver* held = solvers::pc_fourier_solver(pc);
  ASSERT_NE(held, nullptr);
  EXPECT_EQ(&held->bulk(), bulk.get());
  EXPECT_EQ(held->n_region(), 9 * dof);  // the changed patch
  EXPECT_EQ(held->n_region(), rc.n_region());
  EXPECT_EQ(relative_difference(x, reference), 0.0);
  EXPECT_LT(relative_residual(J, x, b), 1e-9);
  solvers::pc_fourier_compose_bulk(J, nullptr);
  KSPDestroy(&ksp);
  VecDestroy(&x);
  VecDestroy(&b);
  VecDestroy(&reference);
  MatDestroy(&J);
  MatDestroy(&A);
}

// Run on 2 ranks by the test fluid_parallel_2ranks (on 1 rank it compares the solver with itself).
TEST(FourierParallel, RegionCorrectedSolverOnAllRanksAsOnOne) {
  // The solver on the ranks of PETSC_COMM_WORLD (slabs of layers and shares of the wave vectors exchanged,
  // the region's LU by MUMPS on every rank) against one rank: the same region, the same iterations (up to
  // one: round-off in the averaged stencil's sums) and the same solution to the solves' tolerance.
  const RegionSolve one = solve_ring(PETSC_COMM_SELF, true), all = solve_ring(PETSC_COMM_WORLD, true);
  EXPECT_EQ(one.region, all.region);
  EXPECT_GT(all.reason, 0);
  EXPECT_LE(std::abs(one.iterations - all.iterations), 1) << one.iterations << " vs " << all.iterations;
  EXPECT_LT(all.residual, 1e-9);
  PetscMPIInt rank = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  if (rank == 0) {
    ASSERT_EQ(one.x.size(), all.x.size());
    double scale = 0, diff = 0;
    for (std::size_t i = 0; i < one.x.size(); ++i) {
      scale = std::max(scale, std::abs(one.x[i]));
      diff = std::max(diff, std::abs(one.x[i] - all.x[i]));
    }
    EXPECT_LT(diff, 1e-8 * scale);
  }
}

TEST(FourierParallel, BulkSolverInvertsTheDistributedJacobian) {
  // The 3D shear box (quadratic, walls in y) on PETSC_COMM_WORLD: the exact inverse of the bulk Jacobian
  // (constant-pressure null space, consistent right-hand side) and the node deviations by natural index,
  // whatever the partition.
  const double ly = 0.0012, shear = 70.0;
  const geometry::Patch box = geometry::box(ly, ly, ly, 6, 5, 4, 2, {true, false, true}, Vec3(0, -ly / 2, 0));
  Mat J;
  const std::unique_ptr<fluid::FluidSolver> solver = shear_box_fluid(box, ly, shear, &J);
  fluid::FluidSolver& fs = *solver;
  AO natural = nullptr;
  CELLFSI_PETSC(DMDAGetAO(fs.dm(), &natural));
  const std::array<int, 3> n{box.n_control(0), box.n_control(1), box.n_control(2)};
  FourierBulkSolver s(n, {true, false, true}, {2, 2, 2}, 4, PETSC_COMM_WORLD, natural);
  s.build(J, true);
  EXPECT_LT(s.deviation(), 1e-12);
  Vec y = natural_pattern(fs), r, x;
  CELLFSI_PETSC(VecDuplicate(y, &r));
  CELLFSI_PETSC(VecDuplicate(y, &x));
  CELLFSI_PETSC(MatMult(J, y, r));
  s.solve(r, x);
  EXPECT_LT(relative_residual(J, x, r), 1e-10);
  // The stencil's product without the matrix, on the ranks' slabs.
  s.multiply(y, x);
  EXPECT_LT(relative_difference(r, x), 1e-13);
  // One entry changed at natural node 37 (added by rank 0 wherever the row lives): that node, and only it,
  // differs, on every rank.
  PetscInt row = 37 * 4 + 1;
  CELLFSI_PETSC(AOApplicationToPetsc(natural, 1, &row));
  PetscMPIInt rank = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  if (rank == 0) CELLFSI_PETSC(MatSetValue(J, row, row, 1e3, ADD_VALUES));
  CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  const std::vector<double> dev = s.node_deviation(J);
  ASSERT_EQ(static_cast<int>(dev.size()), n[0] * n[1] * n[2]);
  for (int i = 0; i < static_cast<int>(dev.size()); ++i) {
    if (i == 37)
      EXPECT_GT(dev[i], 1e-2);
    else
      EXPECT_LT(dev[i], 1e-12) << "node " << i;
  }
  VecDestroy(&y);
  VecDestroy(&r);
  VecDestroy(&x);
  MatDestroy(&J);
}
