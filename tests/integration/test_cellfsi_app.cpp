// Integration tests of the cellfsi executable: the run contract of DESIGN.md section 4, seen from outside.
// Each test runs `cellfsi` (or `mpiexec -np 2 cellfsi`) as a subprocess into its own fresh temporary folder
// and checks the exit code, the printed message and the files written (summary.json, metrics.csv,
// options.yaml, fluid.pvd). No PETSc in this process. Every run is tiny (a few coarse degree-2 steps, well
// under a second).
//
// Compile definitions: CELLFSI_EXE (the cellfsi executable), CELLFSI_SCENES (the scenes/ folder),
// MPIEXEC_EXECUTABLE (mpiexec of the MPI that cellfsi is built with).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vtkDataArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkStructuredGrid.h>
#include <vtkXMLPStructuredGridReader.h>
#include <vtkXMLStructuredGridReader.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

// ---------------------------------------------------------------------------------------------------------
// Running a subprocess

struct RunResult {
  int exit_code = -1;      // the exit status, or 128 + signal if killed by a signal
  bool timed_out = false;  // killed because it ran longer than the time limit
  std::string output;      // stdout and stderr, interleaved
};

/// Runs argv[0] (a path) with argv, stdout and stderr captured together, in its own process group, with the
/// MPI/BLAS environment of the test suite. After `timeout_s` the whole process group gets SIGTERM (mpiexec
/// forwards it to its ranks), then SIGKILL, so a hanging run fails the test instead of blocking the suite.
/// `during`, if given, is called with the child's pid about every 50 ms while it runs (e.g. to signal it).
RunResult run_process(const std::vector<std::string>& argv, double timeout_s = 60,
                      const std::function<void(pid_t)>& during = {}) {
  // The child inherits these (this test process is single-threaded, so setenv is safe here).
  setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
  setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  setenv("OPENBLAS_NUM_THREADS", "1", 1);
  RunResult r;
  int fd[2];
  if (pipe(fd) != 0) {
    r.output = std::string("pipe: ") + std::strerror(errno);
    return r;
  }
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t pid = fork();
  if (pid < 0) {
    r.output = std::string("fork: ") + std::strerror(errno);
    close(fd[0]);
    close(fd[1]);
    return r;
  }
  if (pid == 0) {
    setpgid(0, 0);
    dup2(fd[1], STDOUT_FILENO);
    dup2(fd[1], STDERR_FILENO);
    close(fd[0]);
    close(fd[1]);
    const int devnull = open("/dev/null", O_RDONLY);
    if (devnull >= 0) dup2(devnull, STDIN_FILENO);
    execv(args[0], args.data());
    const std::string msg = std::string("execv ") + args[0] + ": " + std::strerror(errno) + "\n";
    if (write(STDERR_FILENO, msg.data(), msg.size()) < 0) _exit(127);
    _exit(127);
  }
  setpgid(pid, pid);  // also from the parent, so that the group exists before any kill below
  close(fd[1]);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  char buf[4096];
  bool open_pipe = true;
  while (open_pipe) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      r.timed_out = true;
      break;
    }
    if (during) during(pid);
    pollfd p{fd[0], POLLIN, 0};
    const int k = poll(&p, 1, static_cast<int>(std::min<long long>(left.count(), during ? 50 : 1000)));
    if (k < 0 && errno != EINTR) break;
    if (k <= 0) continue;
    const ssize_t n = read(fd[0], buf, sizeof buf);
    if (n > 0)
      r.output.append(buf, static_cast<size_t>(n));
    else if (n == 0 || errno != EINTR)
      open_pipe = false;
  }
  if (r.timed_out) {
    kill(-pid, SIGTERM);
    for (int i = 0; i < 50 && waitpid(pid, nullptr, WNOHANG) == 0; ++i) usleep(100000);
    kill(-pid, SIGKILL);
  }
  close(fd[0]);
  int status = 0;
  if (waitpid(pid, &status, 0) == pid) {
    if (WIFEXITED(status))
      r.exit_code = WEXITSTATUS(status);
    else if (WIFSIGNALED(status))
      r.exit_code = 128 + WTERMSIG(status);
  }
  if (r.timed_out) r.exit_code = -1;
  return r;
}

std::string scene(const std::string& name) { return std::string(CELLFSI_SCENES) + "/" + name; }

/// The options that keep every run tiny: 8 x 4 degree-2 elements, two steps.
const std::vector<std::string> kTiny = {"-fluid_elements", "8,4",  "-fluid_degree", "2",
                                        "-final_time",     "1e-3", "-dt",           "5e-4",
                                        "-output_every",   "0"};

/// The capsule scene kept small: 48 x 24 quadratic fluid elements (the capsule's minor semi-axis spans two),
/// automatic membrane elements, two steps.
const std::vector<std::string> kCapsule = {
    "-fluid_elements", "48,24", "-fluid_degree", "2", "-solid_membrane_elements", "1,0",
    "-final_time",     "1e-3",  "-output_every", "0"};
