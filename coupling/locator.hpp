#pragma once
// Point location in the Eulerian mesh: physical point -> (element, parametric point). A CGAL AABB tree over
// the elements' control-point boxes (which contain the elements: convex-hull property), built once, gives the
// candidate elements; NURBS point inversion inside them finishes. A point located before (a solid point one
// Newton iteration or time step ago) is found from its previous (element, xi) first, which usually takes one
// or two Newton steps.
#include <memory>
#include <vector>

#include "geometry/inversion.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::coupling {

struct Location {
  bool found = false;
  geometry::Index3 element{0, 0, 0};
  geometry::Param xi{0, 0, 0};
};

class Locator {
 public:
  explicit Locator(const geometry::Patch& eulerian);
  ~Locator();
  Locator(const Locator&) = delete;
  Locator& operator=(const Locator&) = delete;

  /// Locates x (in a periodic direction, any periodic image of it). `previous`, if found, is tried first.
  /// Returns found = false if x lies outside the domain.
  Location locate(const geometry::Vec3& x, const Location* previous = nullptr) const;
  /// Like locate, but a point outside the domain is an error naming the point and its distance to the domain.
  Location locate_or_throw(const geometry::Vec3& x, const Location* previous = nullptr) const;

  /// Elements whose box contains x (for tests and statistics).
  std::vector<int> candidates(const geometry::Vec3& x) const;
  const geometry::Patch& patch() const { return patch_; }

 private:
  geometry::Vec3 primary_image(const geometry::Vec3& x) const;
  const geometry::Patch& patch_;
  geometry::PointInverter inverter_;
  struct Tree;
  std::unique_ptr<Tree> tree_;
  geometry::Vec3 box_lo_, box_hi_;
};

}  // namespace cellfsi::coupling
