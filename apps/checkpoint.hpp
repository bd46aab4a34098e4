#pragma once
// Checkpoints and restarts. DIR/checkpoint/ holds fluid.petsc (PETSc binary: the fluid unknowns and their
// rate after the checkpoint's step, as fluid::ImmersedFluid::state_bytes gives them; the VMS fluid's in the
// DMDA's natural ordering, so any number of ranks can read it) and
// state.json (the step, the run's counters, the options of the run that wrote it, each body's state and
// metric records, the output series so far and what their samples found of J). It is replaced whole: written
// as DIR/checkpoint.new, then renamed.
#include <petscvec.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fluid/immersed_fluid.hpp"
#include "geometry/patch_vtk.hpp"
#include "solid/solid_output.hpp"

namespace cellfsi::app {

struct Checkpoint {
  int step = 0;
  double time = 0;
  long newton = 0, linear = 0, factorizations = 0, bulk_factorizations = 0;
  std::string options;  // options.yaml of the run that wrote it
  std::vector<std::string> body_names;
  std::vector<std::vector<double>> bodies, trackers;  // per body: SolidSolver::state, BodyTracker::state
  nlohmann::json scene_metrics;                       // Scene::metric_state
  std::vector<geometry::PvdEntry> fluid_series, solid_series;
  int solid_writes = 0;
  // SolidSeriesWriter::history (absent from checkpoints written before it was recorded: empty)
  std::vector<solid::JHistory> solid_J;
};

/// Writes DIR/checkpoint: collective over comm (the fluid's state, ImmersedFluid::state_bytes); rank 0 writes
/// the rest and renames.
void write_checkpoint(MPI_Comm comm, const std::string& dir, const Checkpoint& c,
                      const fluid::ImmersedFluid& fluid);
/// Throws std::invalid_argument (option -restart) unless DIR holds a checkpoint. Touches nothing: a refused
/// restart must not leave a folder or a lock file behind.
void require_checkpoint(const std::string& dir);
/// Reads DIR/checkpoint (collective); the fluid takes its state (ImmersedFluid::load_state) after the checks.
/// Throws std::invalid_argument naming the folder when there is no checkpoint or it cannot be read, naming
/// the options when the checkpoint was written with options other than `options` (this run's options.yaml
/// text; checked before the fluid state is loaded, so another mesh is named as such), and when the fluid
/// state holds a NaN or an infinity.
Checkpoint read_checkpoint(MPI_Comm comm, const std::string& dir, const std::string& options,
                           fluid::ImmersedFluid& fluid);
/// The options (as "-name: checkpoint SAVED, this run CURRENT") whose values differ between two options.yaml
/// texts, leaving out those a restart may change: final_time, restart, output_every, checkpoint_every,
/// output_dir, metrics_average_from, and monitors, viewers and -help; and -scene when SAVED has none (a
/// checkpoint written before the scene's name was recorded).
std::vector<std::string> conflicting_options(const std::string& saved, const std::string& current);

}  // namespace cellfsi::app
