#include "apps/run_output.hpp"

#include <fcntl.h>
#include <petscsys.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "apps/build_info.hpp"

namespace cellfsi::app {

void write_atomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream os(tmp);
    if (!os) throw std::runtime_error("cannot open '" + tmp + "' for writing");
    os << text;
    if (!os) throw std::runtime_error("error writing '" + tmp + "'");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) throw std::runtime_error("cannot rename '" + tmp + "'");
}

std::string effective_options_yaml() {
  char* all = nullptr;
  if (PetscOptionsGetAll(nullptr, &all) != 0) throw std::runtime_error("cannot read the options database");
  std::istringstream in(all);
  PetscFree(all);
  std::ostringstream out;
  out << "# effective options of this run (PETSc options database)\n";
  std::string tok, key;
  std::vector<std::pair<std::string, std::string>> kv;
  while (in >> tok) {
    if (tok.size() > 1 && tok[0] == '-' && !std::isdigit(static_cast<unsigned char>(tok[1])) &&
        tok[1] != '.') {
      if (!key.empty()) kv.emplace_back(key, "true");
      key = tok.substr(1);
    } else if (!key.empty()) {
      kv.emplace_back(key, tok);
      key.clear();
    }
  }
  if (!key.empty()) kv.emplace_back(key, "true");
  for (auto& [k, v] : kv)
    if (k != "options_file_yaml") out << k << ": " << v << "\n";
  return out.str();
}

namespace {

/// A file of the fluid or solid series: fluid_NNNNNN.vts, its parallel form fluid_NNNNNN.pvts with pieces
/// fluid_NNNNNN_pRRRR.vts, solid_BODY_NNNNNN.vts.
bool is_series_file(const std::string& name) {
  const std::string ext = std::filesystem::path(name).extension().string();
  return (name.rfind("fluid_", 0) == 0 || name.rfind("solid_", 0) == 0) && (ext == ".vts" || ext == ".pvts");
}

/// Locks DIR/.cellfsi.lock (flock: released by the kernel when the process ends, however it ends) and
/// writes this process's id into it. Returns the descriptor, or -1 with `why` set.
int lock_folder(const std::string& dir, std::string& why) {
  const std::string path = dir + "/.cellfsi.lock";
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    why = "cannot open '" + path + "': " + std::strerror(errno);
    return -1;
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    char pid[32] = {};
    const ssize_t n = ::pread(fd, pid, sizeof pid - 1, 0);
    ::close(fd);
    std::string holder = n > 0 ? std::string(pid, static_cast<size_t>(n)) : std::string("?");
    while (!holder.empty() && (holder.back() == '\n' || holder.back() == ' ')) holder.pop_back();
    why = err == EWOULDBLOCK ? "it is in use by another cellfsi run (process " + holder +
                                   "); wait for it or choose another -output_dir"
                             : "cannot lock '" + path + "': " + std::strerror(err);
    return -1;
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) < 0) {
    // The lock holds without the id; only the message of a refused second run is poorer.
  }
  return fd;
}

/// The arguments as one line a shell would split back into them (single quotes where needed).
std::string shell_words(const std::vector<std::string>& args) {
  std::string line;
  for (const std::string& a : args) {
    const bool plain = !a.empty() && a.find_first_not_of(
                                         "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                         "0123456789-_./,:=+@%") == std::string::npos;
    if (!line.empty()) line += ' ';
    if (plain) {
      line += a;
    } else {
      line += '\'';
      for (char c : a) line += c == '\'' ? std::string("'\\''") : std::string(1, c);
      line += '\'';
    }
  }
  return line;
}

/// A restart's metrics.csv lacks the rows of steps first..last (before the checkpoint's step): continuing
/// would leave a gap in it.
[[noreturn]] void throw_missing_rows(const std::string& dir, long first, long last, int checkpoint_step) {
  const std::string rows = first == last ? "row " + std::to_string(first)
                                         : "rows " + std::to_string(first) + ".." + std::to_string(last);
  throw std::invalid_argument("option -restart is invalid here: metrics.csv in '" + dir + "' lacks " + rows +
                              " (rows 1.." + std::to_string(checkpoint_step) +
                              " precede the checkpoint); restore it or run without -restart");
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

}  // namespace

FolderLock::FolderLock(MPI_Comm comm, const std::string& dir) {
  on_rank_zero(comm, [&] {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec || !std::filesystem::is_directory(dir))
      throw std::invalid_argument("option -output_dir = '" + dir +
                                  "' is invalid: it cannot be created: " + ec.message());
    std::string why;
    fd_ = lock_folder(dir, why);
    if (fd_ < 0) throw std::invalid_argument("option -output_dir = '" + dir + "' is invalid: " + why);
  });
}

