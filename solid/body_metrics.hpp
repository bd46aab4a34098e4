#pragma once
// Shape and motion measures of one immersed body over time, from its patches (paper Sec. 3.3-3.4,
// docs/design.md §3). Plain functions of the geometry: they never touch a solver, so they serve every
// SolidSolver and both launch modes.
//
//   r_A        relative change of the solid's own area/volume (paper Eq. (21): for a membrane the area of
//              the thin band, the quantity that spurious mass-conservation errors change)
//   r_P        relative change of the perimeter/surface area (Eq. (22)): of the mid-surface for a membrane,
//   of
//              the outer boundary for a bulky body
//   theta_deg  inclination: angle from the flow direction (+x) to the long axis (least second moment) of the
//              region a membrane encloses (of the body itself when bulky), counter-clockwise positive,
//              unwrapped in time and reported in (-90, 90]; in 3D the long axis of the second moments'
//              block in the shear plane (an oblate RBC's 3D long axis may lie anywhere in its disc)
//   deformation_index
//              Taylor's (L - B) / (L + B) in the shear plane: L and B the axes of the ellipse with the
//              region's second moments in that plane (theta's block in 3D), so (sqrt(l1) - sqrt(l2)) /
//              (sqrt(l1) + sqrt(l2)) of its eigenvalues l1 >= l2: (a - b) / (a + b) for an ellipse or an
//              ellipsoid with semi-axes a, b in the plane
//   omega_tt   tank-treading frequency of a membrane: mean angular velocity of its material points about the
//              centroid, in turns per second, positive clockwise (the sense of a shear flow with
//              gammadot > 0)
//   omega_tu   tumbling frequency: turns per second of the long axis (elongated bodies; in the summary over
//              the whole half-turns of the axis in the window when it made one); of the material points for
//              a body that is round in its reference shape (a round nucleus has no axis of its own, but turns
//              as a whole)
//   regime     (summary) the motion, decided from the data in the window: see motion_regime()
//   max_stretch (summary, membranes) the largest principal stretch of the mid-surface over the run: of the
//              mid-line's length in 2D, the larger eigenvalue of the surface's metric against the reference's
//              in 3D (sampled at 4 points per element and direction)
// theta is reported for every body whose current shape has a long axis (a round body's is that of its
// deformation).
// Angles are taken in the shear plane spanned by x and `plane_dir` (the wall-normal direction).
#include <Eigen/Dense>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "geometry/measures.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::solid {

using Metric = std::pair<std::string, double>;

/// How a tracker's work is shared among ranks: each rank integrates its share of every patch's elements and
/// samples its share of the stretch points; `sum` adds a short array over the ranks in place and `max` takes
/// the largest (apps/scene.cpp: on rank 0, then broadcast), so that every rank records the same sample. The
/// default: one rank does all.
struct MetricShare {
  geometry::ElementShare elements;
  std::function<void(double* values, int n)> sum;
  std::function<void(double* values, int n)> max;
};

class BodyTracker {
 public:
  /// `reference`: the body in its reference configuration (direction 0 through the thickness or from the
  /// centre, as the builders make it). `n_material_points` points along direction 1 (and 2 in 3D) are
  /// followed for omega.
  BodyTracker(const geometry::Patch& reference, bool membrane, int plane_dir = 1, int n_material_points = 64);
  /// A body made of patches (solid/composite_solid.hpp: a membrane's parts, together closed), measured as
  /// one: its integrals about one reference point, each part's share of the material points
  /// (n_material_points over the parts, at least 4 along each direction of each part) and of the stretch
  /// samples. One patch: as the constructor above.
  BodyTracker(const std::vector<geometry::Patch>& reference, bool membrane, int plane_dir = 1,
              int n_material_points = 64);

  /// Records the body's configuration at `time` (call once per step, in order). With a share, collective over
  /// the ranks that hold it: each calls it with the same patch and its own part.
  void record(double time, const geometry::Patch& current, const MetricShare& share = {});
  /// The same for a body made of patches (as many as the reference's, in its order).
  void record(double time, const std::vector<geometry::Patch>& current, const MetricShare& share = {});

