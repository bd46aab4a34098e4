// Linear-solver configurations for the fluid on the paper's 2D shear box (0.0024 x 0.0012 cm, periodic in x,
// walls at y = +-0.0006 moving at +-70 * 0.0012 / 2 cm/s, cubic elements, dt = 5e-4 s): wall time per time
// step and per Newton iteration, GMRES iterations, time in assembly / factorisation / linear solves, and peak
// memory, for whatever solver the PETSc options database describes (prefix fluid_; this program does not
// choose a solver). Optionally s^h = 1e10 on the basis functions whose control points lie in a band around
// the paper's capsule (hollow ellipse, semi-axes 1e-4 along x and 2e-4 along y, centred at (0.0012, 0)).
// Prints one markdown table row; bench/run_fluid_solvers.sh runs every configuration and writes
// docs/performance-solvers.md.
//
//   bench/fluid_solvers [-nx 128] [-ny 64] [-steps 5] [-band true] [-label "..."] [-verbose true] <PETSc
//   options> bench/fluid_solvers -header_only true     (prints the table header and exits)
//
// Initial state: the undisturbed shear v = (70 y, 0) plus 1e-3 sin(2 pi x / L) cm/s in v_x (neither
// divergence-free nor steady, so every step has Newton work to do). Timings are max over ranks; the time
// split comes from PETSc's default logging (enabled here, restricted to a "Steps" log stage around the time
// steps): Jacobian = SNESJacobianEval, residual = SNESFunctionEval (includes the line search's),
// linear = PCSetUp + KSPSolve (in PETSc 3.18 these are disjoint: KSPSolve's event starts after the
// preconditioner set-up; ASM's subdomain factorisations run in PCSetUpOnBlocks, inside a nested PCSetUp),
// factor = MatGetOrdering + MatLUFactorSym + MatLUFactorNum, part of linear (count = numeric factorisations
// on rank 0). The rest of the wall time is SNES/line-search vector work. Peak memory = getrusage ru_maxrss
// (the whole process: PETSc, MPI, MUMPS), max over ranks.
#include <petscsys.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "fluid/fluid_solver.hpp"
#include "common/petsc_error.hpp"
#include "geometry/builders.hpp"

using namespace cellfsi;
using geometry::Vec3;

