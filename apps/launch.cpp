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

#include "apps/fluid_run.hpp"
#include "apps/handshake.hpp"
#include "apps/interrupt.hpp"
#include "apps/option_checks.hpp"
#include "apps/run_output.hpp"
#include "apps/scene.hpp"
#include "apps/scene_file.hpp"
#include "common/petsc_error.hpp"
#include "coupling/remote_solid.hpp"

namespace cellfsi::app {

namespace {

/// The scene run by `cellfsi` with no scene file (scenes/capsule_shear_quick.yaml: the capsule in shear on
/// the divergence-conforming space, within 0.25 deg of the converged inclination), found next to the
/// executable: in <prefix>/share/cellfsi/scenes of an installation, in <build>/share/cellfsi/scenes of a
/// build (CMake copies the scenes there). Empty if it is not there.
std::string default_scene_path() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  const std::filesystem::path p =
      exe.parent_path().parent_path() / "share" / "cellfsi" / "scenes" / "capsule_shear_quick.yaml";
  return std::filesystem::is_regular_file(p, ec) ? p.string() : std::string();
}

// How the run was launched (summary.json and options.yaml record it).
LaunchRecord g_launch;

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

/// The solid side: reads the same scene, builds and checks the bodies, serves the fluid side until it stops.
/// Prints nothing unless its own input is bad and the fluid side's is not (the fluid side reports first).
int run_solid(const std::string& default_name, MPI_Comm inter, Handshake& hs) {
  std::string error;
  std::vector<std::unique_ptr<solid::SolidSolver>> owned;
  std::vector<solid::SolidSolver*> mine;
  int state = 2;  // the Handshake's states
  try {
    const SceneSettings settings = SceneSettings::from_options(default_name, false);
    PetscBool help = PETSC_FALSE;
    CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-help", &help));
    if (help) state = 1;
    if (state == 2) {
      check_bodies_on_solid_ranks(settings);
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
  coupling::Exchange exchange(inter, kExchangeMailboxBytes);
  coupling::serve_solids(exchange, mine);
  return 0;
}

/// The command line as launch() hands it to PETSc, and what it learnt from it before MPI starts.
struct Arguments {
  std::vector<std::string> args;                                    // for PetscInitialize
  std::string scene_name = "capsule_shear_quick", scene_file;  // the default scene's name
  int solid_ranks = 0;
  std::string error;  // bad input found in the arguments ("": none)
};

/// Takes -solid_ranks B (launch option, command line only) out of the arguments.
void take_solid_ranks(Arguments& a, Role role) {
  std::vector<std::string>& args = a.args;
  for (size_t i = 1; i < args.size(); ++i) {
    if (args[i] != "-solid_ranks") continue;
    char* end = nullptr;
    const long v = i + 1 < args.size() ? std::strtol(args[i + 1].c_str(), &end, 10) : -1;
    if (i + 1 >= args.size() || *end != '\0' || v < 0 || role != Role::combined)
      a.error = role != Role::combined
                    ? "option -solid_ranks is for cellfsi; cellfsi-fluid/-solid take their ranks from mpirun"
                    : "option -solid_ranks = " + (i + 1 < args.size() ? args[i + 1] : std::string("(none)")) +
                          " is invalid; valid: an integer >= 0 (ranks of the solid group)";
    a.solid_ranks = static_cast<int>(std::max(0L, v));
    args.erase(args.begin() + i, args.begin() + std::min(args.size(), i + 2));
    return;
  }
}

/// A scene file anywhere but first (after options, or a second one) would be ignored: why it is refused, or
/// "".
std::string misplaced_scene_file(const std::vector<std::string>& args) {
  for (size_t i = 2; i < args.size(); ++i) {
    const std::string ext = std::filesystem::path(args[i]).extension().string();
    const bool yaml = ext == ".yaml" || ext == ".yml";
    const bool option_value = args[i - 1] == "-options_file_yaml" || args[i - 1] == "-options_file" ||
                              args[i - 1] == "-output_dir" || args[i - 1] == "-scene";
    if (yaml && !option_value)
      return "argument '" + args[i] + "' is invalid here; valid: one scene file, as the first argument (" +
             args[0] + " SCENE.yaml [options])";
  }
  return "";
}

/// An option given twice on the command line (PETSc would silently keep the last): why it is refused, or "".
std::string repeated_option(const std::vector<std::string>& args) {
  auto is_option = [](const std::string& a) {
    return a.size() > 1 && a[0] == '-' && std::isalpha(static_cast<unsigned char>(a[1]));
  };
  auto value = [&](std::size_t k) {
    return k + 1 < args.size() && !is_option(args[k + 1]) ? args[k + 1] : std::string("(no value)");
  };
  std::map<std::string, std::size_t> seen;
  for (size_t i = 1; i < args.size(); ++i) {
    if (!is_option(args[i])) continue;
    const auto [it, fresh] = seen.emplace(args[i], i);
    if (!fresh)
      return "option " + args[i] + " is given twice on the command line (" + value(it->second) + ", then " +
             value(i) + "); valid: each option once (the command line overrides the scene file)";
  }
  return "";
}

/// The scene file (the first argument, else the default scene) put before the command line as
/// -options_file_yaml, so that the command line wins.
void insert_scene_file(Arguments& a) {
  std::vector<std::string>& args = a.args;
  if (args.size() > 1 && args[1][0] != '-') {
    a.scene_file = args[1];
    a.scene_name = std::filesystem::path(a.scene_file).stem().string();
    args[1] = "-options_file_yaml";
    args.insert(args.begin() + 2, a.scene_file);
    return;
  }
  a.scene_file = default_scene_path();
  const bool help = std::find(args.begin(), args.end(), "-help") != args.end();
  // (-help without a scene lists the options with their built-in defaults: no scene needed.)
  if (a.scene_file.empty() && !help)
    a.error =
        "no scene file given, and the default scene (share/cellfsi/scenes/capsule_shear_quick.yaml next to "
        "the executable's folder) is not there; give one: " +
        args[0] + " SCENE.yaml [options]";
  if (!a.scene_file.empty()) args.insert(args.begin() + 1, {"-options_file_yaml", a.scene_file});
}

/// Reads the arguments (before MPI starts).
Arguments parse_arguments(int argc, char** argv, Role role) {
  Arguments a;
  a.args.assign(argv, argv + argc);
  take_solid_ranks(a, role);
  if (a.error.empty()) a.error = misplaced_scene_file(a.args);
  if (a.error.empty()) a.error = repeated_option(a.args);
  insert_scene_file(a);
  return a;
}

/// What the job is made of, which every rank learns (collective over MPI_COMM_WORLD): cellfsi mixed with
/// cellfsi-fluid or -solid, or cellfsi processes given different -solid_ranks, would split the job
/// differently on each side and each would wait for the other forever. Why it is refused, or "".
std::string job_error(Role role, int solid_ranks) {
  int job[5] = {role == Role::combined, role == Role::fluid, role == Role::solid, solid_ranks, -solid_ranks};
  MPI_Allreduce(MPI_IN_PLACE, job, 5, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  if (job[0] && (job[1] || job[2])) {
    std::string names = "cellfsi";
    if (job[1]) names += job[2] ? ", cellfsi-fluid" : " and cellfsi-fluid";
    if (job[2]) names += " and cellfsi-solid";
    return names +
           " were started in one job; valid: cellfsi alone (mpirun -np N cellfsi SCENE.yaml "
           "[-solid_ranks B]) or cellfsi-fluid with cellfsi-solid (mpirun -np A cellfsi-fluid "
           "SCENE.yaml : -np B cellfsi-solid SCENE.yaml)";
  }
  if (job[0] && job[3] != -job[4])
    return "option -solid_ranks differs between the cellfsi processes of the job (" + std::to_string(-job[4]) +
           " and " + std::to_string(job[3]) +
           "); valid: one value for the whole job (mpirun -np N cellfsi SCENE.yaml -solid_ranks B)";
  return "";
}

/// Why the scene file is refused (missing, or not a scene), or "".
std::string scene_file_error(const std::string& scene_file) {
  if (scene_file.empty()) return "";
  if (!std::filesystem::is_regular_file(scene_file))
    return "scene file '" + scene_file + "' not found (expected a .yaml scene, see scenes/)";
  try {
    check_scene_file(scene_file);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

/// Errors found before the job is split, agreed over the whole job (collective): in an MPMD job only one
/// executable may have one (-solid_ranks given to cellfsi-solid, its scene file missing), and the other must
/// not wait for it. The lowest rank with an error prints it. Returns whether any rank had one.
bool agree_on_early_error(const std::string& error) {
  int world_rank = 0, world_size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &world_rank);
  MPI_Comm_size(MPI_COMM_WORLD, &world_size);
  int first_error = error.empty() ? world_size : world_rank;
  MPI_Allreduce(MPI_IN_PLACE, &first_error, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (world_rank == first_error) std::fprintf(stderr, "cellfsi: error: %s\n", error.c_str());
  return first_error < world_size;
}

/// The job split into a fluid group (color 0) and a solid group (color 1), joined by an intercommunicator
/// when there are two (collective over MPI_COMM_WORLD).
struct Groups {
  int color = 0;
  MPI_Comm local = MPI_COMM_NULL, inter = MPI_COMM_NULL;
  std::string error;  // a bad split (then local and inter are null)
};

Groups split_job(Role role, int solid_ranks) {
  int world_rank = 0, world_size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &world_rank);
  MPI_Comm_size(MPI_COMM_WORLD, &world_size);
  Groups g;
  if (role == Role::solid) g.color = 1;
  if (role == Role::combined && solid_ranks > 0) {
    if (solid_ranks >= world_size) {
      g.error = "option -solid_ranks = " + std::to_string(solid_ranks) + " is invalid; valid: 0 to " +
                std::to_string(world_size - 1) + " (fewer than the job's " + std::to_string(world_size) +
                " ranks)";
      return g;
    }
    g.color = world_rank >= world_size - solid_ranks ? 1 : 0;
  }
  MPI_Comm_split(MPI_COMM_WORLD, g.color, world_rank, &g.local);
  int n_color[2] = {0, 0}, mine[2] = {g.color == 0, g.color == 1};
  MPI_Allreduce(mine, n_color, 2, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
  const bool split = role != Role::combined || solid_ranks > 0;
  if (split && (n_color[0] == 0 || n_color[1] == 0)) {
    MPI_Comm_free(&g.local);
    g.error =
        "cellfsi-fluid and cellfsi-solid run together: mpirun -np A cellfsi-fluid SCENE.yaml : -np B "
        "cellfsi-solid SCENE.yaml";
    return g;
  }
  if (split) {
    // The other group's leader: its lowest world rank.
    int lowest[2] = {world_size, world_size}, mine_low[2] = {world_size, world_size};
    mine_low[g.color] = world_rank;
    MPI_Allreduce(mine_low, lowest, 2, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    MPI_Intercomm_create(g.local, 0, MPI_COMM_WORLD, lowest[1 - g.color], 4242, &g.inter);
  }
  return g;
}

/// What -help prints first (then every option table: scene, fluid, coupling, each body, and PETSc's own).
constexpr const char* kHelp =
    "cellfsi: cell-resolved microscale blood flow by NURBS-based immersed fluid-structure interaction\n"
    "(Casquero et al. 2017): a VMS Navier-Stokes fluid on an Eulerian NURBS patch, hyperelastic NURBS\n"
    "membranes and nuclei, coupled by the paper's block-iterative Newton loop. Output: VTK for ParaView,\n"
    "metrics.csv and summary.json in the output folder (README.md, Output).\n\n"
    "Usage: cellfsi [SCENE.yaml] [-option value ...]   (one job; -solid_ranks B puts the bodies on B "
    "ranks)\n"
    "       mpirun -np A cellfsi-fluid SCENE.yaml [options] : -np B cellfsi-solid SCENE.yaml [options]\n"
    "A scene file's keys are options (nested keys join with _); the command line overrides them.\n\n";

/// This group's side of the run under PETSc (on PETSC_COMM_WORLD = the group): the exit code.
int run_group(Arguments& a, const Groups& g) {
  int n = static_cast<int>(a.args.size());
  std::vector<char*> av;
  for (auto& arg : a.args) av.push_back(arg.data());
  av.push_back(nullptr);
  char** avp = av.data();
  if (PetscInitialize(&n, &avp, nullptr, kHelp) != 0) return 1;
  record_petsc_errors();  // PETSc errors become one-line messages (a misspelt type: bad input, exit 1)
  Handshake hs(g.inter);
  int local_rank = 0, status = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &local_rank);
  install_stop_handlers(g.color == 0 && local_rank == 0);  // replaces PETSc's handlers for these signals
  // A file-size limit (ulimit -f) makes a write fail with EFBIG, reported like a full disk, instead of
  // killing the process by SIGXFSZ with nothing saved.
  std::signal(SIGXFSZ, SIG_IGN);
  try {
    status = g.color == 1 ? run_solid(a.scene_name, g.inter, hs) : FluidRun(g.inter, hs, g_launch).run(a.scene_name);
  } catch (const std::invalid_argument& e) {
    print_error(with_scene_file_line(e.what(), a.scene_file, g_launch.command_line));
    status = 1;
  } catch (const CollectiveError& e) {
    print_error(e.what());  // every rank has the same message: rank 0 prints it
    status = 2;
  } catch (const std::exception& e) {
    print_failure(e.what());
    status = 2;
  }
  if (!hs.done()) hs.agree(0);  // the fluid side failed before the solid side was told to start
  PetscFinalize();
  return status;
}

}  // namespace

int launch(int argc, char** argv, Role role) {
  record_ignored_signals();  // before MPI and PETSc install handlers over the dispositions the process got
  // Arguments: a scene file first is read as PETSc options before the command line, which therefore wins.
  g_launch.command_line.assign(argv, argv + argc);
  Arguments a = parse_arguments(argc, argv, role);
  g_launch.scene_file = a.scene_file;

  MPI_Init(&argc, &argv);
  std::string early_error = a.error;
  const std::string job = job_error(role, a.solid_ranks);  // (collective: before any early return)
  if (!job.empty()) early_error = job;
  if (early_error.empty()) early_error = scene_file_error(a.scene_file);
  if (agree_on_early_error(early_error)) {
    MPI_Finalize();
    return 1;
  }
  Groups g = split_job(role, a.solid_ranks);
  if (!g.error.empty()) {
    int world_rank = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &world_rank);
    if (world_rank == 0) std::fprintf(stderr, "cellfsi: error: %s\n", g.error.c_str());
    MPI_Finalize();
    return 1;
  }
  PETSC_COMM_WORLD = g.local;
  const int status = run_group(a, g);
  if (g.inter != MPI_COMM_NULL) MPI_Comm_free(&g.inter);
  MPI_Comm_free(&g.local);
  MPI_Finalize();
  return status;
}

}  // namespace cellfsi::app
