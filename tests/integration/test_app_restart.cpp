// Integration tests (cellfsi_app_fixture.hpp): checkpoints and restarts.
#include <nlohmann/json.hpp>

#include "cellfsi_app_fixture.hpp"

using namespace cellfsi_app_test;

namespace {

TEST_F(CellfsiApp, RestartContinuesTheRunAsIfItHadNotStopped) {
  // 8 steps in one run against 4 + 4 with a restart. The continued run agrees to 1e-6 relative, not bit for
  // bit: the band solver keeps a step's Newton matrix for the next while the s^h marking stays, and a restart
  // builds it afresh; both stop at the same coupling tolerance (measured: 1.2e-8 on theta).
  const std::vector<std::string> args = with(kDefaultCapsule, {"-output_every", "2"});
  ASSERT_EQ(cellfsi(with(args, {"-final_time", "0.016"})).exit_code, 0) << last_output_;
  const auto straight = last_row(out_ / "metrics.csv");
  const std::string straight_js = summary();
  const auto straight_pvd = pvd_files(out_ / "fluid.pvd");
  fs::remove_all(out_);
  ASSERT_EQ(cellfsi(with(args, {"-final_time", "0.008"})).exit_code, 0) << last_output_;
  EXPECT_TRUE(fs::is_regular_file(out_ / "checkpoint" / "state.json"))
      << "a completed run leaves a checkpoint";
  const RunResult r = cellfsi(with(args, {"-final_time", "0.016", "-restart"}));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("restarting from the checkpoint at t = 0.008 s (step 4)"), std::string::npos)
      << r.output;
  EXPECT_EQ(csv_steps(out_ / "metrics.csv"), one_to(8));
  // r_A (a difference of areas, here 2.7e-4) and the centroid are compared against a floor of 1e-2: 1e-8
  // absolute.
  EXPECT_TRUE(rows_agree(metrics_only(straight), metrics_only(last_row(out_ / "metrics.csv")), 1e-6, 1e-2));
  const std::string js = summary();
  EXPECT_EQ(json_number(js, "steps"), 8) << js;
  // wall_time_s is this invocation's; the step it resumed from says so (absent from a run that did not
  // resume).
  EXPECT_EQ(json_number(js, "resumed_from_step"), 4) << js;
  EXPECT_FALSE(json_number(straight_js, "resumed_from_step").has_value()) << straight_js;
  for (const char* key : {"membrane_theta_deg", "membrane_omega_tt", "membrane_omega_tu"})
    EXPECT_NEAR(json_number(js, key).value_or(0), json_number(straight_js, key).value_or(1),
                1e-6 * std::abs(json_number(straight_js, key).value_or(1)))
        << key;
  EXPECT_EQ(pvd_files(out_ / "fluid.pvd"), straight_pvd);
  EXPECT_EQ(pvd_files(out_ / "solid.pvd").size(), 5u);
}

TEST_F(CellfsiApp, RestartKeepsTheRaisedInterfaceScaling) {
  // -s_interface_raise raises s_I in the second step (the test
  // InterfaceScalingIsRaisedWhenTheAreaErrorPassesHalfTheTarget); the checkpoint after it keeps the
  // raised value, the next threshold and the count, so the continued run neither starts again from the
  // automatic value (it would raise it again at once) nor counts anew: 4 steps in one run against 2 + 2.
  const std::vector<std::string> args = with(
      {scene("capsule_shear.yaml")}, with(kCapsule, {"-s_interface_target", "1e-4", "-s_interface_raise"}));
  ASSERT_EQ(cellfsi(with(args, {"-final_time", "2e-3"})).exit_code, 0) << last_output_;
  const auto straight = last_row(out_ / "metrics.csv");
  const std::string straight_js = summary();
  fs::remove_all(out_);
  ASSERT_EQ(cellfsi(with(args, {"-final_time", "1e-3"})).exit_code, 0) << last_output_;
  const RunResult r = cellfsi(with(args, {"-final_time", "2e-3", "-restart"}));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("s_I raised"), std::string::npos) << r.output;
  const std::string js = summary();
  EXPECT_EQ(json_number(js, "s_interface_final"), json_number(straight_js, "s_interface_final")) << js;
  EXPECT_EQ(json_number(js, "s_interface_raises").value_or(0), 1) << js;
  EXPECT_TRUE(rows_agree(metrics_only(straight), metrics_only(last_row(out_ / "metrics.csv")), 1e-6, 1e-2));
}

