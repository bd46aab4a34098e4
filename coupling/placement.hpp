#pragma once
// Checks of immersed bodies against the fluid mesh and each other, made before a run starts (docs/design.md
// §4: a cell outside the domain, overlapping cells and a mesh too coarse for the cell are bad input).
// Each check throws std::invalid_argument with a message naming the body, what is wrong and by how much.
#include <string>
#include <vector>

#include "coupling/locator.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::coupling {

struct BodyPlacement {
  std::string name;
  geometry::Patch patch;  // reference configuration; direction 0 through the thickness / from the centre
  bool membrane = false;
};

/// The body must lie in the fluid domain: its faces across direction 0 sampled 4 times per element along
/// the other directions (the domains are convex across their walls, so the boundary decides).
void check_inside(const Locator& locator, const BodyPlacement& body);

/// The solid regions of two bodies must not intersect (a nucleus inside a membrane's cavity is fine). 2D: an
/// exact polygon test (CGAL) on the bodies' boundaries sampled 8 times per element; 3D: no sampled point of
/// one body inside the other. Placements of one name are the patches of one body, not set against each other.
void check_no_overlap(const std::vector<BodyPlacement>& bodies);

/// Element sizes: the largest extent of an element of the body along its interface (directions >= 1 for a
/// membrane; every direction for a bulky body) and the smallest Eulerian element extent.
struct Resolution {
  double solid_element = 0, fluid_element = 0;
  double ratio() const { return solid_element / fluid_element; }
};
Resolution resolution(const geometry::Patch& eulerian, const BodyPlacement& body);
/// The same with the smallest Eulerian element extent given (geometry::smallest_element_extent), for a loop
/// over bodies.
Resolution resolution(double fluid_element, const BodyPlacement& body);

}  // namespace cellfsi::coupling
