#pragma once
// What the integration tests of the cellfsi executable share (tests/integration/test_app_*.cpp): running a
// subprocess, reading its output files, and the fixture. The tests: the run contract of docs/design.md §4,
// seen from outside.
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
#include <sys/resource.h>
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
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdio>
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

#include "../support/ompi_session_dir.hpp"
#include "../support/tolerances.hpp"

namespace fs = std::filesystem;

namespace cellfsi_app_test {

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
/// `file_size_limit` (bytes), if given: no file the child writes may grow past it (RLIMIT_FSIZE, with SIGXFSZ
/// ignored, so a write beyond it fails with EFBIG as on a full disk).
inline RunResult run_process(const std::vector<std::string>& argv, double timeout_s = 60,
                             const std::function<void(pid_t)>& during = {},
                             std::optional<rlim_t> file_size_limit = std::nullopt) {
  // The child inherits these (this test process is single-threaded, so setenv is safe here).
  setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
  setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  setenv("OPENBLAS_NUM_THREADS", "1", 1);
  // A process started without mpiexec is an MPI singleton; Open MPI then starts a daemon for it unless the
  // singleton is isolated. The runs here spawn nothing, and the daemon cost a quarter of each short run's CPU
  // (0.94 against 0.69 s for `cellfsi -help` on one core; tests/README.md, "Time").
  setenv("OMPI_MCA_ess_singleton_isolated", "1", 0);
  // And its own session directory (tests/support/ompi_session_dir.hpp): concurrent tests shared one.
  struct SessionBase {
    std::string dir;
    ~SessionBase() { cellfsi_test::remove_ompi_session_base(dir); }
  } session;
  unsetenv("OMPI_MCA_orte_tmpdir_base");  // (the previous run's, removed)
  session.dir = cellfsi_test::private_ompi_session_base();
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
    if (file_size_limit) {
      // MPI's start-up writes shared-memory files that the limit would cut (PMIx's data store, the shared-
      // memory transport): the ranks talk over loopback TCP instead.
      setenv("PMIX_MCA_gds", "hash", 1);
      setenv("OMPI_MCA_btl", "self,tcp", 1);
      const rlimit limit{*file_size_limit, *file_size_limit};
      setrlimit(RLIMIT_FSIZE, &limit);
      signal(SIGXFSZ, SIG_IGN);  // an ignored signal stays ignored across exec
    }
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

inline std::string scene(const std::string& name) { return std::string(CELLFSI_SCENES) + "/" + name; }

/// The options that keep every run tiny: 8 x 4 degree-2 elements, two steps.
inline const std::vector<std::string> kTiny = {"-fluid_elements", "8,4",  "-fluid_degree", "2",
                                               "-final_time",     "1e-3", "-dt",           "5e-4",
                                               "-output_every",   "0"};

/// The capsule scenes kept small, in the scene's own fluid space: 48 x 24 quadratic fluid elements (the
/// capsule's minor semi-axis spans two), automatic membrane elements, two steps.
inline const std::vector<std::string> kCapsuleSmall = {
    "-fluid_elements", "48,24", "-fluid_degree", "2", "-solid_membrane_elements", "1,0",
    "-final_time",     "1e-3",  "-output_every", "0"};
/// kCapsuleSmall on the paper's equal-order space with its s_I, which the capsule scenes leave for the
/// divergence-conforming space (README, "Which space a scene uses"): the tests of s_I, of the region
/// factorisation and of the app's machinery as they were written for it.
inline const std::vector<std::string> kCapsule = [] {
  std::vector<std::string> a = kCapsuleSmall;
  a.insert(a.end(), {"-fluid_space", "equal_order"});
  return a;
}();
/// kCapsule for the default scene (no scene file; dt 2e-3), on the equal-order space: one step.
inline const std::vector<std::string> kDefaultCapsule = [] {
  std::vector<std::string> a = kCapsule;
  *(std::find(a.begin(), a.end(), "-final_time") + 1) = "2e-3";
  return a;
}();

// ---------------------------------------------------------------------------------------------------------
// Reading the output files

/// Two capsules of the pair scene (scenes/capsule_pair_shear.yaml) in a box half as high (0.0032 x 0.0016
/// cm, 48 x 24 quadratic elements, to 2 ms), stacked across the flow with their mid-lines `gap` [cm] apart;
/// the contact repulsion's cut-off there is the smallest element, kPairCutoff.
inline constexpr double kPairCutoff = 0.0032 / 48;
inline std::vector<std::string> touching_capsules(double gap) {
  const double a = 1e-4, y = 8e-4 + a + gap / 2;
  char upper[64], lower[64];
  std::snprintf(upper, sizeof upper, "0.0016,%.10g", y);
  std::snprintf(lower, sizeof lower, "0.0016,%.10g", 1.6e-3 - y);
  return {scene("capsule_pair_shear.yaml"),
          "-domain_size",
          "0.0032,0.0016",
          "-fluid_elements",
          "48,24",
          "-fluid_degree",
          "2",
          "-solid_upper_center",
          upper,
          "-solid_lower_center",
          lower,
          "-final_time",
          "2e-3",
          "-output_every",
          "0"};
}

inline std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

inline std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);)
    if (!l.empty()) out.push_back(l);
  return out;
}

inline std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string item;
  std::istringstream in(s);
  while (std::getline(in, item, sep)) out.push_back(item);
  return out;
}

/// The number stored under "key" in flat JSON text, if present.
inline std::optional<double> json_number(const std::string& json, const std::string& key) {
  const std::regex re("\"" + key + "\"\\s*:\\s*(-?[0-9][0-9.eE+-]*)");
  std::smatch m;
  if (!std::regex_search(json, m, re)) return std::nullopt;
  return std::stod(m[1].str());
}

