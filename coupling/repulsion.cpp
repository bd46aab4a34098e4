#include "coupling/repulsion.hpp"

#include <CGAL/AABB_segment_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

#include "geometry/measures.hpp"

namespace cellfsi::coupling {

using geometry::Vec3;

namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Segment = Kernel::Segment_3;
using Triangle = Kernel::Triangle_3;
using SegmentTree = CGAL::AABB_tree<
    CGAL::AABB_traits<Kernel, CGAL::AABB_segment_primitive<Kernel, std::vector<Segment>::iterator>>>;
using TriangleTree = CGAL::AABB_tree<
    CGAL::AABB_traits<Kernel, CGAL::AABB_triangle_primitive<Kernel, std::vector<Triangle>::iterator>>>;

Kernel::Point_3 point3(const Vec3& x) { return {x[0], x[1], x[2]}; }

// Samples per element edge of a wall face: a curved wall (the narrowing's) is a polyline of 8 chords per
// element in 2D (its distance error is below 1e-3 of an element for the narrowing's transitions); a 3D face
// is 2 x 2 quadrilaterals per element, each split in two triangles (the paper's boxes have flat walls).
constexpr int kWallSamples2d = 8, kWallSamples3d = 2;

}  // namespace

double repulsion_pressure(double distance, double cutoff, double scale) {
  if (!(distance < cutoff)) return 0;
  const double s = std::max(distance / cutoff, 1e-12);
  return scale * (1 - s) * (1 - s) / (s * s);
}

struct Repulsion::Walls {
  std::vector<Segment> segments;
  std::vector<Triangle> triangles;
  SegmentTree segment_tree;
  TriangleTree triangle_tree;
  int wall_dir[3] = {0, 0, 0};  // 1 where direction d has walls
  Vec3 centre = Vec3::Zero();
};

