#include "apps/launch.hpp"

#include <petscsys.h>

#include <algorithm>
#include <cctype>
#include <csignal>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "apps/checkpoint.hpp"
#include "apps/handshake.hpp"
#include "apps/interrupt.hpp"
#include "apps/option_checks.hpp"
#include "apps/run_output.hpp"
#include "apps/scene.hpp"
#include "apps/scene_file.hpp"
#include "common/file_io.hpp"
#include "common/petsc_error.hpp"
#include "coupling/remote_solid.hpp"
#include "fluid/fluid_output.hpp"
#include "solid/solid_output.hpp"

namespace cellfsi::app {

namespace {

/// The scene run by `cellfsi` with no scene file (scenes/capsule_shear_quick.yaml: the capsule in shear at
/// the coarsest mesh whose theta is within 1 deg of the converged value), found next to the executable: in
/// <prefix>/share/cellfsi/scenes of an installation, in <build>/share/cellfsi/scenes of a build (CMake copies
/// the scenes there). Empty if it is not there.
std::string default_scene_path() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  const std::filesystem::path p =
      exe.parent_path().parent_path() / "share" / "cellfsi" / "scenes" / "capsule_shear_quick.yaml";
  return std::filesystem::is_regular_file(p, ec) ? p.string() : std::string();
}

/// Mailbox per rank for shared-memory exchange [bytes] (payloads above it go as messages).
constexpr std::size_t kMailboxBytes = 8u << 20;

// The command line as the user gave it (summary.json records it) and the scene file read (empty: none).
std::vector<std::string> g_command_line;
std::string g_scene_file;

void print_error(const std::string& message) {
  PetscFPrintf(PETSC_COMM_WORLD, PETSC_STDERR, "cellfsi: error: %s\n", message.c_str());
}

/// A failure that need not be the same on every rank (out of memory, a body leaving one rank's part): the
/// ranks other than 0 print it too, with their rank, since rank 0 may not have failed.
void print_failure(const std::string& message) {
  int rank = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  if (rank == 0)
    print_error(message);
  else
    std::fprintf(stderr, "cellfsi: error (rank %d): %s\n", rank, message.c_str());
}

/// A stop request during the set-up (apps/interrupt.hpp): the message, and the exit code 128 + sig.
int stopped_during_set_up(int sig) {
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                            "cellfsi: stopped by %s during set-up, before the first step; nothing written\n",
                            signal_name(sig).c_str()));
  return 128 + sig;
}

