#pragma once
// External loads on a body and the measures of the optical-tweezers stretching test (issue 28, item 4; Mills
// et al. 2004): two beads glued at opposite ends of a red blood cell's rim pull it apart with equal and
// opposite forces; the cell's diameters along the pull (axial, D_A) and across it (transverse, D_T) are
// measured at equilibrium.
//
// A load is a total force F on the material of a patch: the points of the body whose reference position lies
// within a contact radius of a centre (through the whole thickness of a membrane: both faces). It is spread
// uniformly per unit reference volume, f = F / V_patch, so that sum_q w_q f_q = F over the patch's
// quadrature points, and it is a dead load: the density rides with the material and never changes. In the
// immersed method it enters the fluid's momentum equation where the material is, at the solid's current
// quadrature points, as the stress does (QuadratureData::force; fluid::immersed_residual).
#include <array>
#include <limits>
#include <vector>

#include "geometry/patch.hpp"

namespace cellfsi::solid {

/// A total force [dyn] on the material within `radius` [cm] of `center` [cm] (reference configuration).
struct PatchLoad {
  geometry::Vec3 center = geometry::Vec3::Zero();
  double radius = 0;
  geometry::Vec3 force = geometry::Vec3::Zero();
};

/// The force per unit reference volume [dyn/cm^3] at each point (reference positions X, reference volume
/// weights w) from the loads: F / V_patch on every point of a patch, V_patch the sum of its points' weights,
/// zero elsewhere. Throws std::invalid_argument when a patch holds no point (a contact radius smaller than
/// the spacing of the points) or two patches share a point (patches larger than the body).
std::vector<geometry::Vec3> load_densities(const std::vector<geometry::Vec3>& X, const std::vector<double>& w,
                                           const std::vector<PatchLoad>& loads);

/// A membrane's mid-surface (direction 0 at mid-thickness) sampled at n1 x n2 points evenly spaced in the
/// parameters of directions 1 and 2, ends included (in 2D direction 2 is ignored). The default counts take
/// the middle and the quarters of each direction: an RBC's rim and an ellipsoid's equator and axes.
std::vector<geometry::Vec3> mid_surface_points(const geometry::Patch& membrane, int n1 = 129, int n2 = 257);

/// The two ends of a membrane along the unit vector `axis`: its mid-surface points with the smallest and the
/// largest projection on the axis, in that order.
std::array<geometry::Vec3, 2> membrane_ends(const geometry::Patch& membrane, const geometry::Vec3& axis);
/// The same among given mid-surface points (a body of several patches: all of theirs).
std::array<geometry::Vec3, 2> membrane_ends(const std::vector<geometry::Vec3>& points,
                                            const geometry::Vec3& axis);

/// The stretching test's diameters of a membrane's mid-surface: the axial one, its extent along the unit
/// vector `axis`, and the transverse one, its largest extent across the axis (the widest of its projections
/// on 180 directions normal to the axis, 1 degree apart: for a red blood cell pulled along its rim, the width
/// of the disc seen face-on, the diameter Mills et al. measured).
struct StretchDiameters {
  double axial = 0, transverse = 0;
};
StretchDiameters stretch_diameters(const std::vector<geometry::Vec3>& points, const geometry::Vec3& axis);

/// A membrane's extent along each coordinate axis: the largest minus the smallest coordinate of its
/// mid-surface sampled at n1 x n2 points (mid_surface_points; the default counts hold an RBC's rim and an
/// ellipsoid's axes exactly, and a turned 7.8 um cell's extremes to about 1 nm: R (1 - cos(pi / (n2 - 1)))). The
/// bounding box whose sides peers report as a cell's diameters in shear (HemoCell's examples/oneCellShear). z is
/// 0 in 2D.
geometry::Vec3 mid_surface_extent(const geometry::Patch& membrane, int n1 = 65, int n2 = 129);

/// When a stretched body has come to rest: the first record at which neither diameter has changed by more
/// than `tolerance` of itself over the last `window` seconds (compared with the latest record at least
/// `window` before it), with the whole window after `not_before` (the end of a force's ramp: while the force
/// still grows, a body that follows a slow ramp closely changes little over a window without being at rest).
class EquilibriumMonitor {
 public:
  EquilibriumMonitor(double tolerance, double window, double not_before = 0)
      : tolerance_(tolerance), window_(window), not_before_(not_before) {}
  void record(double time, const StretchDiameters& d);
  bool reached() const { return reached_ >= 0; }
  /// The diameters at the last record (zero before the first).
  StretchDiameters last() const { return records_.empty() ? StretchDiameters{} : records_.back().d; }
  /// The time at which equilibrium was first reached (NaN before).
  double time() const;
  /// The largest relative change of the diameters over the window ending at the last record (NaN before a
  /// window has passed).
  double last_change() const { return last_change_; }
  /// The records as plain numbers (for a checkpoint) and their restoration.
  std::vector<double> state() const;
  void restore(const std::vector<double>& state);

 private:
  struct Record {
    double time = 0;
    StretchDiameters d;
  };
  double tolerance_, window_, not_before_;
  std::vector<Record> records_;
  int reached_ = -1;  // index of the first record at equilibrium
  double last_change_ = std::numeric_limits<double>::quiet_NaN();
};

}  // namespace cellfsi::solid
