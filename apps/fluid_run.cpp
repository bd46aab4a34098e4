#include "apps/fluid_run.hpp"

#include <petscsys.h>

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <limits>
#include <sstream>

#include "apps/interrupt.hpp"
#include "apps/option_checks.hpp"
#include "apps/scene_file.hpp"
#include "common/file_io.hpp"
#include "common/petsc_error.hpp"

namespace cellfsi::app {

namespace {

/// A stop request during the set-up, before the output folder is the run's: the message, and the exit code
/// 128 + sig.
int stopped_during_set_up(int sig) {
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                            "cellfsi: stopped by %s during set-up, before the first step; nothing written\n",
                            signal_name(sig).c_str()));
  return 128 + sig;
}

/// The velocity profile of a section as CSV (x, y, z, vx, vy, vz).
std::string profile_csv(const fluid::SectionData& sec) {
  std::ostringstream csv;
  csv << std::setprecision(12) << "x,y,z,vx,vy,vz\n";
  for (size_t i = 0; i < sec.points.size(); ++i)
    csv << sec.points[i][0] << "," << sec.points[i][1] << "," << sec.points[i][2] << "," << sec.velocity[i][0]
        << "," << sec.velocity[i][1] << "," << sec.velocity[i][2] << "\n";
  return csv.str();
}

std::string where_text(const char* format, int step, double time) {
  char where[128];
  std::snprintf(where, sizeof where, format, step, time);
  return where;
}

}  // namespace

FluidRun::SolidShutdown::~SolidShutdown() {
  // Once the exchange exists, the solid side is told to stop whatever happens.
  if (exchange) coupling::shutdown_solids(*exchange, PETSC_COMM_WORLD);
}

FluidRun::FluidRun(MPI_Comm inter, Handshake& hs, LaunchRecord launch)
    : inter_(inter), hs_(hs), launch_(std::move(launch)) {
  MPI_Comm_size(PETSC_COMM_WORLD, &size_);
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank_);
}

FluidRun::~FluidRun() = default;

int FluidRun::run(const std::string& default_name) {
  if (const int code = set_up(default_name); code != 0) return code < 0 ? 0 : code;
  connect_bodies();
  if (const int sig = agreed_stop_signal(PETSC_COMM_WORLD)) return stopped_during_set_up(sig);
  take_folder();
  open_output();
  if (const int code = stopped_before_the_first_step()) return code;
  if (const int code = step_loop()) return code;
  finish();
  return 0;
}

int FluidRun::stop_requested_during_set_up() {
  // A stop request during the set-up (3D meshes take minutes) is honoured at the end of each of its phases
  // instead of after the set-up and a whole first step; a solid side still waiting at the handshake stops
  // too.
  const int sig = agreed_stop_signal(PETSC_COMM_WORLD);
  if (sig != 0) hs_.agree(-sig);
  return sig;
}

int FluidRun::set_up(const std::string& default_name) {
  user_options_ = option_names();
  settings_ = SceneSettings::from_options(default_name);
  PetscBool help = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-help", &help));
  scene_ = std::make_unique<Scene>(PETSC_COMM_WORLD, settings_);
  if (help) {
    hs_.agree(1);
    return -1;
  }
  if (const int sig = stop_requested_during_set_up()) return stopped_during_set_up(sig);
  if (inter_ != MPI_COMM_NULL) check_bodies_on_solid_ranks(settings_);
  check_bodies(settings_, scene_->fluid().patch());
  if (const int sig = stop_requested_during_set_up()) return stopped_during_set_up(sig);
  // A run without cells solves with the fluid's own SNES and KSP, set up now so that misspelt options of its
  // inner solvers are reported before any step; a coupled run solves with the coupling loop's KSP instead.
  if (settings_.bodies.empty()) scene_->fluid().setup();
  reject_unknown_options(OptionCheck::before_coupling);
  if (const int sig = stop_requested_during_set_up()) return stopped_during_set_up(sig);
  if (const int other = hs_.agree(2, effective_options_yaml()); other < 0)
    return stopped_during_set_up(-other);  // the solid side was stopped during its set-up
  else if (other != 2)
    throw std::invalid_argument("the solid side stopped at start-up (see its message)");
  if (hs_.split())
    if (const std::string diff = split_option_differences(effective_options_yaml(), hs_.remote_options());
        !diff.empty())
      throw std::invalid_argument(
          "the fluid and the solid side were given different options (fluid side -> solid side: " + diff +
          "); give both executables the same scene and options");
  n_steps_ = static_cast<int>(std::ceil(settings_.final_time / settings_.dt - 1e-9));
  return 0;
}