Repulsion::Repulsion(const geometry::Patch& fluid, double cutoff, double scale, bool walls)
    : patch_(fluid),
      cutoff_(cutoff),
      scale_(scale),
      dim_(fluid.param_dim()),
      walls_(std::make_unique<Walls>()) {
  if (!(cutoff > 0 && std::isfinite(cutoff)))
    throw std::invalid_argument("repulsion cut-off must be positive, not " + std::to_string(cutoff));
  if (!(scale >= 0 && std::isfinite(scale)))
    throw std::invalid_argument("repulsion pressure scale must be >= 0, not " + std::to_string(scale));
  // The elements a point within r_c of another can lie in, per direction: r_c over the shortest element
  // extent there (exact on an affine patch, the paper's boxes: its shortest knot span times the map's scale;
  // a curved element's faces can be closer than its corners, hence one more element there).
  const std::optional<geometry::AffineMap> affine = geometry::affine_map(fluid);
  std::array<double, 3> shortest{1e300, 1e300, 1e300};
  if (affine) {
    for (int d = 0; d < dim_; ++d)
      for (int i = 0; i < fluid.knots(d).n_elements(); ++i)
        shortest[d] =
            std::min(shortest[d], (fluid.knots(d).element_end(i) - fluid.knots(d).element_begin(i)) *
                                      std::abs(affine->scale[d]));
  } else {
    for (int e = 0; e < fluid.n_elements(); ++e) {
      const std::array<double, 3> ext = geometry::element_extents(fluid, e);
      for (int d = 0; d < dim_; ++d) shortest[d] = std::min(shortest[d], ext[d]);
    }
  }
  for (int d = 0; d < dim_; ++d) {
    n_[d] = fluid.n_elements(d);
    reach_[d] = static_cast<int>(std::ceil(cutoff / shortest[d] - 1e-12)) + (affine ? 0 : 1);
    periodic_[d] = fluid.knots(d).periodic();
  }
  Vec3 lo, hi;
  fluid.bounding_box(lo, hi);
  walls_->centre = 0.5 * (lo + hi);
  if (!walls) return;
  // The walls: both faces of every direction that is not periodic, sampled per element.
  const int m = dim_ == 2 ? kWallSamples2d : kWallSamples3d;
  for (int d = 0; d < dim_; ++d) {
    if (periodic_[d]) continue;
    walls_->wall_dir[d] = 1;
    const auto& kd = fluid.knots(d);
    for (double face : {kd.a(), kd.b()}) {
      const int a = (d + 1) % dim_, b = dim_ == 3 ? (d + 2) % dim_ : -1;
      const auto& ka = fluid.knots(a);
      // Parameters along the face: every element split in m.
      const auto samples = [&](const geometry::KnotVector& k) {
        std::vector<double> t;
        for (int i = 0; i < k.n_elements(); ++i) {
          const double t0 = k.element_begin(i), t1 = k.element_end(i);
          for (int j = 0; j < m; ++j) t.push_back(t0 + (t1 - t0) * j / m);
        }
        t.push_back(k.b());
        return t;
      };
      const std::vector<double> ta = samples(ka);
      const auto at = [&](double u, double v) {
        geometry::Param xi{0, 0, 0};
        xi[d] = face, xi[a] = u;
        if (b >= 0) xi[b] = v;
        return point3(fluid.point(xi));
      };
      if (dim_ == 2) {
        for (size_t i = 0; i + 1 < ta.size(); ++i)
          walls_->segments.emplace_back(at(ta[i], 0), at(ta[i + 1], 0));
        continue;
      }
      const std::vector<double> tb = samples(fluid.knots(b));
      for (size_t i = 0; i + 1 < ta.size(); ++i)
        for (size_t j = 0; j + 1 < tb.size(); ++j) {
          const auto p00 = at(ta[i], tb[j]), p10 = at(ta[i + 1], tb[j]), p01 = at(ta[i], tb[j + 1]),
                     p11 = at(ta[i + 1], tb[j + 1]);
          walls_->triangles.emplace_back(p00, p10, p11);
          walls_->triangles.emplace_back(p00, p11, p01);
        }
    }
  }
  if (!walls_->segments.empty()) {
    walls_->segment_tree.insert(walls_->segments.begin(), walls_->segments.end());
    walls_->segment_tree.build();
    walls_->segment_tree.accelerate_distance_queries();
  }
  if (!walls_->triangles.empty()) {
    walls_->triangle_tree.insert(walls_->triangles.begin(), walls_->triangles.end());
    walls_->triangle_tree.build();
    walls_->triangle_tree.accelerate_distance_queries();
  }
}

Repulsion::~Repulsion() = default;

Vec3 Repulsion::separation(const Vec3& x, const Vec3& y) const {
  return geometry::nearest_image(patch_, x - y);
}

double Repulsion::wall_distance(const Vec3& x, Vec3& normal) const {
  normal = Vec3::Zero();
  if (walls_->segments.empty() && walls_->triangles.empty()) return std::numeric_limits<double>::infinity();
  // The walls were sampled over one period: x's image in it.
  const Vec3 y = walls_->centre + geometry::nearest_image(patch_, x - walls_->centre);
  const auto q = point3(y);
  const Kernel::Point_3 c =
      dim_ == 2 ? walls_->segment_tree.closest_point(q) : walls_->triangle_tree.closest_point(q);
  const Vec3 w(c.x(), c.y(), c.z());
  Vec3 r = y - w;
  const double dist = r.norm();
  // (On the wall itself the normal points into the domain.)
  if (dist == 0) r = walls_->centre - w;
  normal = r.normalized();
  return dist;
}

