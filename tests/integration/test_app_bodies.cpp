// Integration tests (cellfsi_app_fixture.hpp): immersed bodies: the scenes with cells, the launch modes, the
// coupled solvers' options.
#include "cellfsi_app_fixture.hpp"

using namespace cellfsi_app_test;

namespace {

// ---------------------------------------------------------------------------------------------------------
// 4. Immersed bodies: the capsule scene, its launch modes and its input checks

TEST_F(CellfsiApp, CapsuleSceneWritesBodyMetricsAndSolidSeries) {
  const RunResult r = cellfsi(
      with({scene("capsule_shear.yaml")}, with(kCapsule, {"-final_time", "2e-3", "-output_every", "2"})));
  ASSERT_FALSE(r.timed_out) << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  EXPECT_TRUE(is_flat_json_object(js));
  for (const char* key :
       {"membrane_r_A", "membrane_r_P", "membrane_theta_deg", "membrane_omega_tt", "membrane_max_abs_r_P"})
    EXPECT_TRUE(json_number(js, key).has_value()) << key << " missing:\n" << js;
  // Starts across the flow (90 deg) and turns clockwise towards it.
  const double theta = json_number(js, "membrane_theta_deg").value_or(0);
  EXPECT_GT(theta, 60.0) << js;
  EXPECT_LT(theta, 89.9) << js;
  EXPECT_GT(json_number(js, "membrane_omega_tt").value_or(0), 0.0) << js;
  // The paper's dimensionless numbers of this scene (Sec. 3.3) and the motion regime (two steps: too short
  // for the material to turn a quarter, "steady").
  EXPECT_NEAR(json_number(js, "membrane_Delta").value_or(0), 0.841, 5e-4) << js;
  EXPECT_NEAR(json_number(js, "membrane_chi").value_or(0), 0.257, 5e-4) << js;
  EXPECT_NEAR(json_number(js, "membrane_Ca").value_or(0), 0.0345, 5e-5) << js;
  EXPECT_NEAR(json_number(js, "membrane_Re").value_or(0), 1.42e-4, 5e-7) << js;
  EXPECT_EQ(json_string(js, "membrane_regime"), "steady") << js;
  EXPECT_EQ(json_string(js, "membrane_material"), "neo_hookean") << js;
  EXPECT_EQ(json_number(js, "membrane_shear_modulus"), 7500.0) << js;
  const std::vector<std::string> files = pvd_files(out_ / "solid.pvd");
  ASSERT_EQ(files.size(), 3u) << read_text(out_ / "solid.pvd");
  for (const auto& f : files) EXPECT_TRUE(fs::exists(out_ / f)) << f;
  EXPECT_GE(read_csv(out_ / "metrics.csv").column("membrane_theta_deg"), 0);
}

TEST_F(CellfsiApp, CapsuleRunsWithEachMaterialLawAndRecordsIt) {
  // Issue 28: the law and its constant are in summary.json and options.yaml. In 2D Mooney-Rivlin is the
  // neo-Hookean law (plane strain: I2 = I1) by another formula: stresses equal to round-off (1e-15 relative,
  // test_materials), which the coupled solves carry into theta by the Jacobian's condition number (about 1e6
  // on this mesh): agreement to 1e-9 relative, not to the bit (with OpenBLAS's AVX-512 kernels the last
  // digits differ; tests/support/tolerances.hpp).
  const std::vector<std::string> base = with({scene("capsule_shear.yaml")}, kCapsule);
  std::optional<double> theta_neo_hookean;
  for (const std::vector<std::string>& law :
       {std::vector<std::string>{"-solid_membrane_material", "neo_hookean"},
        std::vector<std::string>{"-solid_membrane_material", "mooney_rivlin",
                                 "-solid_membrane_mooney_rivlin_fraction", "0.3"},
        std::vector<std::string>{"-solid_membrane_material", "strain_hardening",
                                 "-solid_membrane_hardening_c3", "0.1"}}) {
    fs::remove_all(out_);
    const RunResult r = cellfsi(with(base, law));
    ASSERT_FALSE(r.timed_out) << r.output;
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const std::string js = summary();
    EXPECT_EQ(json_string(js, "membrane_material"), law[1]) << js;
    if (law.size() == 4) {
      const std::string key = law[2].substr(std::string("-solid_").size());
      EXPECT_EQ(json_number(js, key), std::stod(law[3])) << key << "\n" << js;
    }
    EXPECT_NE(read_text(out_ / "options.yaml").find("material: " + law[1]), std::string::npos)
        << read_text(out_ / "options.yaml");
    const std::optional<double> theta = json_number(js, "membrane_theta_deg");
    ASSERT_TRUE(theta.has_value()) << js;
    if (law[1] == "neo_hookean") theta_neo_hookean = theta;
    if (law[1] == "mooney_rivlin") {
      EXPECT_TRUE(cellfsi_test::agree(theta, theta_neo_hookean, 1e-9)) << js;
    }
  }
}

TEST_F(CellfsiApp, InnerViscosityOfTheFluidsChangesNoMetricAndFiveTimesItRuns) {
  // Issue 27: the default capsule, 3 steps. An inner viscosity equal to the fluid's (0.012) gives the same
  // summary to the last digit; lambda = 5 runs, is recorded (summary, options.yaml and the fluid output's
  // viscosity array, which only a viscosity field writes) and turns the capsule differently.
  const std::vector<std::string> base = with(kDefaultCapsule, {"-final_time", "6e-3", "-output_every", "3"});
  const char* keys[] = {"steps",        "coupling_iterations", "linear_iterations", "corrected_unknowns",
                        "membrane_r_A", "membrane_r_P",        "membrane_theta_deg", "membrane_omega_tt",
                        "membrane_omega_tu"};
  std::map<std::string, std::optional<double>> plain;
  for (const std::string mu : {"", "0.012", "0.06"}) {
    fs::remove_all(out_);
    const RunResult r = cellfsi(mu.empty() ? base : with(base, {"-solid_membrane_inner_viscosity", mu}));
    ASSERT_FALSE(r.timed_out) << r.output;
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const std::string js = summary();
    for (const char* k : keys) {
      if (mu.empty()) plain[k] = json_number(js, k);
      ASSERT_TRUE(plain[k].has_value()) << k << "\n" << js;
      if (mu == "0.012") {
        EXPECT_EQ(json_number(js, k), plain[k]) << k << "\n" << js;
      }
    }
    const bool field = read_text(out_ / "fluid_000003.vts").find("Name=\"viscosity\"") != std::string::npos;
    EXPECT_EQ(field, mu == "0.06") << mu;
    if (mu == "0.06") {
      EXPECT_DOUBLE_EQ(json_number(js, "membrane_viscosity_ratio").value_or(0), 5.0) << js;
      EXPECT_NE(json_number(js, "membrane_theta_deg"), plain["membrane_theta_deg"]) << js;
      EXPECT_NE(read_text(out_ / "options.yaml").find("inner_viscosity: 0.06"), std::string::npos)
          << read_text(out_ / "options.yaml");
      // The scene-file form: options.yaml nests `inner_viscosity` under the body; run from it, the same run.
      const fs::path again = root_ / "again";
      const RunResult r2 =
          run_process({CELLFSI_EXE, (out_ / "options.yaml").string(), "-output_dir", again.string()}, 60);
      ASSERT_EQ(r2.exit_code, 0) << r2.output;
      const std::string js2 = read_text(again / "summary.json");
      EXPECT_DOUBLE_EQ(json_number(js2, "membrane_viscosity_ratio").value_or(0), 5.0) << js2;
      EXPECT_EQ(json_number(js2, "membrane_theta_deg"), json_number(js, "membrane_theta_deg")) << js2;
    }
  }
}

TEST_F(CellfsiApp, ElementRatioSizesABodysAutomaticElementsOnEitherSpace) {
  // -solid_NAME_element_ratio R replaces the space's rule for automatic counts (0.1125 for a 2D membrane on
  // the divergence-conforming space, 0.9 on the paper's): the body's largest element is then about R times
  // the fluid's smallest (the counts are scaled from a trial mesh and rounded up to a multiple of 4), on both
  // spaces alike. Measured at 48 x 24: 212 elements around (ratio 0.114) by the rule, 28 (0.861) on the
  // paper's space, and 56 (0.431) with R = 0.45 on both; asserted within -10 % and +5 % of R.
  const std::vector<std::string> run =
      with({scene("capsule_shear.yaml")}, with(kCapsuleSmall, {"-final_time", "5e-4"}));
  for (const char* space : {"div_conforming", "equal_order"}) {
    SCOPED_TRACE(space);
    ASSERT_EQ(cellfsi(with(run, {"-fluid_space", space}), 120).exit_code, 0) << last_output_;
    const double rule = std::string(space) == "div_conforming" ? 0.1125 : 0.9;
    EXPECT_LE(json_number(summary(), "membrane_mesh_ratio").value_or(9), 1.05 * rule);
    EXPECT_GE(json_number(summary(), "membrane_mesh_ratio").value_or(0), 0.9 * rule);
    ASSERT_EQ(
        cellfsi(with(run, {"-fluid_space", space, "-solid_membrane_element_ratio", "0.45"}), 120).exit_code,
        0)
        << last_output_;
    EXPECT_LE(json_number(summary(), "membrane_mesh_ratio").value_or(9), 1.05 * 0.45);
    EXPECT_GE(json_number(summary(), "membrane_mesh_ratio").value_or(0), 0.9 * 0.45);
    EXPECT_EQ(json_number(summary(), "membrane_elements_1").value_or(0), 56);
  }
}

TEST_F(CellfsiApp, CoarseCapsuleInclinationWithCentralAndSupportMarking) {
  // Issue 8: at 96 x 48 quadratic elements the capsule's inclination with the default (central) s^h marking
  // is closer to the converged 26.09 deg (paper, 512 x 256 cubic) than the paper's own 17.81 at this mesh;
  // the wider support marking gives 14.1 (docs/validation.md, "The capsule in shear (paper Sec. 3.3-3.4, Table 1)"). Measured
  // over 0.08-0.12 s with dt 2e-3 (theta is steady from about 0.08 s and does not depend on dt): 18.942 and
  // 14.142 deg. Pinned to 0.05 deg: a change of the discretisation shows here first. With s_I = 1e10, the
  // value these were measured with (-s_interface auto chooses 2.0e10 and 4.8e9 for the two markings here:
  // 18.443 and 15.143 deg).
  // clang-format off
  const std::vector<std::string> run = {
      scene("capsule_shear.yaml"), "-fluid_elements", "96,48", "-fluid_degree", "2",
      "-solid_membrane_elements", "1,0", "-dt", "2e-3", "-final_time", "0.12",
      "-metrics_average_from", "0.08", "-output_every", "0", "-s_interface", "1e10", "-fluid_space", "equal_order"};
  // clang-format on
  double theta[2] = {0, 0};
  const char* markings[2] = {"central", "support"};
  for (int k = 0; k < 2; ++k) {
    const RunResult r = cellfsi(with(run, {"-s_interface_marking", markings[k]}), 120);
    ASSERT_FALSE(r.timed_out) << r.output;
    ASSERT_EQ(r.exit_code, 0) << r.output;
    theta[k] = json_number(summary(), "membrane_theta_deg").value_or(0);
  }
  std::printf("  theta %.3f deg (central), %.3f deg (support)\n", theta[0], theta[1]);
  EXPECT_NEAR(theta[0], 18.942, 0.05);
  EXPECT_NEAR(theta[1], 14.142, 0.05);
  EXPECT_LT(std::abs(theta[0] - 26.09), std::abs(17.81 - 26.09));
}

TEST_F(CellfsiApp, ThreeDimensionalCompoundCapsuleWritesItsSeries) {
  // The 3D compound capsule of paper Sec. 3.6 (scenes/compound_capsule_shear_3d.yaml) at 12^3, two steps with
  // output: the polar points of the ellipsoid and the sphere, where F is undefined, no longer stop the
  // writer; the summary carries the paper's numbers (Delta_m = 0.960, chi = 0.387, phi = 0.083).
  const RunResult r = cellfsi({scene("compound_capsule_shear_3d.yaml"), "-fluid_elements", "12,12,12",
                               "-solid_membrane_elements", "1,0,0", "-solid_nucleus_elements", "0,0,0",
                               "-final_time", "1e-3", "-output_every", "1", "-fluid_space", "equal_order"},
                              120);
  ASSERT_FALSE(r.timed_out) << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  EXPECT_NEAR(json_number(js, "membrane_Delta").value_or(0), 0.960, 5e-4) << js;
  EXPECT_NEAR(json_number(js, "membrane_chi").value_or(0), 0.387, 1e-3) << js;
  EXPECT_NEAR(json_number(js, "nucleus_phi").value_or(0), 0.083, 5e-4) << js;
  // The scene's walls are normal to y (-domain_periodic 1,0,1, once ignored: the walls were normal to z and
  // theta, measured in the x-z plane where this ellipsoid is round, was noise): the long axis starts across
  // the flow and has barely turned after two steps.
  EXPECT_GT(std::abs(json_number(js, "membrane_theta_deg").value_or(0)), 85.0) << js;
  const std::vector<std::string> files = pvd_files(out_ / "solid.pvd");
  EXPECT_EQ(files.size(), 6u) << read_text(out_ / "solid.pvd");  // two bodies, steps 0, 1, 2
  for (const auto& f : files) EXPECT_TRUE(fs::exists(out_ / f)) << f;
}

TEST_F(CellfsiApp, ThreeDimensionalRbcTurnsAndKeepsItsVolume) {
  // The 3D RBC (scenes/rbc_shear_3d.yaml, issue 28) at 12^3, three steps (about 8 s): it passes the placement
  // checks, its shell has the RBC's bending modulus (2e-12 erg) and G h = 6e-3 dyn/cm, and it starts to
  // tumble in the sense of the shear. Measured: theta 80.22 deg (from 90 at about 10 turns/s; a rigid thin
  // disc standing across the flow turns at nearly gammadot / (2 pi) = 11 turns/s), max |r_A| 3.3e-4, enclosed
  // volume -2.4e-4.
  const RunResult r = cellfsi({scene("rbc_shear_3d.yaml"), "-fluid_elements", "12,12,12", "-final_time",
                               "3e-3", "-output_every", "0"},
                              120);
  ASSERT_FALSE(r.timed_out) << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  EXPECT_NEAR(json_number(js, "rbc_bending_modulus").value_or(0), 2e-12, 1e-15) << js;
  EXPECT_NEAR(json_number(js, "rbc_shear_modulus").value_or(0) * 3.1623e-5, 6e-3, 1e-6) << js;
  EXPECT_NEAR(json_number(js, "rbc_Ca").value_or(0), 0.0457, 1e-4) << js;
  EXPECT_LE(json_number(js, "rbc_mesh_ratio").value_or(2), 1.0) << js;
  EXPECT_LT(json_number(js, "rbc_max_abs_r_A").value_or(1), 1e-3) << js;
  EXPECT_LT(std::abs(json_number(js, "rbc_enclosed_change").value_or(1)), 1e-3) << js;
  EXPECT_NEAR(json_number(js, "rbc_theta_deg").value_or(0), 80.2, 0.5) << js;
}

TEST_F(CellfsiApp, MaterialLawOfThe3dRbcSwapsByOneOption) {
  // Issue 28, item 5: the solid's material is swapped on the 3D RBC by an option alone (nothing in fluid/ or
  // coupling/ knows the law). At ten times the scene's shear rate (Ca 0.46), 4 steps of 2e-4 s at 12^3: the
  // strain-hardening law (C3 = G) stretches the cell less than the neo-Hookean one with the same G. Measured:
  // largest stretch 1.2597 against 1.2642, r_P 0.0546 against 0.0561 (8 steps of 1e-4 s, which took twice the
  // coupling iterations and 1.6 times the CPU: 1.2594 against 1.2645; at 50 steps: 1.418 against 1.746).
  double stretch[2] = {0, 0};
  const char* laws[2] = {"neo_hookean", "strain_hardening"};
  for (int k = 0; k < 2; ++k) {
    std::vector<std::string> args = {scene("rbc_shear_3d.yaml"), "-fluid_elements", "12,12,12", "-shear_rate",
                                     "700", "-dt", "2e-4", "-final_time", "8e-4", "-output_every", "0",
                                     "-solid_rbc_material", laws[k]};
    if (k == 1) args.insert(args.end(), {"-solid_rbc_hardening_c3", "1"});
    const RunResult r = cellfsi(args, 120);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const std::string js = summary();
    EXPECT_EQ(json_string(js, "rbc_material").value_or(""), laws[k]) << js;
    stretch[k] = json_number(js, "rbc_max_stretch").value_or(0);
  }
  EXPECT_NEAR(stretch[0], 1.2642, 2e-3);
  EXPECT_LT(stretch[1], stretch[0] - 2e-3);
}

TEST_F(CellfsiApp, TheRedCellOnSixPatchesMovesAsThePolarOne) {
  // -solid_rbc_patches 6: the 3D red cell's shell on the faces of a cube (no poles; solid::CompositeSolid),
  // one body with six VTK pieces, against the polar shell with about as many elements (1 x 10 x 10 a face:
  // 600; 1 x 16 x 32: 512), 2 steps at 12^3. Measured: theta 81.964 / 81.951 deg, deformation index 0.51577 /
  // 0.51594, omega_TT 9.154 / 9.047 1/s, extent along x 3.2827 / 3.2817 um, r_A -3.0e-4 / -3.4e-4.
  std::map<std::string, double> m[2];
  const std::vector<std::vector<std::string>> shells = {
      {"-solid_rbc_elements", "1,16,32"}, {"-solid_rbc_patches", "6", "-solid_rbc_elements", "1,10,10"}};
  for (int k = 0; k < 2; ++k) {
    const RunResult r = cellfsi(with({scene("rbc_shear_3d.yaml"), "-fluid_elements", "12,12,12",
                                      "-final_time", "2e-3", "-output_every", "2"},
                                     shells[k]),
                                120);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    for (const auto& [key, v] : last_row(out_ / "metrics.csv")) m[k][key] = v;
    if (k == 1) {
      EXPECT_EQ(json_number(summary(), "rbc_patches").value_or(0), 6);
      for (int part = 0; part < 6; ++part)
        EXPECT_TRUE(fs::exists(out_ / ("solid_rbc_p" + std::to_string(part) + "_000001.vts"))) << part;
    }
    fs::remove_all(out_);
  }
  EXPECT_NEAR(m[1].at("rbc_theta_deg"), m[0].at("rbc_theta_deg"), 0.05);
  EXPECT_NEAR(m[1].at("rbc_deformation_index"), m[0].at("rbc_deformation_index"), 1e-3);
  EXPECT_NEAR(m[1].at("rbc_omega_tt"), m[0].at("rbc_omega_tt"), 0.03 * m[0].at("rbc_omega_tt"));
  for (const char* e : {"rbc_extent_x", "rbc_extent_y", "rbc_extent_z"})
    EXPECT_NEAR(m[1].at(e), m[0].at(e), 1e-3 * m[0].at(e)) << e;
  EXPECT_LT(std::abs(m[1].at("rbc_r_A")), 1e-3);
}

TEST_F(CellfsiApp, AMembraneCubicThroughItsThicknessOnlyKeepsItsShapeAndMotion) {
  // -solid_NAME_thickness_degree 3: the capsule's membrane raised to cubic through its thickness (4
  // collocation points across it), quadratic around: the same map, so, 0.02 s into the shear at 48 x 24, the
  // same motion as the quadratic membrane to the discretisation's change through a thin shell. Measured:
  // theta 34.7251 deg and deformation index 0.389923 on both, omega_TT 3.55551 / 3.55552 1/s.
  std::map<std::string, double> m[2];
  for (int k = 0; k < 2; ++k) {
    std::vector<std::string> run =
        with({scene("capsule_shear.yaml")}, with(kCapsuleSmall, {"-final_time", "0.02"}));
    if (k == 1) run = with(run, {"-solid_membrane_thickness_degree", "3"});
    ASSERT_EQ(cellfsi(run, 120).exit_code, 0) << last_output_;
    const std::string js = summary();
    EXPECT_EQ(json_number(js, "membrane_degree_0").value_or(0), k == 1 ? 3 : 2) << js;
    EXPECT_EQ(json_number(js, "membrane_degree_1").value_or(0), 2) << js;
    for (const auto& [key, v] : last_row(out_ / "metrics.csv")) m[k][key] = v;
    fs::remove_all(out_);
  }
  EXPECT_NEAR(m[1].at("membrane_theta_deg"), m[0].at("membrane_theta_deg"), 1e-3);
  EXPECT_NEAR(m[1].at("membrane_deformation_index"), m[0].at("membrane_deformation_index"), 1e-5);
  EXPECT_NEAR(m[1].at("membrane_omega_tt"), m[0].at("membrane_omega_tt"),
              1e-3 * m[0].at("membrane_omega_tt"));
  EXPECT_NEAR(m[0].at("membrane_theta_deg"), 34.725, 0.01);
}

TEST_F(CellfsiApp, TheThinShellRedCellMovesAsTheSolidShell) {
  // -solid_rbc_thin_shell: the six-patch red cell as a Kirchhoff-Love shell about its mid-surface, against
  // the solid shell (quadratic across), 2 steps at 12^3. The two discretise the same shell: the same motion
  // to the difference of their kinematics across 0.32 um (and of their tangents: the thin shell has no
  // collocation tangent yet). Measured (solid / thin): theta 81.964 / 81.306 deg, deformation index 0.51577 /
  // 0.51718, omega_TT 9.154 / 9.514 1/s, extent along x 3.283 / 3.344 um, r_A -3.0e-4 / 8.0e-6.
  std::map<std::string, double> m[2];
  std::string js[2];
  for (int k = 0; k < 2; ++k) {
    std::vector<std::string> run = {scene("rbc_shear_3d.yaml"),
                                    "-fluid_elements",
                                    "12,12,12",
                                    "-final_time",
                                    "2e-3",
                                    "-output_every",
                                    "2",
                                    "-solid_rbc_patches",
                                    "6",
                                    "-solid_rbc_elements",
                                    "1,10,10"};
    if (k == 1) run = with(run, {"-solid_rbc_thin_shell", "true"});
    const RunResult r = cellfsi(run, 120);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    js[k] = summary();
    for (const auto& [key, v] : last_row(out_ / "metrics.csv")) m[k][key] = v;
    if (k == 1) {
      for (int part = 0; part < 6; ++part)
        EXPECT_TRUE(fs::exists(out_ / ("solid_rbc_p" + std::to_string(part) + "_000001.vts"))) << part;
    }
    fs::remove_all(out_);
  }
  EXPECT_EQ(json_number(js[1], "rbc_thin_shell").value_or(0), 1) << js[1];
  EXPECT_EQ(json_number(js[1], "rbc_degree_0").value_or(0), 1) << js[1];  // (its view: linear across)
  EXPECT_FALSE(json_number(js[0], "rbc_thin_shell").has_value()) << js[0];
  EXPECT_NEAR(m[1].at("rbc_theta_deg"), m[0].at("rbc_theta_deg"), 1.0);
  EXPECT_NEAR(m[1].at("rbc_deformation_index"), m[0].at("rbc_deformation_index"), 3e-3);
  EXPECT_NEAR(m[1].at("rbc_omega_tt"), m[0].at("rbc_omega_tt"), 0.08 * m[0].at("rbc_omega_tt"));
  for (const char* e : {"rbc_extent_x", "rbc_extent_y", "rbc_extent_z"})
    EXPECT_NEAR(m[1].at(e), m[0].at(e), 0.03 * m[0].at(e)) << e;
  // The thin shell's enclosed volume: its mid-surface, which follows the divergence-free velocity, where the
  // solid shell's middle moves with its three points across.
  EXPECT_LT(std::abs(m[1].at("rbc_r_A")), 0.1 * std::abs(m[0].at("rbc_r_A")));
}

TEST_F(CellfsiApp, ARedCellOnSixPatchesIsRefusedOnSolidRanks) {
  // The solid ranks serve a body by one patch; the six faces run in the fluid's ranks.
  const RunResult r = mpi_cellfsi(
      2, {scene("rbc_shear_3d.yaml"), "-solid_rbc_patches", "6", "-solid_ranks", "1", "-final_time", "1e-3"});
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
  EXPECT_NE(
      r.output.find("option -solid_rbc_patches = 6 is invalid; valid: 1 with the bodies on solid ranks"),
      std::string::npos)
      << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, StretchedRbcElongatesStaysPutAndStopsAtEquilibrium) {
  // Issue 28, item 4: scenes/rbc_stretch_3d.yaml at 2 um fluid elements (12 x 4 x 6; 1 x 8 x 16 shell
  // elements), 190 pN, dt 1 ms, about 1.5 s a step. The cell elongates along the pull and narrows across it,
  // its centroid stays where it was (equal and opposite forces) and its volume is kept. With a loose
  // tolerance the equilibrium test stops it early; continued by a restart, the records of the first part
  // count (else the change over the window would be measured from the start and the stop come later).
  // Measured in one run: D_A 8.710, 9.796, 10.762, 11.679 um at 1 ... 4 ms (rest 7.820), D_T 7.361, 6.830,
  // 6.409 um at 1 ... 3 ms; the change over 1 ms at 3 ms: 0.090; centroid shift 3e-19 cm; enclosed
  // change 2.4e-4.
  const std::vector<std::string> base = {scene("rbc_stretch_3d.yaml"),
                                         "-fluid_elements",
                                         "12,4,6",
                                         "-dt",
                                         "1e-3",
                                         "-output_every",
                                         "0",
                                         "-solid_rbc_stretch_force",
                                         "1.9e-5",
                                         "-equilibrium_tolerance",
                                         "0.1"};
  ASSERT_EQ(cellfsi(with(base, {"-final_time", "2e-3"}), 120).exit_code, 0) << last_output_;
  const RunResult r = cellfsi(with(base, {"-final_time", "6e-3", "-restart"}), 120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("equilibrium reached at t = 0.003 s (step 3 of 6)"), std::string::npos) << r.output;
  const std::string js = summary();
  EXPECT_EQ(json_string(js, "status").value_or(""), "completed") << js;
  EXPECT_EQ(json_number(js, "steps"), 3) << js;
  EXPECT_NEAR(json_number(js, "rbc_equilibrium_time").value_or(0), 3e-3, 1e-12) << js;
  EXPECT_NEAR(json_number(js, "rbc_stretch_force").value_or(0), 1.9e-5, 1e-18) << js;
  EXPECT_NEAR(json_number(js, "rbc_axial_diameter").value_or(0), 10.762e-4, 0.05e-4) << js;
  EXPECT_NEAR(json_number(js, "rbc_transverse_diameter").value_or(0), 6.409e-4, 0.05e-4) << js;
  EXPECT_LT(json_number(js, "rbc_centroid_shift").value_or(1), 1e-9) << js;
  EXPECT_LT(std::abs(json_number(js, "rbc_enclosed_change").value_or(1)), 1e-3) << js;
  // Every step: longer along the pull and narrower across it than the step before.
  const Csv csv = read_csv(out_ / "metrics.csv");
  const int a = csv.column("rbc_axial_diameter"), t = csv.column("rbc_transverse_diameter");
  ASSERT_GE(a, 0);
  ASSERT_EQ(csv.rows.size(), 3u);
  double last_a = 7.82e-4, last_t = 7.82e-4;
  for (const auto& row : csv.rows) {
    EXPECT_GT(std::stod(row[a]), last_a);
    EXPECT_LT(std::stod(row[t]), last_t);
    last_a = std::stod(row[a]), last_t = std::stod(row[t]);
  }
}

TEST_F(CellfsiApp, StretchedRbcOnSixPatchesAsASolidOrAThinShellElongatesAsTheOnePatchCell) {
  // The same pull (190 pN, 2 um fluid elements, 2 steps of 1 ms) on the cell of six patches, as a solid shell
  // and as a thin one: the loads spread over every part within the contact diameter, the diameters measured
  // over every part's mid-surface. Measured: D_A, D_T 9.796, 6.830 um (one patch), 9.741, 6.843 (six), 9.856,
  // 6.782 (six, thin) at 2 ms.
  const std::vector<std::string> base = {
      scene("rbc_stretch_3d.yaml"), "-fluid_elements", "12,4,6",      "-dt", "1e-3", "-output_every", "0",
      "-solid_rbc_stretch_force",   "1.9e-5",          "-final_time", "2e-3"};
  double polar[2] = {0, 0};
  for (const std::vector<std::string>& extra :
       {std::vector<std::string>{}, std::vector<std::string>{"-solid_rbc_patches", "6"},
        std::vector<std::string>{"-solid_rbc_patches", "6", "-solid_rbc_thin_shell", "true"}}) {
    const RunResult r = cellfsi(with(base, extra), 120);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const std::string js = summary();
    const double d_a = json_number(js, "rbc_axial_diameter").value_or(0);
    const double d_t = json_number(js, "rbc_transverse_diameter").value_or(0);
    if (extra.empty()) {
      polar[0] = d_a, polar[1] = d_t;
      EXPECT_NEAR(d_a, 9.796e-4, 0.02e-4) << js;  // (the one-patch test's value at 2 ms)
      continue;
    }
    EXPECT_NEAR(d_a, polar[0], 0.01 * polar[0]) << extra.size() << js;
    EXPECT_NEAR(d_t, polar[1], 0.01 * polar[1]) << extra.size() << js;
    EXPECT_LT(json_number(js, "rbc_centroid_shift").value_or(1), 1e-9) << js;
  }
}

TEST_F(CellfsiApp, StretchedRbcWithSkalaksLawOrStrainHardeningWithAnAreaTermKeepsItsArea) {
  // Issue 47, item 1: the same pull (190 pN, 2 um fluid elements) on the area-preserving law
  // (-solid_rbc_material skalak, C = 100): the membrane's area grows by under 2 % at equilibrium (measured
  // 1.61 %, D_A 10.35 um, D_T 6.13 um, at 24 ms), where the neo-Hookean shell has grown by 5.7 % after 4 ms,
  // less stretched (D_A 11.68 um) than it will be. The summary carries C and the shell's bending modulus
  // G (1 + C) h^3 / 6 (docs/materials.md).
  const std::vector<std::string> base = {
      scene("rbc_stretch_3d.yaml"), "-fluid_elements", "12,4,6", "-output_every", "0",
      "-solid_rbc_stretch_force",   "1.9e-5"};
  ASSERT_EQ(cellfsi(with(base, {"-final_time", "4e-3"}), 120).exit_code, 0) << last_output_;
  const double neo_growth = json_number(summary(), "rbc_r_P").value_or(0);
  EXPECT_NEAR(neo_growth, 0.0573, 0.005) << summary();
  const RunResult r =
      cellfsi(with(base, {"-solid_rbc_material", "skalak", "-solid_rbc_area_dilation", "100"}), 120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  EXPECT_EQ(json_string(js, "rbc_material").value_or(""), "skalak") << js;
  EXPECT_EQ(json_number(js, "rbc_area_dilation"), 100.0) << js;
  const double bending = 189.74 * 101 / 6 * std::pow(3.1623e-5, 3);
  EXPECT_NEAR(json_number(js, "rbc_bending_modulus").value_or(0), bending, 1e-9 * bending) << js;
  ASSERT_TRUE(json_number(js, "rbc_equilibrium_time").has_value()) << js;
  const double growth = json_number(js, "rbc_r_P").value_or(1);
  EXPECT_GT(growth, 0.0);
  EXPECT_LT(growth, 0.02) << js;
  EXPECT_LT(growth, neo_growth / 3) << js;
  EXPECT_NEAR(json_number(js, "rbc_axial_diameter").value_or(0), 10.35e-4, 0.1e-4) << js;
  EXPECT_NEAR(json_number(js, "rbc_transverse_diameter").value_or(0), 6.13e-4, 0.1e-4) << js;
  // Strain hardening with the same area term (-solid_rbc_material strain_hardening_membrane): the same small-
  // strain moduli and bending modulus, the summary carries C3 / G and C, the area kept as well (measured r_P
  // 1.79 %), and the cell softer at this stretch than Skalak's (D_A 10.43 um, D_T 6.08 um, at 24 ms).
  const double skalak_axial = json_number(js, "rbc_axial_diameter").value_or(0);
  const RunResult h = cellfsi(
      with(base, {"-solid_rbc_material", "strain_hardening_membrane", "-solid_rbc_area_dilation", "100"}),
      120);
  ASSERT_EQ(h.exit_code, 0) << h.output;
  const std::string jh = summary();
  EXPECT_EQ(json_string(jh, "rbc_material").value_or(""), "strain_hardening_membrane") << jh;
  EXPECT_NEAR(json_number(jh, "rbc_hardening_c3").value_or(0), 1.0 / 30, 1e-12) << jh;
  EXPECT_EQ(json_number(jh, "rbc_area_dilation"), 100.0) << jh;
  EXPECT_NEAR(json_number(jh, "rbc_bending_modulus").value_or(0), bending, 1e-9 * bending) << jh;
  ASSERT_TRUE(json_number(jh, "rbc_equilibrium_time").has_value()) << jh;
  EXPECT_LT(json_number(jh, "rbc_r_P").value_or(1), 0.02) << jh;
  EXPECT_NEAR(json_number(jh, "rbc_axial_diameter").value_or(0), 10.43e-4, 0.03e-4) << jh;
  EXPECT_NEAR(json_number(jh, "rbc_transverse_diameter").value_or(0), 6.08e-4, 0.03e-4) << jh;
  EXPECT_GT(json_number(jh, "rbc_axial_diameter").value_or(0), skalak_axial + 0.04e-4) << jh;
}

TEST_F(CellfsiApp, RunFailingInItsFirstStepSaysWhereAndKeepsTheColumns) {
  // Issue 10: a step too long for the membrane at 192 x 96 (dt 4e-3 inverts an element in step 1 with the
  // paper's iteration; the Anderson-accelerated one, the default, gets through it). The run exits with 2, the
  // message and summary.json name the step and the time, and metrics.csv has its header (before: a 0-byte
  // file and no step or time).
  const RunResult r = cellfsi({scene("capsule_shear.yaml"), "-fluid_elements", "192,96", "-dt", "4e-3",
                               "-final_time", "8e-3", "-solid_membrane_elements", "1,0", "-output_every", "0",
                               "-coupling_acceleration", "none", "-fluid_space", "equal_order"},
                              120);
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("in step 1 at t = 0.004 s"), std::string::npos) << r.output;
  EXPECT_NE(json_string(summary(), "status").value_or("").find("in step 1 at t = 0.004 s"), std::string::npos)
      << summary();
  const std::string csv = read_text(out_ / "metrics.csv");
  EXPECT_EQ(csv.rfind("step,time,coupling_iterations,linear_iterations,factorizations,", 0), 0u) << csv;
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1) << csv;
}