void FluidRun::connect_bodies() {
  if (inter_ == MPI_COMM_NULL) {
    // The bodies live in this process (every rank holds a copy and does the same, cheap, solid work).
    owned_ = build_bodies(settings_);
    for (auto& b : owned_) bodies_.push_back(b.get());
  } else {
    exchange_ = std::make_unique<coupling::Exchange>(inter_, kExchangeMailboxBytes);
    shutdown_.exchange = exchange_.get();
    solid_ranks_ = exchange_->remote_size();
    for (size_t i = 0; i < settings_.bodies.size(); ++i) {
      const BodySettings& b = settings_.bodies[i];
      remote_.push_back(
          std::make_unique<coupling::RemoteSolid>(*exchange_, PETSC_COMM_WORLD, static_cast<int>(i), b.name,
                                                  build_body_patch(settings_, b), b.membrane()));
      remote_.back()->hello();
      bodies_.push_back(remote_.back().get());
    }
  }
  scene_->attach_bodies(bodies_);
  const coupling::FsiCoupler* coupler = scene_->coupler();
  if (coupler) reject_inapplicable_solver_options(user_options_, coupler->linear_solver().pc_type());
  reject_unknown_options(OptionCheck::before_first_step);
}

void FluidRun::take_folder() {
  // A restart without a checkpoint is refused before the lock would create the folder and its lock file.
  if (settings_.restart) on_rank_zero(PETSC_COMM_WORLD, [&] { require_checkpoint(settings_.output_dir); });
  // The folder is this run's from here on (before a restart reads its checkpoint: another run may be writing
  // one).
  lock_ = std::make_unique<FolderLock>(PETSC_COMM_WORLD, settings_.output_dir, settings_.output_dir_adopt);
  if (settings_.restart) restore_checkpoint();
  newton_ = resume_.newton, linear_ = resume_.linear, factorizations_ = resume_.factorizations;
  bulk_factorizations_ = resume_.bulk_factorizations;
  done_ = resume_.step;
}

void FluidRun::restore_checkpoint() {
  // The checkpoint must come from a run with the same options (but the final time and the output
  // intervals: checked before the state is read); the fluid takes its state there, the scene then its own.
  resume_ = read_checkpoint(PETSC_COMM_WORLD, settings_.output_dir, checkpoint_options(), scene_->fluid());
  std::vector<std::string> names;
  for (const solid::SolidSolver* b : scene_->bodies()) names.push_back(b->name());
  if (names != resume_.body_names)
    throw std::invalid_argument(
        "option -restart is invalid here: the checkpoint's bodies differ from the "
        "scene's");
  if (resume_.step >= n_steps_) {
    char msg[256];
    std::snprintf(msg, sizeof msg,
                  "option -final_time = %g is invalid with -restart: the checkpoint in '%s' is at t = %g s "
                  "(after %d steps); valid: a later time",
                  settings_.final_time, settings_.output_dir.c_str(), resume_.time, resume_.step);
    throw std::invalid_argument(msg);
  }
  scene_->restore(resume_.bodies, resume_.trackers);
  scene_->restore_metric_state(resume_.scene_metrics);
}