TEST_F(CellfsiApp, RestartsWithAndWithoutOutputKeepTheSeries) {
  // A restart without series output (-output_every 0) must keep the series written before it for the next
  // restart (the checkpoint used to drop them, and the next restart deleted their files).
  const std::vector<std::string> base = {
      scene("shear.yaml"), "-fluid_elements", "8,4", "-fluid_degree", "2", "-dt", "5e-4"};
  ASSERT_EQ(cellfsi(with(base, {"-final_time", "2e-3", "-output_every", "2"})).exit_code, 0) << last_output_;
  ASSERT_EQ(cellfsi(with(base, {"-final_time", "3e-3", "-output_every", "0", "-restart"})).exit_code, 0)
      << last_output_;
  ASSERT_EQ(cellfsi(with(base, {"-final_time", "4e-3", "-output_every", "2", "-restart"})).exit_code, 0)
      << last_output_;
  const std::vector<std::string> files = pvd_files(out_ / "fluid.pvd");
  EXPECT_EQ(files, (std::vector<std::string>{"fluid_000000.vts", "fluid_000002.vts", "fluid_000004.vts",
                                             "fluid_000008.vts"}));
  for (const std::string& f : files) EXPECT_TRUE(fs::is_regular_file(out_ / f)) << f;
  EXPECT_EQ(csv_steps(out_ / "metrics.csv"), one_to(8));
}

TEST_F(CellfsiApp, CheckpointThatDoesNotFitTheRemoteBodiesIsBadInput) {
  // A body state of the wrong size, refused on the solid rank, reaches the fluid side as bad input (exit 1).
  const std::vector<std::string> args = with({scene("capsule_shear.yaml")}, kCapsule);
  ASSERT_EQ(mpi_cellfsi(2, with(args, {"-final_time", "1e-3", "-solid_ranks", "1"})).exit_code, 0)
      << last_output_;
  const fs::path state = out_ / "checkpoint" / "state.json";
  std::string js = read_text(state);
  const std::size_t at = js.find("\"bodies\":[[");
  ASSERT_NE(at, std::string::npos) << js.substr(0, 300);
  js.insert(at + 11, "1.0,");
  { std::ofstream(state) << js; }
  const RunResult r = mpi_cellfsi(2, with(args, {"-final_time", "2e-3", "-solid_ranks", "1", "-restart"}));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("option -restart is invalid here: body 'membrane' (solid side)"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("a state of 577 numbers does not fit its 576"), std::string::npos) << r.output;
}

TEST_F(CellfsiApp, KilledRunRestartsFromItsLastCheckpoint) {
  // kill -9 after step 7 or later; checkpoints every 3 steps. The restart drops the rows written after the
  // last checkpoint and finishes the run: every step once in metrics.csv.
  const std::vector<std::string> args =
      with({scene("shear.yaml")}, {"-fluid_elements", "16,8", "-fluid_degree", "2", "-dt", "5e-4",
                                   "-output_every", "0", "-checkpoint_every", "3"});
  bool sent = false;
  const fs::path csv_path = out_ / "metrics.csv";
  const RunResult killed = cellfsi(with(args, {"-final_time", "100"}), 60, [&](pid_t pid) {
    if (!sent && fs::exists(csv_path) && lines(read_text(csv_path)).size() >= 8) {
      kill(pid, SIGKILL);
      sent = true;
    }
  });
  ASSERT_TRUE(sent) << killed.output;
  ASSERT_EQ(killed.exit_code, 128 + SIGKILL) << killed.output;
  const int rows = static_cast<int>(read_csv(csv_path).rows.size());
  ASSERT_GE(rows, 7);
  // The same options (the final time may change): from the last checkpoint to 5 steps past the kill.
  const int n = rows + 5;
  char final_time[32];
  std::snprintf(final_time, sizeof final_time, "%.10g", n * 5e-4);
  const RunResult r = cellfsi(with(args, {"-final_time", final_time, "-restart"}));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(csv_steps(csv_path), one_to(n));
  EXPECT_EQ(json_string(summary(), "status"), "completed") << summary();
  EXPECT_LT(json_number(summary(), "shear_profile_rel_error").value_or(1), 1e-10) << summary();
}