  /// Values at the last record (omega: over the last interval; 0 before the second record; 3D: the short
  /// axis's angle to the vorticity direction, short_axis_to_vorticity_deg).
  std::vector<Metric> metrics() const;
  /// The run's results: final r_A and r_P, the largest |r_A| and |r_P|, the largest anisotropy of the shape
  /// (largest / smallest second moment - 1) with its time and centroid x, and over the records with time >=
  /// average_from (the oscillatory regime) the mean inclination, its half peak-to-peak oscillation and the
  /// mean frequencies (left out when fewer than two records fall into the window).
  std::vector<Metric> summary(double average_from) const;

  /// The motion in the window from average_from (see motion_regime); "undetermined" with fewer than two
  /// records.
  std::string regime(double average_from) const;

  /// The centroid at every record: (time, centroid).
  std::vector<std::pair<double, geometry::Vec3>> centroid_track() const;
  /// The records and the unwrapping state as plain numbers (for a checkpoint), and their restoration into a
  /// tracker built for the same body (throws std::invalid_argument if they do not fit).
  std::vector<double> state() const;
  void restore(const std::vector<double>& state);

  bool membrane() const { return membrane_; }
  /// True when the body has a long axis (second moments differ by more than 1 %): theta is defined.
  bool elongated() const { return elongated_; }

 private:
  struct Sample {
    double time = 0, r_a = 0, r_p = 0;
    double axis = 0;        // long-axis angle, unwrapped [rad]
    double anisotropy = 0;  // largest / smallest second moment - 1 of the current shape
    double stretch = 0;     // largest principal stretch of a membrane's mid-surface (0: not a membrane)
    double material = 0;    // mean unwrapped angle of the material points [rad]
    geometry::Vec3 centroid = geometry::Vec3::Zero();
  };
  void measure(const std::vector<geometry::Patch>& p, const MetricShare& share, double& area,
               double& boundary, geometry::RegionMoments& region) const;
  std::vector<double> material_angles(const std::vector<geometry::Patch>& p,
                                      const geometry::Vec3& centroid) const;
  double largest_stretch(const std::vector<geometry::Patch>& p, const MetricShare& share) const;
  std::vector<const Sample*> window(double average_from) const;

  bool membrane_;
  bool face_bounds_ = false;  // a bulky body whose outer face bounds it (its inner face has no measure)
  int dim_, plane_dir_;
  bool elongated_ = false;
  // 3D: the angle [deg] between the current shape's short principal axis and the vorticity direction (not
  // part of state(): recomputed by each record; NaN after a restore until the next).
  double short_axis_to_vorticity_ = std::numeric_limits<double>::quiet_NaN();
  // The deformation index of the last record (not part of state() either: NaN after a restore until the
  // next).
  double deformation_index_ = std::numeric_limits<double>::quiet_NaN();
  double area0_ = 0, boundary0_ = 0;
  int n_parts_ = 1;
  std::vector<geometry::Param> material_xi_;
  std::vector<int> material_part_;   // the part of each material point
  std::vector<double> last_angles_;  // unwrapped, per material point
  std::vector<double> weights_;      // per material point (1 in 2D; squared in-plane radius in 3D)
  // Membranes: mid-surface points where the stretch is sampled, and the inverse of the reference surface's
  // metric there (2D: 1 / |dX/dxi_1|^2 in entry (0, 0)).
  std::vector<geometry::Param> stretch_xi_;
  std::vector<int> stretch_part_;
  std::vector<Eigen::Matrix2d> reference_metric_inverse_;
  std::vector<Sample> history_;
};

/// Lateral migration across a channel (paper Sec. 4.2) from a centroid track: the offset from the centre line
/// `mid` along direction `dir` at the first and last record, and the first time the offset fell below
/// `fraction` of its initial magnitude (NaN if it never did; 0 for a body starting on the line).
struct Migration {
  double offset_start = 0, offset_final = 0, time_to_centreline = 0;
};
Migration lateral_migration(const std::vector<std::pair<double, geometry::Vec3>>& track, int dir, double mid,
                            double fraction = 0.1);