FolderLock::~FolderLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the lock
}

RunOutput::RunOutput(MPI_Comm comm, const std::string& dir, const std::string& scene,
                     const std::vector<std::string>& columns, std::vector<std::string> command_line,
                     int resume_step)
    : comm_(comm),
      dir_(dir),
      scene_(scene),
      started_(utc_now()),
      command_line_(std::move(command_line)),
      columns_(columns),
      start_(MPI_Wtime()) {
  MPI_Comm_rank(comm, &rank_);
  MPI_Comm_size(comm, &size_);
  resumed_ = resume_step >= 0;
  on_rank_zero(comm, [&] {
    if (resumed_) {
      // A restart: the columns must be this run's (checked before anything is touched); the rows up to the
      // checkpoint's step stay (those after it, written before the run stopped, go), and the run appends.
      std::ifstream in(dir_ + "/metrics.csv");
      if (!in)
        throw std::invalid_argument("option -restart is invalid here: '" + dir_ +
                                    "' has a checkpoint but no metrics.csv (the rows before the checkpoint "
                                    "would be lost); restore it, or run without -restart");
      std::string line, kept;
      std::vector<std::string> existing;
      if (std::getline(in, line)) {
        kept = line + "\n";
        std::istringstream cols(line);
        for (std::string c; std::getline(cols, c, ',');) existing.push_back(c);
      }
      if (existing != columns_)
        throw std::invalid_argument("option -restart is invalid here: metrics.csv in '" + dir_ +
                                    "' has other columns than this run writes (written by another version?)");
      long next = 1;  // the step the next kept row must have: rows lost before the checkpoint leave a gap
      while (std::getline(in, line)) {
        const long step = std::strtol(line.c_str(), nullptr, 10);
        if (step < 1 || step > resume_step || line.find(',') == std::string::npos) continue;
        if (step > next) throw_missing_rows(dir_, next, step - 1, resume_step);
        next = std::max(next, step + 1);
        kept += line + "\n";
      }
      if (next <= resume_step) throw_missing_rows(dir_, next, resume_step, resume_step);
      in.close();
      std::error_code ec;
      for (const char* f : {"/summary.json", "/profile.csv", "/profile_mean.csv"})
        std::filesystem::remove(dir_ + f, ec);
      write_atomically(dir_ + "/metrics.csv", kept);
      write_atomically(dir_ + "/options.yaml", effective_options_yaml());
      csv_.open(dir_ + "/metrics.csv", std::ios::app);
      if (!csv_) throw std::runtime_error("cannot write '" + dir_ + "/metrics.csv'");
      return;
    }
    // A previous run's results (and its checkpoint, which -restart would otherwise resume) in this folder
    // would be mistaken for this run's: remove them first.
    for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
      const std::string name = entry.path().filename().string();
      const bool series = is_series_file(name);
      if (name == "summary.json" || name == "fluid.pvd" || name == "solid.pvd" || name == "profile.csv" ||
          name == "profile_mean.csv" || series)
        std::filesystem::remove(entry.path());
      if (name == "checkpoint" || name == "checkpoint.new" || name == "checkpoint.old")
        std::filesystem::remove_all(entry.path());
    }
    write_atomically(dir_ + "/options.yaml", effective_options_yaml());
    csv_.open(dir_ + "/metrics.csv", std::ios::trunc);
    if (!csv_) throw std::runtime_error("cannot write '" + dir_ + "/metrics.csv'");
    // The header now: a run that fails in its first step leaves the columns, not an empty file.
    for (size_t i = 0; i < columns_.size(); ++i) csv_ << (i ? "," : "") << columns_[i];
    csv_ << "\n";
    csv_.flush();
  });
}

