// Element regions (the coupling loop's re-assembled region, the band solver's band): elements in the support
// of functions, growth by a margin (periodic directions wrap, walls stop it), the functions on a set of
// elements.
#include <gtest/gtest.h>

#include <algorithm>

#include "geometry/builders.hpp"
#include "geometry/element_region.hpp"

using namespace cellfsi;

namespace {
int count(const std::vector<char>& m) { return static_cast<int>(std::count(m.begin(), m.end(), 1)); }
}  // namespace

TEST(ElementRegion, SupportOfAFunctionIsDegreePlusOneElementsPerDirectionAndWrapsPeriodically) {
  // 10 x 6 cubic elements, periodic in x: 10 x 9 functions.
  const geometry::Patch box = geometry::rectangle(1.0, 0.6, 10, 6, 3, {true, false});
  ASSERT_EQ(box.n_control(0), 10);
  ASSERT_EQ(box.n_control(1), 9);
  // A function in the middle has a 4 x 4 support; function 0 in x wraps across the periodic seam; the first
  // function in y (on the wall) is nonzero on one element row only.
  EXPECT_EQ(count(geometry::elements_supporting(box, {box.control_index(4, 4)})), 16);
  const std::vector<char> seam = geometry::elements_supporting(box, {box.control_index(0, 4)});
  EXPECT_EQ(count(seam), 16);
  EXPECT_TRUE(seam[9 + 10 * 3]);  // element (9, 3): across the seam
  EXPECT_EQ(count(geometry::elements_supporting(box, {box.control_index(4, 0)})), 4);
  // Every function on a set of elements, and back: the support of those functions contains the set.
  const std::vector<char> one = geometry::elements_supporting(box, {box.control_index(4, 4)});
  const std::vector<int> f = geometry::functions_on_elements(box, one);
  EXPECT_EQ(static_cast<int>(f.size()), 7 * 7);  // 4 x 4 elements of a cubic: 7 x 7 functions
  EXPECT_TRUE(geometry::contains(geometry::elements_supporting(box, f), one));
}

TEST(ElementRegion, GrowingWrapsPeriodicDirectionsAndStopsAtWalls) {
  const geometry::Patch box = geometry::rectangle(1.0, 0.6, 10, 6, 2, {true, false});
  std::vector<char> m(box.n_elements(), 0);
  m[0] = 1;  // element (0, 0): at the seam and on the wall
  const std::vector<char> g = geometry::grow_elements(box, m, 2);
  EXPECT_EQ(count(g), 5 * 3);  // x: 8, 9, 0, 1, 2 (wrapped); y: 0, 1, 2 (the wall stops it)
  EXPECT_TRUE(g[8] && g[9] && g[2] && g[2 + 10 * 2]);
  EXPECT_FALSE(g[3] || g[10 * 3]);
  EXPECT_TRUE(geometry::contains(g, m));
  EXPECT_FALSE(geometry::contains(m, g));
  EXPECT_EQ(geometry::grow_elements(box, m, 0), m);
  EXPECT_THROW(geometry::grow_elements(box, std::vector<char>(3, 0), 1), std::invalid_argument);
}