/// The fluid side (and, without a solid group, the bodies too).
int run_fluid(const std::string& default_name, MPI_Comm inter, Handshake& hs) {
  // A stop request during the set-up (3D meshes take minutes) is honoured at the end of each of its phases
  // instead of after the set-up and a whole first step; a solid side still waiting at the handshake stops
  // too.
  auto set_up_stop = [&hs]() {
    const int sig = agreed_stop_signal(PETSC_COMM_WORLD);
    if (sig != 0) hs.agree(-sig);
    return sig;
  };
  const std::vector<std::string> user_options = option_names();
  const SceneSettings settings = SceneSettings::from_options(default_name);
  PetscBool help = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-help", &help));
  Scene scene(PETSC_COMM_WORLD, settings);
  if (help) {
    hs.agree(1);
    return 0;
  }
  if (const int sig = set_up_stop()) return stopped_during_set_up(sig);
  check_bodies(settings, scene.fluid().patch());
  if (const int sig = set_up_stop()) return stopped_during_set_up(sig);
  scene.fluid().setup();
  reject_unknown_options(OptionCheck::before_coupling);
  if (const int sig = set_up_stop()) return stopped_during_set_up(sig);
  if (const int other = hs.agree(2, effective_options_yaml()); other < 0)
    return stopped_during_set_up(-other);  // the solid side was stopped during its set-up
  else if (other != 2)
    throw std::invalid_argument("the solid side stopped at start-up (see its message)");
  if (hs.split())
    if (const std::string diff = split_option_differences(effective_options_yaml(), hs.remote_options());
        !diff.empty())
      throw std::invalid_argument(
          "the fluid and the solid side were given different options (fluid side -> "
          "solid side: " +
          diff + "); give both executables the same scene and options");

  std::vector<std::unique_ptr<solid::NurbsSolid>> owned;
  std::vector<std::unique_ptr<coupling::RemoteSolid>> remote;
  std::unique_ptr<coupling::Exchange> exchange;
  std::vector<solid::SolidSolver*> bodies;
  // Once the exchange exists, the solid side is told to stop whatever happens (declared after `exchange`, so
  // destroyed before it).
  struct Stop {
    coupling::Exchange* ex = nullptr;
    ~Stop() {
      if (ex) coupling::shutdown_solids(*ex, PETSC_COMM_WORLD);
    }
  } stop;
  if (inter == MPI_COMM_NULL) {
    // The bodies live in this process (every rank holds a copy and does the same, cheap, solid work).
    owned = build_bodies(settings);
    for (auto& b : owned) bodies.push_back(b.get());
  } else {
    exchange = std::make_unique<coupling::Exchange>(inter, kMailboxBytes);
    stop.ex = exchange.get();
    for (size_t i = 0; i < settings.bodies.size(); ++i) {
      const BodySettings& b = settings.bodies[i];
      remote.push_back(std::make_unique<coupling::RemoteSolid>(*exchange, PETSC_COMM_WORLD,
                                                               static_cast<int>(i), b.name,
                                                               build_body_patch(settings, b), b.membrane()));
      remote.back()->hello();
      bodies.push_back(remote.back().get());
    }
  }
  scene.attach_bodies(bodies);
  if (scene.coupler()) reject_inapplicable_solver_options(user_options, scene.coupler()->solver());
  // The band and Fourier solvers do not use the fluid's KSP: what its set-up built (ASM's copy of the whole
  // Jacobian on one rank: 4.3 GB and 11 s at 64^3) is freed.
  if (scene.coupler() && scene.coupler()->solver() != coupling::CouplingSolver::fluid)
    scene.fluid().release_linear_solver();
  reject_unknown_options(OptionCheck::before_first_step);
  if (const int sig = agreed_stop_signal(PETSC_COMM_WORLD)) return stopped_during_set_up(sig);

  int size = 1, rank = 0, solid_ranks = 0;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  if (exchange) solid_ranks = exchange->remote_size();
  const int n_steps = static_cast<int>(std::ceil(settings.final_time / settings.dt - 1e-9));
  // A restart without a checkpoint is refused before the lock would create the folder and its lock file.
  if (settings.restart) on_rank_zero(PETSC_COMM_WORLD, [&] { require_checkpoint(settings.output_dir); });
  // The folder is this run's from here on (before a restart reads its checkpoint: another run may be writing
  // one).
  FolderLock lock(PETSC_COMM_WORLD, settings.output_dir, settings.output_dir_adopt);
  // A restart: the checkpoint must come from a run with the same options (but the final time and the output
  // intervals); the scene then takes its state.
  Checkpoint resume;
  if (settings.restart) {
    Vec U = nullptr, Udot = nullptr;
    CELLFSI_PETSC(DMCreateGlobalVector(scene.fluid().dm(), &U));
    CELLFSI_PETSC(VecDuplicate(U, &Udot));
    try {
      // The same options (but the final time and the output intervals): checked before the state is read.
      resume = read_checkpoint(PETSC_COMM_WORLD, settings.output_dir, effective_options_yaml(), U, Udot);
      std::vector<std::string> names;
      for (const solid::SolidSolver* b : scene.bodies()) names.push_back(b->name());
      if (names != resume.body_names)
        throw std::invalid_argument(
            "option -restart is invalid here: the checkpoint's bodies differ from the "
            "scene's");
      if (resume.step >= n_steps) {
        char msg[256];
        std::snprintf(
            msg, sizeof msg,
            "option -final_time = %g is invalid with -restart: the checkpoint in '%s' is at t = %g s "
            "(after %d steps); valid: a later time",
            settings.final_time, settings.output_dir.c_str(), resume.time, resume.step);
        throw std::invalid_argument(msg);
      }
      scene.restore(U, Udot, resume.step, resume.bodies, resume.trackers);
      scene.restore_metric_state(resume.scene_metrics);
    } catch (...) {
      VecDestroy(&U);
      VecDestroy(&Udot);
      throw;
    }
    VecDestroy(&U);
    VecDestroy(&Udot);
  }
  // metrics.csv's columns: those of every step's row (the metrics' names now).
  const std::string iterations_key = scene.coupler() ? "coupling_iterations" : "newton_iterations";
  std::vector<std::string> columns{"step", "time", iterations_key, "linear_iterations"};
  if (scene.coupler()) columns.emplace_back("factorizations");
  for (const auto& kv : scene.metrics()) columns.push_back(kv.first);
  RunOutput out(PETSC_COMM_WORLD, settings.output_dir, settings.name, columns,
                given_options_yaml(g_scene_file, g_command_line, settings.name), g_command_line,
                settings.restart ? resume.step : -1);
  out.set_first_step(resume.step);
  std::unique_ptr<fluid::FluidSeriesWriter> series;
  std::unique_ptr<solid::SolidSeriesWriter> solid_series;
  static const PetscLogEvent output_event = register_log_event("cellfsi app", "CellfsiOutput");
  auto write_series = [&] {
    if (!series) return;
    CELLFSI_PETSC(PetscLogEventBegin(output_event, 0, 0, 0, 0));
    series->write(scene.fluid());
    // Every rank samples the bodies (remote ones collectively), rank 0 writes: its failure stops them all.
    if (solid_series)
      on_every_rank(PETSC_COMM_WORLD, [&] { solid_series->write(scene.fluid().time(), scene.bodies()); });
    CELLFSI_PETSC(PetscLogEventEnd(output_event, 0, 0, 0, 0));
  };
  if (settings.output_every > 0) {
    series = std::make_unique<fluid::FluidSeriesWriter>(settings.output_dir);
    if (!bodies.empty() && scene.undisturbed_velocity())
      series->set_undisturbed_velocity(scene.undisturbed_velocity());
    if (!bodies.empty())
      solid_series = std::make_unique<solid::SolidSeriesWriter>(settings.output_dir, rank == 0);
    if (settings.restart) {
      series->resume(resume.fluid_series);
      if (solid_series) solid_series->resume(resume.solid_series, resume.solid_writes);
    } else {
      write_series();
    }
  }
  if (settings.restart) {
    // Series files written after the checkpoint (before the run stopped) belong to no series now.
    std::vector<std::string> keep;
    for (const auto* list : {&resume.fluid_series, &resume.solid_series})
      for (const geometry::PvdEntry& e : *list) keep.push_back(e.file);
    out.remove_series_except(keep);
  }
  CELLFSI_PETSC(PetscPrintf(
      PETSC_COMM_WORLD,
      "cellfsi %s: %s, %d fluid ranks%s, %zu bodies, %d steps of %g s to t = %g s, output in %s\n",
      CELLFSI_VERSION, settings.name.c_str(), size,
      solid_ranks ? (" + " + std::to_string(solid_ranks) + " solid ranks").c_str() : "", bodies.size(),
      n_steps, settings.dt, n_steps * settings.dt, settings.output_dir.c_str()));
  if (scene.coupler() && scene.coupler()->solver() == coupling::CouplingSolver::fluid &&
      settings.coupling.solver != coupling::CouplingSolver::fluid)
    CELLFSI_PETSC(
        PetscPrintf(PETSC_COMM_WORLD,
                    "cellfsi: note: the band solver needs one fluid rank and a BAIJ Jacobian, the Fourier "
                    "solver a BAIJ Jacobian and a box uniform along its periodic directions; on %d "
                    "rank(s) the coupling loop uses -coupling_solver fluid\n",
                    size));
  // A coupled run's iterations are the coupling loop's block iterations, not Newton iterations.
  out.set_iteration_kind(scene.coupler() ? "coupling" : "newton");
  long newton = resume.newton, linear = resume.linear, factorizations = resume.factorizations;
  int done = resume.step;
  std::vector<std::pair<std::string, double>> last;
  auto write_checkpoint_now = [&](int k) {
    Checkpoint c;
    c.step = k;
    c.time = scene.fluid().time();
    c.newton = newton, c.linear = linear, c.factorizations = factorizations;
    c.options = effective_options_yaml();
    for (const solid::SolidSolver* b : scene.bodies()) c.body_names.push_back(b->name());
    c.bodies = scene.body_states();
    c.trackers = scene.tracker_states();
    c.scene_metrics = scene.metric_state();
    // Without writers (-output_every 0 in this run) the series so far stay as the checkpoint found them.
    c.fluid_series = series ? series->entries() : resume.fluid_series;
    c.solid_series = solid_series ? solid_series->entries() : resume.solid_series;
    c.solid_writes = solid_series ? solid_series->count() : resume.solid_writes;
    write_checkpoint(PETSC_COMM_WORLD, settings.output_dir, c, scene.fluid().solution(),
                     scene.fluid().solution_rate());
  };
  if (settings.restart)
    CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                              "cellfsi: restarting from the checkpoint at t = %g s (step %d)\n", resume.time,
                              resume.step));
  const std::string iteration = bodies.empty() ? "Newton" : "the coupling iteration";
  // The last look before the steps: the folder is this run's now, so the summary says where it stopped.
  if (const int sig = agreed_stop_signal(PETSC_COMM_WORLD)) {
    char where[96];
    std::snprintf(where, sizeof where, " during set-up, before step %d of %d", resume.step + 1, n_steps);
    out.summary("interrupted: " + signal_name(sig) + where, done, newton, linear, {});
    CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD, "cellfsi: stopped by %s%s; summary in %s/summary.json\n",
                              signal_name(sig).c_str(), where, settings.output_dir.c_str()));
    return 128 + sig;
  }
  mark_time_stepping();
  // The summary of a failed run. If it cannot be written either (the full disk that failed the run), the
  // previous summary.json stays and the returned note says so, for the message.
  auto summary_of_failure = [&](const std::string& status) -> std::string {
    try {
      out.summary(status, done, newton, linear, last);
      return {};
    } catch (const std::exception& e) {
      return std::string("; summary.json not updated: ") + e.what();
    }
  };
  int current_step = resume.step + 1;  // the step being computed or written, for a failure's message
  try {
    for (int k = resume.step + 1; k <= n_steps; ++k) {
      current_step = k;
      const SceneStep st = scene.step();
      newton += st.iterations;
      linear += st.linear_iterations;
      factorizations += st.factorizations;
      if (k == resume.step + 1)
        reject_unknown_options(scene.coupler() && scene.coupler()->fell_back()
                                   ? OptionCheck::after_fallback
                                   : OptionCheck::after_first_step);
      if (!st.converged) {
        const std::string why = iteration + " diverged (" + st.reason + ") in step " + std::to_string(k) +
                                " at t = " + std::to_string(k * settings.dt) + " s";
        const std::string note = summary_of_failure("failed: " + why);
        print_error(why + "; output so far is in " + settings.output_dir + note);
        return 2;
      }
      done = k;
      last = scene.metrics();
      std::vector<std::pair<std::string, double>> row{{"step", k},
                                                      {"time", scene.fluid().time()},
                                                      {iterations_key, st.iterations},
                                                      {"linear_iterations", st.linear_iterations}};
      if (scene.coupler()) row.emplace_back("factorizations", st.factorizations);
      row.insert(row.end(), last.begin(), last.end());
      out.metrics_row(row);
      out.progress(k, n_steps, scene.fluid().time(), st.iterations, st.linear_iterations);
      const bool written = series && k % settings.output_every == 0;
      if (written) write_series();
      if (settings.checkpoint_every > 0 && k % settings.checkpoint_every == 0 && k < n_steps)
        write_checkpoint_now(k);
      // A stop request (SIGINT, SIGTERM, SIGHUP, SIGUSR1, SIGPIPE; apps/interrupt.hpp) ends the run after
      // this step.
      if (const int sig = agreed_stop_signal(PETSC_COMM_WORLD); sig != 0 && k < n_steps) {
        if (series && !written) write_series();  // the state the run stopped at
        write_checkpoint_now(k);
        char where[128];
        std::snprintf(where, sizeof where, " after step %d of %d at t = %g s", k, n_steps,
                      scene.fluid().time());
        std::vector<std::pair<std::string, double>> final_metrics = scene.summary_metrics();
        if (scene.coupler())
          final_metrics.emplace_back("factorizations", static_cast<double>(factorizations));
        out.summary("interrupted: " + signal_name(sig) + where, done, newton, linear, final_metrics,
                    scene.summary_text());
        CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                                  "cellfsi: interrupted by %s%s; output in %s (continue it with the same "
                                  "options and -restart)\n",
                                  signal_name(sig).c_str(), where, settings.output_dir.c_str()));
        return 128 + sig;
      }
    }
  } catch (const std::invalid_argument& e) {
    // Bad input found once the solvers read their options (after the first step): exit 1, as before a run.
    const std::string note = summary_of_failure(std::string("failed: ") + e.what());
    if (!note.empty()) throw std::invalid_argument(e.what() + note);
    throw;
  } catch (const std::exception& e) {
    // Whatever stopped the run mid-way, the summary says so next to the output written so far, and where.
    char where[96];
    std::snprintf(where, sizeof where, " in step %d at t = %g s", current_step, current_step * settings.dt);
    const std::string note = summary_of_failure(std::string("failed: ") + e.what() + where);
    throw std::runtime_error(e.what() + std::string(where) + "; output so far is in " + settings.output_dir +
                             note);
  }
  std::vector<std::pair<std::string, double>> final_metrics = scene.summary_metrics();
  if (scene.coupler()) {
    // What the linear algebra cost: factorisations of the whole fluid Jacobian (band solver: of its fixed
    // part; Fourier solver: the bulk solver's set-up; the small factorisations of the band or the region
    // are not counted) and the band's size.
    final_metrics.emplace_back("factorizations", static_cast<double>(factorizations));
    final_metrics.emplace_back("band_unknowns", static_cast<double>(scene.coupler()->band_unknowns()));
  }
  if (exchange) {
    final_metrics.emplace_back("solid_ranks", solid_ranks);
    final_metrics.emplace_back("exchange_shared_mb", exchange->shared_bytes() / 1e6);
    final_metrics.emplace_back("exchange_message_mb", exchange->message_bytes() / 1e6);
  }
  std::vector<std::pair<std::string, std::string>> words = scene.summary_text();
  if (scene.coupler()) {
    const coupling::CouplingSolver used = scene.coupler()->solver();
    words.emplace_back("coupling_solver", used == coupling::CouplingSolver::fourier ? "fourier"
                                          : used == coupling::CouplingSolver::band  ? "band"
                                                                                    : "fluid");
  }
  // The velocity profile across the domain at x = mid-length (section xi_0 = 1/2), as CSV; for channel
  // flows also averaged over the metrics' window.
  auto profile_csv = [](const fluid::SectionData& sec) {
    std::ostringstream csv;
    csv << std::setprecision(12) << "x,y,z,vx,vy,vz\n";
    for (size_t i = 0; i < sec.points.size(); ++i)
      csv << sec.points[i][0] << "," << sec.points[i][1] << "," << sec.points[i][2] << ","
          << sec.velocity[i][0] << "," << sec.velocity[i][1] << "," << sec.velocity[i][2] << "\n";
    return csv.str();
  };
  const fluid::SectionData sec = fluid::section(scene.fluid(), 0.5, 65), mean = scene.mean_profile();
  // The final checkpoint (a later run may go on from it: -restart with a later -final_time) and the
  // profiles, then "completed": a summary that says so is written last.
  try {
    write_checkpoint_now(n_steps);
    on_rank_zero(PETSC_COMM_WORLD, [&] {
      write_file_atomically(settings.output_dir + "/profile.csv", profile_csv(sec));
      if (!mean.points.empty())
        write_file_atomically(settings.output_dir + "/profile_mean.csv", profile_csv(mean));
    });
    out.summary("completed", done, newton, linear, final_metrics, words);
  } catch (const std::exception& e) {
    char where[96];
    std::snprintf(where, sizeof where, " after the last step (%d) at t = %g s", n_steps, n_steps * settings.dt);
    const std::string note = summary_of_failure(std::string("failed: ") + e.what() + where);
    throw std::runtime_error(e.what() + std::string(where) + "; output so far is in " + settings.output_dir +
                             note);
  }
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                            "cellfsi: completed %d steps in %.2f s; summary in %s/summary.json\n", n_steps,
                            out.elapsed(), settings.output_dir.c_str()));
  return 0;
}

