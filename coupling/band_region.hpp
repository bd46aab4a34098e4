#pragma once
// Where the coupled Jacobian changes from step to step: the Eulerian elements that carry s^h != 1 or an
// immersed point ("active"), a region around them that a factorisation is built for, and the unknowns that
// region touches (the band of solvers::BandSchurSolver). Element masks are indexed like
// Patch::element_multi_index; functions by the patch's natural (folded) control index.
#include <vector>

#include "geometry/patch.hpp"

namespace cellfsi::coupling {

/// Mask of the elements in the support of any of `functions` (where s^h differs from 1 when they carry s_I).
std::vector<char> elements_supporting(const geometry::Patch& patch, const std::vector<int>& functions);

/// The mask grown by `margin` elements in every parametric direction (periodic directions wrap; open ones
/// stop at the boundary), counting diagonal neighbours: a box of (2 margin + 1)^d around each element.
std::vector<char> grow_elements(const geometry::Patch& patch, const std::vector<char>& mask, int margin);

/// Natural indices of the basis functions nonzero on any masked element, sorted.
std::vector<int> functions_on_elements(const geometry::Patch& patch, const std::vector<char>& mask);

/// Whether every element of `inner` is in `outer`.
bool contains(const std::vector<char>& outer, const std::vector<char>& inner);

}  // namespace cellfsi::coupling