namespace {

constexpr double kLx = 0.0024, kLy = 0.0012, kShearRate = 70.0;
constexpr double kCapsuleA = 2e-4, kCapsuleB = 1e-4;  // semi-axes along y and x
constexpr double kCapsuleX = 0.0012, kCapsuleY = 0.0;
constexpr double kBandScaling = 1e10;

const char* const kHeader =
    "| configuration | mesh | ranks | s^h | unknowns | steps | wall s | s/step | Newton/step | GMRES/Newton "
    "| "
    "s/Newton | Jacobian s | residual s | linear s | factor s (count) | peak MB/rank | result |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";

/// Inclusive time (s) and count of a PETSc log event in a stage on this rank.
struct EventTime {
  double time = 0;
  int count = 0;
};
EventTime event_time(PetscLogStage stage, const char* name) {
  PetscLogEvent ev;
  CELLFSI_PETSC(PetscLogEventGetId(name, &ev));
  PetscEventPerfInfo info{};
  CELLFSI_PETSC(PetscLogEventGetPerfInfo(stage, ev, &info));
  return {info.time, info.count};
}

double max_over_ranks(double v) {
  double m = v;
  MPI_Allreduce(&v, &m, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
  return m;
}

int run(PetscInt nx, PetscInt ny, PetscInt steps, bool band, const std::string& label, bool verbose) {
  const auto box = geometry::rectangle(kLx, kLy, static_cast<int>(nx), static_cast<int>(ny), 3, {true, false},
                                       Vec3(0, -kLy / 2, 0));
  fluid::FluidOptions opt;
  opt.dt = 5e-4;
  const double vw = kShearRate * kLy / 2;
  opt.wall_velocity[1][0] = Vec3(-vw, 0, 0);
  opt.wall_velocity[1][1] = Vec3(vw, 0, 0);
  opt.set_from_options(2);  // -fluid_viscosity etc. may still override the paper's values

  fluid::FluidSolver fs(PETSC_COMM_WORLD, box, opt);
  fs.set_initial_velocity(
      [](const Vec3& x) { return Vec3(kShearRate * x[1] + 1e-3 * std::sin(2 * M_PI * x[0] / kLx), 0, 0); });
  int band_nodes = 0;
  if (band) {
    const double h = std::min(kLx / nx, kLy / ny);
    const auto& cp = fs.patch().control_points();
    auto in_band = [&](int node) {
      const Vec3& x = cp[node];
      const double r = std::hypot((x[0] - kCapsuleX) / kCapsuleB, (x[1] - kCapsuleY) / kCapsuleA);
      return std::abs(r - 1) * std::min(kCapsuleA, kCapsuleB) < 1.5 * h;
    };
    for (int n = 0; n < static_cast<int>(cp.size()); ++n) band_nodes += in_band(n);
    fs.set_scaling([&](int node) { return in_band(node) ? kBandScaling : 1.0; });
  }
  PetscInt n_unknowns = 0;
  CELLFSI_PETSC(VecGetSize(fs.solution(), &n_unknowns));
  int size = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);

  PetscLogStage stage;
  CELLFSI_PETSC(PetscLogStageRegister("Steps", &stage));
  CELLFSI_PETSC(PetscLogStagePush(stage));
  int newton = 0, linear = 0, done = 0;
  std::string result = "converged";
  CELLFSI_PETSC(MPI_Barrier(PETSC_COMM_WORLD));
  const double t0 = MPI_Wtime();
  for (int s = 0; s < steps; ++s) {
    const double ts = MPI_Wtime();
    const fluid::StepStats st = fs.step();
    newton += st.newton_iterations;
    linear += st.linear_iterations;
    if (verbose)
      CELLFSI_PETSC(PetscFPrintf(PETSC_COMM_WORLD, stderr, "  step %d: %s, %d Newton, %d linear, %.3f s\n",
                                 s + 1, st.reason.c_str(), st.newton_iterations, st.linear_iterations,
                                 MPI_Wtime() - ts));
    if (!st.converged) {
      result = st.reason + " at step " + std::to_string(s + 1);
      break;
    }
    ++done;
  }
  CELLFSI_PETSC(MPI_Barrier(PETSC_COMM_WORLD));
  const double wall = MPI_Wtime() - t0;
  CELLFSI_PETSC(PetscLogStagePop());

  const double jac = max_over_ranks(event_time(stage, "SNESJacobianEval").time);
  const double res = max_over_ranks(event_time(stage, "SNESFunctionEval").time);
  const double linear_s =
      max_over_ranks(event_time(stage, "PCSetUp").time + event_time(stage, "KSPSolve").time);
  const EventTime num = event_time(stage, "MatLUFactorNum");
  const double factor = max_over_ranks(event_time(stage, "MatGetOrdering").time +
                                       event_time(stage, "MatLUFactorSym").time + num.time);
  struct rusage ru {};
  getrusage(RUSAGE_SELF, &ru);
  const double peak_mb = max_over_ranks(static_cast<double>(ru.ru_maxrss) / 1024.0);  // ru_maxrss is in KiB

  const int attempted = done + (result == "converged" ? 0 : 1);
  const std::string sh = band ? "1e10 on band (" + std::to_string(band_nodes) + " nodes)" : std::string("1");
  CELLFSI_PETSC(
      PetscPrintf(PETSC_COMM_WORLD,
                  "| %s | %dx%d | %d | %s | %d | %d | %.2f | %.3f | %.2f | %.1f | %.3f | %.2f | %.2f | "
                  "%.2f | %.2f (%d) | %.0f | %s |\n",
                  label.c_str(), (int)nx, (int)ny, size, sh.c_str(), (int)n_unknowns, done, wall,
                  wall / std::max(attempted, 1), static_cast<double>(newton) / std::max(attempted, 1),
                  static_cast<double>(linear) / std::max(newton, 1), wall / std::max(newton, 1), jac, res,
                  linear_s, factor, num.count, peak_mb, result.c_str()));
  return result == "converged" ? 0 : 2;
}

}  // namespace

int main(int argc, char** argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, nullptr));
  PetscBool header_only = PETSC_FALSE, band = PETSC_FALSE, verbose = PETSC_FALSE;
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-header_only", &header_only, nullptr));
  if (header_only) {
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "%s", kHeader));
    PetscCall(PetscFinalize());
    return 0;
  }
  PetscCall(PetscLogDefaultBegin());
  PetscInt nx = 128, ny = 64, steps = 5;
  char label[256] = "default";
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-nx", &nx, nullptr));
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-ny", &ny, nullptr));
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-steps", &steps, nullptr));
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-band", &band, nullptr));
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-verbose", &verbose, nullptr));
  PetscCall(PetscOptionsGetString(nullptr, nullptr, "-label", label, sizeof label, nullptr));
  int rc = 0;
  try {
    rc = run(nx, ny, steps, band, label, verbose);
  } catch (const std::exception& e) {
    PetscCall(
        PetscPrintf(PETSC_COMM_WORLD, "| %s | %dx%d | error: %s |\n", label, (int)nx, (int)ny, e.what()));
    rc = 1;
  }
  PetscCall(PetscFinalize());
  return rc;
}
