#pragma once
// Rheology of a cell suspension in a channel (paper Sec. 4.3, Eqs. 23-24), from records of the flow and the
// cells: plane Poiseuille flow along x between walls across y, driven by a body force.
//   H_t  tube hematocrit: the area the membranes enclose / the channel's area (mean over the window);
//   v_m  mean blood velocity: flow rate / cross-section; v_RBCs: the cells' mean velocity (centroid speed);
//   zeta = H_t / H_d = v_m / v_RBCs, the Fahraeus ratio (the paper's Eq. 23 prints the velocity ratio upside
//        down: cells travel faster than the mean, so H_t < H_d and zeta < 1 is the Fahraeus effect);
//   H_d  discharge hematocrit: the cells' flux / the blood's = H_t v_RBCs / v_m;
//   eta  relative apparent viscosity v_P / v_m, v_P the plasma's mean velocity at the same forcing (Eq. 24);
//   h_cf cell-free layer: the gap between each wall and the nearest membrane point, averaged over both walls
//        and the window.
#include <limits>
#include <vector>

#include "geometry/builders.hpp"

namespace cellfsi::solid {

struct SuspensionRecord {
  double time = 0;
  double mean_velocity = 0;          // v_m: flow rate / cross-section
  double cell_area = 0;              // area enclosed by all membranes
  std::vector<double> cell_x;        // each cell's centroid x (continuous: not wrapped by the period)
  double gap_low = 0, gap_high = 0;  // from each wall to the nearest membrane point
};

struct SuspensionRheology {
  int records = 0;                  // records in the window (at least two for the velocities)
  double tube_hematocrit = 0;       // H_t
  double mean_velocity = 0;         // v_m
  double cell_velocity = 0;         // v_RBCs
  double fahraeus = 0;              // zeta
  double discharge_hematocrit = 0;  // H_d
  double relative_viscosity = 0;    // eta
  double cell_free_layer = 0;       // h_cf
};

/// Over the records with time >= from: means of H_t, v_m and h_cf over the records, v_RBCs from each cell's
/// centroid displacement over the window (first to last record) averaged over the cells, and zeta, H_d, eta
/// from those. Fewer than two records: records < 2 and the rest 0. Throws std::invalid_argument for a
/// non-positive channel area or records whose cell counts differ.
SuspensionRheology suspension_rheology(const std::vector<SuspensionRecord>& records, double channel_area,
                                       double plasma_mean_velocity, double from);

/// The cell-free layer in a channel narrowing's straight throat (paper Sec. 4.4 with red cells; issue 46): of
/// the points (the red cells' membrane faces) whose x lies in the throat, within throat_length / 2 of
/// throat_center or of one of its periodic images, the gap from the lower wall
/// y = -(height / 2 - offset(x)) to the nearest one and from the upper wall to the nearest one.
struct ThroatGaps {
  int points = 0;  // points in the throat (0: no gap, low and high NaN)
  double low = std::numeric_limits<double>::quiet_NaN();
  double high = std::numeric_limits<double>::quiet_NaN();
  double mean() const { return 0.5 * (low + high); }  // h_cf at the throat
};
ThroatGaps throat_gaps(const std::vector<geometry::Vec3>& points, const geometry::NarrowingChannel& channel);

}  // namespace cellfsi::solid
