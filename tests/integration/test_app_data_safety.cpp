// Data safety (issue 24): a foreign output folder, a full disk or a file-size limit, and options.yaml must
// never cost a user their files or results. Each test failed on the code before the fix.
//
// A full disk is imitated with a file-size limit (RLIMIT_FSIZE with SIGXFSZ ignored: a write past the limit
// fails with EFBIG, "File too large", where a full disk fails with ENOSPC); the limits are set from the sizes
// a probe run of the same case writes, so the tests do not depend on the files' exact lengths.
#include <map>
#include <set>

#include "cellfsi_app_fixture.hpp"

namespace cellfsi_app_test {
namespace {

/// The poiseuille scene kept tiny (kTiny: 8 x 4 quadratic elements, dt 5e-4), with no checkpoint before the
/// end.
std::vector<std::string> tiny_poiseuille(const std::string& final_time) {
  return with(with({scene("poiseuille.yaml")}, kTiny), {"-final_time", final_time, "-checkpoint_every", "0"});
}

/// Every file below `dir` with its contents.
std::map<std::string, std::string> tree(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    out[fs::relative(e.path(), dir).string()] = e.is_regular_file() ? read_text(e.path()) : "(folder)";
  return out;
}

::testing::AssertionResult no_temporary_files(const fs::path& dir) {
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.path().extension() == ".tmp" || e.path().filename() == "checkpoint.new")
      return ::testing::AssertionFailure() << "left behind: " << e.path();
  return ::testing::AssertionSuccess();
}

/// metrics.csv ends with a whole row: every row has the header's columns and the file ends in a newline.
::testing::AssertionResult whole_rows(const fs::path& csv_path) {
  const std::string text = read_text(csv_path);
  if (text.empty() || text.back() != '\n') return ::testing::AssertionFailure() << "no final newline:\n" << text;
  const Csv csv = read_csv(csv_path);
  for (size_t i = 0; i < csv.rows.size(); ++i)
    if (csv.rows[i].size() != csv.header.size())
      return ::testing::AssertionFailure() << "row " << i + 1 << " is cut:\n" << text;
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------------------------
// An output folder cellfsi owns

TEST_F(CellfsiApp, ForeignFolderIsRefusedAndLeftUntouched) {
  // Before: -output_dir on a user's folder deleted or replaced its metrics.csv, summary.json, options.yaml,
  // *.pvd and *.vts, and replaced its whole checkpoint/ folder, with no word.
  fs::create_directories(out_ / "checkpoint");
  std::ofstream(out_ / "metrics.csv") << "the user's own table\n";
  std::ofstream(out_ / "summary.json") << "{\"mine\": 1}\n";
  std::ofstream(out_ / "fluid_000000.vts") << "not cellfsi's\n";
  std::ofstream(out_ / "checkpoint" / "notes.txt") << "keep me\n";
  const auto before = tree(out_);
  const RunResult r = cellfsi(tiny_poiseuille("1e-3"));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("option -output_dir"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("not made by cellfsi"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("-output_dir_adopt"), std::string::npos) << r.output;
  EXPECT_EQ(tree(out_), before) << "nothing in a refused folder may change (not even a lock file)";
}

TEST_F(CellfsiApp, AdoptedFolderKeepsTheUsersFilesAndRefusesClashingNames) {
  fs::create_directories(out_ / "data");
  std::ofstream(out_ / "notes.txt") << "keep me\n";
  std::ofstream(out_ / "data" / "x.csv") << "1,2\n";
  const RunResult r = cellfsi(with(tiny_poiseuille("1e-3"), {"-output_dir_adopt"}));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(read_text(out_ / "notes.txt"), "keep me\n");
  EXPECT_EQ(read_text(out_ / "data" / "x.csv"), "1,2\n");
  EXPECT_EQ(json_string(summary(), "status"), "completed");
  // Now cellfsi's: a second run needs no opt-in, replaces its own results and still keeps the user's files.
  const RunResult again = cellfsi(tiny_poiseuille("5e-4"));
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_EQ(json_number(summary(), "steps"), 1);
  EXPECT_EQ(read_text(out_ / "notes.txt"), "keep me\n");

  // A foreign folder holding a file of a name cellfsi writes is refused even with the opt-in.
  const fs::path other = root_ / "other";
  fs::create_directories(other);
  std::ofstream(other / "metrics.csv") << "the user's own table\n";
  const auto before = tree(other);
  std::vector<std::string> args = with(tiny_poiseuille("1e-3"), {"-output_dir_adopt"});
  args.insert(args.begin(), CELLFSI_EXE);
  for (const std::string& a : {std::string("-output_dir"), other.string()}) args.push_back(a);
  const RunResult refused = run_process(args);
  expect_one_clear_error(refused);
  EXPECT_NE(refused.output.find("metrics.csv"), std::string::npos) << refused.output;
  EXPECT_EQ(tree(other), before);
}

TEST_F(CellfsiApp, EmptyFolderIsTaken) {
  fs::create_directories(out_);
  const RunResult r = cellfsi(tiny_poiseuille("1e-3"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out_ / ".cellfsi-output")) << "the folder is marked as cellfsi's";
}

// ---------------------------------------------------------------------------------------------------------
// Every write checked to the end

TEST_F(CellfsiApp, NoRoomAtTheStartStopsBeforeTheFirstStep) {
  // Before: with the disk full from the start, the run computed every step, kept nothing, and failed only
  // at its end.
  file_size_limit_ = 0;
  const RunResult r = cellfsi(tiny_poiseuille("2e-3"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("File too large"), std::string::npos) << "the system's reason:\n" << r.output;
  EXPECT_NE(r.output.find("cannot write '" + out_.string()), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("step 1/"), std::string::npos) << "no step may run:\n" << r.output;
}

TEST_F(CellfsiApp, MetricsWriteFailureStopsTheRunWithWholeRows) {
  // Before: metrics.csv's write errors were never checked; rows were dropped without a word.
  const fs::path probe_dir = out_;
  ASSERT_EQ(cellfsi(tiny_poiseuille("2e-3")).exit_code, 0) << last_output_;
  const std::string csv = read_text(probe_dir / "metrics.csv");
  const size_t header = csv.find('\n') + 1, row = (csv.size() - header) / 4;
  const size_t limit = std::max(read_text(probe_dir / "options.yaml").size(), summary().size()) + 600;
  const size_t rows_that_fit = (limit - header) / row;
  fs::remove_all(out_);

  file_size_limit_ = limit;
  const RunResult r = cellfsi(tiny_poiseuille(std::to_string((rows_that_fit + 20) * 5e-4)));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("cannot write '" + (out_ / "metrics.csv").string() + "': File too large in step"),
            std::string::npos)
      << r.output;
  EXPECT_TRUE(whole_rows(out_ / "metrics.csv"));
  const std::vector<int> steps = csv_steps(out_ / "metrics.csv");
  EXPECT_EQ(steps, one_to(static_cast<int>(steps.size())));
  EXPECT_GE(steps.size() + 2, rows_that_fit);
  EXPECT_LE(steps.size(), rows_that_fit + 1);
  const std::string js = summary();
  EXPECT_TRUE(is_flat_json_object(js));
  EXPECT_EQ(json_string(js, "status").value_or("").rfind("failed: cannot write", 0), 0u) << js;
  EXPECT_TRUE(no_temporary_files(out_));
}

TEST_F(CellfsiApp, WriteFailureOnRankZeroStopsTwoRanks) {
  // Rank 0 writes metrics.csv; the other rank went on into the next step's collective calls and the run hung
  // (review of this change). Every rank now agrees on the write's outcome.
  file_size_limit_ = 1200;
  const RunResult r = mpi_cellfsi(2, tiny_poiseuille("2e-2"), 60);
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("cannot write '" + (out_ / "metrics.csv").string() + "': File too large in step"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error"), 1u) << "the ranks agree on the failure: one message\n" << r.output;
  EXPECT_TRUE(whole_rows(out_ / "metrics.csv"));
  EXPECT_EQ(json_string(summary(), "status").value_or("").rfind("failed: cannot write", 0), 0u) << summary();
}

TEST_F(CellfsiApp, SeriesWriteFailureNamesTheFile) {
  // Before: a VTK write that failed at close went unseen or said only "cannot write VTK file".
  ASSERT_EQ(cellfsi(with(tiny_poiseuille("1e-3"), {"-output_every", "1"})).exit_code, 0) << last_output_;
  const size_t vts = fs::file_size(out_ / "fluid_000000.vts"), small = summary().size() + 600;
  ASSERT_LT(small, vts) << "the case must have a series file larger than its summary";
  fs::remove_all(out_);
  file_size_limit_ = small;
  const RunResult r = cellfsi(with(tiny_poiseuille("1e-3"), {"-output_every", "1"}));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("cannot write '" + (out_ / "fluid_000000.vts").string() + "': File too large"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out_ / "fluid_000000.vts")) << "no truncated file under the final name";
  EXPECT_TRUE(no_temporary_files(out_));
}

TEST_F(CellfsiApp, RestartThatCannotWriteKeepsTheRunItContinues) {
  // Before: a restart removed the earlier run's summary.json first, and an unchecked write then left it
  // empty or missing.
  ASSERT_EQ(cellfsi(tiny_poiseuille("2e-3")).exit_code, 0) << last_output_;
  const std::string summary_before = summary(), csv_before = read_text(out_ / "metrics.csv");
  const auto checkpoint_before = tree(out_ / "checkpoint");
  file_size_limit_ = csv_before.size() - 1;  // the rows the restart keeps do not fit
  const RunResult r = cellfsi(with(tiny_poiseuille("4e-3"), {"-restart"}));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("metrics.csv': File too large"), std::string::npos) << r.output;
  EXPECT_EQ(summary(), summary_before);
  EXPECT_EQ(read_text(out_ / "metrics.csv"), csv_before);
  EXPECT_EQ(tree(out_ / "checkpoint"), checkpoint_before);
  EXPECT_TRUE(no_temporary_files(out_));
}

TEST_F(CellfsiApp, CheckpointWriteFailureKeepsThePreviousCheckpoint) {
  // 32 x 16 elements: a checkpoint larger than the other files.
  const std::vector<std::string> base = with(tiny_poiseuille("2e-3"), {"-fluid_elements", "32,16"});
  ASSERT_EQ(cellfsi(base).exit_code, 0) << last_output_;
  const auto checkpoint_before = tree(out_ / "checkpoint");
  const size_t fluid_file = fs::file_size(out_ / "checkpoint" / "fluid.petsc");
  const size_t others = std::max({read_text(out_ / "metrics.csv").size() * 2, summary().size() + 600,
                                  read_text(out_ / "checkpoint" / "state.json").size()});
  ASSERT_LT(others, fluid_file) << "the case must have a checkpoint larger than its other files";
  file_size_limit_ = fluid_file - 1;
  const RunResult r = cellfsi(with(base, {"-final_time", "4e-3", "-restart", "-checkpoint_every", "1"}));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("fluid.petsc"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("File too large"), std::string::npos) << r.output;
  EXPECT_EQ(tree(out_ / "checkpoint"), checkpoint_before) << "the last good checkpoint stays";
  EXPECT_TRUE(no_temporary_files(out_));
  EXPECT_EQ(json_string(summary(), "status").value_or("").rfind("failed: cannot write", 0), 0u) << summary();
}

// ---------------------------------------------------------------------------------------------------------
// options.yaml: what the run was given, re-runnable

/// Every scene file, with the options that make it a run of a second or two.
struct SceneCase {
  std::string file;
  std::vector<std::string> tiny;
};
/// How gtest names a case in test lists (not the struct's bytes).
void PrintTo(const SceneCase& c, std::ostream* os) { *os << c.file; }

const std::vector<SceneCase> kEveryScene = {
    {"shear.yaml", kTiny},
    {"poiseuille.yaml", kTiny},
    {"narrowing_flow.yaml",
     {"-fluid_elements", "48,16", "-fluid_degree", "2", "-final_time", "1e-3", "-output_every", "0"}},
    {"capsule_shear_quick.yaml", with(kCapsuleSmall, {"-final_time", "2e-3"})},
    {"capsule_shear.yaml", kCapsuleSmall},
    {"biconcave_capsule_shear.yaml", with(kCapsuleSmall, {"-fluid_elements", "64,32"})},
    {"bulky_ellipse_shear.yaml",
     {"-fluid_elements", "48,24", "-fluid_degree", "2", "-solid_body_elements", "0,0", "-final_time", "1e-3",
      "-output_every", "0"}},
    {"compound_capsule_shear.yaml",
     {"-fluid_elements", "96,48", "-fluid_degree", "2", "-final_time", "1e-3", "-output_every", "0"}},
    // (a membrane coarser than the automatic one of the scene's space, 1 x 40 x 80 here: 6.6 s a run instead
    // of 17)
    {"compound_capsule_shear_3d.yaml",
     {"-fluid_elements", "12,12,12", "-solid_membrane_elements", "1,12,24", "-solid_nucleus_elements",
      "0,0,0", "-final_time", "5e-4", "-output_every", "0"}},
    {"rbc_shear_3d.yaml", {"-fluid_elements", "12,12,12", "-final_time", "1e-3", "-output_every", "0"}},
    {"rbc_stretch_3d.yaml", {"-fluid_elements", "12,4,6", "-final_time", "2e-3", "-output_every", "0"}},
    {"rbc_channel.yaml",
     {"-fluid_elements", "96,32", "-fluid_degree", "2", "-solid_rbc_elements", "1,0", "-final_time", "5e-4",
      "-output_every", "0"}},
    {"capsule_channel_migration.yaml",
     {"-fluid_elements", "64,32", "-fluid_degree", "2", "-final_time", "1e-3", "-output_every", "0"}},
    {"ctc_narrowing.yaml",
     {"-fluid_elements", "96,32", "-fluid_degree", "2", "-solid_membrane_elements", "1,0",
      "-solid_nucleus_elements", "0,0", "-dt", "5e-4", "-final_time", "1e-3", "-output_every", "0"}},
    {"capsule_pair_shear.yaml",
     {"-fluid_elements", "32,32", "-fluid_degree", "2", "-final_time", "1e-3", "-output_every", "0"}},
    {"inertial_migration.yaml",
     {"-fluid_elements", "16,16", "-fluid_degree", "2", "-final_time", "1e-5", "-output_every", "0"}},
    {"ctc_rbc_narrowing.yaml",
     {"-fluid_elements", "48,16", "-dt", "5e-4", "-final_time", "5e-4", "-output_every", "0"}},
};

// One test per scene file (each its own ctest entry, with its own time limit).
class OptionsYamlOfEveryScene : public CellfsiApp, public ::testing::WithParamInterface<SceneCase> {};

TEST_P(OptionsYamlOfEveryScene, RunsAgainToTheSameMetrics) {
  // Before: `cellfsi DIR/options.yaml` was refused for every coupled scene ("option
  // -fluid_mat_mumps_icntl_24 does not apply": the file held defaults the program set itself).
  const SceneCase& c = GetParam();
  std::vector<std::string> args = c.tiny;
  args.insert(args.begin(), scene(c.file));
  const RunResult first = cellfsi(args, 120);
  ASSERT_EQ(first.exit_code, 0) << first.output;
  const fs::path again = root_ / "again";
  const RunResult second =
      run_process({CELLFSI_EXE, (out_ / "options.yaml").string(), "-output_dir", again.string()}, 120);
  ASSERT_EQ(second.exit_code, 0) << second.output << "\noptions.yaml:\n" << read_text(out_ / "options.yaml");
  EXPECT_EQ(read_text(again / "metrics.csv"), read_text(out_ / "metrics.csv"));
  EXPECT_EQ(json_string(read_text(again / "summary.json"), "scene"), json_string(summary(), "scene"));
}

INSTANTIATE_TEST_SUITE_P(SceneFiles, OptionsYamlOfEveryScene, ::testing::ValuesIn(kEveryScene),
                         [](const ::testing::TestParamInfo<SceneCase>& info) {
                           return info.param.file.substr(0, info.param.file.find('.'));
                         });

TEST(SceneFiles, EverySceneFileHasAnOptionsYamlCase) {
  std::set<std::string> covered;
  for (const SceneCase& c : kEveryScene) covered.insert(c.file);
  for (const auto& e : fs::directory_iterator(CELLFSI_SCENES))
    EXPECT_TRUE(covered.count(e.path().filename().string())) << "no case for " << e.path();
}

TEST_F(CellfsiApp, OptionsYamlKeepsSpacesNewlinesAndControlCharacters) {
  // Before: a value with a space was cut at it (a re-run wrote elsewhere) and control characters made the
  // file unreadable.
  out_ = root_ / "with space";
  const std::string name = "two\nlines\tand\x01";
  ASSERT_EQ(cellfsi(with(tiny_poiseuille("5e-4"), {"-scene", name})).exit_code, 0) << last_output_;
  const std::string yaml = read_text(out_ / "options.yaml");
  fs::remove(out_ / "summary.json");
  // No -output_dir: the file's own, with its space, must be the folder the re-run writes to.
  const RunResult again = run_process({CELLFSI_EXE, (out_ / "options.yaml").string()});
  ASSERT_EQ(again.exit_code, 0) << again.output << "\noptions.yaml:\n" << yaml;
  ASSERT_TRUE(fs::exists(out_ / "summary.json")) << yaml;
  EXPECT_NE(summary().find("\"scene\": \"two\\nlines\\tand\\u0001\""), std::string::npos) << summary();
}

}  // namespace
}  // namespace cellfsi_app_test