TEST_F(CellfsiApp, SummaryKeepsTheFirstFoldAcrossARestart) {
  // summary.json reports what the output's samples found of J (the writer's history, tested alone in
  // SolidOutput.HistoryKeepsTheSmallestJAndTheFirstFoldAcrossARestart), and the checkpoint carries it: a fold
  // recorded in the checkpoint at t = 2e-3 s is still the first one in the continued run's summary. A
  // checkpoint written before the history was recorded restarts with the history of the new writes alone.
  const std::vector<std::string> args = with(kDefaultCapsule, {"-output_every", "1"});
  ASSERT_EQ(cellfsi(with(args, {"-final_time", "4e-3"})).exit_code, 0) << last_output_;
  const std::string straight = summary();
  const double least = json_number(straight, "membrane_output_min_J").value_or(-1);
  EXPECT_GT(least, 0.5) << straight;
  EXPECT_LT(least, 1.0 + 1e-9) << straight;
  EXPECT_NE(straight.find("\"membrane_fold_time\": null"), std::string::npos) << straight;
  const fs::path state = out_ / "checkpoint" / "state.json";
  nlohmann::json js = nlohmann::json::parse(read_text(state));
  ASSERT_EQ(js.at("solid_J").size(), 1u) << js.at("solid_J");
  const nlohmann::json fold = {{"J", -0.5}, {"x", {1e-3, 2e-3, 0.0}}, {"time", 2e-3}};
  js["solid_J"][0] = {{"least", fold}, {"first_fold", fold}};
  std::ofstream(state) << js.dump() << "\n";
  RunResult r = cellfsi(with(args, {"-final_time", "6e-3", "-restart"}));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::string after = summary();
  EXPECT_EQ(json_number(after, "membrane_fold_time"), 2e-3) << after;
  EXPECT_EQ(json_number(after, "membrane_fold_J"), -0.5) << after;
  EXPECT_EQ(json_number(after, "membrane_output_min_J"), -0.5) << after;
  EXPECT_EQ(json_number(after, "membrane_output_min_J_time"), 2e-3) << after;
  // The checkpoint of an earlier version, without the history.
  js = nlohmann::json::parse(read_text(state));
  js.erase("solid_J");
  std::ofstream(state) << js.dump() << "\n";
  r = cellfsi(with(args, {"-final_time", "8e-3", "-restart"}));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  after = summary();
  EXPECT_NE(after.find("\"membrane_fold_time\": null"), std::string::npos) << after;
  EXPECT_EQ(json_number(after, "membrane_output_min_J_time"), 8e-3) << after;
}

TEST_F(CellfsiApp, RestartWithOtherOptionsOrWithoutACheckpointIsRefused) {
  const std::vector<std::string> args = with({scene("shear.yaml")}, kTiny);
  expect_one_clear_error(cellfsi(with(args, {"-restart"})));
  EXPECT_NE(last_output_.find("holds no checkpoint"), std::string::npos) << last_output_;
  ASSERT_EQ(cellfsi(args).exit_code, 0) << last_output_;
  const std::string csv = read_text(out_ / "metrics.csv");
  expect_one_clear_error(cellfsi(with(args, {"-final_time", "2e-3", "-dt", "2.5e-4", "-restart"})));
  EXPECT_NE(last_output_.find("was written with other options (-dt: checkpoint 5e-4, this run 2.5e-4)"),
            std::string::npos)
      << last_output_;
  expect_one_clear_error(cellfsi(with(args, {"-restart"})));
  EXPECT_NE(last_output_.find("option -final_time = 0.001 is invalid with -restart"), std::string::npos)
      << last_output_;
  EXPECT_EQ(read_text(out_ / "metrics.csv"), csv) << "a refused restart leaves the run's files alone";
  // A checkpoint without the metrics.csv it continues (copied alone to another folder) is refused by name.
  std::filesystem::rename(out_ / "metrics.csv", out_ / "metrics.kept");
  expect_one_clear_error(cellfsi(with(args, {"-final_time", "2e-3", "-restart"})));
  EXPECT_NE(last_output_.find("has a checkpoint but no metrics.csv"), std::string::npos) << last_output_;
  EXPECT_TRUE(std::filesystem::is_directory(out_ / "checkpoint"));
  EXPECT_FALSE(std::filesystem::exists(out_ / "metrics.csv"));
}

