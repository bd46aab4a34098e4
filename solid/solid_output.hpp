#pragma once
// Output of the immersed bodies: a ParaView time series (DIR/solid.pvd, one .vts per body and output step,
// the bodies as parts) with the displacement [cm], J = det F and the Cauchy stress [dyn/cm^2] sampled on each
// body's current configuration. Works through the SolidSolver interface, so it serves every solid
// implementation and both launch modes.
#include <string>
#include <vector>

#include "geometry/patch_vtk.hpp"
#include "solid/solid_solver.hpp"

namespace cellfsi::solid {

class SolidSeriesWriter {
 public:
  /// writes == false: the bodies are queried (a remote body must be queried on every rank of its group) but
  /// nothing is written (ranks other than the one that writes).
  SolidSeriesWriter(std::string dir, bool writes, int samples_per_element = 4);
  void write(double time, const std::vector<SolidSolver*>& bodies);
  /// The entries and the number of writes so far, and a restart's: continue the series after these.
  const std::vector<geometry::PvdEntry>& entries() const { return entries_; }
  int count() const { return count_; }
  void resume(std::vector<geometry::PvdEntry> entries, int count) {
    entries_ = std::move(entries);
    count_ = count;
  }

 private:
  std::string dir_;
  bool writes_;
  int samples_;
  int count_ = 0;
  std::vector<geometry::PvdEntry> entries_;
};

}  // namespace cellfsi::solid
