// The coupled solvers as PETSc PC types (solvers/pc_types.hpp, one file per type): chosen by
// -<prefix>pc_type, configured by their options, shown by KSPView, finding what they need on their operator,
// and solving like the solver objects they hold.
#include <gtest/gtest.h>

#include <petscksp.h>

#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "test_operators.hpp"
#include "common/petsc_error.hpp"
#include "solvers/pc_types.hpp"

using cellfsi::test::Grid;
using cellfsi::test::kBs;
using cellfsi::test::view_text;
constexpr auto set_up_once = cellfsi::test::set_up_pc_types_once;
namespace solvers = cellfsi::solvers;

namespace {

/// Sets an option for the duration of a test.
struct ScopedOption {
  std::string name;
  ScopedOption(std::string n, const char* value) : name(std::move(n)) {
    CELLFSI_PETSC(PetscOptionsSetValue(nullptr, name.c_str(), value));
  }
  ~ScopedOption() { PetscOptionsClearValue(nullptr, name.c_str()); }
};

/// The band problem of test_band_schur.cpp: a kept part outside the cells 5 <= i < 9, a band part on them
/// (one strip scaled by 1e10, like s_I), and the band's unknowns.
struct BandProblem {
  Grid g;
  Mat fixed = nullptr, K = nullptr;
  IS band = nullptr;
  Vec r = nullptr, x = nullptr;
  BandProblem() {
    std::mt19937 rng(11);
    auto in_region = [](int i, int) { return i >= 5 && i < 9; };
    fixed = g.assemble(rng, [&](int i, int j) { return !in_region(i, j); }, [](int, int) { return 1.0; });
    Mat part = g.assemble(rng, in_region, [](int i, int) { return i == 6 ? 1e10 : 1.0; });
    CELLFSI_PETSC(MatDuplicate(fixed, MAT_COPY_VALUES, &K));
    CELLFSI_PETSC(MatAXPY(K, 1.0, part, SAME_NONZERO_PATTERN));
    MatDestroy(&part);
    std::vector<PetscInt> idx;
    for (int j = 0; j < g.ny; ++j)
      for (int i = 5; i <= 9; ++i)
        for (int c = 0; c < kBs; ++c) idx.push_back(g.node(i, j) * kBs + c);
    CELLFSI_PETSC(ISCreateGeneral(PETSC_COMM_SELF, static_cast<PetscInt>(idx.size()), idx.data(),
                                  PETSC_COPY_VALUES, &band));
    CELLFSI_PETSC(MatCreateVecs(K, &x, &r));
    cellfsi::test::fill_random(r, rng);
  }
  ~BandProblem() {
    MatDestroy(&fixed);
    MatDestroy(&K);
    ISDestroy(&band);
    VecDestroy(&r);
    VecDestroy(&x);
  }
  double relative_residual() const { return cellfsi::test::relative_residual(K, x, r); }
};

}  // namespace

TEST(PCTypes, BandTypeIsChosenByOptionsAndSolvesExactlyInOneIteration) {
  set_up_once();
  BandProblem p;
  ScopedOption type("-t_pc_type", "cellfsi_band"), blr("-t_pc_band_blr_tolerance", "0"),
      ksp_type("-t_ksp_type", "fgmres");
  KSP ksp;
  CELLFSI_PETSC(KSPCreate(PETSC_COMM_SELF, &ksp));
  CELLFSI_PETSC(KSPSetOptionsPrefix(ksp, "t_"));
  CELLFSI_PETSC(KSPSetFromOptions(ksp));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  ASSERT_TRUE(solvers::pc_is(pc, solvers::kPCBand));
  solvers::pc_band_compose_split(p.K, p.fixed, p.band);  // what the PC finds on its operator
  CELLFSI_PETSC(KSPSetOperators(ksp, p.K, p.K));
  CELLFSI_PETSC(KSPSetTolerances(ksp, 1e-10, 1e-50, PETSC_DEFAULT, 10));
  CELLFSI_PETSC(KSPSolve(ksp, p.r, p.x));
  PetscInt its = 0;
  CELLFSI_PETSC(KSPGetIterationNumber(ksp, &its));
  // The PC is the exact inverse of K (its band part found as K - K_fixed on the band): one iteration.
  EXPECT_LE(its, 1);
  EXPECT_LT(p.relative_residual(), 1e-10);
  const std::string text = view_text(ksp);
  EXPECT_NE(text.find("type: cellfsi_band"), std::string::npos) << text;
  EXPECT_NE(text.find("block low-rank tolerance of the kept part 0"), std::string::npos) << text;
  EXPECT_NE(text.find("band: 150 of 420 unknowns, edge 60"), std::string::npos) << text;
  // A second set-up on the same split keeps the kept part's factors; new entries of the kept part (its state
  // rises) factorise it again: the same answer either way.
  const solvers::BandSchurSolver* band = solvers::pc_band_solver(pc);
  ASSERT_NE(band, nullptr);
  CELLFSI_PETSC(MatAssemblyBegin(p.K, MAT_FINAL_ASSEMBLY));  // (K's state rises: KSP sets the PC up again)
  CELLFSI_PETSC(MatAssemblyEnd(p.K, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(KSPSolve(ksp, p.r, p.x));
  EXPECT_EQ(solvers::pc_band_solver(pc), band);
  EXPECT_LT(p.relative_residual(), 1e-10);
  CELLFSI_PETSC(MatAssemblyBegin(p.fixed, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(p.fixed, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyBegin(p.K, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(p.K, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(KSPSolve(ksp, p.r, p.x));
  EXPECT_LT(p.relative_residual(), 1e-10);
  KSPDestroy(&ksp);
}

TEST(PCTypes, ABadOptionValueIsRefusedNamingIt) {
  set_up_once();
  ScopedOption type("-t_pc_type", "cellfsi_fourier"), bad("-t_pc_fourier_threshold", "-1");
  KSP ksp;
  CELLFSI_PETSC(KSPCreate(PETSC_COMM_SELF, &ksp));
  CELLFSI_PETSC(KSPSetOptionsPrefix(ksp, "t_"));
  try {
    CELLFSI_PETSC(KSPSetFromOptions(ksp));
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("-t_pc_fourier_threshold -1"), std::string::npos) << what;
    EXPECT_NE(what.find("is invalid. Valid values are > 0"), std::string::npos) << what;
  }
  KSPDestroy(&ksp);
}

TEST(PCTypes, SetUpWithoutTheOwnersDataSaysWhatIsMissing) {
  set_up_once();
  BandProblem p;
  KSP ksp;
  CELLFSI_PETSC(KSPCreate(PETSC_COMM_SELF, &ksp));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp, &pc));
  CELLFSI_PETSC(PCSetType(pc, solvers::kPCBand));
  CELLFSI_PETSC(KSPSetOperators(ksp, p.K, p.K));
  try {
    CELLFSI_PETSC(KSPSetUp(ksp));
    ADD_FAILURE() << "no error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("pc_band_compose_split"), std::string::npos) << e.what();
  }
  // Another type afterwards: the PC is a plain PETSc PC again.
  CELLFSI_PETSC(PCSetType(pc, PCJACOBI));
  EXPECT_FALSE(solvers::pc_is(pc, solvers::kPCBand));
  EXPECT_EQ(solvers::pc_band_solver(pc), nullptr);
  KSPDestroy(&ksp);
}
