#pragma once
// The short-range repulsion between cells and from the walls (coupling/README.md, "Repulsion"). Two membranes
// (or a membrane and a wall) that come within about one fluid element of each other move with nearly the same
// interpolated velocity: the fluid alone cannot keep them apart, and in dense suspensions and narrowings they
// cross or invert an element. Peers add a force that acts only below a cut-off of the order of an element
// (HemoCell's cell-cell and boundary repulsion, for one); so does cellfsi.
//
// The law is a contact pressure between a membrane and whatever is within the cut-off r_c of it:
//   P(d) = P0 (1 - s)^2 / s^2,  s = d / r_c,  zero for d >= r_c,
// smooth where it starts (P and dP/dd vanish at r_c), P0 at half the cut-off, and unbounded as d -> 0 like
// 1 / d^2: two equal and opposite forces a distance d apart inside one fluid element move their points apart
// only by the difference of the fluid's smoothed response at 0 and at d, which falls like d^2, so a law
// that grows more slowly (1 / d) would push less and less as the membranes close in.
// Each quadrature point q of a membrane, of reference mid-surface area a_q (QuadratureData::area), finds the
// nearest point p of every other membrane (or of its own image, below) within r_c: the pair gets the force
// a_q P(d) / 2 along x_q - x_p on q and its opposite on p (both points see each other, so two parallel sheets
// feel P(d) each, and the forces on the fluid sum to zero exactly). A point within r_c of a wall gets a_q
// P(d_w) along the wall's normal; the wall takes the reaction. A body's own points never repel each other
// within one periodic image (a membrane that spans a period less r_c meets its own image in the next period),
// and bulky bodies (a nucleus, a disk) take no part: their points are inside them, not on a surface. A
// membrane's points are taken as one continuous surface in unwrapped coordinates (as the solids keep them),
// shorter than a period: points wrapped into the period, or a membrane joined to its own image, would repel
// their neighbours across the period.
//
// The pairs are found through the point location the coupling already has: the points are sorted into the
// fluid elements that hold them, and a point looks only at the elements within r_c of its own (wrapping
// around periodic directions); only points near a wall look for it, in a CGAL AABB tree of the walls'
// faces sampled per element. The forces enter the fluid like an optical tweezers' load
// (QuadratureData::force); they are evaluated at every coupling iteration at the current positions and left
// out of the Jacobian (the residual, and so the solution, is exact).
#include <limits>
#include <memory>
#include <vector>

#include "coupling/locator.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::coupling {

/// The contact pressure P(d) [dyn/cm^2] at distance d [cm] for cut-off r_c and scale P0 (see above).
double repulsion_pressure(double distance, double cutoff, double scale);

/// One membrane as the repulsion sees it: its quadrature points' current positions, reference mid-surface
/// areas (QuadratureData::area) and elements (Location::element, from the coupling's point location).
struct RepulsionBody {
  const std::vector<geometry::Vec3>* x = nullptr;
  const std::vector<double>* area = nullptr;
  const std::vector<Location>* location = nullptr;
};

/// What one evaluation found (for the metrics).
struct RepulsionStats {
  double cell_gap = std::numeric_limits<double>::infinity();  // the least membrane-membrane distance seen
  double wall_gap = std::numeric_limits<double>::infinity();  // the least membrane-wall distance seen
  int cell_pairs = 0, wall_points = 0;                        // pairs and points with a force
};

class Repulsion {
 public:
  /// `fluid`: the Eulerian patch (kept by reference); its faces in the directions that are not periodic are
  /// the walls (walls = false: none). cutoff r_c > 0 [cm], scale P0 >= 0 [dyn/cm^2].
  Repulsion(const geometry::Patch& fluid, double cutoff, double scale, bool walls = true);
  ~Repulsion();
  Repulsion(const Repulsion&) = delete;
  Repulsion& operator=(const Repulsion&) = delete;

  double cutoff() const { return cutoff_; }
  double scale() const { return scale_; }
  /// The forces [dyn; in 2D per unit depth] on every point of every membrane (force[b][i], zero where none
  /// acts), and what was found. Bodies with no points (a bulky body) take no part.
  RepulsionStats forces(const std::vector<RepulsionBody>& bodies,
                        std::vector<std::vector<geometry::Vec3>>& force) const;
  /// The distance from x to the nearest wall and the unit normal pointing from the wall to x (infinite
  /// distance where there is no wall).
  double wall_distance(const geometry::Vec3& x, geometry::Vec3& normal) const;

 private:
  /// x - y wrapped into the nearest periodic image.
  geometry::Vec3 separation(const geometry::Vec3& x, const geometry::Vec3& y) const;
  const geometry::Patch& patch_;
  double cutoff_, scale_;
  int dim_;
  std::array<int, 3> n_{1, 1, 1};      // elements per direction
  std::array<int, 3> reach_{0, 0, 0};  // elements within r_c of a point's own, per direction
  std::array<bool, 3> periodic_{false, false, false};
  struct Walls;
  std::unique_ptr<Walls> walls_;
};

}  // namespace cellfsi::coupling