TEST_F(CellfsiApp, RestartFromTheRunsOwnOptionsFileContinuesIt) {
  // options.yaml says "run it again with: cellfsi options.yaml"; it names the scene, which the scene file
  // left to its stem. A restart from it is the same run; one under another scene name is not.
  ASSERT_EQ(cellfsi(with({scene("shear.yaml")}, kTiny)).exit_code, 0) << last_output_;
  const fs::path given = out_.parent_path() / "given_options.yaml";
  fs::copy_file(out_ / "options.yaml", given, fs::copy_options::overwrite_existing);
  expect_one_clear_error(cellfsi({given.string(), "-final_time", "2e-3", "-scene", "other", "-restart"}));
  EXPECT_NE(last_output_.find("(-scene: checkpoint shear, this run other)"), std::string::npos)
      << last_output_;
  const RunResult r = cellfsi({given.string(), "-final_time", "2e-3", "-restart"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("restarting from the checkpoint at t = 0.001 s (step 2)"), std::string::npos)
      << r.output;
  EXPECT_EQ(csv_steps(out_ / "metrics.csv"), one_to(4));
  fs::remove(given);
}

TEST_F(CellfsiApp, SplitJobRestartsItsRemoteBodies) {
  // The bodies on a solid rank (-solid_ranks 1): their state goes into the checkpoint and back through the
  // exchange. Against the one-process run of the same 4 steps.
  const std::vector<std::string> args = with({scene("capsule_shear.yaml")}, kCapsule);
  ASSERT_EQ(cellfsi(with(args, {"-final_time", "2e-3"})).exit_code, 0) << last_output_;
  const auto straight = last_row(out_ / "metrics.csv");
  fs::remove_all(out_);
  ASSERT_EQ(mpi_cellfsi(2, with(args, {"-final_time", "1e-3", "-solid_ranks", "1"})).exit_code, 0)
      << last_output_;
  ASSERT_EQ(mpi_cellfsi(2, with(args, {"-final_time", "2e-3", "-solid_ranks", "1", "-restart"})).exit_code, 0)
      << last_output_;
  EXPECT_EQ(csv_steps(out_ / "metrics.csv"), one_to(4));
  EXPECT_TRUE(rows_agree(metrics_only(straight), metrics_only(last_row(out_ / "metrics.csv")), 1e-6, 1e-2));
}

TEST_F(CellfsiApp, RefusedRestartCreatesNothing) {
  // Issue 24: a -restart without a checkpoint made the folder and left a lock file in it.
  const std::vector<std::string> args = with({scene("shear.yaml"), "-restart"}, kTiny);
  expect_one_clear_error(cellfsi(args));
  EXPECT_NE(last_output_.find("holds no checkpoint"), std::string::npos) << last_output_;
  EXPECT_FALSE(fs::exists(out_)) << "a refused restart made the folder";
  fs::create_directory(out_);
  expect_one_clear_error(cellfsi(args));
  EXPECT_TRUE(nothing_written()) << "a refused restart left a lock file";
}

TEST_F(CellfsiApp, RestartWithRowsMissingFromMetricsIsRefused) {
  // Issue 24: a restart carried on after metrics.csv had lost rows before the checkpoint, leaving a gap.
  const std::vector<std::string> args = with({scene("shear.yaml")}, with(kTiny, {"-final_time", "2e-3"}));
  ASSERT_EQ(cellfsi(args).exit_code, 0) << last_output_;  // 4 steps, the checkpoint after step 4
  const fs::path csv = out_ / "metrics.csv";
  const std::vector<std::string> rows = lines(read_text(csv));
  ASSERT_EQ(rows.size(), 5u);
  const std::vector<std::pair<std::vector<std::size_t>, std::string>> cases = {
      {{2},
       "metrics.csv in '" + out_.string() + "' lacks row 2 (rows 1..4 precede the checkpoint); restore it"},
      {{3, 4}, "lacks rows 3..4 (rows 1..4 precede the checkpoint)"}};
  for (const auto& [lost, why] : cases) {
    std::string damaged;
    for (std::size_t i = 0; i < rows.size(); ++i)
      if (std::find(lost.begin(), lost.end(), i) == lost.end()) damaged += rows[i] + "\n";
    { std::ofstream(csv) << damaged; }
    expect_one_clear_error(cellfsi(with(args, {"-final_time", "3e-3", "-restart"})));
    EXPECT_NE(last_output_.find(why), std::string::npos) << last_output_;
    EXPECT_EQ(read_text(csv), damaged) << "a refused restart leaves metrics.csv alone";
  }
}

TEST_F(CellfsiApp, RestartFromAFluidStateWithNaNsIsRefused) {
  // Issue 24: the fluid state was loaded unchecked; the run went on from NaNs.
  const std::vector<std::string> args = with({scene("shear.yaml")}, kTiny);
  ASSERT_EQ(cellfsi(args).exit_code, 0) << last_output_;
  {
    // PETSc binary: class id and length (two 4-byte integers), then big-endian doubles; the sixth is a NaN.
    std::fstream f(out_ / "checkpoint" / "fluid.petsc", std::ios::in | std::ios::out | std::ios::binary);
    const unsigned char nan[8] = {0x7f, 0xf8, 0, 0, 0, 0, 0, 0};
    f.seekp(8 + 5 * 8);
    f.write(reinterpret_cast<const char*>(nan), 8);
    ASSERT_TRUE(f.good());
  }
  expect_one_clear_error(cellfsi(with(args, {"-final_time", "2e-3", "-restart"})));
  EXPECT_NE(last_output_.find("fluid.petsc' holds NaN or infinite values"), std::string::npos)
      << last_output_;
}

TEST_F(CellfsiApp, RestartOnAnotherMeshNamesTheOption) {
  // Issue 24: it said the checkpoint "does not fit this fluid mesh (or is damaged)", naming no option.
  const std::vector<std::string> args = with({scene("shear.yaml")}, kTiny);
  ASSERT_EQ(cellfsi(args).exit_code, 0) << last_output_;
  expect_one_clear_error(cellfsi(with(args, {"-final_time", "2e-3", "-fluid_elements", "16,8", "-restart"})));
  EXPECT_NE(last_output_.find("(-fluid_elements: checkpoint 8,4, this run 16,8)"), std::string::npos)
      << last_output_;
}

// Channel scenes (issue 12): RBC suspensions and their rheology, an off-centre capsule's migration.

}  // namespace