/// kCapsule for the default scene (no scene file; dt 2e-3): one step.
const std::vector<std::string> kDefaultCapsule = [] {
  std::vector<std::string> a = kCapsule;
  a.insert(a.end(), {"-final_time", "2e-3"});
  return a;
}();

// ---------------------------------------------------------------------------------------------------------
// Reading the output files

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);)
    if (!l.empty()) out.push_back(l);
  return out;
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string item;
  std::istringstream in(s);
  while (std::getline(in, item, sep)) out.push_back(item);
  return out;
}

/// The number stored under "key" in flat JSON text, if present.
std::optional<double> json_number(const std::string& json, const std::string& key) {
  const std::regex re("\"" + key + "\"\\s*:\\s*(-?[0-9][0-9.eE+-]*)");
  std::smatch m;
  if (!std::regex_search(json, m, re)) return std::nullopt;
  return std::stod(m[1].str());
}

/// The string stored under "key" in flat JSON text, if present.
std::optional<std::string> json_string(const std::string& json, const std::string& key) {
  const std::regex re("\"" + key + "\"\\s*:\\s*\"([^\"]*)\"");
  std::smatch m;
  if (!std::regex_search(json, m, re)) return std::nullopt;
  return m[1].str();
}

/// Minimal well-formedness of summary.json as cellfsi writes it: one flat object, one "key": value per line,
/// commas between entries, values numbers or strings.
::testing::AssertionResult is_flat_json_object(const std::string& json) {
  const std::vector<std::string> ls = lines(json);
  if (ls.size() < 2 || ls.front() != "{" || ls.back() != "}")
    return ::testing::AssertionFailure() << "not a {...} object:\n" << json;
  const std::regex entry("\\s*\"[A-Za-z0-9_]+\": (\"[^\"]*\"|-?[0-9][0-9.eE+-]*|null)(,?)");
  for (size_t i = 1; i + 1 < ls.size(); ++i) {
    std::smatch m;
    if (!std::regex_match(ls[i], m, entry))
      return ::testing::AssertionFailure() << "malformed entry '" << ls[i] << "' in:\n" << json;
    const bool last = i + 2 == ls.size();
    if ((m[2].str() == ",") == last)
      return ::testing::AssertionFailure() << "misplaced comma at '" << ls[i] << "' in:\n" << json;
  }
  return ::testing::AssertionSuccess();
}

struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  int column(const std::string& name) const {
    for (size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return static_cast<int>(i);
    return -1;
  }
};

Csv read_csv(const fs::path& p) {
  Csv csv;
  const std::vector<std::string> ls = lines(read_text(p));
  if (ls.empty()) return csv;
  csv.header = split(ls[0], ',');
  for (size_t i = 1; i < ls.size(); ++i) csv.rows.push_back(split(ls[i], ','));
  return csv;
}

/// The file="..." entries of a .pvd collection, in order.
std::vector<std::string> pvd_files(const fs::path& p) {
  std::vector<std::string> out;
  const std::string text = read_text(p);
  const std::regex re("file=\"([^\"]*)\"");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it)
    out.push_back((*it)[1].str());
  return out;
}

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t pos = text.find(what); pos != std::string::npos; pos = text.find(what, pos + what.size())) ++n;
  return n;
}

// ---------------------------------------------------------------------------------------------------------
// Fixture: a fresh temporary folder per test; the run's output folder `out` inside it does not exist yet

class CellfsiApp : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "cellfsi_it_XXXXXX").string();
    ASSERT_NE(mkdtemp(tmpl.data()), nullptr) << std::strerror(errno);
    root_ = tmpl;
    out_ = root_ / "out";
  }
  void TearDown() override {
    std::error_code ec;
    if (HasFailure())
      std::printf("kept the output of the failed test in %s\n", root_.c_str());
    else
      fs::remove_all(root_, ec);
  }

  /// Runs `cellfsi args... -output_dir out_` (one rank).
  RunResult cellfsi(std::vector<std::string> args, double timeout_s = 60,
                    const std::function<void(pid_t)>& during = {}) const {
    args.insert(args.begin(), CELLFSI_EXE);
    args.push_back("-output_dir");
    args.push_back(out_.string());
    RunResult r = run_process(args, timeout_s, during);
    last_output_ = r.output;
    return r;
  }

  /// Runs `mpiexec -np N --oversubscribe cellfsi args... -output_dir out_`.
  RunResult mpi_cellfsi(int np, std::vector<std::string> args, double timeout_s = 60,
                        const std::function<void(pid_t)>& during = {}) const {
    std::vector<std::string> a = {MPIEXEC_EXECUTABLE, "-np", std::to_string(np), "--oversubscribe",
                                  CELLFSI_EXE};
    a.insert(a.end(), args.begin(), args.end());
    a.push_back("-output_dir");
    a.push_back(out_.string());
    RunResult r = run_process(a, timeout_s, during);
    last_output_ = r.output;
    return r;
  }

  /// True if the output folder does not exist or is empty; lists what is there otherwise.
  ::testing::AssertionResult nothing_written() const {
    if (!fs::exists(out_)) return ::testing::AssertionSuccess();
    std::string found;
    for (const auto& e : fs::directory_iterator(out_)) {
      found += ' ';
      found += e.path().filename().string();
    }
    if (found.empty()) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << "bad input, but " << out_ << " holds:" << found;
  }

  std::string summary() const { return read_text(out_ / "summary.json"); }

  fs::path root_, out_;
  mutable std::string last_output_;
};

