#pragma once
// One run of a scene on the fluid side (and, without a solid group, the bodies too), as named phases:
//
//   1. set_up            settings, the scene, the cheap and the expensive checks, the fluid's set-up, the
//                        handshake with a solid group;
//   2. connect_bodies    the bodies: built here, or stand-ins for those a solid group owns; the coupling
//                        solver's option checks;
//   3. take_folder       the output folder locked and owned (apps/run_output.hpp); a restart's checkpoint
//   read;
//   4. open_output       options.yaml, metrics.csv, the series writers;
//   5. step_loop         the time steps: a row per step, the series, checkpoints, stop requests;
//   6. finish            the final checkpoint, the profiles, then summary.json "completed".
//
// Exit codes as launch() documents them: a stop request during set-up ends the run at the end of the phase in
// progress (128 + signal), one during the steps after the step in progress; bad input throws
// std::invalid_argument (exit 1); a failure mid-way is written to summary.json, with where it happened, and
// thrown on (exit 2). The run contract: docs/running.md.
#include <mpi.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "apps/checkpoint.hpp"
#include "apps/handshake.hpp"
#include "apps/run_output.hpp"
#include "apps/scene.hpp"
#include "coupling/remote_solid.hpp"
#include "fluid/fluid_output.hpp"
#include "solid/solid_output.hpp"

namespace cellfsi::app {

/// Mailbox per rank for the fluid/solid shared-memory exchange [bytes] (payloads above it go as messages);
/// the same on both sides.
inline constexpr std::size_t kExchangeMailboxBytes = 8u << 20;

/// What a run records of how it was launched: the arguments as given (summary.json, options.yaml) and the
/// scene file read (empty: none).
struct LaunchRecord {
  std::vector<std::string> command_line;
  std::string scene_file;
};

class FluidRun {
 public:
  /// inter: the intercommunicator to the solid group (MPI_COMM_NULL: the bodies live in this process).
  FluidRun(MPI_Comm inter, Handshake& hs, LaunchRecord launch);
  FluidRun(const FluidRun&) = delete;
  FluidRun& operator=(const FluidRun&) = delete;
  ~FluidRun();

  /// The phases in order; the exit code (0 completed or -help, 2 diverged, 128 + S stopped by signal S).
  int run(const std::string& default_name);

 private:
  using Metrics = std::vector<std::pair<std::string, double>>;

  int set_up(const std::string& default_name);  // 0: go on; > 0: the exit code; -1: -help done
  int stop_requested_during_set_up();           // the signal agreed on, told to a waiting solid side
  void connect_bodies();
  void take_folder();
  void restore_checkpoint();
  void open_output();
  int stopped_before_the_first_step();  // the last look before the steps: 0 or the exit code
  int step_loop();
  int stop_after_step(int signal, int k, bool series_written);
  void finish();

  void write_series();
  /// Says once per body when the output's samples find it folded (J <= 0) where the solver does not look.
  void notice_folds(const std::vector<solid::SmallestJ>& smallest);
  void write_checkpoint_after(int k);
  /// The options a checkpoint records and a restart compares: the options database, with the scene's name
  /// when the database lacks it (the scene file's stem), so that a restart from the run's options.yaml,
  /// which names the scene, continues the same run.
  std::string checkpoint_options() const;
  /// summary.json for a failed run; if it cannot be written either, a note for the message (the previous
  /// summary.json stays).
  std::string summary_of_failure(const std::string& status);
  /// Rethrows `e` with where it happened and the note of summary_of_failure.
  [[noreturn]] void fail(const std::exception& e, const std::string& where);
  Metrics final_metrics(bool with_solver_size) const;
  /// Per body, what the output's samples found of J over the run (JHistory): <body>_output_min_J and its
  /// _time, <body>_fold_time and _fold_J of the first write that found J <= 0 (NaN, null in summary.json:
  /// none).
  Metrics fold_metrics() const;
  std::vector<std::pair<std::string, std::string>> final_words() const;

  MPI_Comm inter_;
  Handshake& hs_;
  LaunchRecord launch_;
  int rank_ = 0, size_ = 1, solid_ranks_ = 0, n_steps_ = 0;

  // Declared in the order they must be built; destroyed in reverse (the solid side is told to stop before
  // the exchange and the bodies go, the folder's lock is released last of the output).
  std::vector<std::string> user_options_;
  SceneSettings settings_;
  std::unique_ptr<Scene> scene_;
  std::vector<std::unique_ptr<solid::SolidSolver>> owned_;
  std::vector<std::unique_ptr<coupling::RemoteSolid>> remote_;
  std::unique_ptr<coupling::Exchange> exchange_;
  std::vector<solid::SolidSolver*> bodies_;
  struct SolidShutdown {
    coupling::Exchange* exchange = nullptr;
    ~SolidShutdown();
  } shutdown_;
  std::unique_ptr<FolderLock> lock_;
  Checkpoint resume_;
  std::unique_ptr<RunOutput> out_;
  std::unique_ptr<fluid::FluidSeriesWriter> series_;
  std::unique_ptr<solid::SolidSeriesWriter> solid_series_;
  std::vector<bool> fold_noticed_;

  // The counters of the steps (a restart's start from the checkpoint's).
  long newton_ = 0, linear_ = 0, factorizations_ = 0, bulk_factorizations_ = 0;
  int done_ = 0;          // steps completed
  int current_step_ = 0;  // the step being computed or written, for a failure's message
  Metrics last_;          // the last step's metrics
};

}  // namespace cellfsi::app
