#pragma once
// Point inversion on patches whose parametric and physical dimensions agree: physical point x ->
// (element, parametric point xi) with x(xi) = x.
//
// Newton's method runs inside one element at a time, with the step clamped to the element's parametric box.
// When the iterate is held on an element face and the step keeps pushing outward, the search walks to the
// neighbouring element (wrapping around periodic and closed directions). On the patch boundary the pushed
// directions are held fixed and the rest of the step is a least-squares (Gauss-Newton) step, so a point
// outside the patch ends at the nearest boundary point found and is reported as outside with its distance.
#include "geometry/patch.hpp"

namespace cellfsi::geometry {

/// Stopping rules. Thin patches (a 5e-7 cm membrane on a 4e-4 cm capsule) make a residual test alone too
/// loose across the thickness, so convergence is judged on the parametric step, relative to the element.
struct InversionOptions {
  double residual_tolerance = 1e-15;  // stop when |x(xi) - x| <= this times the patch's bounding-box diagonal
  double step_tolerance = 1e-9;       // or when a Newton step moved xi by <= this times the element's length
                                      // (quadratic convergence: the error left is ~ its square)
  double inside_tolerance = 1e-10;    // converged point is inside if |x(xi) - x| <= this times the diagonal
  int max_iterations = 60;            // Newton iterations, summed over all elements visited
};

struct InversionResult {
  bool inside = false;      // x(xi) = x within tolerance, xi inside the patch
  Index3 element{0, 0, 0};  // element holding xi
  Param xi{0, 0, 0};        // parametric point (in the element's box)
  double distance = 0;  // |x(xi) - x|: ~0 when inside; distance to the nearest boundary point found if not
  int iterations = 0;   // Newton iterations taken
  int elements_visited = 1;  // elements entered, the first included
};

class PointInverter {
 public:
  explicit PointInverter(const Patch& patch, InversionOptions options = {});

  /// Warm start from a known element and parametric point (e.g. the point's previous location).
  InversionResult invert(const Vec3& x, const Index3& element, const Param& xi_guess) const;
  /// Cold start: begins in the element whose parametric centre maps closest to x.
  InversionResult invert(const Vec3& x) const;

  const Patch& patch() const { return patch_; }
  const InversionOptions& options() const { return options_; }

 private:
  const Patch& patch_;
  InversionOptions options_;
  double scale_ = 1;
  Vec3 centre_ = Vec3::Zero();  // of the patch's bounding box (the patch does not change)
  std::vector<Vec3> element_centres_;
};

}  // namespace cellfsi::geometry
