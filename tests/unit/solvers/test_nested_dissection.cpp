// The region's fill-reducing ordering (solvers/nested_dissection.hpp): SCOTCH's nested dissection of a
// graph, and the PETSc ordering type that hands it to MUMPS.
#include <gtest/gtest.h>

#include <petscksp.h>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "test_operators.hpp"
#include "common/petsc_error.hpp"
#include "solvers/nested_dissection.hpp"

namespace solvers = cellfsi::solvers;
using cellfsi::test::Grid;
using cellfsi::test::kBs;

namespace {

/// The 5-point graph of an n x n grid, in CSR form.
void grid_graph(int n, std::vector<int>& xadj, std::vector<int>& adj) {
  xadj.assign(1, 0);
  adj.clear();
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      if (i > 0) adj.push_back(i - 1 + n * j);
      if (i + 1 < n) adj.push_back(i + 1 + n * j);
      if (j > 0) adj.push_back(i + n * (j - 1));
      if (j + 1 < n) adj.push_back(i + n * (j + 1));
      xadj.push_back(static_cast<int>(adj.size()));
    }
}

/// Sizes of the connected parts of the graph without the vertices `removed`.
std::vector<int> parts_without(const std::vector<int>& xadj, const std::vector<int>& adj,
                               const std::vector<char>& removed) {
  const int n = static_cast<int>(xadj.size()) - 1;
  std::vector<char> seen(removed);
  std::vector<int> sizes, stack;
  for (int s = 0; s < n; ++s) {
    if (seen[s]) continue;
    int size = 0;
    stack.assign(1, s);
    seen[s] = 1;
    while (!stack.empty()) {
      const int v = stack.back();
      stack.pop_back();
      ++size;
      for (int k = xadj[v]; k < xadj[v + 1]; ++k)
        if (!seen[adj[k]]) {
          seen[adj[k]] = 1;
          stack.push_back(adj[k]);
        }
    }
    sizes.push_back(size);
  }
  return sizes;
}

/// An LU solve of A x = 1 by `package` with the ordering type `ordering`: the relative residual, and for MUMPS
/// its INFOG(7) (ordering used) and INFOG(20) (entries in the factors).
struct LuRun {
  PetscInt ordering_used = -1, entries = 0;
  double residual = 1;
};
LuRun lu_solve(Mat A, const char* package, const char* ordering) {
  KSP ksp;
  PC pc;
  CELLFSI_PETSC(KSPCreate(PETSC_COMM_SELF, &ksp));
  CELLFSI_PETSC(KSPSetOperators(ksp, A, A));
  CELLFSI_PETSC(KSPSetType(ksp, KSPPREONLY));
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, PCLU));
  CELLFSI_PETSC(PCFactorSetMatSolverType(pc, package));
  CELLFSI_PETSC(PCFactorSetMatOrderingType(pc, ordering));
  CELLFSI_PETSC(KSPSetUp(ksp));
  LuRun out;
  PetscBool mumps = PETSC_FALSE;
  CELLFSI_PETSC(PetscStrcmp(package, MATSOLVERMUMPS, &mumps));
  if (mumps) {
    Mat F;
    CELLFSI_PETSC(PCFactorGetMatrix(pc, &F));
    CELLFSI_PETSC(MatMumpsGetInfog(F, 7, &out.ordering_used));
    CELLFSI_PETSC(MatMumpsGetInfog(F, 20, &out.entries));
  }
  Vec b, x;
  CELLFSI_PETSC(MatCreateVecs(A, &x, &b));
  CELLFSI_PETSC(VecSet(b, 1.0));
  CELLFSI_PETSC(KSPSolve(ksp, b, x));
  out.residual = cellfsi::test::relative_residual(A, x, b);
  VecDestroy(&b);
  VecDestroy(&x);
  KSPDestroy(&ksp);
  return out;
}

/// The fluid Jacobian's shape on an nx x ny grid of nodes: SeqBAIJ blocks of kBs unknowns, every cell filled.
Mat full_grid(int nx, int ny, unsigned seed) {
  Grid g;
  g.nx = nx;
  g.ny = ny;
  std::mt19937 rng(seed);
  return g.assemble(rng, [](int, int) { return true; }, [](int, int) { return 1.0; });
}

}  // namespace

TEST(NestedDissection, IsAPermutationThatOrdersASeparatorLast) {
  // A 31 x 31 grid: nested dissection orders a separator last, a line of about 31 vertices across the grid;
  // removing the last 40 vertices leaves the grid in at least two parts, none more than 60 % of it.
  const int n = 31;
  std::vector<int> xadj, adj;
  grid_graph(n, xadj, adj);
  const std::vector<int> position = solvers::nested_dissection(xadj, adj);
  ASSERT_EQ(position.size(), static_cast<std::size_t>(n * n));
  std::vector<int> sorted(position);
  std::sort(sorted.begin(), sorted.end());
  for (int i = 0; i < n * n; ++i) ASSERT_EQ(sorted[i], i);
  std::vector<char> last(n * n, 0);
  for (int v = 0; v < n * n; ++v) last[v] = position[v] >= n * n - 40;
  const std::vector<int> parts = parts_without(xadj, adj, last);
  EXPECT_GE(parts.size(), 2u);
  EXPECT_LE(*std::max_element(parts.begin(), parts.end()), 0.6 * n * n);
}

