// The coupled solve's policy (coupling/solver_policy.hpp): the defaults per dimension, the PC type per
// situation and its fallbacks, the memory plan, which options apply to which PC type, and the option table's
// defaults and ranges (the same values the PC types read).
#include <gtest/gtest.h>

#include <optional>
#include <stdexcept>
#include <string>

#include "common/option_table.hpp"
#include "coupling/solver_policy.hpp"
#include "geometry/builders.hpp"

using namespace cellfsi;
using coupling::LinearSolverOptions;

TEST(SolverPolicy, DefaultsPerDimension) {
  const LinearSolverOptions d2 = coupling::linear_solver_defaults(2),
                            d3 = coupling::linear_solver_defaults(3);
  EXPECT_EQ(d2.region_margin, 4);
  EXPECT_FALSE(d2.bulk_stencil);
  EXPECT_EQ(d2.rtol, 1e-5);
  EXPECT_EQ(d3.region_margin, 1);
  EXPECT_TRUE(d3.bulk_stencil);
  EXPECT_EQ(d3.rtol, 1e-2);
  // cellfsi_bulk applies its bulk inverse's stencil in both dimensions unless told otherwise; the other types
  // keep the dimension's default.
  EXPECT_EQ(coupling::pc_type_bulk_stencil("cellfsi_bulk"), std::optional<bool>(true));
  EXPECT_EQ(coupling::pc_type_bulk_stencil("cellfsi_fourier"), std::nullopt);
  EXPECT_EQ(coupling::pc_type_bulk_stencil("asm"), std::nullopt);
  EXPECT_EQ(coupling::pc_type_refresh_steps("cellfsi_bulk"), std::optional<int>(1));
  EXPECT_EQ(coupling::pc_type_refresh_steps("cellfsi_fourier"), std::nullopt);
  EXPECT_EQ(coupling::pc_type_refresh_steps("asm"), std::nullopt);
  // What does not depend on the dimension.
  for (const LinearSolverOptions& d : {d2, d3}) {
    EXPECT_EQ(d.pc_type, "");
    EXPECT_EQ(d.refresh_steps, 10);
    EXPECT_EQ(d.refresh_lag, 0);
    EXPECT_EQ(d.refactor_every, 0);
    EXPECT_TRUE(d.partial_jacobian);
    EXPECT_EQ(d.preconditioner_lag, 10);
    EXPECT_EQ(d.uniformity, 1e-2);
  }
  // The PETSc-PC path starts from the fluid's own defaults.
  EXPECT_EQ(coupling::kFluidRtol, 1e-5);
  EXPECT_EQ(coupling::PetscPCDefaults::asm_overlap, 4);
  EXPECT_EQ(coupling::PetscPCDefaults::options(false).size(), 2u);
  EXPECT_EQ(coupling::PetscPCDefaults::options(true).size(), 4u);  // with MUMPS' null-pivot detection
}

TEST(SolverPolicy, PCTypePerSituation) {
  coupling::SolverSituation s;  // BAIJ, one rank, Fourier applies
  EXPECT_EQ(coupling::default_pc_type(s), "cellfsi_fourier");
  s.fluid_ranks = 4;
  EXPECT_EQ(coupling::default_pc_type(s), "cellfsi_fourier");  // any number of ranks
  s.fourier_inapplicable = "the narrowing channel";
  EXPECT_EQ(coupling::default_pc_type(s), "asm");
  s.fluid_ranks = 1;
  EXPECT_EQ(coupling::default_pc_type(s), "cellfsi_band");
  s.baij = false;  // both cellfsi types need BAIJ
  EXPECT_EQ(coupling::default_pc_type(s), "asm");
  s.fourier_inapplicable.clear();
  EXPECT_EQ(coupling::default_pc_type(s), "asm");
  // cellfsi_fourier's fallback: cellfsi_band on one rank with BAIJ, else asm; cellfsi_band's: asm.
  EXPECT_EQ(coupling::fallback_pc_type(true, 1), "cellfsi_band");
  EXPECT_EQ(coupling::fallback_pc_type(true, 2), "asm");
  EXPECT_EQ(coupling::fallback_pc_type(false, 1), "asm");
  EXPECT_EQ(std::string(coupling::kBandFallbackPCType), "asm");
  // A region of more than half the elements holds most of the domain.
  EXPECT_FALSE(coupling::region_holds_most(50, 100));
  EXPECT_TRUE(coupling::region_holds_most(51, 100));
}

TEST(SolverPolicy, FourierAppliesToUniformBoxesWithAtMostOneWallDirection) {
  EXPECT_EQ(coupling::fourier_inapplicable(geometry::rectangle(1.0, 0.5, 8, 4, 2, {true, false})), "");
  const std::string two_walls =
      coupling::fourier_inapplicable(geometry::rectangle(1.0, 0.5, 8, 4, 2, {false, false}));
  EXPECT_NE(two_walls.find("2 non-periodic directions"), std::string::npos) << two_walls;
}