void FluidRun::open_output() {
  // metrics.csv's columns: those of every step's row (the metrics' names now).
  const bool coupled = scene_->coupler() != nullptr;
  std::vector<std::string> columns{"step", "time", coupled ? "coupling_iterations" : "newton_iterations",
                                   "linear_iterations"};
  if (coupled) columns.emplace_back("factorizations");
  for (const auto& kv : scene_->metrics()) columns.push_back(kv.first);
  out_ = std::make_unique<RunOutput>(
      PETSC_COMM_WORLD, settings_.output_dir, settings_.name, columns,
      given_options_yaml(launch_.scene_file, launch_.command_line, settings_.name), launch_.command_line,
      settings_.restart ? resume_.step : -1);
  out_->set_first_step(resume_.step);
  // A coupled run's iterations are the coupling loop's block iterations, not Newton iterations.
  out_->set_iteration_kind(coupled ? "coupling" : "newton");
  if (settings_.output_every > 0) {
    series_ = std::make_unique<fluid::FluidSeriesWriter>(settings_.output_dir);
    if (!bodies_.empty() && scene_->undisturbed_velocity())
      series_->set_undisturbed_velocity(scene_->undisturbed_velocity());
    if (!bodies_.empty())
      solid_series_ = std::make_unique<solid::SolidSeriesWriter>(settings_.output_dir, rank_ == 0);
    if (settings_.restart) {
      series_->resume(resume_.fluid_series);
      if (solid_series_) solid_series_->resume(resume_.solid_series, resume_.solid_writes, resume_.solid_J);
    } else {
      write_series();
    }
  }
  if (settings_.restart) {
    // Series files written after the checkpoint (before the run stopped) belong to no series now.
    std::vector<std::string> keep;
    for (const auto* list : {&resume_.fluid_series, &resume_.solid_series})
      for (const geometry::PvdEntry& e : *list) keep.push_back(e.file);
    out_->remove_series_except(keep);
  }
  CELLFSI_PETSC(PetscPrintf(
      PETSC_COMM_WORLD,
      "cellfsi %s: %s, %d fluid ranks%s, %zu bodies, %d steps of %g s to t = %g s, output in %s\n",
      CELLFSI_VERSION, settings_.name.c_str(), size_,
      solid_ranks_ ? (" + " + std::to_string(solid_ranks_) + " solid ranks").c_str() : "", bodies_.size(),
      n_steps_, settings_.dt, n_steps_ * settings_.dt, settings_.output_dir.c_str()));
  if (coupled && settings_.coupling.linear.pc_type.empty())
    CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD, "cellfsi: the coupled solve uses -coupling_pc_type %s\n",
                              scene_->coupler()->linear_solver().pc_type().c_str()));
  if (const coupling::Repulsion* r = coupled ? scene_->coupler()->repulsion() : nullptr)
    CELLFSI_PETSC(
        PetscPrintf(PETSC_COMM_WORLD,
                    "cellfsi: contact repulsion below %.4g cm (-coupling_repulsion_cutoff), pressure "
                    "scale %.4g dyn/cm^2 (-coupling_repulsion_pressure)\n",
                    r->cutoff(), r->scale()));
  if (settings_.restart)
    CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                              "cellfsi: restarting from the checkpoint at t = %g s (step %d)\n", resume_.time,
                              resume_.step));
}

int FluidRun::stopped_before_the_first_step() {
  // The folder is this run's now, so the summary says where it stopped.
  const int sig = agreed_stop_signal(PETSC_COMM_WORLD);
  if (sig == 0) {
    mark_time_stepping();
    return 0;
  }
  const std::string where =
      " during set-up, before step " + std::to_string(resume_.step + 1) + " of " + std::to_string(n_steps_);
  out_->summary("interrupted: " + signal_name(sig) + where, done_, newton_, linear_, {});
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD, "cellfsi: stopped by %s%s; summary in %s/summary.json\n",
                            signal_name(sig).c_str(), where.c_str(), settings_.output_dir.c_str()));
  return 128 + sig;
}

