#include "apps/run_output.hpp"

#include <dlfcn.h>
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
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "apps/build_info.hpp"
#include "common/file_io.hpp"

namespace cellfsi::app {

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

/// The file that marks a folder as cellfsi's own (claim_folder).
constexpr const char* kOwnerMark = ".cellfsi-output";

/// A file of the fluid or solid series: fluid_NNNNNN.vts, its parallel form fluid_NNNNNN.pvts with pieces
/// fluid_NNNNNN_pRRRR.vts, solid_BODY_NNNNNN.vts.
bool is_series_file(const std::string& name) {
  const std::string ext = std::filesystem::path(name).extension().string();
  return (name.rfind("fluid_", 0) == 0 || name.rfind("solid_", 0) == 0) && (ext == ".vts" || ext == ".pvts");
}

/// The names cellfsi writes in an output folder (a file's temporary ".tmp" form included).
bool is_cellfsi_output(std::string name) {
  if (name.size() > 4 && name.compare(name.size() - 4, 4, ".tmp") == 0) name.resize(name.size() - 4);
  static const char* const kFiles[] = {"options.yaml", "metrics.csv", "summary.json", "profile.csv",
                                       "profile_mean.csv", "fluid.pvd", "solid.pvd", "checkpoint",
                                       "checkpoint.new", "checkpoint.old", kOwnerMark, ".cellfsi.lock"};
  for (const char* f : kFiles)
    if (name == f) return true;
  return is_series_file(name);
}

/// Whether cellfsi made DIR: its mark, or the lock file that cellfsi versions before the mark left in
/// every output folder.
bool owned_by_cellfsi(const std::filesystem::path& dir) {
  std::error_code ec;
  return std::filesystem::exists(dir / kOwnerMark, ec) || std::filesystem::exists(dir / ".cellfsi.lock", ec);
}

/// Makes DIR this run's output folder: creates it (and marks it) if missing; takes an empty folder; refuses
/// a non-empty folder cellfsi did not make, unless `adopt`, and then still refuses one that holds files of
/// the names cellfsi writes (they would be replaced or deleted). Throws std::invalid_argument naming the
/// option.
void claim_folder(const std::string& dir, bool adopt) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const std::string bad = "option -output_dir = '" + dir + "' is invalid: ";
  const bool existed = fs::exists(dir, ec);
  if (existed && !fs::is_directory(dir, ec)) throw std::invalid_argument(bad + "it is a file, not a folder");
  if (!existed) {
    fs::create_directories(dir, ec);
    if (ec || !fs::is_directory(dir))
      throw std::invalid_argument(bad + "it cannot be created: " + ec.message());
  } else if (!owned_by_cellfsi(dir)) {
    std::vector<std::string> names, clashes;
    for (const auto& entry : fs::directory_iterator(dir, ec)) {
      names.push_back(entry.path().filename().string());
      if (is_cellfsi_output(names.back())) clashes.push_back(names.back());
    }
    if (ec) throw std::invalid_argument(bad + "it cannot be read: " + ec.message());
    auto listed = [](const std::vector<std::string>& v) {
      std::string l;
      for (size_t i = 0; i < v.size() && i < 5; ++i) l += (i ? ", " : "") + v[i];
      return v.size() > 5 ? l + ", ... (" + std::to_string(v.size()) + " in all)" : l;
    };
    if (!names.empty() && !adopt)
      throw std::invalid_argument(
          bad + "the folder is not empty and was not made by cellfsi (it holds " + listed(names) +
          "); cellfsi would replace or delete files in it. Choose a new or empty folder, or give "
          "-output_dir_adopt to write into it beside its files");
    if (!clashes.empty())
      throw std::invalid_argument(bad + "it holds files of the names cellfsi writes (" + listed(clashes) +
                                  "), which -output_dir_adopt does not replace; move them or choose "
                                  "another folder");
  }
  if (!owned_by_cellfsi(dir))
    write_file_atomically((fs::path(dir) / kOwnerMark).string(),
                          "This folder is a cellfsi output folder: cellfsi may replace the files it writes "
                          "here (options.yaml, metrics.csv, summary.json, the .pvd series, checkpoint/).\n");
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

FolderLock::FolderLock(MPI_Comm comm, const std::string& dir, bool adopt) {
  on_rank_zero(comm, [&] {
    claim_folder(dir, adopt);
    std::string why;
    fd_ = lock_folder(dir, why);
    if (fd_ < 0) throw std::invalid_argument("option -output_dir = '" + dir + "' is invalid: " + why);
  });
}

FolderLock::~FolderLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the lock
}

