// Integration tests (cellfsi_app_fixture.hpp): bad input, one clear message, exit code 1, nothing written.
#include "cellfsi_app_fixture.hpp"

using namespace cellfsi_app_test;

namespace {

// ---------------------------------------------------------------------------------------------------------
// 3. Bad input: one clear message, exit code 1, nothing written

TEST_F(CellfsiApp, UnknownOptionIsRejected) {
  const RunResult r = cellfsi(with({scene("shear.yaml"), "-fluid_viscosty", "0.01"}, kTiny));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("fluid_viscosty"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, NegativeViscosityIsRejected) {
  const RunResult r = cellfsi(with({scene("shear.yaml"), "-fluid_viscosity", "-1"}, kTiny));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-fluid_viscosity"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("-1"), std::string::npos) << "the message names the value:\n" << r.output;
  EXPECT_NE(r.output.find("1e-08 ... 1e+06 [g/(cm s)]"), std::string::npos)
      << "the message names the valid range:\n"
      << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, DegreeOneIsRejected) {
  const RunResult r = cellfsi(with(with({scene("shear.yaml")}, kTiny), {"-fluid_degree", "1"}));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-fluid_degree"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("2 <= p <= 8"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, QuadraticNarrowingOnTheDivergenceConformingSpaceIsRejected) {
  // Its Piola map takes the channel's second derivatives, which jump between elements at p = 2: a step of the
  // CTC among red cells stalled there (DcPiola.AMapWhoseSecondDerivativesJumpBetweenElementsIsRefused).
  const RunResult r =
      cellfsi({scene("ctc_narrowing.yaml"), "-fluid_elements", "48,16", "-fluid_degree", "2", "-fluid_space",
               "div_conforming", "-final_time", "2.5e-4", "-output_every", "0"});
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("option -fluid_degree = 2 is invalid"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("3 <= p <= 8 with -fluid_space div_conforming on the narrowing"), std::string::npos)
      << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, ZeroElementsAreRejected) {
  const RunResult r = cellfsi(with(with({scene("shear.yaml")}, kTiny), {"-fluid_elements", "0,4"}));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-fluid_elements"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, UnknownDomainIsRejected) {
  const RunResult r = cellfsi(with({scene("shear.yaml"), "-domain", "blob"}, kTiny));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-domain"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("blob"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("rectangle"), std::string::npos) << "the message lists the valid domains:\n"
                                                           << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, Rbc3dThickerThanItsDimplesIsRejected) {
  // The 3D RBC's two sheets are C0 = 0.81 um apart at the dimples: a thicker shell would fold through itself.
  const RunResult r = cellfsi({scene("rbc_shear_3d.yaml"), "-fluid_elements", "12,12,12", "-final_time",
                               "1e-3", "-solid_rbc_thickness", "1e-4"});
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-solid_rbc_thickness = 0.0001"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("C0 = 8.1e-05 [cm]"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, MissingSceneFileIsRejected) {
  const std::string missing = scene("no_such_scene.yaml");
  const RunResult r = cellfsi(with({missing}, kTiny));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find(missing), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, ZeroTimeStepIsRejected) {
  const RunResult r = cellfsi(with(with({scene("shear.yaml")}, kTiny), {"-dt", "0"}));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-dt"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, StepCountsThatDoNotFitAndMissingValuesAreRejected) {
  // Issue 10: each of these ran and said "completed" (-2147483648 steps; 0 steps; output_every wrapped; the
  // built-in dt with "dt: true" in options.yaml).
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"-final_time", "10", "-dt", "1e-12"}, "at most 1e9 steps"},
      {{"-dt", "1e300"}, "at least one step"},
      {{"-output_every", "10000000000"}, "an integer up to"},
      {{"-dt"}, "-dt has no value"},
      {{"-dt", "-final_time", "0.01"}, "-dt has no value"}};
  for (const auto& [opts, why] : cases) {
    const RunResult r = cellfsi(with(with({scene("shear.yaml")}, kTiny), opts));
    expect_one_clear_error(r);
    EXPECT_NE(r.output.find(why), std::string::npos) << r.output;
    EXPECT_TRUE(nothing_written());
  }
}