TEST(NestedDissection, TheSameGraphGivesTheSameOrderAtEveryCall) {
  // Debian's SCOTCH orders in threads with a random generator that runs on between calls: without a context
  // that fixes both, two orders of one graph differed (and so did repeated runs, by 5e-7 relative in the 3D
  // metrics). A 24 x 24 x 6 grid with the couplings of quadratic splines (every vertex within 2 in each
  // direction).
  const int nx = 24, ny = 24, nz = 6;
  std::vector<int> xadj{0}, adj;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        for (int c = -2; c <= 2; ++c)
          for (int b = -2; b <= 2; ++b)
            for (int a = -2; a <= 2; ++a) {
              const int ii = i + a, jj = j + b, kk = k + c;
              if ((a || b || c) && ii >= 0 && jj >= 0 && kk >= 0 && ii < nx && jj < ny && kk < nz)
                adj.push_back(ii + nx * (jj + ny * kk));
            }
        xadj.push_back(static_cast<int>(adj.size()));
      }
  const std::vector<int> first = solvers::nested_dissection(xadj, adj);
  std::vector<int> small_xadj, small_adj;
  grid_graph(9, small_xadj, small_adj);
  solvers::nested_dissection(small_xadj, small_adj);  // another graph in between
  EXPECT_EQ(solvers::nested_dissection(xadj, adj), first);
  EXPECT_EQ(solvers::nested_dissection(xadj, adj), first);
}

TEST(NestedDissection, RefusesAMalformedGraph) {
  EXPECT_THROW(solvers::nested_dissection({}, {}), std::invalid_argument);
  EXPECT_THROW(solvers::nested_dissection({0, 1, 3}, {1, 0}), std::invalid_argument);
  EXPECT_TRUE(solvers::nested_dissection({0}, {}).empty());
}

TEST(NestedDissection, GivesMumpsFewerEntriesThanTheNaturalOrderWithTheSameSolution) {
  // The ordering type on a 40 x 40 grid of 3-unknown blocks (the fluid Jacobian's shape, as AIJ): MUMPS takes
  // the order PETSc gives (INFOG(7) = 1), keeps a node's unknowns together, stores fewer entries than with
  // the natural (banded) order, and solves exactly.
  solvers::register_orderings();
  Mat B = full_grid(40, 40, 7);
  Mat A;
  CELLFSI_PETSC(MatConvert(B, MATAIJ, MAT_INITIAL_MATRIX, &A));
  IS row, col;
  CELLFSI_PETSC(MatGetOrdering(A, solvers::kMatOrderingNestedDissection, &row, &col));
  const PetscInt* position = nullptr;
  CELLFSI_PETSC(ISGetIndices(row, &position));
  for (PetscInt r = 0; r < 40 * 40 * kBs; ++r)  // a node's unknowns: consecutive positions, in their order
    ASSERT_EQ(position[r], position[r - r % kBs] + r % kBs) << "row " << r;
  CELLFSI_PETSC(ISRestoreIndices(row, &position));
  ISDestroy(&row);
  ISDestroy(&col);
  const LuRun nd = lu_solve(A, MATSOLVERMUMPS, solvers::kMatOrderingNestedDissection);
  const LuRun natural = lu_solve(A, MATSOLVERMUMPS, MATORDERINGNATURAL);
  EXPECT_EQ(nd.ordering_used, 1);
  EXPECT_EQ(natural.ordering_used, 1);
  EXPECT_LT(nd.entries, 0.7 * natural.entries) << nd.entries << " against " << natural.entries;
  EXPECT_LT(nd.residual, 1e-12);
  EXPECT_LT(natural.residual, 1e-12);
  MatDestroy(&A);
  MatDestroy(&B);
}

TEST(NestedDissection, OrdersABlockedMatrixByItsBlockRowsForPetscsOwnLU) {
  // On a BAIJ matrix PETSc orders block rows: the ordering is then one of nodes, and PETSc's own LU with it
  // solves exactly (a user who picks -..._pc_factor_mat_solver_type petsc keeps the region's default order).
  solvers::register_orderings();
  Mat A = full_grid(12, 9, 3);
  IS row, col;
  CELLFSI_PETSC(MatGetOrdering(A, solvers::kMatOrderingNestedDissection, &row, &col));
  PetscInt n = 0;
  CELLFSI_PETSC(ISGetSize(row, &n));
  EXPECT_EQ(n, 12 * 9);  // block rows
  ISDestroy(&row);
  ISDestroy(&col);
  EXPECT_LT(lu_solve(A, MATSOLVERPETSC, solvers::kMatOrderingNestedDissection).residual, 1e-12);
  MatDestroy(&A);
}
