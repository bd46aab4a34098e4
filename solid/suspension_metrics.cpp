#include "solid/suspension_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cellfsi::solid {

SuspensionRheology suspension_rheology(const std::vector<SuspensionRecord>& records, double channel_area,
                                       double plasma_mean_velocity, double from) {
  if (!(channel_area > 0)) throw std::invalid_argument("suspension_rheology: channel area must be > 0");
  std::vector<const SuspensionRecord*> w;
  for (const SuspensionRecord& r : records)
    if (r.time >= from) w.push_back(&r);
  SuspensionRheology out;
  out.records = static_cast<int>(w.size());
  if (w.size() < 2) return out;
  const std::size_t cells = w.front()->cell_x.size();
  double ht = 0, vm = 0, gap = 0;
  for (const SuspensionRecord* r : w) {
    if (r->cell_x.size() != cells) throw std::invalid_argument("suspension_rheology: cell counts differ");
    ht += r->cell_area / channel_area;
    vm += r->mean_velocity;
    gap += 0.5 * (r->gap_low + r->gap_high);
  }
  const double n = static_cast<double>(w.size());
  out.tube_hematocrit = ht / n;
  out.mean_velocity = vm / n;
  out.cell_free_layer = gap / n;
  const double span = w.back()->time - w.front()->time;
  double v = 0;
  for (std::size_t c = 0; c < cells; ++c) v += (w.back()->cell_x[c] - w.front()->cell_x[c]) / span;
  out.cell_velocity = cells > 0 ? v / static_cast<double>(cells) : 0.0;
  if (out.cell_velocity != 0) out.fahraeus = out.mean_velocity / out.cell_velocity;
  if (out.mean_velocity != 0) {
    out.discharge_hematocrit = out.tube_hematocrit * out.cell_velocity / out.mean_velocity;
    out.relative_viscosity = plasma_mean_velocity / out.mean_velocity;
  }
  return out;
}

ThroatGaps throat_gaps(const std::vector<geometry::Vec3>& points, const geometry::NarrowingChannel& channel) {
  ThroatGaps g;
  for (const geometry::Vec3& p : points) {
    // Along x from the throat's centre, to the nearest periodic image (a throat may straddle x = 0).
    double dx = p[0] - channel.throat_center;
    dx -= channel.length * std::round(dx / channel.length);
    if (std::abs(dx) > 0.5 * channel.throat_length) continue;
    const double wall = 0.5 * channel.height - channel.wall_offset(p[0]);  // the walls at y = -wall and +wall
    const double low = p[1] + wall, high = wall - p[1];
    g.low = g.points == 0 ? low : std::min(g.low, low);
    g.high = g.points == 0 ? high : std::min(g.high, high);
    ++g.points;
  }
  return g;
}

}  // namespace cellfsi::solid