namespace {

/// The scene records of a checkpoint (state.json's "scene_metrics", named JSON fields) in the flat list of
/// numbers that checkpoints of earlier versions hold.
nlohmann::json flat_scene_metrics(const nlohmann::json& m) {
  std::vector<double> flat{m.at("profile_from"), m.at("profile_count")};
  const nlohmann::json& p = m.at("profile_sum");
  flat.push_back(static_cast<double>(p.at("points").size()));
  for (std::size_t i = 0; i < p.at("points").size(); ++i)
    for (const char* key : {"points", "velocity"})
      for (int c = 0; c < 3; ++c) flat.push_back(p.at(key).at(i).at(c));
  flat.insert(flat.end(), {p.at("flow_rate"), p.at("area"), static_cast<double>(m.at("suspension").size())});
  for (const auto& r : m.at("suspension")) {
    flat.insert(flat.end(), {r.at("time"), r.at("mean_velocity"), r.at("cell_area"), r.at("gap_low"),
                             r.at("gap_high"), static_cast<double>(r.at("cell_x").size())});
    for (const auto& x : r.at("cell_x")) flat.push_back(x);
  }
  flat.push_back(static_cast<double>(m.at("flow_rates").size()));
  for (const auto& tq : m.at("flow_rates")) flat.insert(flat.end(), {tq.at(0), tq.at(1)});
  return flat;
}

TEST_F(CellfsiApp, CheckpointOfAnEarlierVersionRestartsToTheSameAverages) {
  // The scene's records are named JSON fields now (issue 25); a checkpoint written before, with the same
  // records as one flat list of numbers, restarts to the same averaged profile and flow metrics as a run
  // that did not stop.
  const std::vector<std::string> args =
      with(with({scene("poiseuille.yaml")}, kTiny), {"-metrics_average_from", "0", "-checkpoint_every", "0"});
  ASSERT_EQ(cellfsi(with(args, {"-final_time", "4e-3"})).exit_code, 0) << last_output_;
  const std::string straight_mean = read_text(out_ / "profile_mean.csv");
  const auto straight = last_row(out_ / "metrics.csv");
  fs::remove_all(out_);
  ASSERT_EQ(cellfsi(with(args, {"-final_time", "2e-3"})).exit_code, 0) << last_output_;
  const fs::path state = out_ / "checkpoint" / "state.json";
  nlohmann::json js = nlohmann::json::parse(read_text(state));
  ASSERT_TRUE(js.at("scene_metrics").is_object()) << js.at("scene_metrics");
  ASSERT_FALSE(js.at("scene_metrics").at("flow_rates").empty());
  js["scene_metrics"] = flat_scene_metrics(js.at("scene_metrics"));
  std::ofstream(state) << js.dump() << "\n";
  const RunResult r = cellfsi(with(args, {"-final_time", "4e-3", "-restart"}));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(rows_agree(metrics_only(straight), metrics_only(last_row(out_ / "metrics.csv")), 1e-9, 1e-9));
  const std::vector<std::string> a = lines(straight_mean), b = lines(read_text(out_ / "profile_mean.csv"));
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 1; i < a.size(); ++i) {
    const std::vector<std::string> x = split(a[i], ','), y = split(b[i], ',');
    for (std::size_t c = 0; c < x.size(); ++c)
      EXPECT_NEAR(std::stod(x[c]), std::stod(y[c]), 1e-9 * std::max(1.0, std::abs(std::stod(x[c]))))
          << "profile_mean.csv row " << i;
  }
}

}  // namespace