TEST(SolverPolicy, MemoryPlanDropsTheSecondCopyWhenFourAndAHalfJacobiansDoNotFit) {
  LinearSolverOptions o = coupling::linear_solver_defaults(2);
  const double gb = 1e9;
  // 4.5 Jacobians of 1 GB fit in 4.5 GB: both copies kept.
  coupling::MemoryPlan p = coupling::plan_memory("cellfsi_fourier", o, false, gb, 4.5 * gb);
  EXPECT_TRUE(p.partial_jacobian);
  EXPECT_EQ(p.jacobian_copies, 2);
  // In 4.4 GB the second copy goes.
  p = coupling::plan_memory("cellfsi_fourier", o, false, gb, 4.4 * gb);
  EXPECT_FALSE(p.partial_jacobian);
  EXPECT_EQ(p.jacobian_copies, 1);
  // Asked for, it stays.
  p = coupling::plan_memory("cellfsi_fourier", o, true, gb, 4.4 * gb);
  EXPECT_TRUE(p.partial_jacobian);
  EXPECT_EQ(p.jacobian_copies, 2);
  // With the bulk stencil (3D) there is one copy anyway, and nothing to drop.
  p = coupling::plan_memory("cellfsi_fourier", coupling::linear_solver_defaults(3), false, gb, 1.5 * gb);
  EXPECT_TRUE(p.partial_jacobian);
  EXPECT_EQ(p.jacobian_copies, 1);
  // cellfsi_band keeps three, a PETSc PC one; neither has a second copy to drop.
  p = coupling::plan_memory("cellfsi_band", o, false, gb, 1.5 * gb);
  EXPECT_TRUE(p.partial_jacobian);
  EXPECT_EQ(p.jacobian_copies, 3);
  EXPECT_EQ(coupling::plan_memory("asm", o, false, gb, 1.5 * gb).jacobian_copies, 1);
  EXPECT_EQ(coupling::jacobian_copies("cellfsi_fourier", false), 1);
  EXPECT_EQ(coupling::jacobian_copies("cellfsi_fourier", true, true), 1);
}

TEST(SolverPolicy, WhichOptionsApplyToWhichPCType) {
  const std::string fourier = "cellfsi_fourier", band = "cellfsi_band", asm_pc = "asm";
  // Each type's own options.
  EXPECT_EQ(coupling::option_inapplicable("coupling_bulk_stencil", "cellfsi_bulk"), "");
  for (const char* name : {"coupling_pc_fourier_threshold", "coupling_fourier_region_pc_type",
                           "coupling_partial_jacobian", "coupling_bulk_stencil"}) {
    EXPECT_EQ(coupling::option_inapplicable(name, fourier), "") << name;
    EXPECT_EQ(coupling::option_inapplicable(name, band),
              "this coupled run solves with -coupling_pc_type cellfsi_band")
        << name;
    EXPECT_EQ(coupling::option_inapplicable(name, asm_pc),
              "this coupled run solves with -coupling_pc_type asm")
        << name;
  }
  for (const char* name :
       {"coupling_pc_band_fused", "coupling_band_mat_mumps_icntl_14", "coupling_refactor_every"}) {
    EXPECT_EQ(coupling::option_inapplicable(name, band), "") << name;
    EXPECT_NE(coupling::option_inapplicable(name, fourier), "") << name;
  }
  // Both cellfsi types' refresh options, and the PETSc PCs' lag; -coupling_refresh_lag applies to every type
  // (a PETSc PC's Jacobian inside a step).
  EXPECT_EQ(coupling::option_inapplicable("coupling_refresh_lag", fourier), "");
  EXPECT_EQ(coupling::option_inapplicable("coupling_refresh_lag", band), "");
  EXPECT_EQ(coupling::option_inapplicable("coupling_refresh_lag", asm_pc), "");
  for (const char* name : {"coupling_region_margin", "coupling_refresh_steps"}) {
    EXPECT_EQ(coupling::option_inapplicable(name, fourier), "") << name;
    EXPECT_EQ(coupling::option_inapplicable(name, band), "") << name;
    EXPECT_EQ(coupling::option_inapplicable(name, asm_pc),
              "this coupled run solves with -coupling_pc_type asm, which refreshes its preconditioner every "
              "-coupling_pc_lag solves")
        << name;
  }
  EXPECT_EQ(coupling::option_inapplicable("coupling_pc_lag", asm_pc), "");
  EXPECT_EQ(coupling::option_inapplicable("coupling_pc_lag", fourier),
            "this coupled run solves with -coupling_pc_type cellfsi_fourier, which is refreshed by the "
            "motion of the "
            "cells (-coupling_refresh_steps)");
  // Options every PC type reads, and the fluid's solver options, which a coupled run does not.
  EXPECT_EQ(coupling::option_inapplicable("coupling_ksp_rtol", band), "");
  EXPECT_EQ(coupling::option_inapplicable("fluid_mat_type_jacobian", fourier), "");
  EXPECT_EQ(
      coupling::option_inapplicable("fluid_pc_type", asm_pc),
      "a coupled run solves with the KSP -coupling_ (e.g. -coupling_pc_type): -fluid_ solver options act on "
      "runs without cells");
  EXPECT_NE(coupling::option_inapplicable("fluid_snes_rtol", asm_pc).find("the coupling loop"),
            std::string::npos);
  // Renamed options.
  EXPECT_EQ(coupling::renamed_option("coupling_solver"), "coupling_pc_type");
  EXPECT_EQ(coupling::renamed_option("coupling_band_margin"), "coupling_region_margin");
  EXPECT_EQ(coupling::renamed_option("coupling_pc_type"), "");
}

