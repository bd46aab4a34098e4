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
  coupling::Exchange exchange(inter, kExchangeMailboxBytes);
  coupling::serve_solids(exchange, mine);
  return 0;
}

}  // namespace

int launch(int argc, char** argv, Role role) {
  record_ignored_signals();  // before MPI and PETSc install handlers over the dispositions the process got
  // Arguments: a scene file first is read as PETSc options before the command line, which therefore wins;
  // -solid_ranks B (launch option, command line only) splits the job.
  std::vector<std::string> args(argv, argv + argc);
  g_launch.command_line = args;
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
    g_launch.scene_file = scene_file;
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
    g_launch.scene_file = scene_file;
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
      status = color == 1 ? run_solid(scene_name, inter, hs) : FluidRun(inter, hs, g_launch).run(scene_name);
    } catch (const std::invalid_argument& e) {
      print_error(with_scene_file_line(e.what(), scene_file, g_launch.command_line));
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
  }
  if (inter != MPI_COMM_NULL) MPI_Comm_free(&inter);
  MPI_Comm_free(&local);
  MPI_Finalize();
  return status;
}

}  // namespace cellfsi::app
