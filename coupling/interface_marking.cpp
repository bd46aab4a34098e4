#include "coupling/interface_marking.hpp"

#include <algorithm>
#include <stdexcept>

namespace cellfsi::coupling {

std::vector<int> functions_near(const Locator& locator, const std::vector<geometry::Vec3>& points,
                                Marking marking) {
  const geometry::Patch& patch = locator.patch();
  const int P = patch.param_dim();
  std::vector<int> out;
  for (const geometry::Vec3& x : points) {
    const Location l = locator.locate_or_throw(x);
    // Local indices [first, first + np) of the element's p + 1 functions per direction; function a has the
    // element as the (p - a)-th of its p + 1 support elements, an inner one for 1 <= a <= p - 1.
    int first[3] = {0, 0, 0}, np[3] = {1, 1, 1};
    for (int d = 0; d < P; ++d) {
      const int p = patch.degree(d);
      first[d] = patch.knots(d).element_span(l.element[d]) - p;
      np[d] = p + 1;
      if (marking == Marking::central && p >= 2) {
        first[d] += 1;
        np[d] = p - 1;
      }
    }
    for (int c = 0; c < np[2]; ++c)
      for (int b = 0; b < np[1]; ++b)
        for (int a = 0; a < np[0]; ++a) {
          const int loc[3] = {a, b, c};
          int g[3] = {0, 0, 0};
          for (int d = 0; d < P; ++d) g[d] = patch.knots(d).fold(first[d] + loc[d]);
          out.push_back(patch.control_index(g[0], g[1], g[2]));
        }
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

void check_interface_scaling(double s_interface) {
  if (!(s_interface >= 1)) throw std::invalid_argument("s_interface must be >= 1");
}

std::vector<double> scaling_values(int n_control, const std::vector<int>& marked, double s_interface) {
  check_interface_scaling(s_interface);
  std::vector<double> s(n_control, 1.0);
  for (int k : marked) {
    if (k < 0 || k >= n_control) throw std::out_of_range("scaling_values: function index out of range");
    s[k] = s_interface;
  }
  return s;
}

}  // namespace cellfsi::coupling
