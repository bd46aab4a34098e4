#pragma once
// Output of the fluid state: a ParaView time series (fluid.pvd + one .vts per output step, each written by
// the discretisation: ImmersedFluid::write_fields; the VMS one's in fluid_output.cpp, with velocity,
// pressure (dyn/cm^2), s^h and vorticity sampled on the patch, and the velocity's disturbance of a known
// flow). Section data (the flow rate through, and the velocity profile across, the section xi_0 = const: a
// plane x = const for the builders' channels) is ImmersedFluid::section; the VMS one's is here too.
#include <functional>
#include <string>
#include <vector>

#include "fluid/immersed_fluid.hpp"
#include "geometry/patch_vtk.hpp"

namespace cellfsi::fluid {

/// Writes DIR/fluid_NNNNNN.vts for each call (on several ranks: a piece per rank, fluid_NNNNNN_pRRRR.vts, and
/// the index fluid_NNNNNN.pvts) and keeps DIR/fluid.pvd listing them (collective; each rank samples its own
/// elements, nothing is gathered).
class FluidSeriesWriter {
 public:
  FluidSeriesWriter(std::string dir, int samples_per_element = 2);
  /// Also write "velocity_disturbance" = velocity - `undisturbed`(x) (the flow without cells, e.g. the shear;
  /// paper Figs. 3d and 4f plot its magnitude).
  void set_undisturbed_velocity(std::function<geometry::Vec3(const geometry::Vec3&)> undisturbed) {
    undisturbed_ = std::move(undisturbed);
  }
  void write(const ImmersedFluid& fluid);
  /// The entries written so far, and a restart's: continue the series after these.
  const std::vector<geometry::PvdEntry>& entries() const { return entries_; }
  void resume(std::vector<geometry::PvdEntry> entries) { entries_ = std::move(entries); }

 private:
  std::string dir_;
  int samples_;
  std::function<geometry::Vec3(const geometry::Vec3&)> undisturbed_;
  std::vector<geometry::PvdEntry> entries_;
};

}  // namespace cellfsi::fluid