TEST_F(CellfsiApp, ValuesThatAreNumbersButNotInputAreRejected) {
  // Issue 24: each ran, or failed later with a reason that named no option: s_I = inf or 1e300 as
  // FACTOR_OUTMEMORY, denormal or huge material constants (G = 1e-310 "completed" as steady), an averaging
  // window from nan or -5 (silently the default), an origin whose coordinates lose the mesh ("det F = -nan"),
  // a final time between two steps (run on to the next with no word).
  const std::vector<std::string> tiny = with({scene("shear.yaml")}, kTiny);
  const std::vector<std::string> capsule = with({scene("capsule_shear.yaml")}, kCapsule);
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {with(capsule, {"-s_interface", "inf"}),
       "option -s_interface = inf is invalid; valid: auto, or a number 1 ... 1e+12 ("},
      {with(capsule, {"-s_interface", "1e300"}),
       "option -s_interface = 1e+300 is invalid; valid: auto, or a number 1 ... 1e+12"},
      {with(capsule, {"-s_interface", "1e10x"}),
       "option -s_interface = 1e10x is invalid; valid: auto, or a number"},
      {with(capsule, {"-s_interface", "1e10", "-s_interface_target", "1e-4"}),
       "option -s_interface_target = 0.0001 is invalid; valid: only with -s_interface auto (here "
       "-s_interface 1e10)"},
      {with(capsule, {"-s_interface", "1e10", "-s_interface_raise"}),
       "option -s_interface_raise = true is invalid; valid: only with -s_interface auto (here -s_interface "
       "1e10)"},
      {with(capsule, {"-s_interface_target", "0"}),
       "option -s_interface_target = 0 is invalid; valid: 1e-06 ... 0.1"},
      {with(capsule, {"-solid_membrane_shear_modulus", "1e-310"}),
       "option -solid_membrane_shear_modulus = 1e-310 is invalid; valid: 1e-06 ... 1e+08 [dyn/cm^2] (a "
       "material constant in CGS units; stiffer than any cell"},
      {with(capsule, {"-solid_membrane_shear_modulus", "1e11"}),
       "option -solid_membrane_shear_modulus = 1e+11 is invalid"},
      {with(capsule, {"-solid_membrane_shear_modulus", "1e300"}),
       "option -solid_membrane_shear_modulus = 1e+300 is invalid"},
      {with(capsule, {"-solid_membrane_density", "1e300"}),
       "option -solid_membrane_density = 1e+300 is invalid"},
      {with(capsule, {"-solid_membrane_thickness_degree", "5"}),
       "option -solid_membrane_thickness_degree = 5 is invalid; valid: 0, 2, 3 or 4"},
      {with(capsule, {"-solid_membrane_degree", "3", "-solid_membrane_thickness_degree", "2"}),
       "option -solid_membrane_thickness_degree = 2 is invalid; valid: 0 or from -solid_membrane_degree (3) "
       "to 4"},
      {{scene("compound_capsule_shear.yaml"), "-solid_nucleus_thickness_degree", "3"},
       "option -solid_nucleus_thickness_degree = 3 is invalid; valid: 0 for a bulky ellipse (membranes only: "
       "shape hollow_ellipse, rbc, hollow_ellipsoid or rbc_3d)"},
      {with(capsule, {"-solid_membrane_thin_shell", "true"}),
       "option -solid_membrane_thin_shell = true is invalid; valid: false for a 2D body (3D membranes only: "
       "shape hollow_ellipsoid or rbc_3d)"},
      {{scene("rbc_shear_3d.yaml"), "-solid_rbc_thin_shell", "true"},
       "option -solid_rbc_thin_shell = true is invalid; valid: false for shape rbc_3d on one patch (a thin "
       "shell "
       "needs a mid-surface without poles: shape rbc_3d with -solid_rbc_patches 6)"},
      {{scene("rbc_shear_3d.yaml"), "-solid_rbc_thin_shell", "true", "-solid_rbc_patches", "6",
        "-solid_rbc_thickness_degree", "3"},
       "option -solid_rbc_thickness_degree = 3 is invalid; valid: 0 with -solid_rbc_thin_shell (a thin shell "
       "has "
       "no degree through its thickness)"},
      {with(capsule, {"-solid_membrane_patches", "3"}),
       "option -solid_membrane_patches = 3 is invalid; valid: 1 or 6"},
      {with(capsule, {"-solid_membrane_patches", "6"}),
       "option -solid_membrane_patches = 6 is invalid; valid: 1 for shape hollow_ellipse (6: rbc_3d only)"},
      {{scene("rbc_shear_3d.yaml"), "-solid_rbc_patches", "6", "-solid_rbc_elements", "1,8,12"},
       "option -solid_rbc_elements = 1,8,12 is invalid; valid: 1,n,n with -solid_rbc_patches 6"},
      {with(capsule, {"-solid_membrane_element_ratio", "1.5"}),
       "option -solid_membrane_element_ratio = 1.5 is invalid; valid: 0 ... 1 (0: the space's rule)"},
      {with(capsule, {"-solid_membrane_element_ratio", "0.8", "-coupling_max_mesh_ratio", "0.5"}),
       "option -solid_membrane_element_ratio = 0.8 is invalid; valid: at most -coupling_max_mesh_ratio = 0.5 "
       "(paper Remark 3)"},
      {with(tiny, {"-fluid_viscosity", "1e-310"}),
       "option -fluid_viscosity = 1e-310 is invalid; valid: 1e-08 ... 1e+06 [g/(cm s)]"},
      {with(tiny, {"-fluid_density", "1e-310"}), "option -fluid_density = 1e-310 is invalid"},
      {with(tiny, {"-fluid_density", "1e300"}), "option -fluid_density = 1e+300 is invalid"},
      // Options renamed with the PC types of the coupled solve (issue 25): refused with the new name.
      {with(capsule, {"-coupling_solver", "band"}),
       "option -coupling_solver was renamed -coupling_pc_type in cellfsi 0.2 (docs/options.md): "
       "-coupling_solver band is -coupling_pc_type cellfsi_band"},
      {with(capsule, {"-coupling_band_margin", "3"}),
       "option -coupling_band_margin was renamed -coupling_region_margin"},
      {with(capsule, {"-coupling_bulk_stencil", "true", "-coupling_pc_type", "asm"}),
       "option -coupling_bulk_stencil does not apply: this coupled run solves with -coupling_pc_type asm"},
      {with(capsule, {"-coupling_bulk_stencil", "true", "-fluid_pressure_null_space", "false"}),
       "-coupling_bulk_stencil needs the constant pressure as the Jacobian's null space"},
      {with(capsule, {"-coupling_pc_fourier_threshold", "-1"}),
       "option -coupling_pc_fourier_threshold = -1 is invalid"},
      {with(capsule, {"-metrics_average_from", "nan"}),
       "option -metrics_average_from = nan is invalid; valid: 0 <="},
      {with(capsule, {"-metrics_average_from", "-5"}), "option -metrics_average_from = -5 is invalid"},
      {with(tiny, {"-domain_origin", "1e10,1e10"}),
       "option -domain_origin = 1e+10,1e+10 is invalid; valid: |x| <= 1e+06 x the domain's extent"},
      {with(tiny, {"-final_time", "0.005", "-dt", "0.004"}),
       "option -final_time = 0.005 is invalid; valid: a whole number of steps of -dt = 0.004 s, e.g. 0.004 "
       "or "
       "0.008 s"}};
  for (const auto& [args, message] : cases) {
    expect_one_clear_error(cellfsi(args, 20));
    EXPECT_NE(last_output_.find(message), std::string::npos) << last_output_;
    EXPECT_TRUE(nothing_written());
  }
}

