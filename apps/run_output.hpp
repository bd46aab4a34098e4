#pragma once
// The run contract of DESIGN.md section 4: DIR/options.yaml (effective options), DIR/metrics.csv (one row per
// step, named columns), DIR/summary.json (scalars and final metrics), and a progress line. Rank 0 writes;
// every file is rewritten atomically or appended line by line, so a run that stops mid-way leaves what it
// wrote intact. The folder is locked for the run (DIR/.cellfsi.lock, flock): a second run on it is refused
// instead of interleaving its files with this one's.
#include <mpi.h>

#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace cellfsi::app {

class RunOutput {
 public:
  /// Creates DIR (rank 0), locks it, removes a previous run's results and writes DIR/options.yaml from the
  /// options database. Throws std::invalid_argument if DIR cannot be made or another run holds it.
  /// `command_line`: the arguments as given (recorded in summary.json).
  /// `resume_step` >= 0: a restart from the checkpoint after that step: metrics.csv keeps its header and the
  /// rows up to that step and grows from there, the series files stay (see also remove_series_except).
  RunOutput(MPI_Comm comm, const std::string& dir, const std::string& scene,
            std::vector<std::string> command_line = {}, int resume_step = -1);
  ~RunOutput();
  RunOutput(const RunOutput&) = delete;
  RunOutput& operator=(const RunOutput&) = delete;
  const std::string& dir() const { return dir_; }

  /// Removes the fluid_*.vts and solid_*.vts files of the folder that are not in `keep` (a restart: those
  /// written after its checkpoint). Rank 0.
  void remove_series_except(const std::vector<std::string>& keep) const;
  /// Writes metrics.csv's header now (a run that fails in its first step leaves the columns, not an empty
  /// file); the rows must then have these columns.
  void metrics_columns(const std::vector<std::string>& names);
  /// Appends one row to metrics.csv; the first call fixes the columns (in the given order) unless
  /// metrics_columns did.
  void metrics_row(const std::vector<std::pair<std::string, double>>& row);
  /// What an iteration of a step is: "newton" (a fluid-only run's Newton iterations) or "coupling" (a coupled
  /// run's block iterations); names the summary's "<kind>_iterations" and the progress line.
  void set_iteration_kind(const std::string& kind) { iteration_kind_ = kind; }
  /// Prints "step k/n  t=...  newton ..  linear ..  elapsed ..  left ~.." at most every `every_seconds`.
  void progress(int step, int n_steps, double t, int newton, int linear, bool force = false);

  /// Writes summary.json: what ran (scene, cellfsi version, source revision, command line, start time), the
  /// status ("completed", or why and where it stopped), the fixed scalars, `metrics` (non-finite values as
  /// null) and the words in `text`.
  void summary(const std::string& status, int steps, long newton, long linear,
               const std::vector<std::pair<std::string, double>>& metrics,
               const std::vector<std::pair<std::string, std::string>>& text = {});
  double elapsed() const { return MPI_Wtime() - start_; }

 private:
  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
  std::string dir_, scene_, started_;
  std::vector<std::string> command_line_;
  int lock_fd_ = -1;
  bool resumed_ = false;
  std::string iteration_kind_ = "newton";
  std::vector<std::string> columns_;
  std::ofstream csv_;
  double start_ = 0, last_print_ = -1e9;
};

/// Writes text to path atomically (temporary file + rename).
void write_atomically(const std::string& path, const std::string& text);
/// The options database as options.yaml writes it (flat keys, re-runnable with -options_file_yaml).
std::string effective_options_yaml();

}  // namespace cellfsi::app
