#pragma once
// Point location in the Eulerian mesh: physical point -> (element, parametric point). A CGAL AABB tree over
// the elements' control-point boxes (which contain the elements: convex-hull property), built once, gives the
// candidate elements; NURBS point inversion inside them finishes. A point located before (a solid point one
// Newton iteration or time step ago) is found from its previous (element, xi) first, which usually takes one
// or two Newton steps.
//
// On an axis-aligned affine patch (the paper's boxes and straight channels, geometry::affine_map) none of
// that is needed: xi = (x - offset) / scale per direction and the element follows from the knots.
#include <memory>
#include <optional>
#include <vector>

#include "geometry/inversion.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::coupling {

struct Location {
  bool found = false;
  geometry::Index3 element{0, 0, 0};
  geometry::Param xi{0, 0, 0};
};

/// How Locator::locate finds (element, xi): `automatic` takes the closed form on an affine patch and NURBS
/// inversion otherwise; `inversion` always inverts (the tests compare the two).
enum class LocatorMethod { automatic, inversion };

class Locator {
 public:
  explicit Locator(const geometry::Patch& eulerian, LocatorMethod method = LocatorMethod::automatic);
  ~Locator();
  Locator(const Locator&) = delete;
  Locator& operator=(const Locator&) = delete;

  /// Locates x (in a periodic direction, any periodic image of it). `previous`, if found, is tried first (not
  /// needed by, and ignored on, the closed-form path). Returns found = false if x lies outside the domain; a
  /// point outside by at most the inverter's inside_tolerance (relative to the domain's diagonal) is found on
  /// the nearest boundary point, as by the inversion.
  Location locate(const geometry::Vec3& x, const Location* previous = nullptr) const;
  /// Like locate, but a point outside the domain is an error naming the point and its distance to the domain.
  Location locate_or_throw(const geometry::Vec3& x, const Location* previous = nullptr) const;

  /// Elements whose box contains x (for tests and statistics).
  std::vector<int> candidates(const geometry::Vec3& x) const;
  const geometry::Patch& patch() const { return patch_; }
  /// Whether locate() takes the closed form (an affine patch, method automatic).
  bool closed_form() const { return affine_.has_value(); }

 private:
  geometry::Vec3 primary_image(const geometry::Vec3& x) const;
  Location locate_affine(const geometry::Vec3& x) const;
  const geometry::Patch& patch_;
  geometry::PointInverter inverter_;
  std::optional<geometry::AffineMap> affine_;
  double inside_distance_ = 0;  // how far outside a point may lie and still be found (the inverter's rule)
  struct Tree;
  std::unique_ptr<Tree> tree_;
  geometry::Vec3 box_lo_, box_hi_;
};

}  // namespace cellfsi::coupling
