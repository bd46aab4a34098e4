#include "apps/checkpoint.hpp"

#include <petscviewer.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "apps/run_output.hpp"
#include "common/file_io.hpp"
#include "common/petsc_error.hpp"

namespace cellfsi::app {

namespace fs = std::filesystem;

namespace {

nlohmann::json series_json(const std::vector<geometry::PvdEntry>& entries) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& e : entries)
    a.push_back({{"file", e.file}, {"time", e.time}, {"part", e.part}, {"name", e.name}});
  return a;
}

std::vector<geometry::PvdEntry> series_from(const nlohmann::json& a) {
  std::vector<geometry::PvdEntry> out;
  for (const auto& e : a)
    out.push_back({e.at("file").get<std::string>(), e.at("time").get<double>(), e.at("part").get<int>(),
                   e.at("name").get<std::string>()});
  return out;
}

nlohmann::json smallest_json(const solid::SmallestJ& s) {
  return {{"J", s.J}, {"x", {s.x[0], s.x[1], s.x[2]}}, {"time", s.time}};
}

solid::SmallestJ smallest_from(const nlohmann::json& o) {
  solid::SmallestJ s;
  // (JSON has no infinity: a J never sampled is written as null)
  s.J = o.at("J").is_null() ? std::numeric_limits<double>::infinity() : o.at("J").get<double>();
  for (int d = 0; d < 3; ++d) s.x[d] = o.at("x").at(d).get<double>();
  s.time = o.at("time").get<double>();
  return s;
}

nlohmann::json j_history_json(const std::vector<solid::JHistory>& history) {
  nlohmann::json a = nlohmann::json::array();
  for (const solid::JHistory& h : history)
    a.push_back({{"least", smallest_json(h.least)},
                 {"first_fold", h.folded ? smallest_json(h.first_fold) : nlohmann::json()}});
  return a;
}

std::vector<solid::JHistory> j_history_from(const nlohmann::json& a) {
  std::vector<solid::JHistory> out;
  for (const auto& e : a) {
    solid::JHistory h;
    h.least = smallest_from(e.at("least"));
    h.folded = !e.at("first_fold").is_null();
    if (h.folded) h.first_fold = smallest_from(e.at("first_fold"));
    out.push_back(h);
  }
  return out;
}

/// "key: value" lines of an options.yaml text (comments skipped).
std::map<std::string, std::string> option_map(const std::string& text) {
  std::map<std::string, std::string> m;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    const auto colon = line.find(": ");
    if (colon == std::string::npos) continue;
    m[line.substr(0, colon)] = line.substr(colon + 2);
  }
  return m;
}

/// A PETSc binary viewer on path (no .info file).
PetscViewer binary_viewer(MPI_Comm comm, const fs::path& path, PetscFileMode mode) {
  PetscViewer v = nullptr;
  CELLFSI_PETSC(PetscViewerCreate(comm, &v));
  CELLFSI_PETSC(PetscViewerSetType(v, PETSCVIEWERBINARY));
  CELLFSI_PETSC(PetscViewerBinarySetSkipInfo(v, PETSC_TRUE));
  CELLFSI_PETSC(PetscViewerFileSetMode(v, mode));
  CELLFSI_PETSC(PetscViewerFileSetName(v, path.c_str()));
  return v;
}

bool may_change(const std::string& key) {
  static const char* const kFree[] = {
      "final_time",           "restart", "output_every", "checkpoint_every", "output_dir", "output_dir_adopt",
      "metrics_average_from", "help",    "log_view",     "options_left",     "malloc_dump"};
  for (const char* k : kFree)
    if (key == k) return true;
  return key.find("monitor") != std::string::npos || key.find("view") != std::string::npos ||
         key.find("converged_reason") != std::string::npos;
}

}  // namespace

std::vector<std::string> conflicting_options(const std::string& saved, const std::string& current) {
  const auto a = option_map(saved), b = option_map(current);
  std::vector<std::string> out;
  for (const auto& [k, v] : a) {
    if (may_change(k)) continue;
    const auto it = b.find(k);
    if (it == b.end())
      out.push_back("-" + k + ": checkpoint " + v + ", this run (not given)");
    else if (it->second != v)
      out.push_back("-" + k + ": checkpoint " + v + ", this run " + it->second);
  }
  // (A checkpoint written before the scene's name was recorded has none: its name is not compared.)
  for (const auto& [k, v] : b)
    if (!may_change(k) && k != "scene" && a.find(k) == a.end())
      out.push_back("-" + k + ": checkpoint (not given), this run " + v);
  return out;
}