std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

/// Bad input: exit code 1, exactly one "cellfsi: error:" line and no PETSc error trace.
void expect_one_clear_error(const RunResult& r) {
  EXPECT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
  EXPECT_EQ(count(r.output, "PETSC ERROR"), 0u) << r.output;
  EXPECT_EQ(count(r.output, "step "), 0u) << "no time step may run on bad input:\n" << r.output;
}

// ---------------------------------------------------------------------------------------------------------
// 1. The run contract on a good run

TEST_F(CellfsiApp, PoiseuilleWritesTheRunContract) {
  const RunResult r = cellfsi({scene("poiseuille.yaml"), "-fluid_elements", "16,8", "-fluid_degree", "2",
                               "-final_time", "2.5e-3", "-output_every", "5"});
  ASSERT_FALSE(r.timed_out) << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("completed 10 steps"), std::string::npos) << r.output;

  // summary.json: fixed scalars and the scene's final metrics.
  ASSERT_TRUE(fs::is_regular_file(out_ / "summary.json"));
  const std::string js = summary();
  EXPECT_TRUE(is_flat_json_object(js));
  EXPECT_EQ(json_string(js, "scene"), "poiseuille") << js;
  EXPECT_EQ(json_string(js, "status"), "completed") << js;
  EXPECT_EQ(json_number(js, "steps"), 10) << js;
  EXPECT_EQ(json_number(js, "ranks"), 1) << js;
  for (const char* key : {"wall_time_s", "newton_iterations", "linear_iterations", "max_velocity_rel_error",
                          "mean_velocity_rel_error", "max_velocity", "flow_rate"})
    EXPECT_TRUE(json_number(js, key).has_value()) << "summary.json lacks " << key << ":\n" << js;
  EXPECT_GT(json_number(js, "wall_time_s").value_or(-1), 0) << js;
  // What ran: version, source revision, the command line as given, the start time.
  EXPECT_TRUE(std::regex_match(json_string(js, "cellfsi_version").value_or(""),
                               std::regex("[0-9]+\\.[0-9]+\\.[0-9]+")))
      << js;
  EXPECT_FALSE(json_string(js, "commit").value_or("").empty()) << js;
  EXPECT_NE(json_string(js, "command_line").value_or("").find("poiseuille.yaml -fluid_elements 16,8"),
            std::string::npos)
      << js;
  EXPECT_TRUE(std::regex_match(json_string(js, "started_utc").value_or(""),
                               std::regex("20[0-9]{2}-[01][0-9]-[0-3][0-9]T[0-9:]{8}Z")))
      << js;
  EXPECT_GE(json_number(js, "newton_iterations").value_or(-1), 10)
      << "at least one Newton iteration per step";
  EXPECT_GE(json_number(js, "linear_iterations").value_or(-1),
            json_number(js, "newton_iterations").value_or(0));
  // From rest, after 10 steps of 2.5e-4 s on 16 x 8 degree-2 elements the centreline velocity is within
  // 5.3e-4 of f H^2 / (8 mu) (measured 5.257e-4; the error still decays, oscillating, from 0.41 after step
  // 1). 1e-3 leaves a factor 2 for solver changes and still catches a wrong body force, viscosity or scaling.
  const double err = json_number(js, "max_velocity_rel_error").value_or(1.0);
  EXPECT_LT(err, 1e-3) << js;

  // metrics.csv: named columns, one row per step, steps 1..10, the last row matching summary.json.
  const Csv csv = read_csv(out_ / "metrics.csv");
  ASSERT_FALSE(csv.header.empty());
  for (const char* col : {"step", "time", "newton_iterations", "linear_iterations", "max_velocity_rel_error"})
    EXPECT_GE(csv.column(col), 0) << "metrics.csv lacks column " << col;
  EXPECT_EQ(csv.header[0], "step");
  EXPECT_EQ(csv.header[1], "time");
  ASSERT_EQ(csv.rows.size(), 10u);
  for (size_t i = 0; i < csv.rows.size(); ++i) {
    ASSERT_EQ(csv.rows[i].size(), csv.header.size()) << "row " << i + 1;
    EXPECT_EQ(std::stoi(csv.rows[i][0]), static_cast<int>(i) + 1);
    EXPECT_NEAR(std::stod(csv.rows[i][1]), 2.5e-4 * (i + 1), 1e-12);
  }
  EXPECT_NEAR(std::stod(csv.rows.back()[csv.column("max_velocity_rel_error")]), err, 1e-9 * err);

  // options.yaml: the effective options, as given on the command line.
  const std::string opts = read_text(out_ / "options.yaml");
  for (const char* line : {"fluid_elements: 16,8", "fluid_degree: 2", "final_time: 2.5e-3", "output_every: 5",
                           "dt: 2.5e-4", "fluid_viscosity: 0.012", "scene: poiseuille"})
    EXPECT_NE(("\n" + opts).find(std::string("\n") + line + "\n"), std::string::npos)
        << "options.yaml lacks '" << line << "':\n"
        << opts;
  EXPECT_EQ(opts.find("fluid_elements: 96,32"), std::string::npos) << "the scene's value must be overridden";
  EXPECT_EQ(opts.find("options_file_yaml"), std::string::npos) << opts;

  // fluid.pvd: the initial state and every 5th step, and the pieces exist.
  ASSERT_TRUE(fs::is_regular_file(out_ / "fluid.pvd"));
  const std::vector<std::string> pieces = pvd_files(out_ / "fluid.pvd");
  EXPECT_EQ(pieces, (std::vector<std::string>{"fluid_000000.vts", "fluid_000005.vts", "fluid_000010.vts"}));
  for (const std::string& p : pieces) {
    EXPECT_TRUE(fs::is_regular_file(out_ / p)) << p;
    if (fs::is_regular_file(out_ / p)) {
      EXPECT_GT(fs::file_size(out_ / p), 0u) << p;
    }
  }
  // profile.csv: the velocity across the channel at mid-length, 65 points from wall to wall; zero at the
  // walls.
  ASSERT_TRUE(fs::is_regular_file(out_ / "profile.csv"));
  const std::vector<std::string> prof = lines(read_text(out_ / "profile.csv"));
  ASSERT_EQ(prof.size(), 66u);
  EXPECT_EQ(prof[0], "x,y,z,vx,vy,vz");
  EXPECT_EQ(prof[1], "0.0015,0,0,0,0,0");
  // No temporary files of the atomic writes left behind.
  for (const auto& e : fs::directory_iterator(out_)) EXPECT_NE(e.path().extension(), ".tmp") << e.path();
}