TEST_F(CellfsiApp, CouplingThatDoesNotConvergeSaysWhereItsResidualsStood) {
  // The message gives the last residuals against their targets (the fluid's, and the body farthest above
  // its own): a stall just above them reads differently from residuals that grew.
  const RunResult r =
      cellfsi(with(with({scene("capsule_shear.yaml")}, kCapsuleSmall), {"-coupling_max_iterations", "2"}));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  const std::string head = "no convergence in 2 iterations: |R_MC| ";
  const std::size_t at = r.output.find(head);
  ASSERT_NE(at, std::string::npos) << r.output;
  double residual = 0, target = 0;
  ASSERT_EQ(std::sscanf(r.output.c_str() + at + head.size(), "%lf against %lf", &residual, &target), 2)
      << r.output;
  EXPECT_GT(residual, target) << r.output;
  EXPECT_NE(r.output.find(", |R_K(membrane)| "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("in step 1 at t = "), std::string::npos) << r.output;
}

TEST_F(CellfsiApp, FactorisationOutOfMemorySaysSo) {
  // A 3D mesh whose LU factors exceed the memory said only "DIVERGED_PC_FAILED". Under a 900 MB address-space
  // limit the shear scene's 160 x 80 LU (through ASM's subdomain) cannot be allocated: the run exits with 2
  // and says why, and where.
  const std::string cmd = "ulimit -v 900000; exec " + std::string(CELLFSI_EXE) + " " + scene("shear.yaml") +
                          " -fluid_elements 160,80 -final_time 1e-3 -output_every 0 -output_dir " +
                          out_.string();
  const RunResult r = run_process({"/bin/sh", "-c", cmd}, 60);
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("the LU factorisation ran out of memory"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("in step 1 at t = 0.0005"), std::string::npos) << r.output;
}

TEST_F(CellfsiApp, DomainArraysOfTheWrongLengthAreRejected) {
  // -domain_periodic, -domain_size and -domain_origin were read without their "set" flag: a wrong length
  // passed and -domain_periodic was ignored altogether (issue 10).
  for (const char* opt : {"-domain_periodic", "-domain_size", "-domain_origin"}) {
    const std::string value = std::string(opt) == "-domain_periodic" ? "1,0,1" : "0.001,0.001,0.001";
    const RunResult r = cellfsi(with({scene("shear.yaml"), opt, value}, kTiny));
    expect_one_clear_error(r);
    EXPECT_NE(r.output.find(opt), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("2 comma-separated values"), std::string::npos) << r.output;
  }
}

TEST_F(CellfsiApp, LaunchModesAgree) {
  // One process; one job split into a fluid and a solid rank; two executables (MPMD). Same numbers. The
  // capsule is also pulled at both ends (issue 28, item 4): the external force travels with the quadrature
  // data to the fluid ranks in every mode. Measured: D_A 2.07658e-4 cm against 2.07246e-4 without the pull.
  const std::vector<std::string> args =
      with({scene("capsule_shear.yaml")},
           with(kCapsule, {"-final_time", "2e-3", "-solid_membrane_stretch_force", "1e-4"}));
  ASSERT_EQ(cellfsi(args).exit_code, 0) << last_output_;
  const auto single = last_row(out_ / "metrics.csv");
  EXPECT_GT(json_number(summary(), "membrane_axial_diameter").value_or(0), 2.0755e-4) << summary();
  ASSERT_EQ(mpi_cellfsi(2, with(args, {"-solid_ranks", "1"})).exit_code, 0) << last_output_;
  const auto split = last_row(out_ / "metrics.csv");
  EXPECT_EQ(json_number(summary(), "solid_ranks"), 1) << summary();
  std::vector<std::string> mpmd = {MPIEXEC_EXECUTABLE, "--oversubscribe", "-np", "1", CELLFSI_FLUID_EXE};
  mpmd.insert(mpmd.end(), args.begin(), args.end());
  mpmd.insert(mpmd.end(), {"-output_dir", out_.string(), ":", "-np", "1", CELLFSI_SOLID_EXE});
  mpmd.insert(mpmd.end(), args.begin(), args.end());
  const RunResult r = run_process(mpmd);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto two_exes = last_row(out_ / "metrics.csv");
  // r_A is a difference of areas (cancellation): compared against a floor of 1e-6.
  EXPECT_TRUE(rows_agree(single, split, 1e-10, 1e-6));
  EXPECT_TRUE(rows_agree(single, two_exes, 1e-10, 1e-6));
}

// Restarts (issue 10: a run lost at hour 20 started again from zero). A run writes DIR/checkpoint every
// -checkpoint_every steps, at its end and when interrupted; -restart continues it.
TEST_F(CellfsiApp, RbcChannelSceneGivesItsHematocritAndRheology) {
  // Six RBCs placed by -solid_rbc_count (two steps at a tiny mesh): H_t is the paper's 0.2573 (six cells of
  // the default RBC's area in the 0.003 x 0.001 channel); the window's zeta, eta, h_cf are in summary.json
  // and the time-averaged profile in profile_mean.csv. With cells the plasma comparison is a ratio, not an
  // error.
  const RunResult r = cellfsi({scene("rbc_channel.yaml"), "-fluid_elements", "96,32", "-fluid_degree", "2",
                               "-solid_rbc_elements", "1,0", "-final_time", "5e-4", "-output_every", "0"},
                              120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  EXPECT_NEAR(json_number(js, "H_t").value_or(0), 0.2573, 2e-4) << js;
  for (const char* key : {"H_d", "zeta", "eta", "h_cf", "v_cells", "v_mean"})
    EXPECT_TRUE(json_number(js, key).has_value()) << key << "\n" << js;
  EXPECT_EQ(json_number(js, "rheology_records"), 2) << js;
  // The cell-free layer of the placement: half the height less the RBC's half-length across the flow (the
  // Evans-Fung R0 = 3.91e-4 cm scaled by sqrt(1.2868e-7 / 1.36271e-7) = 0.971747 to the default area) and
  // half the membrane's thickness: 1.19797e-4 cm; in two steps the cells move by less than 1e-7 cm across.
  EXPECT_NEAR(json_number(js, "h_cf").value_or(0), 1.19797e-4, 2e-7) << js;
  for (int i = 1; i <= 6; ++i)
    EXPECT_TRUE(json_number(js, "rbc_" + std::to_string(i) + "_r_A").has_value()) << i;
  const Csv csv = read_csv(out_ / "metrics.csv");
  EXPECT_GE(csv.column("tube_hematocrit"), 0);
  EXPECT_GE(csv.column("mean_velocity_ratio"), 0);
  EXPECT_LT(csv.column("mean_velocity_rel_error"), 0);
  EXPECT_EQ(read_csv(out_ / "profile_mean.csv").rows.size(), 65u);
}

TEST_F(CellfsiApp, TwelveRbcsPlacedEvenlyOrStaggeredAreAcceptedAndOverlapsRefused) {
  const std::vector<std::string> base = {scene("rbc_channel.yaml"),
                                         "-fluid_elements",
                                         "96,32",
                                         "-fluid_degree",
                                         "2",
                                         "-solid_rbc_elements",
                                         "1,0",
                                         "-final_time",
                                         "2.5e-4",
                                         "-output_every",
                                         "0",
                                         "-solid_rbc_count",
                                         "12"};
  // metrics.csv after one step (2.5e-4 s at about 0.01 cm/s: the cells moved about 3e-6 cm).
  auto value = [&](const std::string& key) {
    for (const auto& [k, v] : last_row(out_ / "metrics.csv"))
      if (k == key) return v;
    return -1.0;
  };
  ASSERT_EQ(cellfsi(base, 120).exit_code, 0) << last_output_;
  EXPECT_NEAR(value("rbc_12_centroid_x"), 0.003 * 23 / 24, 1e-5);
  EXPECT_NEAR(value("tube_hematocrit"), 0.5147, 2e-4);  // the paper's H_t of twelve cells
  ASSERT_EQ(cellfsi(with(base, {"-solid_rbc_arrangement", "staggered", "-solid_rbc_spread", "5e-5"}), 120)
                .exit_code,
            0)
      << last_output_;
  EXPECT_NEAR(value("rbc_1_centroid_y"), 5e-4 + 5e-5, 1e-5);
  EXPECT_NEAR(value("rbc_2_centroid_y"), 5e-4 - 5e-5, 1e-5);
  // Arrangement options without copies, and an odd staggered row, are refused.
  fs::remove_all(out_);
  expect_one_clear_error(cellfsi(with(base, {"-solid_rbc_count", "1", "-solid_rbc_spread", "1e-5"})));
  EXPECT_NE(last_output_.find("option -solid_rbc_spread = 1e-05 is invalid; valid: 0 (or -solid_rbc_count 2"),
            std::string::npos)
      << last_output_;
  expect_one_clear_error(
      cellfsi(with(base, {"-solid_rbc_count", "5", "-solid_rbc_arrangement", "staggered"})));
  EXPECT_NE(last_output_.find("an even count"), std::string::npos) << last_output_;
  // 24 cells lying along the flow (angle 0, 7.8e-4 cm long) cannot fit in 0.003 cm.
  fs::remove_all(out_);
  expect_one_clear_error(cellfsi(with(base, {"-solid_rbc_count", "24", "-solid_rbc_angle", "0"})));
  EXPECT_NE(last_output_.find("overlap"), std::string::npos) << last_output_;
  expect_one_clear_error(cellfsi(with(base, {"-domain_periodic", "0,0"})));
  EXPECT_NE(last_output_.find("option -solid_rbc_count = 12 is invalid"), std::string::npos) << last_output_;
}

TEST_F(CellfsiApp, MigrationSceneReportsTheLateralOffset) {
  const RunResult r = cellfsi({scene("capsule_channel_migration.yaml"), "-fluid_elements", "64,32",
                               "-fluid_degree", "2", "-solid_membrane_elements", "1,0", "-final_time", "5e-4",
                               "-output_every", "0", "-fluid_space", "equal_order"},
                              120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  EXPECT_NEAR(json_number(js, "membrane_lateral_offset_start").value_or(0), 2e-4, 1e-8) << js;
  EXPECT_TRUE(json_number(js, "membrane_lateral_offset_final").has_value()) << js;
  // The ellipse starts aligned with the flow: symmetric about both lines through its centroid (measured after
  // 2 steps: 0.004-0.016 depending on the mesh).
  for (const char* key : {"membrane_asymmetry_flow_axis", "membrane_asymmetry_front_back"})
    EXPECT_LT(json_number(js, key).value_or(1), 0.03) << key << "\n" << js;
  EXPECT_TRUE(js.find("\"membrane_time_to_centreline\": null") != std::string::npos)
      << "not there in 2 steps\n"
      << js;
}

TEST_F(CellfsiApp, InertialMigrationSceneStartsDevelopedAndReportsWhereTheDiskSettles) {
  // The stiff disk in the channel at plasma Reynolds number 13.91 (20 steps on a tiny mesh): the flow starts
  // developed, and the lateral-equilibrium keys are those of the centroid track in metrics.csv.
  const RunResult r = cellfsi({scene("inertial_migration.yaml"), "-fluid_elements", "16,16", "-fluid_degree",
                               "2", "-final_time", "4e-5", "-output_every", "0"},
                              120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  EXPECT_NEAR(json_number(js, "channel_reynolds_plasma").value_or(0), 13.91, 0.01) << js;
  // From the start the flow has the plasma's mean velocity (from rest it would be 0); the disk slows it by
  // about 10 % only as its wake forms (measured: 13.90 after five steps, 12.6 once settled at 32 x 32).
  EXPECT_NEAR(json_number(js, "channel_reynolds").value_or(0), 13.91, 0.02 * 13.91) << js;
  // The track's last tenth (t >= 3.6e-5 s: three records): the mean offset from the centre line (y = 0.002)
  // and its least-squares slope; the disk moved less than 1 % of W, so it was "settled" from the start.
  const Csv csv = read_csv(out_ / "metrics.csv");
  const int ct = csv.column("time"), cy = csv.column("disk_centroid_y");
  ASSERT_GE(ct, 0);
  ASSERT_GE(cy, 0);
  double n = 0, st = 0, sy = 0, stt = 0, sty = 0;
  for (const auto& row : csv.rows) {
    const double t = std::stod(row[ct]), y = std::stod(row[cy]) - 0.002;
    if (t < 3.6e-5 - 1e-12) continue;
    n += 1, st += t, sy += y, stt += t * t, sty += t * y;
  }
  ASSERT_EQ(n, 3);
  const double offset = sy / n, drift = (n * sty - st * sy) / (n * stt - st * st);
  // (metrics.csv prints 12 digits; measured offset -4.11e-4 cm, drift -0.39 cm/s, the start's transient)
  EXPECT_NEAR(json_number(js, "disk_lateral_offset_equilibrium").value_or(0), offset, 1e-12) << js;
  EXPECT_NEAR(json_number(js, "disk_wall_distance_over_height").value_or(0), 0.5 - std::abs(offset) / 0.004,
              1e-9)
      << js;
  EXPECT_NEAR(json_number(js, "disk_lateral_drift_final").value_or(0), drift, 1e-6 * std::abs(drift)) << js;
  EXPECT_GT(std::abs(drift), 0.01) << "the disk moves across in its first steps";
  EXPECT_EQ(json_number(js, "disk_lateral_settle_time").value_or(-1), 0.0) << js;
}

TEST_F(CellfsiApp, CtcNarrowingSceneRunsAndReportsItsPassage) {
  // Paper Sec. 4.4 (five steps at a tiny mesh, past the flow's 5 viscous times, 1.7e-3 s): the compound
  // capsule upstream of the throat; the passage keys are there (null until the cell crosses the throat) with
  // the developed flow rate's extremes and each body's peak deformation.
  const RunResult r = cellfsi({scene("ctc_narrowing.yaml"), "-fluid_elements", "96,32", "-fluid_degree", "2",
                               "-solid_membrane_elements", "1,0", "-solid_nucleus_elements", "0,0", "-dt",
                               "5e-4", "-final_time", "2.5e-3", "-output_every", "0"},
                              120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  for (const std::string key :
       {"membrane_throat_entry_time", "nucleus_throat_exit_time", "membrane_throat_transit_time"}) {
    const std::string entry = '"' + key + "\": null";
    EXPECT_NE(js.find(entry), std::string::npos) << key << "\n" << js;
  }
  for (const char* key :
       {"flow_rate_max", "flow_rate_min", "nucleus_max_anisotropy", "nucleus_max_anisotropy_x"})
    EXPECT_TRUE(json_number(js, key).has_value()) << key << "\n" << js;
  // In 2.5e-3 s the cell (about 0.013 cm/s) has moved less than 5e-5 cm from its start at x = 0.001 cm.
  EXPECT_NEAR(json_number(js, "nucleus_max_anisotropy_x").value_or(0), 0.001, 5e-5) << js;
  EXPECT_LE(json_number(js, "flow_rate_min").value_or(1), json_number(js, "flow_rate_max").value_or(0)) << js;
  EXPECT_GT(json_number(js, "flow_rate_min").value_or(0), 0.0) << js;
  // The narrowing is not uniform along x: the automatic choice is the band solver, and the Fourier solver
  // is refused with the reason.
  EXPECT_EQ(json_string(js, "coupling_pc_type").value_or(""), "cellfsi_band") << js;
  fs::remove_all(out_);
  const RunResult refused = cellfsi({scene("ctc_narrowing.yaml"), "-fluid_elements", "96,32", "-fluid_degree",
                                     "2", "-final_time", "5e-4", "-coupling_pc_type", "cellfsi_fourier"});
  expect_one_clear_error(refused);
  EXPECT_NE(refused.output.find("not uniform along its periodic directions"), std::string::npos)
      << refused.output;
  // The narrowing's size comes from the channel options; -domain_size was silently ignored.
  fs::remove_all(out_);
  expect_one_clear_error(
      cellfsi({scene("ctc_narrowing.yaml"), "-domain_size", "0.01,0.002", "-fluid_elements", "96,32"}));
  EXPECT_NE(last_output_.find("use -channel_length, -channel_height"), std::string::npos) << last_output_;
}

// Linear-solver options of a coupled run (issue 13): the fluid's KSP options do not apply to the band solver
// and say so; options PETSc reads at the first solve (factorisation packages, convergence reports) are
// accepted in both solvers, and a misspelt one is reported once every solver has read its options.
TEST_F(CellfsiApp, FluidSolverOptionsOfABandRunAreRejectedWithTheReason) {
  const RunResult r = cellfsi(with(kDefaultCapsule, {"-fluid_pc_type", "lu"}));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-fluid_pc_type"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("a coupled run solves with the KSP -coupling_ (e.g. -coupling_pc_type)"),
            std::string::npos)
      << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, SnesOptionsOfACoupledRunAreRejectedWithTheReason) {
  // Issue 10: -fluid_snes_* options were silently ignored in coupled runs with the fluid's KSP.
  for (const char* pc : {"cellfsi_band", "asm"}) {
    expect_one_clear_error(
        cellfsi(with(kDefaultCapsule, {"-coupling_pc_type", pc, "-fluid_snes_rtol", "1e-3"})));
    EXPECT_NE(
        last_output_.find("option -fluid_snes_rtol does not apply: in a coupled run the nonlinear iteration "
                          "is the coupling loop"),
        std::string::npos)
        << last_output_;
  }
}

TEST_F(CellfsiApp, OptionsReadAtTheFirstSolveAreAcceptedInEverySolver) {
  RunResult r =
      cellfsi(with(kDefaultCapsule,
                   {"-coupling_pc_type", "cellfsi_band", "-coupling_band_mat_mumps_icntl_14", "40",
                    "-coupling_band_schur_mat_mumps_icntl_14", "40", "-coupling_ksp_converged_reason"}));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = cellfsi(with(kDefaultCapsule, {"-coupling_fourier_region_mat_mumps_icntl_14", "40",
                                     "-coupling_ksp_converged_reason"}));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = cellfsi(with(kDefaultCapsule, {"-coupling_pc_type", "asm", "-coupling_sub_mat_mumps_icntl_14", "40",
                                     "-coupling_ksp_converged_reason"}));
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

TEST_F(CellfsiApp, OptionsOfTheSolverReplacedInTheFirstStepAreAccepted) {
  // A band region of the whole domain (margin 40 elements at 48 x 24) hands the loop to the fluid's solver in
  // the first step: the band's factorisation options were checked before it and are never read.
  const RunResult r = cellfsi(with(kDefaultCapsule, {"-coupling_pc_type", "cellfsi_band", "-coupling_region_margin",
                                                     "40", "-coupling_band_mat_mumps_icntl_14", "40"}));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("the coupling loop uses -coupling_pc_type asm"), std::string::npos) << r.output;
}

TEST_F(CellfsiApp, MisspeltFactorisationOptionIsRejectedAfterTheFirstStep) {
  for (const std::vector<std::string>& o :
       {std::vector<std::string>{"-coupling_pc_type", "cellfsi_band", "-coupling_band_mat_mumps_icntll_14", "40"},
        std::vector<std::string>{"-coupling_fourier_region_mat_mumps_icntll_14", "40"}}) {
    const RunResult r = cellfsi(with(kDefaultCapsule, o));
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
    EXPECT_NE(r.output.find(o[o.size() - 2].substr(1)), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("after the first time step"), std::string::npos) << r.output;
  }
}

TEST_F(CellfsiApp, FactorisationOptionValueRefusedAtTheFirstSolveIsBadInput) {
  // MUMPS' interface checks ICNTL(7) when it factorises (PETSc 3.18 takes no ordering through ICNTL(7); one
  // from -pc_factor_mat_ordering_type, docs/design.md §8): exit 1 with one
  // message, as for any bad value, not a failed step.
  const RunResult r = cellfsi(with(kDefaultCapsule, {"-coupling_fourier_region_mat_mumps_icntl_7", "1"}));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
  EXPECT_NE(r.output.find("Valid values"), std::string::npos) << r.output;
  EXPECT_EQ(count(r.output, "a solver option's value is invalid"), 1u) << r.output;
  // A factorisation package this PETSc does not have: bad input, not a diverged step.
  const RunResult s = cellfsi(with(kDefaultCapsule, {"-coupling_fourier_region_pc_factor_mat_solver_type",
                                                     "nosuchpackage"}));
  EXPECT_EQ(s.exit_code, 1) << s.output;
  EXPECT_EQ(count(s.output, "cellfsi: error:"), 1u) << s.output;
  EXPECT_NE(s.output.find("Could not locate solver type nosuchpackage"), std::string::npos) << s.output;
  EXPECT_EQ(s.output.find("diverged"), std::string::npos) << s.output;
}

TEST_F(CellfsiApp, RegionFactorisationsWithoutBAIJAreGivenTheRegionAsAIJ) {
  // Issue 26 (docs/design.md §8): SuperLU and SuperLU_DIST factorise AIJ only, and were refused while
  // the region went to its LU as BAIJ; now the region is converted for them. Their LU is exact too, so the
  // run agrees with MUMPS' to far below the coupling tolerance (measured: 2e-11 of max(|value|, 1e-3), on
  // r_A; asserted: 1e-8).
  ASSERT_EQ(cellfsi(kDefaultCapsule).exit_code, 0) << last_output_;
  const auto mumps = last_row(out_ / "metrics.csv");
  for (const char* package : {"superlu", "superlu_dist"}) {
    SCOPED_TRACE(package);
    ASSERT_EQ(cellfsi(with(kDefaultCapsule, {"-coupling_fourier_region_pc_factor_mat_solver_type", package}))
                  .exit_code,
              0)
        << last_output_;
    EXPECT_TRUE(rows_agree(metrics_only(mumps), metrics_only(last_row(out_ / "metrics.csv")), 1e-8, 1e-3));
  }
}

TEST_F(CellfsiApp, FourierBandAndFluidSolversAgree) {
  // Issue 13: the coupling loop's three linear solvers on the capsule (2D, 2 steps) and the 3D compound
  // capsule (12^3, 1 step). Each linear solve stops at rtol 1e-5 on a correction that is itself below the
  // coupling tolerance (1e-4 of the step's first), so the states agree to far below it (measured: 1e-9 in
  // 2D, 6e-8 at 16^3 in 3D).
  const std::vector<std::vector<std::string>> cases = {
      with({scene("capsule_shear.yaml")}, with(kCapsule, {"-final_time", "1e-3"})),
      {scene("compound_capsule_shear_3d.yaml"), "-fluid_elements", "12,12,12", "-solid_membrane_elements",
       "1,0,0", "-solid_nucleus_elements", "0,0,0", "-final_time", "5e-4", "-output_every", "0",
       "-fluid_space", "equal_order"}};
  for (const auto& args : cases) {
    ASSERT_EQ(cellfsi(args, 120).exit_code, 0) << last_output_;
    EXPECT_EQ(json_string(summary(), "coupling_pc_type").value_or(""), "cellfsi_fourier");  // the automatic choice
    const auto fourier = last_row(out_ / "metrics.csv");
    for (const char* other : {"cellfsi_band", "asm"}) {
      fs::remove_all(out_);
      ASSERT_EQ(cellfsi(with(args, {"-coupling_pc_type", other}), 120).exit_code, 0) << last_output_;
      EXPECT_TRUE(rows_agree(metrics_only(fourier), metrics_only(last_row(out_ / "metrics.csv")), 1e-6, 1e-4))
          << other;
    }
    fs::remove_all(out_);
  }
}

TEST_F(CellfsiApp, BandPCOnTwoFluidRanksIsRefusedWithTheReason) {
  // cellfsi_band runs on one fluid rank (PETSc 3.18 computes MUMPS Schur complements on one rank only).
  const RunResult r = mpi_cellfsi(2, with(kDefaultCapsule, {"-coupling_pc_type", "cellfsi_band"}));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
  EXPECT_NE(r.output.find("cellfsi_band needs one fluid rank"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, OneAndTwoFluidRanksAgree) {
  const std::vector<std::string> args =
      with({scene("capsule_shear.yaml")}, with(kCapsule, {"-final_time", "2e-3"}));
  ASSERT_EQ(cellfsi(args).exit_code, 0) << last_output_;
  const auto one = last_row(out_ / "metrics.csv");
  EXPECT_EQ(json_string(summary(), "coupling_pc_type").value_or(""), "cellfsi_fourier");
  ASSERT_EQ(mpi_cellfsi(2, args).exit_code, 0) << last_output_;
  EXPECT_EQ(json_string(summary(), "coupling_pc_type").value_or(""), "cellfsi_fourier");  // on 2 ranks too
  const auto two = last_row(out_ / "metrics.csv");
  // The same solver on both: the partition changes only the order of sums (the averaged stencil's, the
  // products'), so the iterations are the same and the state agrees to round-off amplified by the linear
  // solves (measured: 1e-14 at 64 x 32 over 10 steps); r_A, a difference of areas, to 1e-12 absolute: its
  // round-off is absolute (measured 6.5e-14 on r_A = -5.47e-5 between two 2-rank runs on a loaded machine,
  // 1.2e-9 relative).
  auto split_r_A = [](std::vector<std::pair<std::string, double>>& row) {
    std::vector<std::pair<std::string, double>> r_A;
    for (const auto& kv : row)
      if (kv.first.ends_with("_r_A")) r_A.push_back(kv);
    std::erase_if(row, [](const auto& kv) { return kv.first.ends_with("_r_A"); });
    return r_A;
  };
  auto one_rest = one, two_rest = two;
  const auto one_r_A = split_r_A(one_rest), two_r_A = split_r_A(two_rest);
  EXPECT_TRUE(rows_agree(one_rest, two_rest, 1e-9, 1e-9));
  EXPECT_TRUE(rows_agree(one_r_A, two_r_A, 1e-12, 1.0));  // |r_A| < 1: 1e-12 absolute
  // The fluid's KSP (ASM) on 2 ranks: the state agrees to well below the coupling tolerance (the linear
  // solves stop at rtol 1e-5).
  ASSERT_EQ(mpi_cellfsi(2, with(args, {"-coupling_pc_type", "asm"})).exit_code, 0) << last_output_;
  EXPECT_TRUE(rows_agree(metrics_only(one), metrics_only(last_row(out_ / "metrics.csv")), 1e-6, 1e-4));
}

TEST_F(CellfsiApp, InterfaceScalingReducesTheAreaError) {
  // Paper Fig. 1b on a coarse mesh: the spurious area change falls as s_I grows.
  double previous = 1e300;
  for (const char* s_i : {"1", "1e5", "1e10"}) {
    const RunResult r =
        cellfsi(with({scene("capsule_shear.yaml")},
                     {"-fluid_elements", "48,24", "-solid_membrane_elements", "1,0", "-final_time", "0.02",
                      "-output_every", "0", "-s_interface", s_i, "-fluid_space", "equal_order"}),
                120);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const double ra = std::abs(json_number(summary(), "membrane_r_A").value_or(1e300));
    std::printf("  s_I = %s: |r_A| = %.3e\n", s_i, ra);
    EXPECT_LT(ra, previous / 3) << "s_I = " << s_i;
    previous = ra;
  }
}

TEST_F(CellfsiApp, AutomaticInterfaceScalingIsChosenFromTheMeshAndWritten) {
  // Issue 27, item 4: the capsule scene's default -s_interface auto at 48 x 24 quadratic (h = 5e-5 cm, a band
  // of 3 h): s_I = 6.25e10 (5e-5 / 1.5e-4)^2.8 = 2.884e9 for |r_A| <= 1e-3, 4 times that for 5e-4; the
  // value used is in summary.json, with how it was set.
  const std::vector<std::string> run = with({scene("capsule_shear.yaml")}, kCapsule);
  for (const auto& [target, expected] : {std::pair{"1e-3", 2.8836e9}, std::pair{"5e-4", 4 * 2.8836e9}}) {
    ASSERT_EQ(cellfsi(with(run, {"-s_interface_target", target}), 120).exit_code, 0) << last_output_;
    const std::string js = summary();
    EXPECT_EQ(json_string(js, "s_interface_choice").value_or(""), "auto");
    EXPECT_NEAR(json_number(js, "s_interface").value_or(0), expected, 1e-3 * expected) << target;
    EXPECT_NEAR(json_number(js, "s_interface_target").value_or(0), std::stod(target), 1e-15);
  }
  // A number is used as given.
  ASSERT_EQ(cellfsi(with(run, {"-s_interface", "1e10"}), 120).exit_code, 0) << last_output_;
  EXPECT_EQ(json_string(summary(), "s_interface_choice").value_or(""), "given");
  EXPECT_EQ(json_number(summary(), "s_interface").value_or(0), 1e10);
  EXPECT_FALSE(json_number(summary(), "s_interface_target").has_value());
}

TEST_F(CellfsiApp, InterfaceScalingIsRaisedWhenTheAreaErrorPassesHalfTheTarget) {
  // -s_interface_raise with the target 1e-4 at 48 x 24 quadratic: auto chooses 2.88e11. |r_A| (measured
  // 6.0e-5, 8.1e-5, 6.8e-5, 5.6e-5 over 4 steps, whatever s_I) passes half the target in the first step,
  // which does not count (the start from rest), and grows past it in the second: s_I goes to 4 times 2.88e11,
  // capped at 1e12.
  const std::vector<std::string> run =
      with({scene("capsule_shear.yaml")},
           with(kCapsule, {"-final_time", "2e-3", "-s_interface_target", "1e-4", "-s_interface_raise"}));
  const RunResult r = cellfsi(run, 120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("at t = 0.001 s: s_I raised from 2.88e+11 to 1e+12"), std::string::npos)
      << r.output;
  const std::string js = summary();
  EXPECT_NEAR(json_number(js, "s_interface").value_or(0), 2.8836e11, 1e-3 * 2.8836e11);
  EXPECT_EQ(json_number(js, "s_interface_final").value_or(0), 1e12);
  EXPECT_EQ(json_number(js, "s_interface_raises").value_or(0), 1);
  // Without it, neither is written.
  ASSERT_EQ(cellfsi(with({scene("capsule_shear.yaml")}, kCapsule), 120).exit_code, 0) << last_output_;
  EXPECT_FALSE(json_number(summary(), "s_interface_final").has_value());
}

}  // namespace

namespace {

/// The 3D compound capsule at 12^3 (the coarsest mesh its nucleus allows) with automatic body elements, two
/// steps, no output.
std::vector<std::string> compound_capsule_12(const std::string& scene_file) {
  return {scene_file,   "-fluid_elements",         "12,12,12", "-solid_membrane_elements",
          "1,0,0",      "-solid_nucleus_elements", "0,0,0",    "-final_time",
          "1e-3",       "-output_every",           "0",        "-fluid_space",
          "equal_order"};
}

// The solver paths of a 3D coupled step, on the compound capsule at 12^3, two steps, in one test so that runs
// several assertions need are made once (each run costs seconds; tests/README.md, "Time"). At 16^3, where the
// values quoted "over 10 steps" were measured, every pair below agreed about as closely (the largest
// differences, 16^3 / 12^3: B-A 1.9e-8 / 9.2e-8, B on 2 ranks 2e-12 / 3e-12, E-A 3.9e-9 / 2.7e-9):
//   A  the 3D defaults, one rank: the Fourier solver, the region's LU in single precision, the bulk
//      stencil, the coupled FGMRES to rtol 1e-2;
//   B  A with the FGMRES to rtol 1e-5, on 1 and 2 fluid ranks;
//   E  A with the region's LU in double precision (-coupling_fourier_region_pc_type lu);
//   F  B with the whole Jacobian (-coupling_bulk_stencil false), against B on one rank (so on two as well).
// Five runs (a run on 4 ranks, oversubscribed on 2 cores, and F on 2 ranks were dropped for the suite's time:
// B on 2 ranks covers a partition, F against B the stencil). Each pair's tolerance is stated where it is
// asserted, from the measured agreement (tests/support/tolerances.hpp).
TEST_F(CellfsiApp, ThreeDSolverPathsAgree) {
  const std::vector<std::string> args = compound_capsule_12(scene("compound_capsule_shear_3d.yaml"));
  // A. -coupling_ksp_view shows the 3D tolerance and the region's single-precision LU.
  ASSERT_EQ(cellfsi(with(args, {"-coupling_ksp_view"}), 120).exit_code, 0) << last_output_;
  EXPECT_NE(last_output_.find("relative=0.01,"), std::string::npos) << last_output_;
  EXPECT_NE(last_output_.find("MUMPS LU in single precision, ordering cellfsi_nd"), std::string::npos)
      << last_output_;
  const auto a = last_row(out_ / "metrics.csv");
  const std::string a_summary = summary();

  {
    // Issue 26, rtol 1e-2 in 3D (1e-5 before): the coupling loop, not the linear solve, sets the iterations
    // there. Against 1e-5: the same coupling iterations, fewer FGMRES iterations (measured over 10 steps: 39 and
    // 39 coupling, 114 against 225 FGMRES; over these two steps 7 and 7, 18 against 37), every metric to the
    // coupling tolerance (measured: 2.7e-8 relative over 10 steps, 9.2e-8 over these two; asserted 1e-6, and
    // 1e-9 absolute below 1e-3).
    SCOPED_TRACE("B: rtol 1e-5 against A");
    const std::vector<std::string> tight = with(args, {"-coupling_ksp_rtol", "1e-5"});
    ASSERT_EQ(cellfsi(tight, 120).exit_code, 0) << last_output_;
    const auto b = last_row(out_ / "metrics.csv");
    EXPECT_TRUE(rows_agree(metrics_only(a), metrics_only(b), 1e-6, 1e-3));
    EXPECT_EQ(json_number(a_summary, "coupling_iterations"), json_number(summary(), "coupling_iterations"));
    EXPECT_LT(json_number(a_summary, "linear_iterations").value_or(1e9),
              0.8 * json_number(summary(), "linear_iterations").value_or(0));
    // Issue 26: B on 1 and 2 fluid ranks, the Fourier solver on both partitions. Measured: every metric
    // agrees to 1e-10 relative (here 4.4e-12; 4 ranks, no longer run, 9e-12), r_A (a difference of areas,
    // -3.4e-5) to 1.5e-14 absolute; asserted to 1e-9 relative, and values below 1e-3 (r_A, centroids in cm)
    // to 1e-12 absolute. The region's single-precision LU (SCOTCH's ordering on every rank count) is made up
    // by the FGMRES around it (over 10 steps 1 and 2 ranks agree to 9e-11 relative in r_A). At the 3D default
    // rtol 1e-2 the partitions' round-off is larger (measured: 1, 2 and 4 ranks agree to 3.6e-9 and 5.6e-9
    // relative in the shear profile's error).
    {
      SCOPED_TRACE("2 ranks");
      ASSERT_EQ(mpi_cellfsi(2, tight, 120).exit_code, 0) << last_output_;
      EXPECT_EQ(json_string(summary(), "coupling_pc_type").value_or(""), "cellfsi_fourier");
      EXPECT_TRUE(rows_agree(metrics_only(b), metrics_only(last_row(out_ / "metrics.csv")), 1e-9, 1e-3));
    }
    // Issue 26: -coupling_bulk_stencil (the 3D default) keeps no whole Jacobian after the first step (the
    // Krylov products apply the bulk stencil away from the cells and the assembled rows near them), an
    // inexact Newton iteration whose residual is exact. With the whole Jacobian every metric agrees with B to
    // the linear tolerance (measured at rtol 1e-5 over these two steps: 3.6e-12 relative, r_A to 1e-14
    // absolute, the same 7 coupling and 37 FGMRES iterations; at rtol 1e-2 over 10 steps 3e-11, on 2 ranks as
    // on 1; asserted 1e-9). B on 2 ranks above puts the stencil's partition against the same run.
    SCOPED_TRACE("F: the whole Jacobian against B");
    ASSERT_EQ(cellfsi(with(tight, {"-coupling_bulk_stencil", "false"}), 120).exit_code, 0) << last_output_;
    EXPECT_TRUE(rows_agree(metrics_only(b), metrics_only(last_row(out_ / "metrics.csv")), 1e-9, 1e-3));
  }
  {
    // Issue 26: the region's LU in single precision (cellfsi_lu_single) is a preconditioner in the coupling's
    // FGMRES, not the exact inverse the double one is: the FGMRES makes up the precision. Against MUMPS in
    // double: every metric to the coupling tolerance (at rtol 1e-2: 2.7e-9 relative over these two steps and
    // 1.6e-9 over 10; asserted: 1e-8, and 1e-11 absolute below 1e-3), and the same coupling iterations; the
    // FGMRES iterations within one of each other (two preconditioners: one that ends a solve near its
    // tolerance can take one more; measured: the same).
    SCOPED_TRACE("E: the region's LU in double precision against A");
    ASSERT_EQ(cellfsi(with(args, {"-coupling_fourier_region_pc_type", "lu"}), 120).exit_code, 0)
        << last_output_;
    EXPECT_TRUE(rows_agree(metrics_only(a), metrics_only(last_row(out_ / "metrics.csv")), 1e-8, 1e-3));
    EXPECT_EQ(json_number(a_summary, "coupling_iterations"), json_number(summary(), "coupling_iterations"));
    EXPECT_NEAR(json_number(a_summary, "linear_iterations").value_or(-10),
                json_number(summary(), "linear_iterations").value_or(10), 1.0);
  }
}

TEST_F(CellfsiApp, RegionFactorisationOptionsTheSinglePrecisionLUDoesNotReadAreRefused) {
  // A factorisation option for the region, which the single-precision LU does not read: one error saying so.
  const RunResult r = cellfsi(
      {scene("compound_capsule_shear_3d.yaml"), "-fluid_elements", "12,12,12", "-solid_membrane_elements",
       "1,0,0", "-solid_nucleus_elements", "0,0,0", "-final_time", "5e-4", "-output_every", "0",
       "-fluid_space", "equal_order", "-coupling_fourier_region_mat_mumps_icntl_14", "40"},
      120);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
  EXPECT_NE(r.output.find("-coupling_fourier_region_pc_type lu"), std::string::npos) << r.output;
}

TEST_F(CellfsiApp, CoupledSolveToRtol1e5In2DAndTheOptionSetsIt) {
  // 2D keeps the coupled FGMRES at rtol 1e-5 (there 1e-2 costs coupling iterations: docs/design.md §8); the
  // option sets it in both dimensions (3D: ThreeDSolverPathsAgree).
  std::vector<std::string> two_d = with(kCapsule, {"-coupling_ksp_view"});
  two_d.insert(two_d.begin(), scene("capsule_shear.yaml"));
  ASSERT_EQ(cellfsi(two_d, 120).exit_code, 0) << last_output_;
  EXPECT_NE(last_output_.find("relative=1e-05,"), std::string::npos) << last_output_;
  ASSERT_EQ(cellfsi(with(two_d, {"-coupling_ksp_rtol", "1e-3"}), 120).exit_code, 0) << last_output_;
  EXPECT_NE(last_output_.find("relative=0.001,"), std::string::npos) << last_output_;
}

}  // namespace

TEST_F(CellfsiApp, TwoCapsulesCloserThanTheCutOffArePushedApartWithoutOverlap) {
  // Two capsules of the pair scene (in a box half as high) stacked across the flow with their mid-lines 0.4
  // r_c apart (r_c: the smallest fluid element, 0.0032 / 48 cm). The repulsion pushes them apart: after four
  // steps their centres are farther apart across the flow than with a negligible pressure scale, no point of
  // one lies in the other, and the run reports its constants (P0 = G h / a = 1680 * 5e-7 / 1e-4 = 8.4
  // dyn/cm^2). (Four coarse steps: about 2 s.)
  const double rc = kPairCutoff, gap = 0.4 * rc;
  const std::vector<std::string> base = touching_capsules(gap);
  const auto apart = [&] {
    double yu = 0, yl = 0;
    for (const auto& [k, v] : last_row(out_ / "metrics.csv")) {
      if (k == "upper_centroid_y") yu = v;
      if (k == "lower_centroid_y") yl = v;
    }
    return yu - yl;
  };
  const RunResult off = cellfsi(with(base, {"-coupling_repulsion_pressure", "1e-30"}), 120);
  ASSERT_EQ(off.exit_code, 0) << off.output;
  const double apart_off = apart();
  fs::remove_all(out_);
  const RunResult on = cellfsi(base, 120);
  ASSERT_EQ(on.exit_code, 0) << on.output;
  EXPECT_NE(on.output.find("contact repulsion below 6.667e-05 cm"), std::string::npos) << on.output;
  const std::string js = summary();
  EXPECT_TRUE(cellfsi_test::agree(json_number(js, "repulsion_cutoff").value_or(0), rc, 1e-12)) << js;
  // (R from the perimeter that the quadrature points' areas sum to: a Gauss rule on the rational arcs, 3e-8.)
  EXPECT_TRUE(cellfsi_test::agree(json_number(js, "repulsion_pressure").value_or(0), 8.4, 1e-6)) << js;
  // The first step's least distance: the initial gap, to the quadrature points' spacing along the mid-line
  // and their place across the thickness (a few percent of it here).
  const Csv csv = read_csv(out_ / "metrics.csv");
  const int g = csv.column("contact_cell_gap");
  ASSERT_GE(g, 0);
  EXPECT_NEAR(std::stod(csv.rows.front()[g]), gap, 0.1 * gap);
  EXPECT_EQ(json_number(js, "contact_overlap_points_max"), 0.0) << js;
  const double apart_on = apart();
  // Both start 2a + gap apart. Measured: the repulsion adds 6.3e-7 cm (2.4 % of the gap) to their distance
  // across the flow in 2 ms (at P0 = 8.4 dyn/cm^2 the pressure at this gap is 19 dyn/cm^2, and equal and
  // opposite forces within one fluid element move their points apart only by the difference of the fluid's
  // response there); without it the distance is the same to round-off.
  EXPECT_GT(apart_on - apart_off, 0.01 * gap) << apart_on << " " << apart_off;
  // Off: no repulsion, no cell gap column, but the points of a membrane inside the other still counted (none:
  // bodies placed overlapping are refused, and one step does not bring them together) and the membranes'
  // distance from the walls sampled (the capsules' outer points 6 um - gap / 2 from the walls 16 um apart;
  // one step moves them by under 1e-8 cm); a negative cut-off is refused.
  fs::remove_all(out_);
  ASSERT_EQ(cellfsi(with(base, {"-coupling_repulsion", "false", "-final_time", "5e-4"}), 120).exit_code, 0)
      << last_output_;
  const Csv off_csv = read_csv(out_ / "metrics.csv");
  EXPECT_LT(off_csv.column("contact_cell_gap"), 0);
  const int w = off_csv.column("contact_wall_gap");
  ASSERT_GE(w, 0);
  EXPECT_NEAR(std::stod(off_csv.rows.front()[w]), 6e-4 - gap / 2, 1e-7);
  EXPECT_NEAR(json_number(summary(), "contact_wall_gap_min").value_or(0), 6e-4 - gap / 2, 1e-7);
  const int o = off_csv.column("contact_overlap_points");
  ASSERT_GE(o, 0);
  EXPECT_EQ(std::stod(off_csv.rows.front()[o]), 0.0);
  EXPECT_EQ(json_number(summary(), "contact_overlap_points_max"), 0.0);
  fs::remove_all(out_);
  expect_one_clear_error(cellfsi(with(base, {"-coupling_repulsion_cutoff", "-1"})));
  EXPECT_NE(last_output_.find("option -coupling_repulsion_cutoff = -1 is invalid"), std::string::npos)
      << last_output_;
}

TEST_F(CellfsiApp, ScatteredCopiesKeepAnElementFromEveryBodyAndTheWallsOrAreRefused) {
  // Six RBCs scattered at random around the CTC of the narrowing (issue 46): every copy inside the channel at
  // least one fluid element (r_c: the throat's 8e-4 / 32 cm) from the walls and from every other body, none
  // inside the CTC; the same seed places them the same way (metrics.csv's centroids). Forty do not fit: the
  // count is refused with how many did.
  const std::vector<std::string> base = {scene("ctc_narrowing.yaml"),
                                         "-fluid_elements",
                                         "96,32",
                                         "-fluid_degree",
                                         "2",
                                         "-solid_membrane_elements",
                                         "1,0",
                                         "-solid_nucleus_elements",
                                         "0,0",
                                         "-dt",
                                         "5e-4",
                                         "-final_time",
                                         "5e-4",
                                         "-output_every",
                                         "0",
                                         "-solid_bodies",
                                         "membrane,nucleus,rbc",
                                         "-solid_rbc_shape",
                                         "rbc",
                                         "-solid_rbc_count",
                                         "6",
                                         "-solid_rbc_arrangement",
                                         "scattered",
                                         "-solid_rbc_elements",
                                         "1,0"};
  ASSERT_EQ(cellfsi(base, 120).exit_code, 0) << last_output_;
  const double rc = 8e-4 / 32;
  const auto row = last_row(out_ / "metrics.csv");
  std::vector<double> centres;
  for (const auto& [k, v] : row) {
    if (k == "contact_wall_gap") {
      EXPECT_GE(v, rc * (1 - 1e-9)) << k;  // (one step moved them by < 1e-8 cm)
    }
    if (k == "contact_overlap_points") {
      EXPECT_EQ(v, 0.0);
    }
    if (k.rfind("rbc_", 0) == 0 && k.find("_centroid_") != std::string::npos) centres.push_back(v);
  }
  ASSERT_EQ(centres.size(), 12u) << "six copies, x and y";
  fs::remove_all(out_);
  ASSERT_EQ(cellfsi(base, 120).exit_code, 0) << last_output_;
  std::vector<double> again;
  for (const auto& [k, v] : last_row(out_ / "metrics.csv"))
    if (k.rfind("rbc_", 0) == 0 && k.find("_centroid_") != std::string::npos) again.push_back(v);
  // (The same placement; the one step after it by the same operations, compared to round-off all the same.)
  ASSERT_EQ(again.size(), centres.size());
  for (size_t i = 0; i < again.size(); ++i)
    EXPECT_TRUE(cellfsi_test::agree(again[i], centres[i], 1e-12, 1e-6));
  fs::remove_all(out_);
  // (Coarse copies for the refusal: 2000 draws of the copy that finds no place take 2 s, not 8.)
  expect_one_clear_error(cellfsi(with(base, {"-solid_rbc_count", "40", "-solid_rbc_elements", "1,32"}), 120));
  EXPECT_NE(last_output_.find("option -solid_rbc_count = 40 is invalid; valid: fewer copies: only "),
            std::string::npos)
      << last_output_;
  expect_one_clear_error(cellfsi(with(base, {"-solid_rbc_spread", "1e-5"}), 120));
  EXPECT_NE(last_output_.find("-solid_rbc_spread"), std::string::npos) << last_output_;
}
