#pragma once
// A scene: the domain, the flow, time stepping and output settings, read from the options database (a scene
// YAML file is read into it: nested keys become prefixes, the command line overrides). This scenes
// are plasma only: a shear flow between moving walls and a channel flow driven by a body force.
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "fluid/fluid_solver.hpp"
#include "geometry/builders.hpp"

namespace cellfsi::app {

struct SceneSettings {
  std::string name = "shear";
  int dim = 2;
  std::string domain = "rectangle";          // rectangle | box | narrowing
  std::vector<double> size{0.0024, 0.0012};  // domain extent [cm]
  geometry::Vec3 origin = geometry::Vec3::Zero();
  std::array<bool, 3> periodic{true, false, false};
  geometry::NarrowingChannel channel;
  std::array<int, 3> elements{64, 32, 1};
  int degree = 3;
  std::string flow = "shear";  // shear | poiseuille | rest
  double shear_rate = 70.0;    // [1/s]
  double final_time = 0.05;    // [s]
  int output_every = 0;        // write fluid.pvd every N steps (0: never)
  std::string output_dir;      // default out/<name>
  double dt = 5e-4;            // time step [s] (-dt)

  /// Reads every scene option (see -help) and validates; throws std::invalid_argument naming option, value
  /// and range.
  static SceneSettings from_options(const std::string& default_name);
};

/// The assembled scene: the patch, the fluid solver and the flow's metrics.
class Scene {
 public:
  Scene(MPI_Comm comm, const SceneSettings& settings);
  fluid::FluidSolver& fluid() { return *fluid_; }
  const SceneSettings& settings() const { return s_; }
  /// Metrics of the current state (names are the CSV/JSON keys), including errors against analytic solutions
  /// where the scene has one.
  std::vector<std::pair<std::string, double>> metrics();

 private:
  SceneSettings s_;
  geometry::Patch patch_;
  std::unique_ptr<fluid::FluidSolver> fluid_;
  int wall_dir_ = -1;  // the wall-normal direction (shear, poiseuille)
};

}  // namespace cellfsi::app