int FluidRun::step_loop() {
  const bool coupled = scene_->coupler() != nullptr;
  current_step_ = resume_.step + 1;
  try {
    for (int k = resume_.step + 1; k <= n_steps_; ++k) {
      current_step_ = k;
      const SceneStep st = scene_->step();
      newton_ += st.iterations;
      linear_ += st.linear_iterations;
      factorizations_ += st.factorizations;
      bulk_factorizations_ += st.bulk_factorizations;
      if (k == resume_.step + 1)
        reject_unknown_options(coupled && scene_->coupler()->linear_solver().fell_back() ? OptionCheck::after_fallback
                                                                         : OptionCheck::after_first_step);
      if (!st.converged) {
        const std::string why = std::string(coupled ? "the coupling iteration" : "Newton") + " diverged (" +
                                st.reason + ") in step " + std::to_string(k) +
                                " at t = " + std::to_string(k * settings_.dt) + " s";
        const std::string note = summary_of_failure("failed: " + why);
        PetscFPrintf(PETSC_COMM_WORLD, PETSC_STDERR, "cellfsi: error: %s; output so far is in %s%s\n",
                     why.c_str(), settings_.output_dir.c_str(), note.c_str());
        return 2;
      }
      done_ = k;
      {
        static const PetscLogEvent metrics_event = register_log_event("cellfsi app", "CellfsiMetrics");
        EventScope ev(metrics_event);
        last_ = scene_->metrics();
      }
      Metrics row{{"step", k},
                  {"time", scene_->fluid().time()},
                  {coupled ? "coupling_iterations" : "newton_iterations", st.iterations},
                  {"linear_iterations", st.linear_iterations}};
      if (coupled) row.emplace_back("factorizations", st.factorizations);
      row.insert(row.end(), last_.begin(), last_.end());
      out_->metrics_row(row);
      out_->progress(k, n_steps_, scene_->fluid().time(), st.iterations, st.linear_iterations);
      const bool written = series_ && k % settings_.output_every == 0;
      if (written) write_series();
      if (settings_.checkpoint_every > 0 && k % settings_.checkpoint_every == 0 && k < n_steps_)
        write_checkpoint_after(k);
      // -equilibrium_stop: every stretched body at rest ends the run here, as if -final_time were now (the
      // checkpoint and the summary follow in finish(); a -restart with a later -final_time goes on).
      if (settings_.equilibrium_stop && k < n_steps_ && scene_->at_equilibrium()) {
        CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                                  "cellfsi: equilibrium reached at t = %g s (step %d of %d): the run ends "
                                  "(-equilibrium_stop)\n",
                                  scene_->fluid().time(), k, n_steps_));
        if (series_ && !written) write_series();
        n_steps_ = k;
        break;
      }
      // A stop request (SIGINT, SIGTERM, SIGHUP, SIGUSR1, SIGPIPE; apps/interrupt.hpp) ends the run after
      // this step.
      if (const int sig = agreed_stop_signal(PETSC_COMM_WORLD); sig != 0 && k < n_steps_)
        return stop_after_step(sig, k, written);
    }
  } catch (const std::invalid_argument& e) {
    // Bad input found once the solvers read their options (after the first step): exit 1, as before a run.
    const std::string note = summary_of_failure(std::string("failed: ") + e.what());
    if (!note.empty()) throw std::invalid_argument(e.what() + note);
    throw;
  } catch (const std::exception& e) {
    // Whatever stopped the run mid-way, the summary says so next to the output written so far, and where.
    fail(e, where_text(" in step %d at t = %g s", current_step_, current_step_ * settings_.dt));
  }
  return 0;
}

