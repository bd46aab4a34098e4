#include "coupling/placement.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include <CGAL/Boolean_set_operations_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Polygon_2.h>
#include <CGAL/Polygon_with_holes_2.h>

#include "geometry/inversion.hpp"
#include "geometry/measures.hpp"
#include "geometry/patch_vtk.hpp"
#include "geometry/refine.hpp"

namespace cellfsi::coupling {

using geometry::Param;
using geometry::Patch;
using geometry::Vec3;

namespace {

using Kernel = CGAL::Exact_predicates_exact_constructions_kernel;
using Polygon = CGAL::Polygon_2<Kernel>;
using PolygonWithHoles = CGAL::Polygon_with_holes_2<Kernel>;

/// The closed curve xi_0 = u of a 2D body, sampled: a counter-clockwise polygon.
Polygon boundary_polygon(const Patch& p, double u) {
  const Patch curve = geometry::isoparametric(p, 0, u);
  std::vector<double> t = geometry::sample_values(curve.knots(0), 8);
  t.pop_back();  // closed: the last point repeats the first
  Polygon poly;
  for (double s : t) {
    const Vec3 x = curve.point({s, 0, 0});
    poly.push_back(Kernel::Point_2(x[0], x[1]));
  }
  if (poly.is_clockwise_oriented()) poly.reverse_orientation();
  return poly;
}

PolygonWithHoles region_2d(const BodyPlacement& b) {
  const geometry::KnotVector& k0 = b.patch.knots(0);
  Polygon outer = boundary_polygon(b.patch, k0.b());
  if (!b.membrane) return PolygonWithHoles(outer);
  Polygon inner = boundary_polygon(b.patch, k0.a());
  if (CGAL::abs(inner.area()) > CGAL::abs(outer.area())) std::swap(inner, outer);
  inner.reverse_orientation();  // holes are clockwise
  PolygonWithHoles r(outer);
  r.add_hole(inner);
  return r;
}

}  // namespace

void check_inside(const Locator& locator, const BodyPlacement& body) {
  // The body's two faces across direction 0 (a membrane's inner and outer surface; a bulky body's centre
  // and surface), 4 points per element along the others: every domain holds the segment across its walls
  // between two of its points, so a body whose boundary lies inside lies inside, and its inner points (most
  // of a bulky body's) need not be located. Each point starts from its neighbour's location.
  const geometry::Patch& p = body.patch;
  std::vector<double> u[3] = {{p.knots(0).a(), p.knots(0).b()}, {0.0}, {0.0}};
  for (int d = 1; d < p.param_dim(); ++d) u[d] = geometry::sample_values(p.knots(d), 4);
  Location previous;
  for (double c : u[2])
    for (double b : u[1])
      for (double a : u[0]) {
        const Vec3 x = p.point({a, b, c});
        previous = locator.locate(x, &previous);
        if (!previous.found) {
          std::ostringstream os;
          os << "body '" << body.name << "' is not inside the fluid domain: its point ("
             << x.head(body.patch.physical_dim()).transpose()
             << ") cm lies outside (move its centre or shrink it)";
          throw std::invalid_argument(os.str());
        }
      }
}

void check_no_overlap(const std::vector<BodyPlacement>& bodies) {
  for (size_t i = 0; i < bodies.size(); ++i)
    for (size_t j = i + 1; j < bodies.size(); ++j) {
      const BodyPlacement &a = bodies[i], &b = bodies[j];
      if (a.name == b.name) continue;  // two patches of one body (its parts meet along their edges)
      bool overlap = false;
      if (a.patch.physical_dim() == 2) {
        overlap = CGAL::do_intersect(region_2d(a), region_2d(b));
      } else {
        for (int pass = 0; pass < 2 && !overlap; ++pass) {
          const BodyPlacement& p = pass == 0 ? a : b;
          const BodyPlacement& q = pass == 0 ? b : a;
          const geometry::PointInverter inv(q.patch);
          for (const Param& xi : geometry::sample_grid(p.patch, 2))
            if (inv.invert(p.patch.point(xi)).inside) {
              overlap = true;
              break;
            }
        }
      }
      if (overlap)
        throw std::invalid_argument("bodies '" + a.name + "' and '" + b.name +
                                    "' overlap (move their centres apart or make them smaller)");
    }
}

Resolution resolution(const Patch& eulerian, const BodyPlacement& body) {
  return resolution(geometry::smallest_element_extent(eulerian), body);
}

Resolution resolution(double fluid_element, const BodyPlacement& body) {
  Resolution r;
  r.fluid_element = fluid_element;
  for (int e = 0; e < body.patch.n_elements(); ++e) {
    const std::array<double, 3> ext = geometry::element_extents(body.patch, e);
    for (int d = body.membrane ? 1 : 0; d < body.patch.param_dim(); ++d)
      r.solid_element = std::max(r.solid_element, ext[d]);
  }
  return r;
}

}  // namespace cellfsi::coupling