/// Where a body settles across a channel at a finite Reynolds number (inertial migration, the
/// Segre-Silberberg effect), from a centroid track: the offset from the centre line `mid` along `dir`
/// averaged over the last `window` of the track's time, the lateral drift there (the least-squares slope of
/// the offset, cm/s), and the time from the start after which the offset stays within `tolerance` (cm) of
/// that final offset (NaN if the track ends outside it). Throws for an empty track or a window not in (0, 1].
struct LateralEquilibrium {
  double offset = 0, drift = 0, settle_time = 0;
};
LateralEquilibrium lateral_equilibrium(const std::vector<std::pair<double, geometry::Vec3>>& track, int dir,
                                       double mid, double tolerance, double window = 0.1);

/// How far a closed curve (points in order, e.g. a membrane's mid-line sampled around) is from its mirror
/// image about the line through `centre` along direction `axis` (0: x, 1: y): the mean distance from each
/// mirrored point to the nearest point of the curve, over the curve's mean distance from the centre. 0 for a
/// shape symmetric about that line (to the sampling); an ellipse inclined to the line gives more. Along a
/// channel (axis 0, the flow direction) a parachute and an aligned ellipse are both symmetric, but about the
/// line across the flow (axis 1) only the ellipse is: the pair tells them apart (paper Sec. 4.2).
double mirror_asymmetry(const std::vector<geometry::Vec3>& curve, const geometry::Vec3& centre, int axis);

/// How a body moves over a window of time (paper Sec. 3.2), from its long axis and its material:
///   round      -> a body without a long axis of its own (reference shape round): "steady" when its material
///                 turned by less than a quarter turn (e.g. a circular cell pushed through a narrowing),
///                 else "tumbling" when bulky (it turns as a whole, as the paper's inclusions) and
///                 "tank-treading" when a membrane;
///   tumbling   -> the long axis turned through at least half a turn (pi: the axis has no sign); or it
///                 passed the vertical (theta = -+90 deg) in the window more often one way than the other
///                 (between records at least 1 deg clear of it), which a swinging or tank-treading axis never
///                 does: a membrane whose material turns faster than its axis, caught by the window on either
///                 side of one passage, is tumbling too; or, in a window shorter than half a turn, it turned by
///                 at least 45 deg and at least half as far as the material;
///   steady     -> the material turned by less than a quarter turn (no rotation to speak of);
///   swinging   -> the axis oscillates by at least `swing_deg` (half peak-to-peak) while the material turns;
///   tank-treading -> otherwise: the axis stays (oscillating by less), the material turns.
/// `axis` and `material` are unwrapped angles [rad] at the window's records (at least two).
std::string motion_regime(bool round, bool membrane, const std::vector<double>& axis,
                          const std::vector<double>& material, double swing_deg = 2.0);

/// Turns per second of an unwrapped axis angle (negative angles: clockwise, positive frequency), averaged
/// over the whole half-turns it made from times[0]; `half_turns` returns how many (0: fewer than one, then
/// the average is over the whole window).
double tumbling_frequency(const std::vector<double>& times, const std::vector<double>& axis, int* half_turns);

/// Flow scales for the paper's dimensionless numbers (Sec. 3.1-3.2).
struct FlowScales {
  double viscosity = 0;   // mu [g / (cm s)]
  double density = 0;     // rho_1 [g / cm^3]
  double shear_rate = 0;  // gammadot [1/s] (0: no Ca, Re)
  double half_width = 0;  // half the channel width [cm] (0: no chi)
};

/// The dimensionless numbers of a body in its reference configuration: Delta (swelling degree), R0 (effective
/// radius, cm), chi (R0 / half width), Re (rho gammadot R0^2 / mu), and Ca (membranes: mu gammadot R0 / (h
/// G), the surface capillary number; bulky bodies: mu gammadot / G, the bulk one).
std::vector<Metric> dimensionless_numbers(const geometry::Patch& reference, bool membrane, double thickness,
                                          double shear_modulus, const FlowScales& flow);
/// The same for a body of one patch or a membrane made of parts.
std::vector<Metric> dimensionless_numbers(const std::vector<geometry::Patch>& reference, bool membrane,
                                          double thickness, double shear_modulus, const FlowScales& flow);

/// Filling fraction phi: the inclusion's area (volume) over the area (volume) its membrane encloses.
double filling_fraction(const geometry::Patch& inclusion, const geometry::Patch& membrane);
/// The same against a membrane of one patch or of parts.
double filling_fraction(const geometry::Patch& inclusion, const std::vector<geometry::Patch>& membrane);

}  // namespace cellfsi::solid