int FluidRun::stop_after_step(int sig, int k, bool series_written) {
  if (series_ && !series_written) write_series();  // the state the run stopped at
  write_checkpoint_after(k);
  char where[128];
  std::snprintf(where, sizeof where, " after step %d of %d at t = %g s", k, n_steps_, scene_->fluid().time());
  out_->summary("interrupted: " + signal_name(sig) + where, done_, newton_, linear_, final_metrics(false),
                scene_->summary_text());
  CELLFSI_PETSC(
      PetscPrintf(PETSC_COMM_WORLD,
                  "cellfsi: interrupted by %s%s; output in %s (continue it with the same options and "
                  "-restart)\n",
                  signal_name(sig).c_str(), where, settings_.output_dir.c_str()));
  return 128 + sig;
}

void FluidRun::finish() {
  // The velocity profile across the domain at x = mid-length (section xi_0 = 1/2); for channel flows also
  // averaged over the metrics' window.
  const fluid::SectionData sec = scene_->fluid().section(0.5, 65), mean = scene_->mean_profile();
  // The final checkpoint (a later run may go on from it: -restart with a later -final_time) and the
  // profiles, then "completed": a summary that says so is written last.
  try {
    write_checkpoint_after(n_steps_);
    on_rank_zero(PETSC_COMM_WORLD, [&] {
      write_file_atomically(settings_.output_dir + "/profile.csv", profile_csv(sec));
      if (!mean.points.empty())
        write_file_atomically(settings_.output_dir + "/profile_mean.csv", profile_csv(mean));
    });
    out_->summary("completed", done_, newton_, linear_, final_metrics(true), final_words());
  } catch (const std::exception& e) {
    fail(e, where_text(" after the last step (%d) at t = %g s", n_steps_, n_steps_ * settings_.dt));
  }
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                            "cellfsi: completed %d steps in %.2f s; summary in %s/summary.json\n", n_steps_,
                            out_->elapsed(), settings_.output_dir.c_str()));
}

void FluidRun::write_series() {
  if (!series_) return;
  static const PetscLogEvent output_event = register_log_event("cellfsi app", "CellfsiOutput");
  CELLFSI_PETSC(PetscLogEventBegin(output_event, 0, 0, 0, 0));
  series_->write(scene_->fluid());
  // Every rank samples the bodies (remote ones collectively), rank 0 writes: its failure stops them all.
  if (solid_series_)
    on_every_rank(PETSC_COMM_WORLD, [&] { solid_series_->write(scene_->fluid().time(), scene_->bodies()); });
  CELLFSI_PETSC(PetscLogEventEnd(output_event, 0, 0, 0, 0));
  if (solid_series_) notice_folds(solid_series_->smallest());
}

void FluidRun::notice_folds(const std::vector<solid::SmallestJ>& smallest) {
  // (The writing rank's samples; once per body and launch.)
  fold_noticed_.resize(scene_->bodies().size(), false);
  for (std::size_t b = 0; b < smallest.size() && b < fold_noticed_.size(); ++b) {
    if (fold_noticed_[b] || smallest[b].J > 0) continue;
    fold_noticed_[b] = true;
    const solid::SmallestJ& s = smallest[b];
    std::printf(
        "cellfsi: notice: body '%s' has folded between the solver's quadrature points: det F = %.3g at "
        "x = (%.4g, %.4g, %.4g) cm in the output's samples at t = %.6g s (step %d; the solver's check, at "
        "its quadrature points, has not failed); from here on its shape there is not a membrane's (J in "
        "the .vts files)\n",
        scene_->bodies()[b]->name().c_str(), s.J, s.x[0], s.x[1], s.x[2], scene_->fluid().time(),
        current_step_);
    std::fflush(stdout);
  }
}

std::string FluidRun::checkpoint_options() const {
  std::string options = effective_options_yaml();
  PetscBool named = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-scene", &named));
  if (!named) options += "scene: " + settings_.name + "\n";
  return options;
}