/// The solid side: reads the same scene, builds and checks the bodies, serves the fluid side until it stops.
/// Prints nothing unless its own input is bad and the fluid side's is not (the fluid side reports first).
int run_solid(const std::string& default_name, MPI_Comm inter, Handshake& hs) {
  std::string error;
  std::vector<std::unique_ptr<solid::NurbsSolid>> owned;
  std::vector<solid::SolidSolver*> mine;
  int state = 2;  // the Handshake's states
  try {
    const SceneSettings settings = SceneSettings::from_options(default_name, false);
    PetscBool help = PETSC_FALSE;
    CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-help", &help));
    if (help) state = 1;
    if (state == 2) {
      check_bodies(settings, build_domain(settings));
      owned = build_bodies(settings);
      int rank = 0, size = 1;
      MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
      MPI_Comm_size(PETSC_COMM_WORLD, &size);
      mine.assign(owned.size(), nullptr);
      for (size_t i = 0; i < owned.size(); ++i)
        if (coupling::body_owner(static_cast<int>(i), size) == rank) mine[i] = owned[i].get();
    }
  } catch (const std::exception& e) {
    error = e.what();
    state = 0;
  }
  // A stop request during this side's set-up stops both sides (the fluid side says so).
  if (const int sig = agreed_stop_signal(PETSC_COMM_WORLD); sig != 0 && state != 1) state = -sig;
  const int fluid_state = hs.agree(state, state == 2 ? effective_options_yaml() : std::string());
  if (std::min(state, fluid_state) < 0) return 128 - std::min(state, fluid_state);
  // The same check as the fluid side's, which reports it.
  if (state == 2 && fluid_state == 2 &&
      !split_option_differences(hs.remote_options(), effective_options_yaml()).empty())
    return 1;
  if (state == 0) {
    if (fluid_state == 2) print_error(error);
    return 1;
  }
  if (state == 1 || fluid_state != 2) return fluid_state == 1 ? 0 : 1;
  coupling::Exchange exchange(inter, kMailboxBytes);
  coupling::serve_solids(exchange, mine);
  return 0;
}

}  // namespace