void RunOutput::remove_series_except(const std::vector<std::string>& keep) const {
  if (rank_ != 0) return;
  for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
    const std::string name = entry.path().filename().string();
    // A piece of a parallel file (fluid_NNNNNN_pRRRR.vts) goes with its index (fluid_NNNNNN.pvts).
    const std::size_t piece = name.rfind("_p");
    const std::string owner =
        name.rfind("fluid_", 0) == 0 && piece != std::string::npos ? name.substr(0, piece) + ".pvts" : name;
    if (is_series_file(name) && std::find(keep.begin(), keep.end(), name) == keep.end() &&
        std::find(keep.begin(), keep.end(), owner) == keep.end())
      std::filesystem::remove(entry.path());
  }
}

void RunOutput::metrics_row(const std::vector<std::pair<std::string, double>>& row) {
  if (rank_ != 0) return;
  for (size_t i = 0; i < row.size() && i < columns_.size(); ++i)
    if (row[i].first != columns_[i])
      throw std::logic_error("metrics.csv: column " + std::to_string(i + 1) + " is '" + columns_[i] +
                             "', the row has '" + row[i].first + "'");
  if (row.size() != columns_.size())
    throw std::logic_error("metrics.csv: a row of " + std::to_string(row.size()) + " values for " +
                           std::to_string(columns_.size()) + " columns");
  for (size_t i = 0; i < row.size(); ++i) csv_ << (i ? "," : "") << std::setprecision(12) << row[i].second;
  csv_ << "\n";
  csv_.flush();
}

void RunOutput::progress(int step, int n_steps, double t, int newton, int linear, bool force) {
  if (rank_ != 0) return;
  const double now = MPI_Wtime();
  if (!force && now - last_print_ < 2.0 && step != n_steps) return;
  last_print_ = now;
  const double el = now - start_;
  const int done = step - first_step_;  // this run's steps (a restart started after first_step_)
  const double left = done > 0 ? el / done * (n_steps - step) : 0.0;
  std::printf("step %d/%d  t=%.5g s  %s %d  linear %d  elapsed %.1f s  left ~%.0f s\n", step, n_steps, t,
              iteration_kind_.c_str(), newton, linear, el, left);
  std::fflush(stdout);
}

void RunOutput::summary(const std::string& status, int steps, long newton, long linear,
                        const std::vector<std::pair<std::string, double>>& metrics,
                        const std::vector<std::pair<std::string, std::string>>& text) {
  on_rank_zero(comm_, [&] { write_summary(status, steps, newton, linear, metrics, text); });
}

void RunOutput::write_summary(const std::string& status, int steps, long newton, long linear,
                              const std::vector<std::pair<std::string, double>>& metrics,
                              const std::vector<std::pair<std::string, std::string>>& text) const {
  nlohmann::ordered_json js;
  js["scene"] = scene_;
  js["status"] = status;
  js["cellfsi_version"] = CELLFSI_VERSION;
  js["commit"] = build_commit();
  js["command_line"] = shell_words(command_line_);
  js["started_utc"] = started_;
  js["wall_time_s"] = elapsed();  // this invocation's: after a -restart, from resumed_from_step on
  if (resumed_) js["resumed_from_step"] = first_step_;
  js["steps"] = steps;
  js[iteration_kind_ + "_iterations"] = newton;
  js["linear_iterations"] = linear;
  js["ranks"] = size_;
  for (const auto& [k, v] : metrics) {
    if (std::isfinite(v))
      js[k] = v;
    else
      js[k] = nullptr;
  }
  for (const auto& [k, v] : text) js[k] = v;
  write_atomically(dir_ + "/summary.json", js.dump(2) + "\n");
}

}  // namespace cellfsi::app