TEST(SolverPolicy, WhenTheSolveReadsItsOptions) {
  // At the first solve: the inner solvers' and factorisations' options; not the KSP's or the PC type's.
  for (const char* name :
       {"coupling_fourier_region_pc_type", "coupling_band_mat_mumps_icntl_14", "coupling_sub_pc_type"})
    EXPECT_TRUE(coupling::read_at_first_solve(name)) << name;
  for (const char* name : {"coupling_ksp_rtol", "coupling_pc_fourier_threshold", "coupling_region_margin"})
    EXPECT_FALSE(coupling::read_at_first_solve(name)) << name;
  // What a replaced PC type would have read; the KSP's own options are read by every type.
  for (const char* name : {"coupling_pc_band_fused", "coupling_fourier_region_pc_type",
                           "coupling_sub_pc_type", "coupling_mat_mumps_icntl_24"})
    EXPECT_TRUE(coupling::option_of_replaced_solver(name)) << name;
  EXPECT_FALSE(coupling::option_of_replaced_solver("coupling_ksp_rtol"));
}

TEST(SolverPolicy, TheRegionLUReadsNoFactorisationOptionsIn3dByDefault) {
  const std::string mumps = "coupling_fourier_region_mat_mumps_icntl_14",
                    ordering =
                        "coupling_fourier_region_pc_factor_mat_"
                        "ordering_type";
  EXPECT_NE(coupling::region_option_unread(mumps, 3, false).find("(cellfsi_lu_single)"), std::string::npos);
  EXPECT_NE(coupling::region_option_unread(ordering, 3, false), "");
  EXPECT_EQ(coupling::region_option_unread(mumps, 3, true), "");   // -coupling_fourier_region_pc_type given
  EXPECT_EQ(coupling::region_option_unread(mumps, 2, false), "");  // 2D: MUMPS in double precision
  EXPECT_EQ(coupling::region_option_unread("coupling_fourier_region_ksp_type", 3, false), "");
  EXPECT_EQ(std::string(solvers::default_region_pc_type(true)), "cellfsi_lu_single");
  EXPECT_EQ(std::string(solvers::default_region_pc_type(false)), "lu");
}

TEST(SolverPolicy, OptionTableStatesThePCTypesDefaultsAndRanges) {
  LinearSolverOptions o = coupling::linear_solver_defaults(2);
  coupling::PCTypeOptions pc;
  // The defaults the PC types read themselves.
  EXPECT_EQ(pc.fourier.threshold, 1e-3);
  EXPECT_EQ(pc.fourier.overlap, 0);
  EXPECT_EQ(pc.fourier.region_solves, 1);
  EXPECT_TRUE(pc.band.fused_solve);
  EXPECT_EQ(pc.band.blr_tolerance, 1e-10);
  OptionTable t("test");
  coupling::add_pc_lag_option(t, o);
  coupling::add_solver_options(t, o, pc);
  EXPECT_NO_THROW(t.check());
  auto refused = [&](const char* what) {
    try {
      t.check();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted ") + what;
  };
  pc.fourier.threshold = -1;
  EXPECT_EQ(refused("threshold"), "option -coupling_pc_fourier_threshold = -1 is invalid; valid: > 0");
  pc.fourier.threshold = 1e-3;
  pc.fourier.overlap = 21;
  EXPECT_EQ(refused("overlap"), "option -coupling_pc_fourier_overlap = 21 is invalid; valid: 0 ... 20");
  pc.fourier.overlap = 0;
  pc.band.blr_tolerance = 1;
  EXPECT_EQ(refused("blr"),
            "option -coupling_pc_band_blr_tolerance = 1 is invalid; valid: 0 <= tolerance < 1");
  pc.band.blr_tolerance = 0;
  o.region_margin = -1;
  EXPECT_EQ(refused("margin"), "option -coupling_region_margin = -1 is invalid; valid: >= 0");
  o.region_margin = 4;
  o.preconditioner_lag = 0;
  EXPECT_EQ(refused("lag"), "option -coupling_pc_lag = 0 is invalid; valid: >= 1");
}
