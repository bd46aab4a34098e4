#pragma once
// s^h marking (DESIGN.md section 3): the Eulerian basis functions whose support contains an interface point
// of a solid get the control value s_I, all others 1. Rebuilt whenever the solids move.
#include <vector>

#include "coupling/locator.hpp"

namespace cellfsi::coupling {

/// Natural (folded) indices of the Eulerian basis functions that are nonzero on the elements containing the
/// points, sorted and unique. Points outside the domain are an error (Locator::locate_or_throw).
std::vector<int> functions_near(const Locator& locator, const std::vector<geometry::Vec3>& points);

/// The scaling field's control values: s_interface on `marked`, 1 elsewhere (size: the patch's control
/// points).
std::vector<double> scaling_values(int n_control, const std::vector<int>& marked, double s_interface);

}  // namespace cellfsi::coupling
