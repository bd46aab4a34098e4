#pragma once
// The run contract of docs/design.md §4: DIR/options.yaml (effective options), DIR/metrics.csv (one row per
// step, named columns), DIR/summary.json (scalars and final metrics), and a progress line. Rank 0 writes;
// every file is rewritten atomically or appended line by line, so a run that stops mid-way leaves what it
// wrote intact. The folder is locked for the run (DIR/.cellfsi.lock, flock): a second run on it is refused
// instead of interleaving its files with this one's.
#include <mpi.h>

#include "common/collective.hpp"

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace cellfsi::app {


/// The output folder locked for one run (DIR/.cellfsi.lock, flock on rank 0: released by the kernel however
/// the process ends). Creates DIR and marks it as cellfsi's (DIR/.cellfsi-output). Collective; throws
/// std::invalid_argument on every rank if DIR cannot be made, another run holds it, or it is a non-empty
/// folder that cellfsi did not make: a run there would replace or delete the user's files.
class FolderLock {
 public:
  /// `adopt` (-output_dir_adopt): DIR may be a non-empty folder cellfsi did not make (see claim_folder in
  /// run_output.cpp: the files of the names cellfsi writes must not be in it).
  FolderLock(MPI_Comm comm, const std::string& dir, bool adopt = false);
  ~FolderLock();
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  int fd_ = -1;
};

class RunOutput {
 public:
  /// In DIR (made and locked by a FolderLock the caller holds for the run): removes a previous run's results
  /// (and its checkpoint) and writes DIR/options.yaml (`options_yaml`, given_options_yaml's text) and
  /// metrics.csv's header (`columns`; the rows must then have them). `command_line`: the arguments as given
  /// (recorded in summary.json). Every write is checked: cellfsi::WriteError (as std::runtime_error on every
  /// rank) names the file and the system's reason.
  /// `resume_step` >= 0: a restart from the checkpoint after that step: metrics.csv must have the same
  /// columns (else std::invalid_argument before any file is touched), keeps the rows up to that step and
  /// grows from there; the series files stay (see also remove_series_except). Collective.
  RunOutput(MPI_Comm comm, const std::string& dir, const std::string& scene,
            const std::vector<std::string>& columns, const std::string& options_yaml,
            std::vector<std::string> command_line = {}, int resume_step = -1);
  ~RunOutput();
  RunOutput(const RunOutput&) = delete;
  RunOutput& operator=(const RunOutput&) = delete;
  const std::string& dir() const { return dir_; }

  /// Removes the fluid_*.vts and solid_*.vts files of the folder that are not in `keep` (a restart: those
  /// written after its checkpoint). Rank 0.
  void remove_series_except(const std::vector<std::string>& keep) const;
  /// Appends one row to metrics.csv (the constructor's columns, in order), whole or not at all; throws
  /// cellfsi::WriteError if it cannot be written. Rank 0.
  void metrics_row(const std::vector<std::pair<std::string, double>>& row);
  /// What an iteration of a step is: "newton" (a fluid-only run's Newton iterations) or "coupling" (a coupled
  /// run's block iterations); names the summary's "<kind>_iterations" and the progress line.
  void set_iteration_kind(const std::string& kind) { iteration_kind_ = kind; }
  /// Prints "step k/n  t=...  newton ..  linear ..  elapsed ..  left ~.." at most every `every_seconds`.
  void progress(int step, int n_steps, double t, int newton, int linear, bool force = false);

  /// Writes summary.json (collective; atomically, so a failed write leaves the previous one): what ran (scene, cellfsi version, source revision, command line, start
  /// time), the status ("completed", or why and where it stopped), the fixed scalars, `metrics` (non-finite
  /// values as null) and the words in `text`.
  void summary(const std::string& status, int steps, long newton, long linear,
               const std::vector<std::pair<std::string, double>>& metrics,
               const std::vector<std::pair<std::string, std::string>>& text = {});
  double elapsed() const { return MPI_Wtime() - start_; }
  /// Steps before this run's first (a restart's), so that the progress line's estimate counts only this
  /// run's.
  void set_first_step(int step) { first_step_ = step; }

 private:
  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
  std::string dir_, scene_, started_;
  std::vector<std::string> command_line_;
  bool resumed_ = false;
  int first_step_ = 0;
  void write_summary(const std::string& status, int steps, long newton, long linear,
                     const std::vector<std::pair<std::string, double>>& metrics,
                     const std::vector<std::pair<std::string, std::string>>& text) const;
  std::string iteration_kind_ = "newton";
  std::vector<std::string> columns_;
  int csv_fd_ = -1;  // metrics.csv, appended to (rank 0)
  double start_ = 0, last_print_ = -1e9;
};


/// The whole options database, including the defaults the program set itself, as flat "key: value" lines:
/// what a checkpoint and the two sides of a job compare (not options.yaml: see given_options_yaml).
std::string effective_options_yaml();

}  // namespace cellfsi::app
