// Integration tests (cellfsi_app_fixture.hpp): two MPI ranks, -help and the default scene.
#include "cellfsi_app_fixture.hpp"

using namespace cellfsi_app_test;

namespace {

// ---------------------------------------------------------------------------------------------------------
// 5. Two MPI ranks

TEST_F(CellfsiApp, TwoRanksKeepTheExactShearProfile) {
  // -output_every 0: the fluid series output is covered by TwoRanksWriteTheFluidSeries.
  const RunResult r = mpi_cellfsi(2, {scene("shear.yaml"), "-fluid_elements", "16,8", "-fluid_degree", "2",
                                      "-final_time", "1e-3", "-output_every", "0"});
  ASSERT_FALSE(r.timed_out) << "mpiexec run hung:\n" << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: completed"), 1u) << "rank 0 prints, once:\n" << r.output;
  const std::string js = summary();
  EXPECT_TRUE(is_flat_json_object(js));
  EXPECT_EQ(json_number(js, "ranks"), 2) << js;
  EXPECT_EQ(json_number(js, "steps"), 2) << js;
  EXPECT_EQ(json_string(js, "status"), "completed") << js;
  // The scene starts from its exact steady state, which the discretisation represents exactly (a linear
  // profile): measured 1.7e-16, round-off.
  ASSERT_TRUE(json_number(js, "shear_profile_rel_error").has_value()) << js;
  EXPECT_LT(*json_number(js, "shear_profile_rel_error"), 1e-10) << js;
  EXPECT_EQ(read_csv(out_ / "metrics.csv").rows.size(), 2u) << "rank 0 alone writes the rows";
}

TEST_F(CellfsiApp, TwoRanksWriteTheFluidSeries) {
  // The initial state and every step, each rank writing the piece of the grid on its own elements and rank 0
  // the .pvts index; read back through VTK, the pieces make the one-rank run's grid, point for point.
  const RunResult r = mpi_cellfsi(2,
                                  {scene("shear.yaml"), "-fluid_elements", "16,8", "-fluid_degree", "2",
                                   "-final_time", "1e-3", "-output_every", "1"},
                                  30);
  ASSERT_FALSE(r.timed_out) << "mpiexec run hung (killed after 30 s):\n" << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(json_number(summary(), "ranks"), 2) << summary();
  const std::vector<std::string> files = pvd_files(out_ / "fluid.pvd");
  EXPECT_EQ(files, (std::vector<std::string>{"fluid_000000.pvts", "fluid_000001.pvts", "fluid_000002.pvts"}));
  for (const std::string& f : files) EXPECT_TRUE(fs::is_regular_file(out_ / f)) << f;
  for (const char* piece : {"fluid_000002_p0000.vts", "fluid_000002_p0001.vts"})
    EXPECT_TRUE(fs::is_regular_file(out_ / piece)) << piece;
  const fs::path one_dir = root_ / "one_rank";
  const RunResult one =
      run_process({CELLFSI_EXE, scene("shear.yaml"), "-fluid_elements", "16,8", "-fluid_degree", "2",
                   "-final_time", "1e-3", "-output_every", "1", "-output_dir", one_dir.string()});
  ASSERT_EQ(one.exit_code, 0) << one.output;
  vtkNew<vtkXMLPStructuredGridReader> two_reader;
  two_reader->SetFileName((out_ / "fluid_000002.pvts").c_str());
  two_reader->Update();
  vtkNew<vtkXMLStructuredGridReader> one_reader;
  one_reader->SetFileName((one_dir / "fluid_000002.vts").c_str());
  one_reader->Update();
  vtkStructuredGrid* two = two_reader->GetOutput();
  vtkStructuredGrid* ref = one_reader->GetOutput();
  int d2[3], d1[3];
  two->GetDimensions(d2);
  ref->GetDimensions(d1);
  EXPECT_EQ(std::vector<int>(d2, d2 + 3), (std::vector<int>{33, 17, 1}));
  EXPECT_EQ(std::vector<int>(d2, d2 + 3), std::vector<int>(d1, d1 + 3));
  ASSERT_EQ(two->GetNumberOfPoints(), ref->GetNumberOfPoints());
  // Each point from the same element and parameter on either run: equal to round-off (the wall speed is
  // 0.042 cm/s, the shear rate 70 1/s).
  double worst_x = 0, worst_v = 0, worst_w = 0;
  for (vtkIdType i = 0; i < ref->GetNumberOfPoints(); ++i) {
    double a[3], b[3];
    two->GetPoint(i, a);
    ref->GetPoint(i, b);
    for (int c = 0; c < 3; ++c) worst_x = std::max(worst_x, std::abs(a[c] - b[c]));
    for (int c = 0; c < 3; ++c)
      worst_v = std::max(worst_v, std::abs(two->GetPointData()->GetArray("velocity")->GetComponent(i, c) -
                                           ref->GetPointData()->GetArray("velocity")->GetComponent(i, c)));
    worst_w = std::max(worst_w, std::abs(two->GetPointData()->GetArray("vorticity")->GetComponent(i, 0) -
                                         ref->GetPointData()->GetArray("vorticity")->GetComponent(i, 0)));
  }
  EXPECT_LT(worst_x, 1e-18);
  EXPECT_LT(worst_v, 1e-15);
  EXPECT_LT(worst_w, 1e-10);
  for (const char* array : {"pressure", "s_h"})
    EXPECT_NE(two->GetPointData()->GetArray(array), nullptr) << array;
  // The velocity's divergence (the incompressibility error): zero to round-off in the undisturbed shear flow
  // (70 1/s), which the quadratic space holds exactly.
  vtkDataArray* div = two->GetPointData()->GetArray("divergence");
  ASSERT_NE(div, nullptr);
  double worst_div = 0;
  for (vtkIdType i = 0; i < div->GetNumberOfTuples(); ++i)
    worst_div = std::max(worst_div, std::abs(div->GetComponent(i, 0)));
  EXPECT_LT(worst_div, 1e-9 * 70);
}

// ---------------------------------------------------------------------------------------------------------
// 6. -help, and the default scene

TEST_F(CellfsiApp, HelpListsSceneOptions) {
  const RunResult r = cellfsi({scene("shear.yaml"), "-help"});
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 0) << r.output;
  for (const char* opt : {"-fluid_elements", "-fluid_degree", "-shear_rate", "-final_time", "-dt",
                          "-output_dir", "-output_every", "-domain", "-flow"})
    EXPECT_NE(r.output.find(std::string("  ") + opt + " <"), std::string::npos) << "-help lacks " << opt;
  // Every table, each option with its help text and valid choices, after the program's description.
  EXPECT_EQ(r.output.find("cellfsi: cell-resolved microscale blood flow"), 0u) << r.output.substr(0, 300);
  EXPECT_NE(r.output.find("Usage: cellfsi [SCENE.yaml]"), std::string::npos) << r.output;
  for (const char* table : {"cellfsi scene (docs/design.md §4; CGS units):",
                            "Fluid (VMS Navier-Stokes; CGS units):", "cellfsi immersed bodies and coupling:"})
    EXPECT_NE(r.output.find(table), std::string::npos) << "-help lacks the table " << table;
  EXPECT_NE(r.output.find("Eulerian domain [valid: rectangle, box or narrowing]"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Time step [s] [valid: > 0 [s]]"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("  -fluid_density <"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("  -coupling_acceleration <"), std::string::npos) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error"), 0u) << r.output;
  EXPECT_TRUE(nothing_written()) << "-help runs nothing";
}

TEST_F(CellfsiApp, DefaultSceneRunsWithoutSceneFile) {
  // The default scene is the capsule in shear; two coarse steps of its dt (2e-3 s).
  const RunResult r = cellfsi(with(kCapsule, {"-final_time", "4e-3"}));
  ASSERT_FALSE(r.timed_out) << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  EXPECT_EQ(json_string(js, "scene"), "capsule_shear_quick") << js;
  EXPECT_EQ(json_number(js, "steps"), 2) << js;
  EXPECT_TRUE(json_number(js, "membrane_r_A").has_value()) << js;
}

}  // namespace