void write_checkpoint(MPI_Comm comm, const std::string& dir, const Checkpoint& c,
                      const fluid::ImmersedFluid& fluid) {
  const fs::path next = fs::path(dir) / "checkpoint.new", cur = fs::path(dir) / "checkpoint",
                 old = fs::path(dir) / "checkpoint.old";
  on_rank_zero(comm, [&] {
    std::error_code ec;
    fs::remove_all(next, ec);
    fs::create_directories(next, ec);
    if (ec) throw_write_error(next.string(), ec.message());
  });
  // Every failure below leaves the previous checkpoint as it was (only checkpoint.new is touched) and is
  // reported on every rank, naming the file. The vectors are gathered on rank 0 and written there with
  // checked writes: through a PETSc binary viewer a failed write on rank 0 leaves the other ranks waiting
  // inside VecView, and names no reason.
  const fs::path fluid_file = next / "fluid.petsc";
  const std::string fluid_bytes = fluid.state_bytes();
  on_rank_zero(comm, [&] {
    try {
      write_file_atomically(fluid_file.string(), fluid_bytes);
    } catch (const WriteError&) {
      std::error_code ec;
      fs::remove_all(next, ec);
      throw;
    }
  });
  on_rank_zero(comm, [&] {
    nlohmann::ordered_json js;
    js["format"] = "cellfsi checkpoint 1";
    js["step"] = c.step;
    js["time"] = c.time;
    js["newton_iterations"] = c.newton;
    js["linear_iterations"] = c.linear;
    js["factorizations"] = c.factorizations;
    js["bulk_factorizations"] = c.bulk_factorizations;
    js["options"] = c.options;
    js["body_names"] = c.body_names;
    js["bodies"] = c.bodies;
    js["trackers"] = c.trackers;
    js["scene_metrics"] = c.scene_metrics;
    js["fluid_series"] = series_json(c.fluid_series);
    js["solid_series"] = series_json(c.solid_series);
    js["solid_writes"] = c.solid_writes;
    js["solid_J"] = j_history_json(c.solid_J);
    try {
      write_file_atomically((next / "state.json").string(), js.dump() + "\n");
    } catch (const WriteError&) {
      std::error_code ec;
      fs::remove_all(next, ec);
      throw;
    }
    // The new checkpoint replaces the previous one; between the two renames the previous one is
    // checkpoint.old, which read_checkpoint falls back on.
    std::error_code ec;
    if (fs::exists(cur)) {
      // (Without checkpoint/, checkpoint.old is the only good one, e.g. after a restart from it: it stays
      // until the new one is in place.)
      fs::remove_all(old, ec);
      fs::rename(cur, old, ec);
      if (ec) throw_write_error(cur.string(), "cannot rename it to checkpoint.old: " + ec.message());
    }
    fs::rename(next, cur, ec);
    if (ec) throw_write_error(cur.string(), "cannot rename checkpoint.new to it: " + ec.message());
    sync_folder(dir);
    fs::remove_all(old, ec);
  });
}

namespace {

/// The checkpoint folder of DIR: checkpoint/, or checkpoint.old/ when a run stopped between replacing one by
/// the other; empty if there is none.
fs::path checkpoint_folder(const std::string& dir) {
  for (const char* name : {"checkpoint", "checkpoint.old"}) {
    const fs::path at = fs::path(dir) / name;
    std::error_code ec;
    if (fs::exists(at / "state.json", ec) && fs::exists(at / "fluid.petsc", ec)) return at;
  }
  return {};
}

}  // namespace

void require_checkpoint(const std::string& dir) {
  if (checkpoint_folder(dir).empty())
    throw std::invalid_argument("option -restart is invalid here: '" + dir +
                                "' holds no checkpoint (a run writes DIR/checkpoint every -checkpoint_every "
                                "steps, at its end and when it is interrupted)");
}

Checkpoint read_checkpoint(MPI_Comm comm, const std::string& dir, const std::string& options,
                           fluid::ImmersedFluid& fluid) {
  require_checkpoint(dir);
  const fs::path at = checkpoint_folder(dir);
  Checkpoint c;
  try {
    std::ifstream in(at / "state.json");
    const nlohmann::json js = nlohmann::json::parse(in);
    if (js.at("format") != "cellfsi checkpoint 1") throw std::runtime_error("unknown format");
    c.step = js.at("step").get<int>();
    c.time = js.at("time").get<double>();
    c.newton = js.at("newton_iterations").get<long>();
    c.linear = js.at("linear_iterations").get<long>();
    c.factorizations = js.at("factorizations").get<long>();
    // (absent from checkpoints written before it was counted)
    c.bulk_factorizations = js.value("bulk_factorizations", 0L);
    c.options = js.at("options").get<std::string>();
    c.body_names = js.at("body_names").get<std::vector<std::string>>();
    c.bodies = js.at("bodies").get<std::vector<std::vector<double>>>();
    c.trackers = js.at("trackers").get<std::vector<std::vector<double>>>();
    c.scene_metrics = js.at("scene_metrics");
    c.fluid_series = series_from(js.at("fluid_series"));
    c.solid_series = series_from(js.at("solid_series"));
    c.solid_writes = js.at("solid_writes").get<int>();
    // (absent from checkpoints written before it was recorded)
    if (js.contains("solid_J")) c.solid_J = j_history_from(js.at("solid_J"));
  } catch (const std::exception& e) {
    throw std::invalid_argument("checkpoint '" + (at / "state.json").string() +
                                "' cannot be read: " + e.what());
  }
  // Before the fluid state: a state of another mesh would otherwise be refused as not fitting, naming no
  // option.
  if (const std::vector<std::string> conflicts = conflicting_options(c.options, options);
      !conflicts.empty()) {
    std::string list;
    for (const std::string& k : conflicts) list += (list.empty() ? "" : "; ") + k;
    throw std::invalid_argument("option -restart is invalid here: the checkpoint in '" + dir +
                                "' was written with other options (" + list +
                                "); a restart may change only -final_time, -output_every, "
                                "-checkpoint_every, -metrics_average_from and monitors");
  }
  PetscViewer v = binary_viewer(comm, at / "fluid.petsc", FILE_MODE_READ);
  using Loaded = fluid::ImmersedFluid::LoadedState;
  const Loaded loaded = fluid.load_state(v, c.step);
  PetscViewerDestroy(&v);
  if (loaded == Loaded::does_not_fit)
    throw std::invalid_argument("checkpoint '" + (at / "fluid.petsc").string() +
                                "' does not fit this fluid mesh (or is damaged)");
  // A damaged state would otherwise run on as NaN until the first step fails, far from its cause.
  if (loaded == Loaded::not_finite)
    throw std::invalid_argument("option -restart is invalid here: the fluid state in '" +
                                (at / "fluid.petsc").string() +
                                "' holds NaN or infinite values (the checkpoint is damaged); run without "
                                "-restart");
  return c;
}

}  // namespace cellfsi::app
