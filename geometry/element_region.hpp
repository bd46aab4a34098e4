#pragma once
// Element regions of a patch: masks of elements (indexed like Patch::element_multi_index) and the basis
// functions on them (by the patch's natural, folded control index). The coupling loop describes with them
// where its Jacobian changes from step to step (the elements that carry s^h != 1 or an immersed point,
// "active", and the region around them that its preconditioners re-assemble: the Fourier solver's corrected
// region, the band solver's band); the VMS fluid, which unknowns such a region couples.
#include <vector>

#include "geometry/patch.hpp"

namespace cellfsi::geometry {

/// Mask of the elements in the support of any of `functions` (where s^h differs from 1 when they carry s_I).
std::vector<char> elements_supporting(const Patch& patch, const std::vector<int>& functions);

/// The mask grown by `margin` elements in every parametric direction (periodic directions wrap; open ones
/// stop at the boundary), counting diagonal neighbours: a box of (2 margin + 1)^d around each element.
std::vector<char> grow_elements(const Patch& patch, const std::vector<char>& mask, int margin);

/// Natural indices of the basis functions nonzero on any masked element, sorted.
std::vector<int> functions_on_elements(const Patch& patch, const std::vector<char>& mask);

/// Whether every element of `inner` is in `outer`.
bool contains(const std::vector<char>& outer, const std::vector<char>& inner);

}  // namespace cellfsi::geometry
