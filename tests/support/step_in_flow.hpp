#pragma once
// A body stepped in a prescribed homogeneous flow, without a fluid (tests of solid/).
#include <vector>

#include "solid/solid_solver.hpp"

namespace cellfsi::test {

/// One step of dt in v = L (x - c), the kinematic update made twice (the second finds nothing to correct).
template <class Body>
void step_in_flow(Body& s, const solid::Mat3& L, const solid::Vec3& c, double dt) {
  s.begin_step(solid::TimeParameters::from_rho_inf(0.5, dt));
  for (int it = 0; it < 2; ++it) {
    const std::vector<solid::Vec3> x = s.collocation_points();
    std::vector<solid::VelocitySample> vs(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) vs[i].v = L * (x[i] - c), vs[i].grad_v = L;
    s.kinematic_update(vs);
  }
  s.end_step();
}

}  // namespace cellfsi::test
