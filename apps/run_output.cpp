#include "apps/run_output.hpp"

#include <petscsys.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <sstream>
#include <stdexcept>

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

namespace {

/// The options database as YAML (flat keys, re-runnable with -options_file_yaml).
std::string options_yaml() {
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

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  std::ostringstream os;
  os << std::setprecision(12) << v;
  return os.str();
}

}  // namespace

RunOutput::RunOutput(MPI_Comm comm, const std::string& dir, const std::string& scene)
    : comm_(comm), dir_(dir), scene_(scene), start_(MPI_Wtime()) {
  MPI_Comm_rank(comm, &rank_);
  MPI_Comm_size(comm, &size_);
  int ok = 1;
  std::string why;
  if (rank_ == 0) {
    std::error_code ec;
    std::filesystem::create_directories(dir_, ec);
    if (ec || !std::filesystem::is_directory(dir_)) {
      ok = 0;
      why = ec.message();
    }
  }
  MPI_Bcast(&ok, 1, MPI_INT, 0, comm);
  if (!ok) throw std::invalid_argument("-output_dir '" + dir_ + "' cannot be created: " + why);
  if (rank_ == 0) {
    // A previous run's results in this folder would be mistaken for this run's: remove them first.
    for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
      const std::string name = entry.path().filename().string();
      if (name == "summary.json" || name == "fluid.pvd" || name == "profile.csv" ||
          (name.rfind("fluid_", 0) == 0 && entry.path().extension() == ".vts"))
        std::filesystem::remove(entry.path());
    }
    write_atomically(dir_ + "/options.yaml", options_yaml());
    csv_.open(dir_ + "/metrics.csv", std::ios::trunc);
    if (!csv_) throw std::runtime_error("cannot write '" + dir_ + "/metrics.csv'");
  }
}

void RunOutput::metrics_columns(const std::vector<std::string>& names) {
  if (rank_ != 0) return;
  if (!columns_.empty()) throw std::logic_error("metrics.csv: the columns are already written");
  columns_ = names;
  for (size_t i = 0; i < names.size(); ++i) csv_ << (i ? "," : "") << names[i];
  csv_ << "\n";
  csv_.flush();
}

void RunOutput::metrics_row(const std::vector<std::pair<std::string, double>>& row) {
  if (rank_ != 0) return;
  if (columns_.empty()) {
    std::vector<std::string> names;
    for (const auto& kv : row) names.push_back(kv.first);
    metrics_columns(names);
  }
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
  const double left = step > 0 ? el / step * (n_steps - step) : 0.0;
  std::printf("step %d/%d  t=%.5g s  newton %d  linear %d  elapsed %.1f s  left ~%.0f s\n", step, n_steps, t,
              newton, linear, el, left);
  std::fflush(stdout);
}

void RunOutput::summary(const std::string& status, int steps, long newton, long linear,
                        const std::vector<std::pair<std::string, double>>& metrics,
                        const std::vector<std::pair<std::string, std::string>>& text) {
  if (rank_ != 0) return;
  std::ostringstream os;
  os << "{\n  \"scene\": \"" << scene_ << "\",\n  \"status\": \"" << status
     << "\",\n  \"wall_time_s\": " << json_number(elapsed()) << ",\n  \"steps\": " << steps
     << ",\n  \"newton_iterations\": " << newton << ",\n  \"linear_iterations\": " << linear
     << ",\n  \"ranks\": " << size_;
  for (auto& [k, v] : metrics) os << ",\n  \"" << k << "\": " << json_number(v);
  for (auto& [k, v] : text) os << ",\n  \"" << k << "\": \"" << v << "\"";  // plain words (regimes)
  os << "\n}\n";
  write_atomically(dir_ + "/summary.json", os.str());
}

}  // namespace cellfsi::app
