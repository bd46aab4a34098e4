#pragma once
// Output of the immersed bodies: a ParaView time series (DIR/solid.pvd, one .vts per body and output step,
// the bodies as parts; a body made of patches, solid/composite_solid.hpp, one .vts per patch, NAME_pK) with
// the displacement [cm], J = det F and the Cauchy stress [dyn/cm^2] sampled on each body's current
// configuration. Works through the SolidSolver interface, so it serves every solid
// implementation and both launch modes.
#include <limits>
#include <string>
#include <vector>

#include "geometry/patch_vtk.hpp"
#include "solid/solid_solver.hpp"

namespace cellfsi::solid {

/// The smallest J = det F of a body over the output's samples (`samples_per_element` per element and
/// direction, element edges and a shell's faces included, just off degenerate ends: what the .vts files' J
/// shows) and where, in the current configuration. The solver checks J only at its quadrature points; a shell
/// whose face has folded between them shows J <= 0 here first.
struct SmallestJ {
  double J = 1.0;
  geometry::Vec3 x = geometry::Vec3::Zero();
  double time = 0.0;  // of the write that found it [s]
};

/// What the output's samples found of a body over a run's writes (a restart's included): the smallest J,
/// and the first write at which J <= 0 somewhere (`folded` false: none so far).
struct JHistory {
  SmallestJ least{std::numeric_limits<double>::infinity()};
  bool folded = false;
  SmallestJ first_fold;
};

class SolidSeriesWriter {
 public:
  /// writes == false: the bodies are queried (a remote body must be queried on every rank of its group) but
  /// nothing is written (ranks other than the one that writes).
  SolidSeriesWriter(std::string dir, bool writes, int samples_per_element = 4);
  void write(double time, const std::vector<SolidSolver*>& bodies);
  /// The entries and the number of writes so far, and a restart's: continue the series after these.
  const std::vector<geometry::PvdEntry>& entries() const { return entries_; }
  int count() const { return count_; }
  /// Per body, the smallest J of the last write (the writing rank only, else empty).
  const std::vector<SmallestJ>& smallest() const { return smallest_; }
  /// Per body, the smallest J and the first fold over the writes so far, a restart's history included (the
  /// writing rank only, else empty).
  const std::vector<JHistory>& history() const { return history_; }
  /// A restart: continue the series, and the history, after these (an empty history: start it afresh).
  void resume(std::vector<geometry::PvdEntry> entries, int count, std::vector<JHistory> history = {}) {
    entries_ = std::move(entries);
    count_ = count;
    history_ = std::move(history);
  }

 private:
  /// One dataset: body b's patch (the body itself, or one of its parts) as part `dataset` of the collection.
  void write_body(double time, std::size_t b, int dataset, const SolidSolver& body,
                  const std::string& file_name);
  std::string dir_;
  bool writes_;
  int samples_;
  int count_ = 0;
  std::vector<geometry::PvdEntry> entries_;
  std::vector<SmallestJ> smallest_;
  std::vector<JHistory> history_;
};

}  // namespace cellfsi::solid