void FluidRun::write_checkpoint_after(int k) {
  Checkpoint c;
  c.step = k;
  c.time = scene_->fluid().time();
  c.newton = newton_, c.linear = linear_, c.factorizations = factorizations_;
  c.bulk_factorizations = bulk_factorizations_;
  c.options = checkpoint_options();
  for (const solid::SolidSolver* b : scene_->bodies()) c.body_names.push_back(b->name());
  c.bodies = scene_->body_states();
  c.trackers = scene_->tracker_states();
  c.scene_metrics = scene_->metric_state();
  // Without writers (-output_every 0 in this run) the series so far stay as the checkpoint found them.
  c.fluid_series = series_ ? series_->entries() : resume_.fluid_series;
  c.solid_series = solid_series_ ? solid_series_->entries() : resume_.solid_series;
  c.solid_writes = solid_series_ ? solid_series_->count() : resume_.solid_writes;
  c.solid_J = solid_series_ ? solid_series_->history() : resume_.solid_J;
  write_checkpoint(PETSC_COMM_WORLD, settings_.output_dir, c, scene_->fluid());
}

std::string FluidRun::summary_of_failure(const std::string& status) {
  try {
    Metrics m = last_;
    for (auto& kv : fold_metrics()) m.push_back(std::move(kv));
    out_->summary(status, done_, newton_, linear_, m);
    return {};
  } catch (const std::exception& e) {
    return std::string("; summary.json not updated: ") + e.what();
  }
}

void FluidRun::fail(const std::exception& e, const std::string& where) {
  const std::string note = summary_of_failure(std::string("failed: ") + e.what() + where);
  const std::string message = e.what() + where + "; output so far is in " + settings_.output_dir + note;
  if (dynamic_cast<const CollectiveError*>(&e)) throw CollectiveError(message);  // the same on every rank
  throw std::runtime_error(message);
}

FluidRun::Metrics FluidRun::fold_metrics() const {
  // (Rank 0's, the rank that writes the series and the summary; none without series in this run or the
  // checkpoint's.)
  Metrics m;
  const std::vector<solid::JHistory>& history = solid_series_ ? solid_series_->history() : resume_.solid_J;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t b = 0; b < history.size() && b < scene_->bodies().size(); ++b) {
    const std::string name = scene_->bodies()[b]->name();
    const solid::JHistory& h = history[b];
    m.emplace_back(name + "_output_min_J", h.least.J);
    m.emplace_back(name + "_output_min_J_time", h.least.time);
    m.emplace_back(name + "_fold_time", h.folded ? h.first_fold.time : nan);
    m.emplace_back(name + "_fold_J", h.folded ? h.first_fold.J : nan);
  }
  return m;
}

FluidRun::Metrics FluidRun::final_metrics(bool with_solver_size) const {
  Metrics m = scene_->summary_metrics();
  for (auto& kv : fold_metrics()) m.push_back(std::move(kv));
  if (const coupling::FsiCoupler* coupler = scene_->coupler()) {
    // What the linear algebra cost: the LU factorisations made in steps (coupling::SolveCounts), the bulk
    // operator's (once per run and restart: cellfsi_fourier, cellfsi_bulk), and the unknowns of the band or
    // region.
    m.emplace_back("factorizations", static_cast<double>(factorizations_));
    m.emplace_back("bulk_factorizations", static_cast<double>(bulk_factorizations_));
    if (with_solver_size)
      m.emplace_back("corrected_unknowns", static_cast<double>(coupler->linear_solver().corrected_unknowns()));
  }
  if (exchange_ && with_solver_size) {
    m.emplace_back("solid_ranks", solid_ranks_);
    m.emplace_back("exchange_shared_mb", exchange_->shared_bytes() / 1e6);
    m.emplace_back("exchange_message_mb", exchange_->message_bytes() / 1e6);
  }
  return m;
}

std::vector<std::pair<std::string, std::string>> FluidRun::final_words() const {
  std::vector<std::pair<std::string, std::string>> words = scene_->summary_text();
  if (const coupling::FsiCoupler* coupler = scene_->coupler()) {
    words.emplace_back("coupling_pc_type", coupler->linear_solver().pc_type());
  }
  return words;
}

}  // namespace cellfsi::app