/// The string stored under "key" in flat JSON text, if present.
inline std::optional<std::string> json_string(const std::string& json, const std::string& key) {
  const std::regex re("\"" + key + "\"\\s*:\\s*\"([^\"]*)\"");
  std::smatch m;
  if (!std::regex_search(json, m, re)) return std::nullopt;
  return m[1].str();
}

/// Minimal well-formedness of summary.json as cellfsi writes it: one flat object, one "key": value per line,
/// commas between entries, values numbers or strings.
inline ::testing::AssertionResult is_flat_json_object(const std::string& json) {
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

inline Csv read_csv(const fs::path& p) {
  Csv csv;
  const std::vector<std::string> ls = lines(read_text(p));
  if (ls.empty()) return csv;
  csv.header = split(ls[0], ',');
  for (size_t i = 1; i < ls.size(); ++i) csv.rows.push_back(split(ls[i], ','));
  return csv;
}

/// The file="..." entries of a .pvd collection, in order.
inline std::vector<std::string> pvd_files(const fs::path& p) {
  std::vector<std::string> out;
  const std::string text = read_text(p);
  const std::regex re("file=\"([^\"]*)\"");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it)
    out.push_back((*it)[1].str());
  return out;
}

inline size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t pos = text.find(what); pos != std::string::npos; pos = text.find(what, pos + what.size())) ++n;
  return n;
}

// ---------------------------------------------------------------------------------------------------------
// Fixture: a fresh temporary folder per test; the run's output folder `out` inside it does not exist yet

inline void expect_one_clear_error(const RunResult& r);
inline std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& b);

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
    RunResult r = run_process(args, timeout_s, during, file_size_limit_);
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
    RunResult r = run_process(a, timeout_s, during, file_size_limit_);
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

  /// Runs base followed by each case's options: each is refused with one clear error holding the case's
  /// message, and nothing is written.
  void expect_each_refused(const std::vector<std::string>& base,
                           const std::vector<std::pair<std::vector<std::string>, std::string>>& cases) const {
    for (const auto& [options, message] : cases) {
      const RunResult r = cellfsi(with(base, options));
      expect_one_clear_error(r);
      EXPECT_NE(r.output.find(message), std::string::npos) << r.output;
      EXPECT_TRUE(nothing_written());
    }
  }

  fs::path root_, out_;
  mutable std::string last_output_;
  std::optional<rlim_t> file_size_limit_;  // cellfsi(): see run_process
};

/// True for an option name ("-dt"), false for a value ("-1", "2e-3", "scene.yaml").
inline bool is_option(const std::string& w) {
  return w.size() > 1 && w[0] == '-' && std::isalpha(static_cast<unsigned char>(w[1]));
}

/// The arguments a followed by b, where an option of b that a already has replaces a's value (the command
/// line refuses an option given twice): with(kTiny, {"-dt", "1e-3"}) runs with dt 1e-3.
inline std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& b) {
  for (size_t i = 0; i < b.size(); ++i) {
    const bool has_value = is_option(b[i]) && i + 1 < b.size() && !is_option(b[i + 1]);
    const auto it = is_option(b[i]) ? std::find(a.begin(), a.end(), b[i]) : a.end();
    if (it == a.end()) {
      a.push_back(b[i]);
      if (has_value) a.push_back(b[++i]);
      continue;
    }
    const bool a_has_value = it + 1 != a.end() && !is_option(*(it + 1));
    if (has_value && a_has_value)
      *(it + 1) = b[++i];
    else if (has_value)
      a.insert(it + 1, b[++i]);
    else if (a_has_value)
      a.erase(it + 1);
  }
  return a;
}

/// Bad input: exit code 1, exactly one "cellfsi: error:" line and no PETSc error trace.
inline void expect_one_clear_error(const RunResult& r) {
  EXPECT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(count(r.output, "cellfsi: error:"), 1u) << r.output;
  EXPECT_EQ(count(r.output, "PETSC ERROR"), 0u) << r.output;
  EXPECT_EQ(count(r.output, "step "), 0u) << "no time step may run on bad input:\n" << r.output;
}

/// The last metrics.csv row as name -> value.
inline std::vector<std::pair<std::string, double>> last_row(const fs::path& csv_path) {
  const Csv csv = read_csv(csv_path);
  std::vector<std::pair<std::string, double>> row;
  if (csv.rows.empty()) return row;
  for (size_t i = 0; i < csv.header.size() && i < csv.rows.back().size(); ++i)
    row.emplace_back(csv.header[i], std::stod(csv.rows.back()[i]));
  return row;
}

/// Every value of a agrees with b's to `rel` relative (of max(|a|, |b|, floor)).
inline ::testing::AssertionResult rows_agree(const std::vector<std::pair<std::string, double>>& a,
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

/// A metrics row without the solver's counters (iterations, factorisations), which a restart may change.
inline std::vector<std::pair<std::string, double>> metrics_only(
    std::vector<std::pair<std::string, double>> row) {
  row.erase(std::remove_if(row.begin(), row.end(),
                           [](const auto& kv) {
                             return kv.first == "coupling_iterations" || kv.first == "linear_iterations" ||
                                    kv.first.find("factorizations") != std::string::npos;
                           }),
            row.end());
  return row;
}

/// The steps column of metrics.csv.
inline std::vector<int> csv_steps(const fs::path& p) {
  std::vector<int> out;
  for (const auto& row : read_csv(p).rows) out.push_back(std::stoi(row.at(0)));
  return out;
}
inline std::vector<int> one_to(int n) {
  std::vector<int> v(n);
  for (int i = 0; i < n; ++i) v[i] = i + 1;
  return v;
}

}  // namespace cellfsi_app_test