int launch(int argc, char** argv, Role role) {
  record_ignored_signals();  // before MPI and PETSc install handlers over the dispositions the process got
  // Arguments: a scene file first is read as PETSc options before the command line, which therefore wins;
  // -solid_ranks B (launch option, command line only) splits the job.
  std::vector<std::string> args(argv, argv + argc);
  g_command_line = args;
  std::string scene_name = "capsule_shear_quick", scene_file;  // the default scene's name
  int solid_ranks = 0;
  bool bad_launch = false;
  std::string launch_error;
  for (size_t i = 1; i < args.size(); ++i)
    if (args[i] == "-solid_ranks") {
      char* end = nullptr;
      const long v = i + 1 < args.size() ? std::strtol(args[i + 1].c_str(), &end, 10) : -1;
      if (i + 1 >= args.size() || *end != '\0' || v < 0 || role != Role::combined) {
        bad_launch = true;
        launch_error =
            role != Role::combined
                ? "option -solid_ranks is for cellfsi; cellfsi-fluid/-solid take their ranks from mpirun"
                : "option -solid_ranks = " + (i + 1 < args.size() ? args[i + 1] : std::string("(none)")) +
                      " is invalid; valid: an integer >= 0 (ranks of the solid group)";
      }
      solid_ranks = static_cast<int>(std::max(0L, v));
      args.erase(args.begin() + i, args.begin() + std::min(args.size(), i + 2));
      break;
    }
  // A scene file anywhere but first (after options, or a second one) was ignored: refuse it.
  for (size_t i = 2; i < args.size() && !bad_launch; ++i) {
    const std::string ext = std::filesystem::path(args[i]).extension().string();
    const bool yaml = ext == ".yaml" || ext == ".yml";
    const bool option_value = args[i - 1] == "-options_file_yaml" || args[i - 1] == "-options_file" ||
                              args[i - 1] == "-output_dir" || args[i - 1] == "-scene";
    if (yaml && !option_value) {
      bad_launch = true;
      launch_error = "argument '" + args[i] +
                     "' is invalid here; valid: one scene file, as the first argument (" + args[0] +
                     " SCENE.yaml [options])";
    }
  }
  // An option given twice on the command line: PETSc would silently keep the last.
  {
    std::map<std::string, std::size_t> seen;
    for (size_t i = 1; i < args.size() && !bad_launch; ++i) {
      const std::string& a = args[i];
      if (a.size() < 2 || a[0] != '-' || !std::isalpha(static_cast<unsigned char>(a[1]))) continue;
      const auto [it, fresh] = seen.emplace(a, i);
      if (fresh) continue;
      auto value = [&](std::size_t k) {
        return k + 1 < args.size() && !(args[k + 1].size() > 1 && args[k + 1][0] == '-' &&
                                        std::isalpha(static_cast<unsigned char>(args[k + 1][1])))
                   ? args[k + 1]
                   : std::string("(no value)");
      };
      bad_launch = true;
      launch_error = "option " + a + " is given twice on the command line (" + value(it->second) + ", then " +
                     value(i) + "); valid: each option once (the command line overrides the scene file)";
    }
  }
  if (args.size() > 1 && args[1][0] != '-') {
    scene_file = args[1];
    g_scene_file = scene_file;
    scene_name = std::filesystem::path(scene_file).stem().string();
    args[1] = "-options_file_yaml";
    args.insert(args.begin() + 2, scene_file);
  } else {
    // No scene: the default scene.
    scene_file = default_scene_path();
    const bool help = std::find(args.begin(), args.end(), "-help") != args.end();
    if (scene_file.empty() && help) {
      // -help lists the options with their built-in defaults: no scene needed.
    } else if (scene_file.empty()) {
      bad_launch = true;
      launch_error =
          "no scene file given, and the default scene (share/cellfsi/scenes/capsule_shear_quick.yaml next to "
          "the executable's folder) is not there; give one: " +
          args[0] + " SCENE.yaml [options]";
    }
    if (!scene_file.empty()) args.insert(args.begin() + 1, {"-options_file_yaml", scene_file});
    g_scene_file = scene_file;
  }

  MPI_Init(&argc, &argv);
  int world_rank = 0, world_size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &world_rank);
  MPI_Comm_size(MPI_COMM_WORLD, &world_size);
  auto fail_early = [&](const std::string& msg) {
    if (world_rank == 0) std::fprintf(stderr, "cellfsi: error: %s\n", msg.c_str());
    MPI_Finalize();
    return 1;
  };
  // Errors found before the job is split, agreed over the whole job: in an MPMD job only one executable may
  // have one (-solid_ranks given to cellfsi-solid, its scene file missing), and the other must not wait for
  // it. The lowest rank with an error prints it.
  std::string early_error = bad_launch ? launch_error : std::string();
  // First what the job is made of, which every rank learns: cellfsi mixed with cellfsi-fluid or -solid, or
  // cellfsi processes given different -solid_ranks, would split the job differently on each side and each
  // would wait for the other forever.
  {
    int job[5] = {role == Role::combined, role == Role::fluid, role == Role::solid, solid_ranks,
                  -solid_ranks};
    MPI_Allreduce(MPI_IN_PLACE, job, 5, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (job[0] && (job[1] || job[2])) {
      std::string names = "cellfsi";
      if (job[1]) names += job[2] ? ", cellfsi-fluid" : " and cellfsi-fluid";
      if (job[2]) names += " and cellfsi-solid";
      early_error = names +
                    " were started in one job; valid: cellfsi alone (mpirun -np N cellfsi SCENE.yaml "
                    "[-solid_ranks B]) or cellfsi-fluid with cellfsi-solid (mpirun -np A cellfsi-fluid "
                    "SCENE.yaml : -np B cellfsi-solid SCENE.yaml)";
    } else if (job[0] && job[3] != -job[4]) {
      early_error = "option -solid_ranks differs between the cellfsi processes of the job (" +
                    std::to_string(-job[4]) + " and " + std::to_string(job[3]) +
                    "); valid: one value for the whole job (mpirun -np N cellfsi SCENE.yaml -solid_ranks B)";
    }
  }
  if (early_error.empty() && !scene_file.empty() && !std::filesystem::is_regular_file(scene_file))
    early_error = "scene file '" + scene_file + "' not found (expected a .yaml scene, see scenes/)";
  if (early_error.empty() && !scene_file.empty()) {
    try {
      check_scene_file(scene_file);
    } catch (const std::invalid_argument& e) {
      early_error = e.what();
    }
  }
  int first_error = early_error.empty() ? world_size : world_rank;
  MPI_Allreduce(MPI_IN_PLACE, &first_error, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (first_error < world_size) {
    if (world_rank == first_error) std::fprintf(stderr, "cellfsi: error: %s\n", early_error.c_str());
    MPI_Finalize();
    return 1;
  }

  // The split: color 0 fluid, 1 solid.
  int color = 0;
  if (role == Role::solid) color = 1;
  if (role == Role::combined && solid_ranks > 0) {
    if (solid_ranks >= world_size)
      return fail_early("option -solid_ranks = " + std::to_string(solid_ranks) + " is invalid; valid: 0 to " +
                        std::to_string(world_size - 1) + " (fewer than the job's " +
                        std::to_string(world_size) + " ranks)");
    color = world_rank >= world_size - solid_ranks ? 1 : 0;
  }
  MPI_Comm local = MPI_COMM_NULL, inter = MPI_COMM_NULL;
  MPI_Comm_split(MPI_COMM_WORLD, color, world_rank, &local);
  int n_color[2] = {0, 0}, mine[2] = {color == 0, color == 1};
  MPI_Allreduce(mine, n_color, 2, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
  const bool split = role != Role::combined || solid_ranks > 0;
  if (split && (n_color[0] == 0 || n_color[1] == 0)) {
    MPI_Comm_free(&local);
    return fail_early(
        "cellfsi-fluid and cellfsi-solid run together: mpirun -np A cellfsi-fluid SCENE.yaml : -np B "
        "cellfsi-solid SCENE.yaml");
  }
  if (split) {
    // The other group's leader: its lowest world rank.
    int lowest[2] = {world_size, world_size}, mine_low[2] = {world_size, world_size};
    mine_low[color] = world_rank;
    MPI_Allreduce(mine_low, lowest, 2, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    MPI_Intercomm_create(local, 0, MPI_COMM_WORLD, lowest[1 - color], 4242, &inter);
  }
  PETSC_COMM_WORLD = local;
  int n = static_cast<int>(args.size());
  std::vector<char*> av;
  for (auto& a : args) av.push_back(a.data());
  av.push_back(nullptr);
  char** avp = av.data();
  int status = 0;
  // What -help prints first (then every option table: scene, fluid, coupling, each body, and PETSc's own).
  static const char* const kHelp =
      "cellfsi: cell-resolved microscale blood flow by NURBS-based immersed fluid-structure interaction\n"
      "(Casquero et al. 2017): a VMS Navier-Stokes fluid on an Eulerian NURBS patch, hyperelastic NURBS\n"
      "membranes and nuclei, coupled by the paper's block-iterative Newton loop. Output: VTK for ParaView,\n"
      "metrics.csv and summary.json in the output folder (README.md, Output).\n\n"
      "Usage: cellfsi [SCENE.yaml] [-option value ...]   (one job; -solid_ranks B puts the bodies on B "
      "ranks)\n"
      "       mpirun -np A cellfsi-fluid SCENE.yaml [options] : -np B cellfsi-solid SCENE.yaml [options]\n"
      "A scene file's keys are options (nested keys join with _); the command line overrides them.\n\n";
  if (PetscInitialize(&n, &avp, nullptr, kHelp) != 0) {
    status = 1;
  } else {
    record_petsc_errors();  // PETSc errors become one-line messages (a misspelt type: bad input, exit 1)
    Handshake hs(inter);
    int local_rank = 0;
    MPI_Comm_rank(PETSC_COMM_WORLD, &local_rank);
    install_stop_handlers(color == 0 && local_rank == 0);  // replaces PETSc's handlers for these signals
    // A file-size limit (ulimit -f) makes a write fail with EFBIG, reported like a full disk, instead of
    // killing the process by SIGXFSZ with nothing saved.
    std::signal(SIGXFSZ, SIG_IGN);
    try {
      status = color == 1 ? run_solid(scene_name, inter, hs) : run_fluid(scene_name, inter, hs);
    } catch (const std::invalid_argument& e) {
      print_error(with_scene_file_line(e.what(), scene_file, g_command_line));
      status = 1;
    } catch (const std::exception& e) {
      print_failure(e.what());
      status = 2;
    }
    if (!hs.done()) hs.agree(0);  // the fluid side failed before the solid side was told to start
    PetscFinalize();
  }
  if (inter != MPI_COMM_NULL) MPI_Comm_free(&inter);
  MPI_Comm_free(&local);
  MPI_Finalize();
  return status;
}

}  // namespace cellfsi::app