TEST_F(CellfsiApp, MisspeltPetscTypesAreRejectedByName) {
  // Issue 10: a misspelt type gave a 40-line PETSc traceback and exit 2 (59 for a PC type).
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {with({scene("shear.yaml")}, with(kTiny, {"-fluid_ksp_type", "gmress"})),
       "option -fluid_ksp_type = gmress is invalid: Unable to find requested KSP type gmress"},
      {with(kDefaultCapsule, {"-coupling_pc_type", "asm", "-coupling_sub_pc_type", "ilux"}),
       "option -coupling_sub_pc_type = ilux is invalid: Unable to find requested PC type ilux"},
      {with(kDefaultCapsule, {"-coupling_pc_type", "cellfsi_fourer"}),
       "option -coupling_pc_type = cellfsi_fourer is invalid: Unable to find requested PC type cellfsi_fourer"},
  };
  for (const auto& [args, message] : cases) {
    expect_one_clear_error(cellfsi(args));
    EXPECT_NE(last_output_.find(message), std::string::npos) << last_output_;
    EXPECT_TRUE(nothing_written());
  }
}

TEST_F(CellfsiApp, MeshTooLargeForTheMachineIsRejectedWithAnEstimate) {
  // It allocated for minutes; now it stops at once with what the mesh would need.
  // 1e5 x 1e5 cubic: 3.5e4 GB for the Jacobian alone, more than any one machine has (no cells: once).
  expect_one_clear_error(cellfsi(with({scene("shear.yaml")}, {"-fluid_elements", "100000,100000"}), 20));
  EXPECT_NE(
      last_output_.find("option -fluid_elements = 100000,100000 is invalid; valid: fewer elements: a run "
                        "needs at least 3.53e+04 GB per node (the fluid Jacobian;"),
      std::string::npos)
      << last_output_;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, BodiesTooLargeForTheMachineAreRejectedWithAnEstimate) {
  // Issue 24: a membrane of 1 x 1e8 elements allocated for 25 s, then failed with std::bad_alloc; a throat of
  // 1e-5 cm gave the CTC's nucleus automatic elements of the throat's size (52 million at 384 x 128), which
  // were built and located point by point past 20 GB. Each is refused at once (10.6 kB per element, 2.6 kB
  // of it the basis tabulated at the quadrature points: 1060 GB and 560 GB, more than any one machine has).
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {with({scene("capsule_shear.yaml")}, with(kCapsule, {"-solid_membrane_elements", "1,100000000"})),
       "option -solid_membrane_elements = 1,100000000 is invalid; valid: fewer elements: the bodies need at "
       "least 1.06e+03 GB (body 'membrane': 1.06e+03 GB for 1 x 100000000 elements) and "},
      {{scene("ctc_narrowing.yaml"), "-channel_throat_height", "1e-5", "-solid_membrane_elements", "1,0",
        "-solid_nucleus_elements", "0,0"},
       "option -solid_nucleus_elements = 0,0 is invalid; valid: fewer elements: the bodies need at least "}};
  for (const auto& [args, message] : cases) {
    expect_one_clear_error(cellfsi(args, 12));
    EXPECT_NE(last_output_.find(message), std::string::npos) << last_output_;
    EXPECT_NE(last_output_.find(" GB are available"), std::string::npos) << last_output_;
    EXPECT_TRUE(nothing_written());
  }
}

