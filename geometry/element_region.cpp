#include "geometry/element_region.hpp"

#include <algorithm>
#include <stdexcept>

namespace cellfsi::geometry {

namespace {

/// Per direction d: the folded indices of the p_d + 1 functions nonzero on element e_d.
std::vector<int> element_functions(const Patch& patch, int d, int e) {
  const KnotVector& kv = patch.knots(d);
  std::vector<int> f;
  const int first = kv.element_span(e) - kv.degree();
  for (int a = 0; a <= kv.degree(); ++a) f.push_back(kv.fold(first + a));
  return f;
}

void check_mask(const Patch& patch, const std::vector<char>& mask) {
  if (static_cast<int>(mask.size()) != patch.n_elements())
    throw std::invalid_argument("element mask of " + std::to_string(mask.size()) + " entries for " +
                                std::to_string(patch.n_elements()) + " elements");
}

}  // namespace

std::vector<char> elements_supporting(const Patch& patch, const std::vector<int>& functions) {
  const int P = patch.param_dim();
  // Per direction: the elements on which each (folded) function is nonzero.
  std::vector<std::vector<int>> on[3];
  for (int d = 0; d < 3; ++d) {
    on[d].assign(patch.n_control(d), {});
    if (d >= P) {
      on[d][0] = {0};
      continue;
    }
    for (int e = 0; e < patch.n_elements(d); ++e)
      for (int f : element_functions(patch, d, e)) on[d][f].push_back(e);
  }
  std::vector<char> mask(patch.n_elements(), 0);
  const int n0 = patch.n_elements(0), n1 = patch.n_elements(1);
  for (int k : functions) {
    const Index3 m = patch.control_multi_index(k);
    for (int e2 : on[2][m[2]])
      for (int e1 : on[1][m[1]])
        for (int e0 : on[0][m[0]]) mask[e0 + n0 * (e1 + n1 * e2)] = 1;
  }
  return mask;
}

std::vector<char> grow_elements(const Patch& patch, const std::vector<char>& mask, int margin) {
  check_mask(patch, mask);
  if (margin < 0) throw std::invalid_argument("grow_elements: negative margin");
  const int P = patch.param_dim();
  int n[3] = {patch.n_elements(0), patch.n_elements(1), patch.n_elements(2)};
  std::vector<char> out = mask;
  // One direction at a time: a box is the product of intervals.
  for (int d = 0; d < P; ++d) {
    const bool periodic = patch.knots(d).periodic();
    std::vector<char> next(out.size(), 0);
    for (int e = 0; e < static_cast<int>(out.size()); ++e) {
      if (!out[e]) continue;
      Index3 m = patch.element_multi_index(e);
      const int c = m[d];
      for (int s = -margin; s <= margin; ++s) {
        int k = c + s;
        if (periodic)
          k = ((k % n[d]) + n[d]) % n[d];
        else if (k < 0 || k >= n[d])
          continue;
        m[d] = k;
        next[m[0] + n[0] * (m[1] + n[1] * m[2])] = 1;
      }
    }
    out.swap(next);
  }
  return out;
}

std::vector<int> functions_on_elements(const Patch& patch, const std::vector<char>& mask) {
  check_mask(patch, mask);
  const int P = patch.param_dim();
  std::vector<int> out;
  for (int e = 0; e < static_cast<int>(mask.size()); ++e) {
    if (!mask[e]) continue;
    const Index3 m = patch.element_multi_index(e);
    std::vector<int> f[3] = {{0}, {0}, {0}};
    for (int d = 0; d < P; ++d) f[d] = element_functions(patch, d, m[d]);
    for (int c : f[2])
      for (int b : f[1])
        for (int a : f[0]) out.push_back(patch.control_index(a, b, c));
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

bool contains(const std::vector<char>& outer, const std::vector<char>& inner) {
  if (outer.size() != inner.size()) return false;
  for (std::size_t e = 0; e < inner.size(); ++e)
    if (inner[e] && !outer[e]) return false;
  return true;
}

}  // namespace cellfsi::geometry