// 2. The command line overrides the scene file

TEST_F(CellfsiApp, CommandLineOverridesSceneFile) {
  const RunResult r = cellfsi({scene("poiseuille.yaml"), "-fluid_elements", "8,4", "-fluid_degree", "2",
                               "-final_time", "1e-3", "-dt", "5e-4", "-output_every", "0"});
  ASSERT_FALSE(r.timed_out) << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string js = summary();
  EXPECT_TRUE(is_flat_json_object(js));
  EXPECT_EQ(json_number(js, "steps"), 2) << "1e-3 / 5e-4 steps, not the scene's 0.005 / 2.5e-4:\n" << js;
  EXPECT_EQ(read_csv(out_ / "metrics.csv").rows.size(), 2u);
  const std::string opts = read_text(out_ / "options.yaml");
  EXPECT_NE(opts.find("\ndt: 5e-4\n"), std::string::npos) << opts;
  EXPECT_NE(opts.find("\nfinal_time: 1e-3\n"), std::string::npos) << opts;
  EXPECT_EQ(opts.find("2.5e-4"), std::string::npos) << opts;
  // -output_every 0 (overriding the scene's 10): no series written.
  EXPECT_FALSE(fs::exists(out_ / "fluid.pvd"));
}

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
  EXPECT_NE(r.output.find("> 0"), std::string::npos) << "the message names the valid range:\n" << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, DegreeOneIsRejected) {
  const RunResult r = cellfsi(with(with({scene("shear.yaml")}, kTiny), {"-fluid_degree", "1"}));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-fluid_degree"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("2 <= p <= 8"), std::string::npos) << r.output;
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

TEST_F(CellfsiApp, MisspeltPetscTypesAreRejectedByName) {
  // Issue 10: a misspelt type gave a 40-line PETSc traceback and exit 2 (59 for a PC type).
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {with({scene("shear.yaml")}, with(kTiny, {"-fluid_ksp_type", "gmress"})),
       "option -fluid_ksp_type = gmress is invalid: Unable to find requested KSP type gmress"},
      {with(kDefaultCapsule, {"-coupling_solver", "fluid", "-fluid_sub_pc_type", "ilux"}),
       "option -fluid_sub_pc_type = ilux is invalid: Unable to find requested PC type ilux"},
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
  EXPECT_NE(r.output.find("option -fluid_density = -2 is invalid; valid: > 0 [g/cm^3] (scene file '" +
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
// 4. A second run into the same folder replaces the first

TEST_F(CellfsiApp, SecondRunOverwritesCleanly) {
  const std::vector<std::string> base = {scene("shear.yaml"),
                                         "-fluid_elements",
                                         "8,4",
                                         "-fluid_degree",
                                         "2",
                                         "-dt",
                                         "5e-4",
                                         "-output_every",
                                         "1"};
  const RunResult first = cellfsi(with(base, {"-final_time", "2e-3"}));
  ASSERT_FALSE(first.timed_out) << first.output;
  ASSERT_EQ(first.exit_code, 0) << first.output;
  ASSERT_EQ(json_number(summary(), "steps"), 4) << summary();
  ASSERT_EQ(read_csv(out_ / "metrics.csv").rows.size(), 4u);

  const RunResult second = cellfsi(with(base, {"-final_time", "1e-3"}));
  ASSERT_FALSE(second.timed_out) << second.output;
  ASSERT_EQ(second.exit_code, 0) << second.output;
  const std::string js = summary();
  EXPECT_TRUE(is_flat_json_object(js));
  EXPECT_EQ(json_string(js, "status"), "completed") << js;
  EXPECT_EQ(json_number(js, "steps"), 2) << js;
  const Csv csv = read_csv(out_ / "metrics.csv");
  EXPECT_EQ(csv.rows.size(), 2u) << "metrics.csv must be rewritten, not appended to";
  EXPECT_EQ(count(read_text(out_ / "metrics.csv"), "step,time"), 1u) << "one header";
  EXPECT_NE(read_text(out_ / "options.yaml").find("\nfinal_time: 1e-3\n"), std::string::npos);
  EXPECT_EQ(pvd_files(out_ / "fluid.pvd"),
            (std::vector<std::string>{"fluid_000000.vts", "fluid_000001.vts", "fluid_000002.vts"}));
}

TEST_F(CellfsiApp, RunStopsCleanlyOnSigterm) {
  // Issue 10: SIGTERM used to end the run at once, with no message and no summary. Now the run finishes the
  // step in progress, writes its row, the series and summary.json ("interrupted: SIGTERM after step k ..."),
  // and exits with 128 + 15. The signal is sent once the first two steps are in metrics.csv.
  bool sent = false;
  const fs::path csv_path = out_ / "metrics.csv";
  const RunResult r =
      cellfsi(with(kDefaultCapsule, {"-final_time", "4", "-output_every", "1000"}), 120, [&](pid_t pid) {
        if (!sent && fs::exists(csv_path) && lines(read_text(csv_path)).size() >= 3) {
          kill(pid, SIGTERM);
          sent = true;
        }
      });
  ASSERT_TRUE(sent) << r.output;
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 128 + SIGTERM) << r.output;
  EXPECT_NE(r.output.find("cellfsi: interrupted by SIGTERM after step"), std::string::npos) << r.output;
  EXPECT_EQ(count(r.output, "PETSC ERROR"), 0u) << r.output;
  const std::string js = summary();
  EXPECT_TRUE(is_flat_json_object(js));
  EXPECT_EQ(json_string(js, "status").value_or("").rfind("interrupted: SIGTERM after step", 0), 0u) << js;
  const auto steps = json_number(js, "steps");
  ASSERT_TRUE(steps.has_value()) << js;
  EXPECT_GE(*steps, 2) << js;
  EXPECT_LT(*steps, 2000) << js;
  EXPECT_EQ(read_csv(csv_path).rows.size(), static_cast<size_t>(*steps)) << "one row per step done";
  EXPECT_TRUE(json_number(js, "membrane_r_A").has_value()) << "the metrics of the steps done:\n" << js;
  // The series ends with the state the run stopped at (its 1000-step output interval was never reached).
  EXPECT_EQ(pvd_files(out_ / "fluid.pvd").size(), 2u) << read_text(out_ / "fluid.pvd");
}

TEST_F(CellfsiApp, MpirunForwardsSigusr1AndBothRanksStopAfterTheSameStep) {
  bool sent = false;
  const fs::path csv_path = out_ / "metrics.csv";
  const RunResult r =
      mpi_cellfsi(2,
                  {scene("shear.yaml"), "-fluid_elements", "16,8", "-fluid_degree", "2", "-dt", "5e-4",
                   "-final_time", "100", "-output_every", "0"},
                  120, [&](pid_t pid) {
                    if (!sent && fs::exists(csv_path) && lines(read_text(csv_path)).size() >= 3) {
                      kill(pid, SIGUSR1);  // to mpiexec, which forwards it
                      sent = true;
                    }
                  });
  ASSERT_TRUE(sent) << r.output;
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 128 + SIGUSR1) << r.output;
  const std::string js = summary();
  EXPECT_EQ(json_string(js, "status").value_or("").rfind("interrupted: SIGUSR1 after step", 0), 0u) << js;
  EXPECT_EQ(read_csv(csv_path).rows.size(), static_cast<size_t>(json_number(js, "steps").value_or(-1)));
}

TEST_F(CellfsiApp, OutputFolderInUseIsRefusedAndLeftIntact) {
  // Issue 10: two runs on one folder interleaved their metrics.csv and both said "completed". The folder is
  // locked (DIR/.cellfsi.lock); here this test holds the lock, as a running cellfsi would.
  fs::create_directories(out_);
  { std::ofstream(out_ / "metrics.csv") << "step,time\n1,0.5\n"; }
  const int fd = open((out_ / ".cellfsi.lock").c_str(), O_RDWR | O_CREAT, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(flock(fd, LOCK_EX | LOCK_NB), 0);
  const std::string pid = std::to_string(getpid());
  ASSERT_EQ(write(fd, pid.data(), pid.size()), static_cast<ssize_t>(pid.size()));
  const RunResult r = cellfsi(with({scene("shear.yaml")}, kTiny));
  expect_one_clear_error(r);
  EXPECT_NE(r.output.find("-output_dir = '" + out_.string() +
                          "' is invalid: it is in use by another cellfsi run (process " + pid + ")"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(read_text(out_ / "metrics.csv"), "step,time\n1,0.5\n") << "the other run's file was touched";
  EXPECT_FALSE(fs::exists(out_ / "summary.json"));
  close(fd);  // released: now the run goes ahead
  const RunResult ok = cellfsi(with({scene("shear.yaml")}, kTiny));
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
}

TEST_F(CellfsiApp, ReusedFolderLosesThePreviousRunsSolidSeries) {
  // Issue 10: a capsule run's solid series stayed behind when the next run in the folder wrote none.
  fs::create_directories(out_);
  for (const char* f : {"solid.pvd", "solid_membrane_000007.vts", "fluid_000003.vts", "fluid.pvd"})
    std::ofstream(out_ / f) << "old";
  { std::ofstream(out_ / "notes.txt") << "mine"; }
  const RunResult r = cellfsi(kDefaultCapsule);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* f : {"solid.pvd", "solid_membrane_000007.vts", "fluid_000003.vts", "fluid.pvd"})
    EXPECT_FALSE(fs::exists(out_ / f)) << f;
  EXPECT_EQ(read_text(out_ / "notes.txt"), "mine") << "files cellfsi does not write are kept";
}

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
  for (const char* table : {"cellfsi scene (DESIGN.md section 4; CGS units):",
                            "Fluid (VMS Navier-Stokes; CGS units):", "cellfsi immersed bodies and coupling:"})
    EXPECT_NE(r.output.find(table), std::string::npos) << "-help lacks the table " << table;
  EXPECT_NE(r.output.find("Eulerian domain (rectangle, box, narrowing)"), std::string::npos) << r.output;
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

// ---------------------------------------------------------------------------------------------------------
// 4. Immersed bodies: the capsule scene, its launch modes and its input checks

/// The last metrics.csv row as name -> value.
std::vector<std::pair<std::string, double>> last_row(const fs::path& csv_path) {
  const Csv csv = read_csv(csv_path);
  std::vector<std::pair<std::string, double>> row;
  if (csv.rows.empty()) return row;
  for (size_t i = 0; i < csv.header.size() && i < csv.rows.back().size(); ++i)
    row.emplace_back(csv.header[i], std::stod(csv.rows.back()[i]));
  return row;
}

/// Every value of a agrees with b's to `rel` relative (of max(|a|, |b|, floor)).
::testing::AssertionResult rows_agree(const std::vector<std::pair<std::string, double>>& a,
                                      const std::vector<std::pair<std::string, double>>& b, double rel,
                                      double floor = 1e-300) {
  if (a.size() != b.size() || a.empty()) return ::testing::AssertionFailure() << "different or empty rows";
  for (size_t i = 0; i < a.size(); ++i) {
    const double scale = std::max({std::abs(a[i].second), std::abs(b[i].second), floor});
    if (a[i].first != b[i].first || std::abs(a[i].second - b[i].second) > rel * scale)
      return ::testing::AssertionFailure() << a[i].first << ": " << a[i].second << " vs " << b[i].first
                                           << ": " << b[i].second << " (relative " << rel << ")";
  }
  return ::testing::AssertionSuccess();
}

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
  const std::vector<std::string> files = pvd_files(out_ / "solid.pvd");
  ASSERT_EQ(files.size(), 3u) << read_text(out_ / "solid.pvd");
  for (const auto& f : files) EXPECT_TRUE(fs::exists(out_ / f)) << f;
  EXPECT_GE(read_csv(out_ / "metrics.csv").column("membrane_theta_deg"), 0);
}

TEST_F(CellfsiApp, CoarseCapsuleInclinationWithCentralAndSupportMarking) {
  // Issue 8: at 96 x 48 quadratic elements the capsule's inclination with the default (central) s^h marking
  // is closer to the converged 26.09 deg (paper, 512 x 256 cubic) than the paper's own 17.81 at this mesh;
  // the wider support marking gives 14.1 (docs/validation.md, "Coarse meshes: the s^h marking"). Measured
  // over 0.08-0.12 s with dt 2e-3 (theta is steady from about 0.08 s and does not depend on dt): 18.942 and
  // 14.142 deg. Pinned to 0.05 deg: a change of the discretisation shows here first.
  // clang-format off
  const std::vector<std::string> run = {
      scene("capsule_shear.yaml"), "-fluid_elements", "96,48", "-fluid_degree", "2",
      "-solid_membrane_elements", "1,0", "-dt", "2e-3", "-final_time", "0.12",
      "-metrics_average_from", "0.08", "-output_every", "0"};
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
  const RunResult r = cellfsi(
      {scene("compound_capsule_shear_3d.yaml"), "-fluid_elements", "12,12,12", "-solid_membrane_elements",
       "1,0,0", "-solid_nucleus_elements", "0,0,0", "-final_time", "1e-3", "-output_every", "1"},
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

TEST_F(CellfsiApp, RunFailingInItsFirstStepSaysWhereAndKeepsTheColumns) {
  // Issue 10: a step too long for the membrane at 192 x 96 (dt 4e-3 inverts an element in step 1 with the
  // paper's iteration; the Anderson-accelerated one, the default, gets through it). The run exits with 2, the
  // message and summary.json name the step and the time, and metrics.csv has its header (before: a 0-byte
  // file and no step or time).
  const RunResult r =
      cellfsi({scene("capsule_shear.yaml"), "-fluid_elements", "192,96", "-dt", "4e-3", "-final_time", "8e-3",
               "-solid_membrane_elements", "1,0", "-output_every", "0", "-coupling_acceleration", "none"},
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
  // One process; one job split into a fluid and a solid rank; two executables (MPMD). Same numbers.
  const std::vector<std::string> args =
      with({scene("capsule_shear.yaml")}, with(kCapsule, {"-final_time", "2e-3"}));
  ASSERT_EQ(cellfsi(args).exit_code, 0) << last_output_;
  const auto single = last_row(out_ / "metrics.csv");
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

/// A metrics row without the solver's counters (iterations, factorisations), which a restart may change.
std::vector<std::pair<std::string, double>> metrics_only(std::vector<std::pair<std::string, double>> row) {
  row.erase(std::remove_if(row.begin(), row.end(),
                           [](const auto& kv) {
                             return kv.first == "coupling_iterations" || kv.first == "linear_iterations" ||
                                    kv.first == "factorizations";
                           }),
            row.end());
  return row;
}

/// The steps column of metrics.csv.
std::vector<int> csv_steps(const fs::path& p) {
  std::vector<int> out;
  for (const auto& row : read_csv(p).rows) out.push_back(std::stoi(row.at(0)));
  return out;
}
std::vector<int> one_to(int n) {
  std::vector<int> v(n);
  for (int i = 0; i < n; ++i) v[i] = i + 1;
  return v;
}

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
  for (const char* key : {"membrane_theta_deg", "membrane_omega_tt", "membrane_omega_tu"})
    EXPECT_NEAR(json_number(js, key).value_or(0), json_number(straight_js, key).value_or(1),
                1e-6 * std::abs(json_number(straight_js, key).value_or(1)))
        << key;
  EXPECT_EQ(pvd_files(out_ / "fluid.pvd"), straight_pvd);
  EXPECT_EQ(pvd_files(out_ / "solid.pvd").size(), 5u);
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

TEST_F(CellfsiApp, RestartWithOtherOptionsOrWithoutACheckpointIsRefused) {
  const std::vector<std::string> args = with({scene("shear.yaml")}, kTiny);
  expect_one_clear_error(cellfsi(with(args, {"-restart"})));
  EXPECT_NE(last_output_.find("holds no checkpoint"), std::string::npos) << last_output_;
  ASSERT_EQ(cellfsi(args).exit_code, 0) << last_output_;
  const std::string csv = read_text(out_ / "metrics.csv");
  expect_one_clear_error(cellfsi(with(args, {"-final_time", "2e-3", "-dt", "2.5e-4", "-restart"})));
  EXPECT_NE(last_output_.find("was written with other options (dt: 5e-4 -> 2.5e-4)"), std::string::npos)
      << last_output_;
  expect_one_clear_error(cellfsi(with(args, {"-restart"})));
  EXPECT_NE(last_output_.find("option -final_time = 0.001 is invalid with -restart"), std::string::npos)
      << last_output_;
  EXPECT_EQ(read_text(out_ / "metrics.csv"), csv) << "a refused restart leaves the run's files alone";
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

// Channel scenes (issue 12): RBC suspensions and their rheology, an off-centre capsule's migration.

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
  const RunResult r =
      cellfsi({scene("capsule_channel_migration.yaml"), "-fluid_elements", "64,32", "-fluid_degree", "2",
               "-solid_membrane_elements", "1,0", "-final_time", "5e-4", "-output_every", "0"},
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
  EXPECT_NE(r.output.find("-coupling_solver fluid"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, SnesOptionsOfACoupledRunAreRejectedWithTheReason) {
  // Issue 10: -fluid_snes_* options were silently ignored in coupled runs with -coupling_solver fluid.
  for (const char* solver : {"band", "fluid"}) {
    expect_one_clear_error(
        cellfsi(with(kDefaultCapsule, {"-coupling_solver", solver, "-fluid_snes_rtol", "1e-3"})));
    EXPECT_NE(
        last_output_.find("option -fluid_snes_rtol does not apply: in a coupled run the nonlinear iteration "
                          "is the coupling loop"),
        std::string::npos)
        << last_output_;
  }
}

TEST_F(CellfsiApp, OptionsReadAtTheFirstSolveAreAcceptedInBothSolvers) {
  RunResult r = cellfsi(with(
      kDefaultCapsule, {"-coupling_band_mat_mumps_icntl_14", "40", "-coupling_band_schur_mat_mumps_icntl_14",
                        "40", "-coupling_band_ksp_converged_reason"}));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = cellfsi(with(kDefaultCapsule, {"-coupling_solver", "fluid", "-fluid_sub_mat_mumps_icntl_14", "40",
                                     "-fluid_ksp_converged_reason"}));
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

TEST_F(CellfsiApp, MisspeltFactorisationOptionIsRejectedAfterTheFirstStep) {
  const RunResult r = cellfsi(with(kDefaultCapsule, {"-coupling_band_mat_mumps_icntll_14", "40"}));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
  EXPECT_NE(r.output.find("coupling_band_mat_mumps_icntll_14"), std::string::npos) << r.output;
}

TEST_F(CellfsiApp, BandSolverOptionsOnTwoFluidRanksAreRejectedWithTheReason) {
  const RunResult r = mpi_cellfsi(2, with(kDefaultCapsule, {"-coupling_band_refresh_steps", "3"}));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
  EXPECT_NE(r.output.find("-coupling_band_refresh_steps"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("one fluid rank"), std::string::npos) << r.output;
  EXPECT_TRUE(nothing_written());
}

TEST_F(CellfsiApp, OneAndTwoFluidRanksAgree) {
  const std::vector<std::string> args =
      with({scene("capsule_shear.yaml")}, with(kCapsule, {"-final_time", "2e-3"}));
  ASSERT_EQ(cellfsi(args).exit_code, 0) << last_output_;
  const auto one = last_row(out_ / "metrics.csv");
  ASSERT_EQ(mpi_cellfsi(2, args).exit_code, 0) << last_output_;
  const auto two = last_row(out_ / "metrics.csv");
  // Iteration counts may differ by one between partitions (the linear solves stop at rtol 1e-5), and the
  // solvers differ (one rank: the band solver; two: the fluid's ASM); the state agrees to well below the
  // coupling tolerance.
  auto state = [](std::vector<std::pair<std::string, double>> row) {
    std::erase_if(row, [](const auto& kv) {
      return kv.first.find("iterations") != std::string::npos || kv.first == "factorizations";
    });
    return row;
  };
  EXPECT_TRUE(rows_agree(state(one), state(two), 1e-6, 1e-4));
}

TEST_F(CellfsiApp, InterfaceScalingReducesTheAreaError) {
  // Paper Fig. 1b on a coarse mesh: the spurious area change falls as s_I grows.
  double previous = 1e300;
  for (const char* s_i : {"1", "1e5", "1e10"}) {
    const RunResult r = cellfsi(with({scene("capsule_shear.yaml")},
                                     {"-fluid_elements", "48,24", "-solid_membrane_elements", "1,0",
                                      "-final_time", "0.02", "-output_every", "0", "-s_interface", s_i}),
                                120);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const double ra = std::abs(json_number(summary(), "membrane_r_A").value_or(1e300));
    std::printf("  s_I = %s: |r_A| = %.3e\n", s_i, ra);
    EXPECT_LT(ra, previous / 3) << "s_I = " << s_i;
    previous = ra;
  }
}

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
    EXPECT_NE(r.output.find("different options for the bodies (fluid side -> solid side: " +
                            solid_only[0].substr(1)),
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