TEST_F(CellfsiApp, NarrowThroatIsRefusedByTheMeshRatioBeforeItsPointsAreLocated) {
  // Issue 24: a throat of 5e-5 cm gives the nucleus automatic elements of the throat's size (133 thousand at
  // 96 x 32), every point of which was located (16 s) before the membrane's mesh ratio, which refuses the
  // case, was checked. The cheap checks of every body now come first: refused within the time limit.
  expect_one_clear_error(
      cellfsi({scene("ctc_narrowing.yaml"), "-channel_throat_height", "5e-5", "-fluid_elements", "96,32",
               "-solid_bodies", "nucleus,membrane", "-solid_nucleus_elements", "0,0"},
              12));
  EXPECT_NE(
      last_output_.find("option -solid_membrane_elements = 1,768 is invalid; valid: Lagrangian elements "
                        "no larger than 1 x the fluid's"),
      std::string::npos)
      << last_output_;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, SceneFileAfterOptionsOrTwiceIsRejected) {
  // Issue 10: a scene file after options ran the default scene instead; a second one was ignored.
  for (const auto& args :
       {with(kTiny, {scene("shear.yaml")}), with({scene("shear.yaml"), scene("poiseuille.yaml")}, kTiny)}) {
    const RunResult r = cellfsi(args);
    expect_one_clear_error(r);
    EXPECT_NE(r.output.find("as the first argument"), std::string::npos) << r.output;
    EXPECT_TRUE(nothing_written());
  }
}