RepulsionStats Repulsion::forces(const std::vector<RepulsionBody>& bodies,
                                 std::vector<std::vector<Vec3>>& force) const {
  RepulsionStats st;
  const int nb = static_cast<int>(bodies.size());
  force.assign(nb, {});
  for (int b = 0; b < nb; ++b)
    if (bodies[b].x) force[b].assign(bodies[b].x->size(), Vec3::Zero());
  if (scale_ == 0) return st;
  const auto n_points = [&](int b) { return bodies[b].x ? static_cast<int>(bodies[b].x->size()) : 0; };
  const auto element_of = [&](int b, int i) { return (*bodies[b].location)[i].element; };

  // Walls: only points whose element lies within r_c of a wall face look for it.
  for (int b = 0; b < nb; ++b)
    for (int i = 0; i < n_points(b); ++i) {
      const geometry::Index3 e = element_of(b, i);
      bool near = false;
      for (int d = 0; d < dim_; ++d)
        near = near || (walls_->wall_dir[d] && (e[d] < reach_[d] || e[d] >= n_[d] - reach_[d]));
      if (!near) continue;
      Vec3 normal;
      const double dist = wall_distance((*bodies[b].x)[i], normal);
      st.wall_gap = std::min(st.wall_gap, dist);
      const double p = repulsion_pressure(dist, cutoff_, scale_);
      if (p == 0) continue;
      force[b][i] += (*bodies[b].area)[i] * p * normal;
      ++st.wall_points;
    }

  // Cells: bodies whose boxes, grown by r_c, meet another's (in some periodic image) take part.
  std::vector<Vec3> lo(nb, Vec3::Constant(1e300)), hi(nb, Vec3::Constant(-1e300));
  for (int b = 0; b < nb; ++b)
    for (int i = 0; i < n_points(b); ++i) {
      lo[b] = lo[b].cwiseMin((*bodies[b].x)[i]);
      hi[b] = hi[b].cwiseMax((*bodies[b].x)[i]);
    }
  const std::vector<Vec3> images = geometry::neighbour_image_shifts(patch_);
  std::vector<char> active(nb, 0);
  int n_active = 0;
  for (int a = 0; a < nb; ++a)
    for (int b = a + 1; b < nb; ++b) {
      if (!n_points(a) || !n_points(b)) continue;
      // b's box brought next to a's first: bodies of a periodic channel drift by whole periods.
      const Vec3 ca = 0.5 * (lo[a] + hi[a]), cb = 0.5 * (lo[b] + hi[b]);
      const Vec3 near = separation(cb, ca) - (cb - ca);
      bool meet = false;
      for (const Vec3& image : images) {
        const Vec3 s = near + image;
        bool m = true;
        for (int d = 0; d < dim_; ++d)
          m = m && lo[a][d] - cutoff_ <= hi[b][d] + s[d] && lo[b][d] + s[d] <= hi[a][d] + cutoff_;
        meet = meet || m;
      }
      if (meet) active[a] = active[b] = 1;
    }
  // A membrane that spans a period less r_c meets its own periodic image (a cell stretched along a short
  // periodic box): its points take part against their images, not against their neighbours in one image.
  // Whether another image of the box [xlo, xhi] meets body a's box grown by r_c: for a's own box, whether a
  // meets its own image; for one of its points, whether that point can (only the points at the box's ends;
  // the others skip their own body's points).
  const auto meets_own_image = [&](int a, const Vec3& xlo, const Vec3& xhi) {
    for (const Vec3& s : images) {
      if (s.isZero()) continue;
      bool m = true;
      for (int d = 0; d < dim_; ++d)
        m = m && lo[a][d] - cutoff_ <= xhi[d] + s[d] && xlo[d] + s[d] <= hi[a][d] + cutoff_;
      if (m) return true;
    }
    return false;
  };
  const std::vector<char> with_others = active;
  std::vector<char> self(nb, 0);
  for (int a = 0; a < nb; ++a) {
    self[a] = n_points(a) && meets_own_image(a, lo[a], hi[a]);
    active[a] = active[a] || self[a];
  }
  for (int b = 0; b < nb; ++b) n_active += active[b];
  if (n_active == 0) return st;

  // The active bodies' points sorted into the fluid elements that hold them (counting sort).
  const int n_el = n_[0] * n_[1] * n_[2];
  std::vector<int> begin(n_el + 1, 0);
  const auto linear = [&](const geometry::Index3& e) { return e[0] + n_[0] * (e[1] + n_[1] * e[2]); };
  for (int b = 0; b < nb; ++b)
    if (active[b])
      for (int i = 0; i < n_points(b); ++i) ++begin[linear(element_of(b, i)) + 1];
  for (int e = 0; e < n_el; ++e) begin[e + 1] += begin[e];
  std::vector<std::pair<int, int>> entry(begin[n_el]);
  {
    std::vector<int> fill(begin.begin(), begin.end() - 1);
    for (int b = 0; b < nb; ++b)
      if (active[b])
        for (int i = 0; i < n_points(b); ++i) entry[fill[linear(element_of(b, i))]++] = {b, i};
  }
  // Per direction, the element offsets to visit (all elements once where r_c wraps around a period).
  std::array<std::vector<int>, 3> offsets;
  for (int d = 0; d < 3; ++d) {
    if (d >= dim_) {
      offsets[d] = {0};
      continue;
    }
    if (periodic_[d] && 2 * reach_[d] + 1 >= n_[d]) {
      for (int o = 0; o < n_[d]; ++o) offsets[d].push_back(o);  // (taken modulo n below)
    } else {
      for (int o = -reach_[d]; o <= reach_[d]; ++o) offsets[d].push_back(o);
    }
  }
  // The nearest image of a separation as geometry::nearest_image gives it, with the periods looked up once
  // (it runs for every candidate pair); `wrapped`: whether it is another image than r itself.
  std::vector<std::pair<Vec3, double>> periods;
  for (int d = 0; d < patch_.param_dim(); ++d) {
    const Vec3& s = patch_.shift(d);
    if (patch_.knots(d).periodic() && !s.isZero()) periods.emplace_back(s, s.squaredNorm());
  }
  const auto image_of = [&periods](Vec3 r, bool& wrapped) {
    wrapped = false;
    for (const auto& [s, s2] : periods) {
      const double k = std::round(r.dot(s) / s2);
      if (k != 0) r -= k * s, wrapped = true;
    }
    return r;
  };
  const double rc2 = cutoff_ * cutoff_;
  std::vector<double> best(nb);
  std::vector<int> best_point(nb), touched;
  for (int a = 0; a < nb; ++a) {
    if (!active[a]) continue;
    for (int i = 0; i < n_points(a); ++i) {
      const Vec3& x = (*bodies[a].x)[i];
      const bool own = self[a] && meets_own_image(a, x, x);
      if (!with_others[a] && !own) continue;
      const geometry::Index3 e = element_of(a, i);
      touched.clear();
      for (int o2 : offsets[2])
        for (int o1 : offsets[1])
          for (int o0 : offsets[0]) {
            geometry::Index3 f{e[0] + o0, e[1] + o1, e[2] + o2};
            bool inside = true;
            for (int d = 0; d < dim_; ++d) {
              if (periodic_[d])
                f[d] = ((f[d] % n_[d]) + n_[d]) % n_[d];
              else
                inside = inside && f[d] >= 0 && f[d] < n_[d];
            }
            if (!inside) continue;
            const int l = linear(f);
            for (int k = begin[l]; k < begin[l + 1]; ++k) {
              const auto [b, j] = entry[k];
              if (b == a && !own) continue;
              const Vec3 direct = x - (*bodies[b].x)[j];
              bool wrapped = false;
              const Vec3 r = image_of(direct, wrapped);
              // (A body's own point only through another image.)
              if (b == a && !wrapped) continue;
              const double r2 = r.squaredNorm();
              if (r2 >= rc2) continue;
              if (std::find(touched.begin(), touched.end(), b) == touched.end()) {
                touched.push_back(b);
                best[b] = r2;
                best_point[b] = j;
              } else if (r2 < best[b]) {
                best[b] = r2;
                best_point[b] = j;
              }
            }
          }
      for (int b : touched) {
        const int j = best_point[b];
        bool wrapped;
        const Vec3 r = image_of(x - (*bodies[b].x)[j], wrapped);
        const double dist = r.norm();
        st.cell_gap = std::min(st.cell_gap, dist);
        const double p = repulsion_pressure(dist, cutoff_, scale_);
        if (p == 0 || dist == 0) continue;
        const Vec3 f = 0.5 * (*bodies[a].area)[i] * p * (r / dist);
        force[a][i] += f;
        force[b][j] -= f;
        ++st.cell_pairs;
      }
    }
  }
  return st;
}

}  // namespace cellfsi::coupling