RunOutput::RunOutput(MPI_Comm comm, const std::string& dir, const std::string& scene,
                     const std::vector<std::string>& columns, const std::string& options_yaml,
                     std::vector<std::string> command_line, int resume_step)
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
    const std::string csv_path = dir_ + "/metrics.csv";
    if (resumed_) {
      // A restart: the columns must be this run's (checked before anything is touched); the rows up to the
      // checkpoint's step stay (those after it, written before the run stopped, go), and the run appends.
      // The previous summary.json stays until this run writes its own: a restart that cannot write (a full
      // disk) must not cost the summary of the run it continues.
      std::ifstream in(csv_path);
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
      write_file_atomically(csv_path, kept);
      write_file_atomically(dir_ + "/options.yaml", options_yaml);
    } else {
      // A previous run's results (and its checkpoint, which -restart would otherwise resume) in this folder
      // would be mistaken for this run's: remove them first. Only names cellfsi writes, in a folder cellfsi
      // owns (FolderLock).
      for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
        const std::string name = entry.path().filename().string();
        if (name == "summary.json" || name == "fluid.pvd" || name == "solid.pvd" || name == "profile.csv" ||
            name == "profile_mean.csv" || is_series_file(name))
          std::filesystem::remove(entry.path());
        if (name == "checkpoint" || name == "checkpoint.new" || name == "checkpoint.old")
          std::filesystem::remove_all(entry.path());
      }
      write_file_atomically(dir_ + "/options.yaml", options_yaml);
      // The header now: a run that fails in its first step leaves the columns, not an empty file.
      std::string header;
      for (size_t i = 0; i < columns_.size(); ++i) header += (i ? "," : "") + columns_[i];
      write_file_atomically(csv_path, header + "\n");
    }
    csv_fd_ = ::open(csv_path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
    if (csv_fd_ < 0) throw_write_error(csv_path, std::strerror(errno));
  });
}

RunOutput::~RunOutput() {
  if (csv_fd_ >= 0) ::close(csv_fd_);
}

void RunOutput::remove_series_except(const std::vector<std::string>& keep) const {
  on_rank_zero(comm_, [&] {
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
  });
}

void RunOutput::metrics_row(const std::vector<std::pair<std::string, double>>& row) {
  // Collective: a failed write on rank 0 must stop every rank, not leave them in the next collective call.
  on_rank_zero(comm_, [&] {
    for (size_t i = 0; i < row.size() && i < columns_.size(); ++i)
      if (row[i].first != columns_[i])
        throw std::logic_error("metrics.csv: column " + std::to_string(i + 1) + " is '" + columns_[i] +
                               "', the row has '" + row[i].first + "'");
    if (row.size() != columns_.size())
      throw std::logic_error("metrics.csv: a row of " + std::to_string(row.size()) + " values for " +
                             std::to_string(columns_.size()) + " columns");
    std::ostringstream line;
    line << std::setprecision(12);
    for (size_t i = 0; i < row.size(); ++i) line << (i ? "," : "") << row[i].second;
    line << "\n";
    // A row is written whole or not at all: a failed write (a full disk, a file-size limit) is cut back to
    // the previous row's end, so metrics.csv never ends in half a row, and reported naming the file.
    const std::string text = line.str();
    const off_t end = ::lseek(csv_fd_, 0, SEEK_END);
    if (const int err = write_all(csv_fd_, text.data(), text.size()); err != 0) {
      if (end >= 0 && ::ftruncate(csv_fd_, end) != 0) {
        // The partial row stays; a restart drops rows it cannot read.
      }
      throw_write_error(dir_ + "/metrics.csv", std::strerror(err));
    }
  });
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

namespace {

/// The BLAS the run used, for comparing timings: OpenBLAS's kernels ("Haswell", "SkylakeX", ...) and whether
/// OPENBLAS_CORETYPE chose them. Its kernels set the speed of the region's LU (docs/design.md §5).
std::string blas_description() {
  using Text = char* (*)();
  const auto core = reinterpret_cast<Text>(dlsym(RTLD_DEFAULT, "openblas_get_corename"));
  if (!core || !core()) return "not OpenBLAS";
  const char* set = std::getenv("OPENBLAS_CORETYPE");
  return "OpenBLAS, " + std::string(core()) + " kernels (" +
         (set ? "OPENBLAS_CORETYPE=" + std::string(set) : std::string("its own choice")) + ")";
}

}  // namespace

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
  js["blas"] = blas_description();
  for (const auto& [k, v] : metrics) {
    if (std::isfinite(v))
      js[k] = v;
    else
      js[k] = nullptr;
  }
  for (const auto& [k, v] : text) js[k] = v;
  write_file_atomically(dir_ + "/summary.json", js.dump(2) + "\n");
}

}  // namespace cellfsi::app