TEST_F(CellfsiApp, MalformedSceneFilesAreRejectedWithFileAndLine) {
  // Issue 10: PETSc printed a 13-line traceback naming no file or line for a malformed file, and ran a file
  // with a duplicate key (the last won) or no keys at all (the defaults).
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"dim: 2\nfluid_elements: [8, 4\nfluid_degree: 2\n", "line 3"},
      {"dim: 2\nfluid:\n  density: 1\nfluid:\n  viscosity: 0.01\n", "line 4: key 'fluid' appears twice"},
      {"dim: 2\n\tfluid_degree: 2\n", "line 2"},
      {"- dim\n- 2\n", "not a list"},
      {"# nothing\n", "is empty"}};
  int k = 0;
  for (const auto& [text, why] : cases) {
    const fs::path file = root_ / ("scene" + std::to_string(k++) + ".yaml");
    std::ofstream(file) << text;
    const RunResult r = cellfsi(with({file.string()}, kTiny));
    expect_one_clear_error(r);
    EXPECT_NE(r.output.find(file.string()), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(why), std::string::npos) << r.output;
    EXPECT_TRUE(nothing_written());
  }
}

TEST_F(CellfsiApp, BadValueInSceneFileNamesFileAndLine) {
  // A value the option table refuses names the scene file's line that set it (nested keys included); the
  // command line's value, which wins, is named as such.
  const fs::path file = root_ / "bad_value.yaml";
  std::ofstream(file) << "dim: 2\nflow: shear\nfluid:\n  viscosity: 0.012\n  density: -2\n";
  RunResult r = cellfsi(with({file.string()}, kTiny));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("option -fluid_density = -2 is invalid; valid: 1e-06 ... 1000 [g/cm^3] (a material "
                          "constant in CGS units; far outside these bounds the solver's products of it leave "
                          "double precision) (scene file '" +
                          file.string() + "', line 5)"),
            std::string::npos)
      << r.output;
  r = cellfsi(with({file.string(), "-fluid_density", "-3"}, kTiny));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("option -fluid_density = -3 is invalid"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("line 5"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

// Bad input the app does not reject cleanly yet (see the integration-test report): a non-number for an
// integer option, more element counts than dimensions, a misspelt option of an inner solver.

TEST_F(CellfsiApp, OptionGivenTwiceOnTheCommandLineIsRejected) {
  // PETSc kept the last of "-dt 1e-3 -dt 2e-3" silently.
  std::vector<std::string> args = with({scene("shear.yaml")}, kTiny);
  args.erase(std::find(args.begin(), args.end(), "-dt"), std::find(args.begin(), args.end(), "-dt") + 2);
  args.insert(args.end(), {"-dt", "1e-3", "-dt", "2e-3"});
  const RunResult r = cellfsi(args);
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("option -dt is given twice on the command line (1e-3, then 2e-3)"),
            std::string::npos)
      << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, NonNumericValueIsRejected) {
  const RunResult r = cellfsi(with(with({scene("shear.yaml")}, kTiny), {"-fluid_degree", "abc"}));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("fluid_degree"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("abc"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, ThreeElementCountsIn2DAreRejected) {
  const RunResult r = cellfsi(with(with({scene("shear.yaml")}, kTiny), {"-fluid_elements", "8,4,4"}));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-fluid_elements"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, MisspeltInnerSolverOptionIsRejectedBeforeAnyWork) {
  const RunResult r = cellfsi(with({scene("shear.yaml"), "-fluid_sub_pc_typo", "lu"}, kTiny));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("fluid_sub_pc_typo"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

// ---------------------------------------------------------------------------------------------------------
// Bad input about the immersed bodies

TEST_F(CellfsiApp, CapsuleOutsideTheDomainIsRejected) {
  const RunResult r =
      cellfsi(with({scene("capsule_shear.yaml"), "-solid_membrane_center", "0.0012,0.00005"}, kCapsule));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("'membrane'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("outside"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, CentreOutsideAPeriodicDirectionIsRejected) {
  // Issue 10: x = 0.003 cm in a box 0.0024 long, periodic in x, was accepted (the locator wraps the points).
  const RunResult r =
      cellfsi(with({scene("capsule_shear.yaml"), "-solid_membrane_center", "0.003,0.0006"}, kCapsule));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-solid_membrane_center"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("periodic direction x"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, EmptyBodyListIsRejected) {
  // Issue 10: -solid_bodies "" ended in "unknown option -solid_membrane_angle", naming a symptom.
  const RunResult r = cellfsi(with({scene("capsule_shear.yaml"), "-solid_bodies", ""}, kCapsule));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-solid_bodies = (empty)"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, OverlappingBodiesAreRejected) {
  const RunResult r =
      cellfsi(with({scene("capsule_shear.yaml"), "-solid_bodies", "membrane,nucleus", "-solid_nucleus_shape",
                    "ellipse", "-solid_nucleus_semi_axes", "5e-5,5e-5", "-solid_nucleus_center",
                    "0.0012,0.0008", "-solid_nucleus_shear_modulus", "40"},
                   kCapsule));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("overlap"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, CompoundCapsuleIsAccepted) {
  const RunResult r = cellfsi(with(
      {scene("capsule_shear.yaml"), "-solid_bodies", "membrane,nucleus", "-solid_nucleus_shape", "ellipse",
       "-solid_nucleus_semi_axes", "5e-5,5e-5", "-solid_nucleus_shear_modulus", "40", "-final_time", "5e-4"},
      kCapsule));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  // The nucleus is a bulky body: it turns as a whole (omega_tu, clockwise with the shear), has no
  // tank-treading, and keeps its area over two steps (measured: r_A = -3.8e-5).
  EXPECT_LT(std::abs(json_number(js, "nucleus_r_A").value_or(1.0)), 1e-3) << js;
  EXPECT_GT(json_number(js, "nucleus_omega_tu").value_or(0.0), 0.0) << js;
  EXPECT_FALSE(json_number(js, "nucleus_omega_tt").has_value()) << js;
  EXPECT_TRUE(json_number(js, "membrane_omega_tt").has_value()) << js;
}

TEST_F(CellfsiApp, TooCoarseBodyMeshIsRejected) {
  const RunResult r =
      cellfsi(with({scene("capsule_shear.yaml")}, with(kCapsule, {"-solid_membrane_elements", "1,8"})));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-solid_membrane_elements"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Remark 3"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, TooCoarseFluidMeshForTheCellIsRejected) {
  const RunResult r =
      cellfsi(with({scene("capsule_shear.yaml")}, with(kCapsule, {"-fluid_elements", "16,8"})));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-fluid_elements"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, UnknownBodyKeyIsRejected) {
  const RunResult r =
      cellfsi(with({scene("capsule_shear.yaml"), "-solid_membrane_shear_modulos", "1"}, kCapsule));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("solid_membrane_shear_modulos"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, NegativeShearModulusIsRejected) {
  const RunResult r =
      cellfsi(with({scene("capsule_shear.yaml"), "-solid_membrane_shear_modulus", "-5"}, kCapsule));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-solid_membrane_shear_modulus = -5"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, BadMaterialLawsAndTheirConstantsAreRejected) {
  // Issue 28: the law's name, its constant's range, and a constant given to another law (it would do
  // nothing).
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"-solid_membrane_material", "hooke"},
       "-solid_membrane_material = hooke is invalid; valid: neo_hookean, mooney_rivlin, strain_hardening, "
       "skalak "
       "or strain_hardening_membrane"},
      {{"-solid_membrane_material", "skalak"},
       "-solid_membrane_material = skalak is invalid; valid: neo_hookean, mooney_rivlin or strain_hardening "
       "for a 2D body (skalak: 3D membranes only)"},
      {{"-solid_membrane_material", "strain_hardening_membrane"},
       "-solid_membrane_material = strain_hardening_membrane is invalid; valid: neo_hookean, mooney_rivlin "
       "or "
       "strain_hardening for a 2D body (strain_hardening_membrane: 3D membranes only)"},
      {{"-solid_membrane_area_dilation", "5"},
       "-solid_membrane_area_dilation = 5 is invalid; valid: only with -solid_membrane_material skalak or "
       "strain_hardening_membrane (the material is neo_hookean)"},
      {{"-solid_membrane_material", "mooney_rivlin", "-solid_membrane_mooney_rivlin_fraction", "1.5"},
       "-solid_membrane_mooney_rivlin_fraction = 1.5 is invalid; valid: 0 ... 1 (0: neo-Hookean)"},
      {{"-solid_membrane_material", "strain_hardening", "-solid_membrane_hardening_c3", "-0.1"},
       "-solid_membrane_hardening_c3 = -0.1 is invalid; valid: 0 ... 100"},
      {{"-solid_membrane_hardening_c3", "0.1"},
       "-solid_membrane_hardening_c3 = 0.1 is invalid; valid: only with -solid_membrane_material "
       "strain_hardening or strain_hardening_membrane (the material is neo_hookean)"},
      {{"-solid_membrane_material", "strain_hardening", "-solid_membrane_mooney_rivlin_fraction", "0.2"},
       "-solid_membrane_mooney_rivlin_fraction = 0.2 is invalid; valid: only with -solid_membrane_material "
       "mooney_rivlin (the material is strain_hardening)"}};
  expect_each_refused(with({scene("capsule_shear.yaml")}, kCapsule), cases);
}

TEST_F(CellfsiApp, BadInnerViscositiesAreRejected) {
  // Issue 27: a viscosity that is not one (<= 0, not a number, beyond any liquid), and one given to a bulky
  // body, which encloses no fluid.
  const std::string opt = "-solid_membrane_inner_viscosity";
  const std::string range = " is invalid; valid: 1e-08 ... 1e+06 [g/(cm s)]";
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{opt, "0"}, opt + " = 0" + range},
      {{opt, "-0.06"}, opt + " = -0.06" + range},
      {{opt, "1e300"}, opt + " = 1e+300" + range},
      {{opt, "thick"}, opt},
      {{"-solid_bodies", "membrane,nucleus", "-solid_nucleus_shape", "ellipse", "-solid_nucleus_semi_axes",
        "5e-5,5e-5", "-solid_nucleus_inner_viscosity", "0.06"},
       "-solid_nucleus_inner_viscosity = 0.06 is invalid; valid: only for a membrane (shape hollow_ellipse, "
       "rbc or hollow_ellipsoid): a bulky ellipse (e.g. a nucleus) is solid throughout and encloses no "
       "fluid"}};
  expect_each_refused(with({scene("capsule_shear.yaml")}, kCapsule), cases);
}

TEST_F(CellfsiApp, BadStretchingTestsAreRejected) {
  // Issue 28, item 4: a pull that is not one, the test's options without the pull, a direction that is none
  // or leaves the plane, a bulky body (no mid-surface ends), a contact patch holding no material or so large
  // that the two overlap (found when the body is built, still before any work), and the equilibrium options
  // without a stretched body.
  const std::string f = "-solid_membrane_stretch_force";
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{f, "-1e-5"}, f + " = -1e-05 is invalid; valid: >= 0 [dyn]"},
      {{"-solid_membrane_stretch_patch", "1e-4"},
       "-solid_membrane_stretch_patch = 0.0001 is invalid; valid: only with -solid_membrane_stretch_force"},
      {{"-solid_membrane_stretch_ramp", "1e-3"},
       "-solid_membrane_stretch_ramp = 0.001 is invalid; valid: only with -solid_membrane_stretch_force"},
      {{f, "1e-5", "-solid_membrane_stretch_ramp", "-1e-3"},
       "-solid_membrane_stretch_ramp = -0.001 is invalid; valid: >= 0 [s]"},
      {{f, "1e-5", "-solid_membrane_stretch_axis", "0,0,0"},
       "-solid_membrane_stretch_axis = 0,0,0 is invalid; valid: a nonzero direction"},
      {{f, "1e-5", "-solid_membrane_stretch_axis", "1,0,1"},
       "-solid_membrane_stretch_axis = 1,0,1 is invalid; valid: a direction in the plane (z = 0) in 2D"},
      {{"-solid_bodies", "membrane,nucleus", "-solid_nucleus_shape", "ellipse", "-solid_nucleus_semi_axes",
        "5e-5,5e-5", "-solid_nucleus_stretch_force", "1e-5"},
       "-solid_nucleus_stretch_force = 1e-05 is invalid; valid: only for a membrane"},
      {{f, "1e-5", "-solid_membrane_stretch_patch", "1e-9"},
       "-solid_membrane_stretch_patch = 1e-09 is invalid; valid: a contact diameter whose two patches hold "
       "material and do not overlap"},
      {{f, "1e-5", "-solid_membrane_stretch_patch", "1e-2"}, "overlap"},
      {{"-equilibrium_stop"},
       "-equilibrium_stop = true is invalid; valid: only with a stretched body (-solid_NAME_stretch_force)"},
      {{"-equilibrium_window", "1e-3"},
       "-equilibrium_window = 0.001 is invalid; valid: only with a stretched"}};
  expect_each_refused(with({scene("capsule_shear.yaml")}, kCapsule), cases);
}

TEST_F(CellfsiApp, MpmdBadInputStopsBothSidesWithOneMessage) {
  const std::vector<std::string> args =
      with({scene("capsule_shear.yaml"), "-solid_membrane_center", "0.0012,0.00005"}, kCapsule);
  std::vector<std::string> mpmd = {MPIEXEC_EXECUTABLE, "--oversubscribe", "-np", "1", CELLFSI_FLUID_EXE};
  mpmd.insert(mpmd.end(), args.begin(), args.end());
  mpmd.insert(mpmd.end(), {"-output_dir", out_.string(), ":", "-np", "1", CELLFSI_SOLID_EXE});
  mpmd.insert(mpmd.end(), args.begin(), args.end());
  const RunResult r = run_process(mpmd, 60);
  EXPECT_FALSE(r.timed_out) << r.output;
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, MpmdSidesWithDifferentBodyOptionsAreRefused) {
  // Issue 10: the solid side builds the bodies from its own options; a modulus given to one side only, or an
  // option misspelt on the solid side only, used to run to completion with results unlike options.yaml.
  const std::vector<std::string> args = with({scene("capsule_shear.yaml")}, kCapsule);
  for (const std::vector<std::string>& solid_only :
       {std::vector<std::string>{"-solid_membrane_shear_modulus", "100"},
        std::vector<std::string>{"-solid_membrane_shear_modulos", "100"}}) {
    std::vector<std::string> mpmd = {MPIEXEC_EXECUTABLE, "--oversubscribe", "-np", "1", CELLFSI_FLUID_EXE};
    mpmd.insert(mpmd.end(), args.begin(), args.end());
    mpmd.insert(mpmd.end(), {"-output_dir", out_.string(), ":", "-np", "1", CELLFSI_SOLID_EXE});
    mpmd.insert(mpmd.end(), args.begin(), args.end());
    mpmd.insert(mpmd.end(), solid_only.begin(), solid_only.end());
    const RunResult r = run_process(mpmd, 60);
    EXPECT_FALSE(r.timed_out) << r.output;
    EXPECT_NE(r.exit_code, 0) << r.output;
    EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
    EXPECT_NE(r.output.find("different options (fluid side -> solid side: " + solid_only[0].substr(1)),
              std::string::npos)
        << r.output;
    EXPECT_TRUE(nothing_written());
  }
}

TEST_F(CellfsiApp, SolidRanksGivenToTheSolidExecutableStopsBothSides) {
  // It hung: the solid executable stopped before the job was split, the fluid one waited for it.
  const std::vector<std::string> args = with({scene("capsule_shear.yaml")}, kCapsule);
  std::vector<std::string> mpmd = {MPIEXEC_EXECUTABLE, "--oversubscribe", "-np", "1", CELLFSI_FLUID_EXE};
  mpmd.insert(mpmd.end(), args.begin(), args.end());
  mpmd.insert(mpmd.end(), {"-output_dir", out_.string(), ":", "-np", "1", CELLFSI_SOLID_EXE});
  mpmd.insert(mpmd.end(), args.begin(), args.end());
  mpmd.insert(mpmd.end(), {"-solid_ranks", "1"});
  const RunResult r = run_process(mpmd, 60);
  EXPECT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error: option -solid_ranks is for cellfsi"), 1u) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, SolidExecutableAloneIsRejected) {
  const RunResult r = run_process({CELLFSI_SOLID_EXE, scene("capsule_shear.yaml")});
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("cellfsi-fluid"), std::string::npos) << r.output;
}

}  // namespace
