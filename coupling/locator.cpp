#include "coupling/locator.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "common/petsc_error.hpp"

namespace cellfsi::coupling {

using geometry::Index3;
using geometry::Vec3;

namespace {

using Kernel = CGAL::Simple_cartesian<double>;

/// An element's axis-aligned box as an AABB-tree primitive (Id: linear element index).
struct BoxPrimitive {
  using Id = int;
  using Point = Kernel::Point_3;
  using Datum = Kernel::Iso_cuboid_3;
  BoxPrimitive() = default;
  BoxPrimitive(int id, const Datum& box) : id_(id), box_(box) {}
  /// The tree builds its primitives from iterators over the input range.
  template <class Iterator>
  explicit BoxPrimitive(Iterator it) : id_(it->id()), box_(it->datum()) {}
  Id id() const { return id_; }
  Datum datum() const { return box_; }
  Point reference_point() const { return box_.min(); }

 private:
  int id_ = 0;
  Datum box_;
};

using Traits = CGAL::AABB_traits<Kernel, BoxPrimitive>;
using AabbTree = CGAL::AABB_tree<Traits>;

}  // namespace

struct Locator::Tree {
  AabbTree tree;
};

Locator::Locator(const geometry::Patch& eulerian, LocatorMethod method)
    : patch_(eulerian), inverter_(eulerian), tree_(std::make_unique<Tree>()) {
  if (eulerian.param_dim() != eulerian.physical_dim())
    throw std::invalid_argument("Locator: the Eulerian patch must fill its space");
  patch_.bounding_box(box_lo_, box_hi_);
  if (method == LocatorMethod::automatic) affine_ = geometry::affine_map(eulerian);
  inside_distance_ = inverter_.options().inside_tolerance * (box_hi_ - box_lo_).norm();
  const double pad = 1e-12 * (box_hi_ - box_lo_).norm();
  std::vector<BoxPrimitive> boxes;
  boxes.reserve(eulerian.n_elements());
  for (int e = 0; e < eulerian.n_elements(); ++e) {
    Vec3 lo, hi;
    eulerian.element_bounding_box(eulerian.element_multi_index(e), lo, hi);
    lo.array() -= pad;
    hi.array() += pad;
    boxes.emplace_back(e, Kernel::Iso_cuboid_3(lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]));
  }
  tree_->tree.insert(boxes.begin(), boxes.end());
  tree_->tree.build();
}

Locator::~Locator() = default;

Vec3 Locator::primary_image(const Vec3& x) const {
  // In a periodic direction the tree holds one period: bring x into it.
  const Vec3 centre = 0.5 * (box_lo_ + box_hi_);
  return centre + geometry::nearest_image(patch_, x - centre);
}

std::vector<int> Locator::candidates(const Vec3& x) const {
  const Vec3 y = primary_image(x);
  std::vector<int> ids;
  tree_->tree.all_intersected_primitives(Kernel::Point_3(y[0], y[1], y[2]), std::back_inserter(ids));
  return ids;
}

Location Locator::locate_affine(const Vec3& x) const {
  const Vec3 y = primary_image(x);
  Location l;
  double outside2 = 0;  // squared distance to the nearest point of the domain (a box)
  CELLFSI_PETSC(
      PetscLogFlops(12.0 * patch_.param_dim()));  // (-log_view's counts: the image, the map's inverse)
  for (int d = 0; d < patch_.param_dim(); ++d) {
    const geometry::KnotVector& kv = patch_.knots(d);
    double u = (y[d] - affine_->offset[d]) / affine_->scale[d];
    if (kv.periodic()) {
      u = kv.normalize(u);  // y is the primary image: this only moves u by round-off across the wrap
    } else if (u < kv.a() || u > kv.b()) {
      const double v = std::clamp(u, kv.a(), kv.b());
      outside2 += std::pow((u - v) * affine_->scale[d], 2);
      u = v;
    }
    // On an interior element boundary, the lower element. The s^h marking depends on this choice: with the
    // upper element, the 3D scene (bodies centred on the mid-plane knot, with points on it) ran as the mirror
    // image of its run with the inversion, which gives the lower element there (its candidates tie; round-off
    // settles which is tried first).
    l.element[d] = kv.find_element(u);
    if (l.element[d] > 0 && u == kv.element_begin(l.element[d])) --l.element[d];
    l.xi[d] = u;
  }
  l.found = outside2 <= inside_distance_ * inside_distance_;
  return l.found ? l : Location{};
}

Location Locator::locate(const Vec3& x, const Location* previous) const {
  if (affine_) return locate_affine(x);
  if (previous && previous->found) {
    const geometry::InversionResult r = inverter_.invert(x, previous->element, previous->xi);
    if (r.inside) return {true, r.element, r.xi};
  }
  const Vec3 y = primary_image(x);
  std::vector<int> ids = candidates(y);
  // Try the candidate whose element centre is nearest first.
  std::vector<std::pair<double, int>> order;
  for (int id : ids) {
    Vec3 lo, hi;
    patch_.element_bounding_box(patch_.element_multi_index(id), lo, hi);
    order.emplace_back((0.5 * (lo + hi) - y).squaredNorm(), id);
  }
  std::sort(order.begin(), order.end());
  for (const auto& [dist, id] : order) {
    const Index3 e = patch_.element_multi_index(id);
    geometry::Param lo, hi, c{0, 0, 0};
    patch_.element_bounds(e, lo, hi);
    for (int d = 0; d < patch_.param_dim(); ++d) c[d] = 0.5 * (lo[d] + hi[d]);
    const geometry::InversionResult r = inverter_.invert(y, e, c);
    if (r.inside) return {true, r.element, r.xi};
  }
  return {};
}

Location Locator::locate_or_throw(const Vec3& x, const Location* previous) const {
  const Location l = locate(x, previous);
  if (!l.found) {
    const geometry::InversionResult r = inverter_.invert(primary_image(x));
    std::ostringstream os;
    os << "the point (" << x.transpose() << ") cm left the fluid domain (" << r.distance << " cm outside)";
    throw std::runtime_error(os.str());
  }
  return l;
}

}  // namespace cellfsi::coupling
