#pragma once
// Refinement that preserves the geometry exactly: knot insertion (h-refinement), degree elevation
// (p-refinement), uniform subdivision to a requested element count, and extraction of isoparametric
// sub-patches (boundaries, mid-surfaces).
#include <vector>

#include "geometry/patch.hpp"

namespace cellfsi::geometry {

/// Inserts the (sorted) knots into direction dir by Boehm's algorithm on homogeneous control points
/// (The NURBS Book, A5.4). Open directions only.
Patch insert_knots(const Patch& patch, int dir, const std::vector<double>& knots);

/// Raises the degree of direction dir by `times`, keeping the continuity at every knot (each distinct knot's
/// multiplicity grows by `times`). The new homogeneous control points are the L2 projection of the old
/// homogeneous map onto the elevated space, which contains it, so the map is unchanged up to round-off.
/// Open directions only.
Patch elevate_degree(const Patch& patch, int dir, int times = 1);

/// Subdivides every element of direction dir into equal parts so that the direction has n_elements
/// elements; n_elements must be a positive multiple of the current count. New knots are simple (C^{p-1}).
Patch refine_uniform(const Patch& patch, int dir, int n_elements);

/// The sub-patch at parametric value `value` of direction dir (parametric dimension one lower): a
/// boundary when value is a or b, a mid-surface of a membrane when value is the mid-thickness.
Patch isoparametric(const Patch& patch, int dir, double value);

}  // namespace cellfsi::geometry
