// cellfsi: runs a scene.
//
//   cellfsi                                   # the default scene (plasma shear flow, a few seconds)
//   cellfsi scenes/poiseuille.yaml            # a scene file: YAML read as PETSc options
//   cellfsi scenes/shear.yaml -fluid_elements 128,64 -final_time 0.1 -output_every 10
//   mpirun -np 2 cellfsi scenes/poiseuille.yaml
//   cellfsi scenes/shear.yaml -help           # every option with its default
//
// Writes the run contract of DESIGN.md section 4 to -output_dir (default out/<scene>): summary.json,
// metrics.csv, options.yaml, fluid.pvd. Bad input stops the run before any work with one message and exit
// code 1; a run that fails mid-way (diverged Newton) says why, exits with code 2 and leaves its output
// intact.
#include <petscsys.h>

#include <cmath>
#include <filesystem>
#include <iomanip>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "apps/run_output.hpp"
#include "apps/scene.hpp"
#include "fluid/fluid_output.hpp"
#include "fluid/petsc_error.hpp"

namespace {

/// Fails on options nobody read (a misspelt key must not be silently ignored). Call after the solvers are set
/// up: inner solvers (ASM subdomains, multigrid levels) read their options only then.
void reject_unknown_options() {
  PetscInt n = 0;
  char** names = nullptr;
  char** values = nullptr;
  CELLFSI_PETSC(PetscOptionsLeftGet(nullptr, &n, &names, &values));
  const std::string first = n > 0 ? names[0] : "";
  CELLFSI_PETSC(PetscOptionsLeftRestore(nullptr, &n, &names, &values));
  if (!first.empty())
    throw std::invalid_argument("unknown option -" + first +
                                " (misspelt? run with -help for the valid options)");
}

void print_error(const std::string& message) {
  PetscFPrintf(PETSC_COMM_WORLD, PETSC_STDERR, "cellfsi: error: %s\n", message.c_str());
}

int run(const std::string& default_name) {
  using namespace cellfsi;
  const app::SceneSettings settings = app::SceneSettings::from_options(default_name);
  PetscBool help = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-help", &help));
  app::Scene scene(PETSC_COMM_WORLD, settings);
  if (help) return 0;
  scene.fluid().setup();
  reject_unknown_options();

  int size = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  app::RunOutput out(PETSC_COMM_WORLD, settings.output_dir, settings.name);
  std::unique_ptr<fluid::FluidSeriesWriter> series;
  if (settings.output_every > 0) {
    series = std::make_unique<fluid::FluidSeriesWriter>(settings.output_dir);
    series->write(scene.fluid());
  }
  const int n_steps = static_cast<int>(std::ceil(settings.final_time / settings.dt - 1e-9));
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                            "cellfsi %s: %s, %d ranks, %d steps of %g s to t = %g s, output in %s\n",
                            CELLFSI_VERSION, settings.name.c_str(), size, n_steps, settings.dt,
                            n_steps * settings.dt, settings.output_dir.c_str()));
  long newton = 0, linear = 0;
  int done = 0;
  std::vector<std::pair<std::string, double>> last;
  try {
    for (int k = 1; k <= n_steps; ++k) {
      const fluid::StepStats st = scene.fluid().step();
      newton += st.newton_iterations;
      linear += st.linear_iterations;
      if (!st.converged) {
        const std::string why = "Newton diverged (" + st.reason + ") in step " + std::to_string(k) +
                                " at t = " + std::to_string(k * settings.dt) + " s";
        out.summary("failed: " + why, done, newton, linear, last);
        print_error(why + "; output so far is in " + settings.output_dir);
        return 2;
      }
      done = k;
      last = scene.metrics();
      std::vector<std::pair<std::string, double>> row{{"step", k},
                                                      {"time", scene.fluid().time()},
                                                      {"newton_iterations", st.newton_iterations},
                                                      {"linear_iterations", st.linear_iterations}};
      row.insert(row.end(), last.begin(), last.end());
      out.metrics_row(row);
      out.progress(k, n_steps, scene.fluid().time(), st.newton_iterations, st.linear_iterations);
      if (series && k % settings.output_every == 0) series->write(scene.fluid());
    }
  } catch (const std::exception& e) {
    // Whatever stopped the run mid-way, the summary says so next to the output written so far.
    out.summary(std::string("failed: ") + e.what(), done, newton, linear, last);
    throw;
  }
  out.summary("completed", done, newton, linear, last);
  // The velocity profile across the domain at x = mid-length (section xi_0 = 1/2), as CSV.
  const fluid::SectionData sec = fluid::section(scene.fluid(), 0.5, 65);
  std::ostringstream csv;
  csv << std::setprecision(12) << "x,y,z,vx,vy,vz\n";
  for (size_t i = 0; i < sec.points.size(); ++i)
    csv << sec.points[i][0] << "," << sec.points[i][1] << "," << sec.points[i][2] << "," << sec.velocity[i][0]
        << "," << sec.velocity[i][1] << "," << sec.velocity[i][2] << "\n";
  int rank = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  if (rank == 0) app::write_atomically(settings.output_dir + "/profile.csv", csv.str());
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                            "cellfsi: completed %d steps in %.2f s; summary in %s/summary.json\n", n_steps,
                            out.elapsed(), settings.output_dir.c_str()));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // A scene file as first argument is read as PETSc options before the command line, which therefore wins.
  std::vector<char*> args(argv, argv + argc);
  std::string scene_name = "shear", yaml_flag = "-options_file_yaml", scene_file;
  if (argc > 1 && argv[1][0] != '-') {
    scene_file = argv[1];
    if (!std::filesystem::is_regular_file(scene_file)) {
      std::fprintf(stderr,
                   "cellfsi: error: scene file '%s' not found (expected a .yaml scene, see scenes/)\n",
                   scene_file.c_str());
      return 1;
    }
    scene_name = std::filesystem::path(scene_file).stem().string();
    args[1] = yaml_flag.data();
    args.insert(args.begin() + 2, scene_file.data());
  }
  int n = static_cast<int>(args.size());
  args.push_back(nullptr);
  char** av = args.data();
  if (PetscInitialize(&n, &av, nullptr, nullptr) != 0) return 1;
  int status = 0;
  try {
    status = run(scene_name);
  } catch (const std::invalid_argument& e) {
    print_error(e.what());
    status = 1;
  } catch (const std::exception& e) {
    print_error(e.what());
    status = 2;
  }
  PetscFinalize();
  return status;
}
