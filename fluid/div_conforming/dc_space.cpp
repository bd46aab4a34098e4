#include "fluid/div_conforming/dc_space.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "geometry/basis.hpp"
#include "geometry/quadrature.hpp"

namespace cellfsi::fluid::dc {

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("DivConformingSpace: " + what);
}

}  // namespace

DivConformingSpace::DivConformingSpace(int dim, int k, const Index3& n_elements, const Vec3& lo,
                                       const Vec3& hi, const std::array<bool, 3>& periodic)
    : dim_(dim), k_(k) {
  require(dim == 2 || dim == 3, "dim must be 2 or 3, got " + std::to_string(dim));
  require(k >= 1 && k + 1 <= geometry::kMaxDegree, "the pressure degree k must be in [1, " +
                                                       std::to_string(geometry::kMaxDegree - 1) + "], got " +
                                                       std::to_string(k));
  for (int d = 0; d < dim; ++d) {
    const std::string dir = "direction " + std::to_string(d);
    require(n_elements[d] >= 1, dir + ": n_elements must be >= 1, got " + std::to_string(n_elements[d]));
    require(hi[d] > lo[d], dir + ": the box needs hi > lo");
    periodic_[d] = periodic[d];
    lo_[d] = lo[d];
    hi_[d] = hi[d];
    if (periodic[d]) {
      require(n_elements[d] >= k + 1,
              dir + ": a periodic direction needs n_elements >= k + 1 = " + std::to_string(k + 1) +
                  " (the velocity's degree), got " + std::to_string(n_elements[d]));
      high_[d] = KnotVector::periodic_uniform(k + 1, n_elements[d], lo[d], hi[d]);
      low_[d] = KnotVector::periodic_uniform(k, n_elements[d], lo[d], hi[d]);
    } else {
      high_[d] = KnotVector::open_uniform(k + 1, n_elements[d], lo[d], hi[d]);
      low_[d] = KnotVector::open_uniform(k, n_elements[d], lo[d], hi[d]);
    }
  }
  int off = 0;
  for (int c = 0; c <= dim_; ++c) {
    offset_[c] = off;
    off += n_basis(c);
  }
  // univariate()'s tables: each element's functions expanded about its midpoint (Taylor: all p derivatives
  // there, the polynomials' own coefficients).
  for (int d = 0; d < dim_; ++d) {
    const int n_e = high_[d].n_elements();
    mid_[d].resize(n_e), inv_h_[d].resize(n_e);
    for (int e = 0; e < n_e; ++e) {
      const double a = high_[d].element_begin(e), b = high_[d].element_end(e);
      mid_[d][e] = 0.5 * (a + b), inv_h_[d][e] = 1.0 / (b - a);
    }
    for (int s = 0; s < 2; ++s) {
      const KnotVector& kv = s ? high_[d] : low_[d];
      const int p = kv.degree(), n = p + 1;
      require(kv.n_elements() == n_e, "the two spaces' elements differ along direction " + std::to_string(d));
      std::vector<double>& poly = poly_[s][d];
      poly.resize(static_cast<size_t>(n_e) * n * n);
      double ders[(geometry::kMaxDegree + 1) * (geometry::kMaxDegree + 1)];
      for (int e = 0; e < n_e; ++e) {
        geometry::bspline_basis(kv, kv.element_span(e), mid_[d][e], p, ders);
        for (int j = 0; j < n; ++j) {
          double scale = 1.0;  // h^m / m!
          for (int m = 0; m < n; ++m) {
            poly[(static_cast<size_t>(e) * n + j) * n + m] = ders[m * n + j] * scale;
            scale /= (m + 1) * inv_h_[d][e];
          }
        }
      }
    }
  }
}

namespace {

/// A patch's parametric element grid: per direction its element count, parametric ends and periodicity.
/// Throws std::invalid_argument unless the dimensions agree and the elements are uniform in the parameter.
struct ParametricGrid {
  int dim = 0;
  Index3 n{1, 1, 1};
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();
  std::array<bool, 3> periodic{false, false, false};
};
ParametricGrid parametric_grid(const geometry::Patch& patch) {
  ParametricGrid g;
  g.dim = patch.param_dim();
  require(g.dim == 2 || g.dim == 3, "the patch's parametric dimension must be 2 or 3");
  require(patch.physical_dim() == g.dim, "the patch's parametric and physical dimensions must agree");
  for (int d = 0; d < g.dim; ++d) {
    const KnotVector& kv = patch.knots(d);
    const std::vector<double> breaks = kv.breakpoints();
    g.n[d] = kv.n_elements();
    g.periodic[d] = kv.periodic();
    g.a[d] = kv.a(), g.b[d] = kv.b();
    const double h = (kv.b() - kv.a()) / g.n[d];
    for (int e = 0; e <= g.n[d]; ++e)
      require(std::abs(breaks[e] - (kv.a() + e * h)) <= 1e-12 * (kv.b() - kv.a()),
              "direction " + std::to_string(d) + ": the elements must be uniform in the parameter");
  }
  return g;
}

/// The largest jump of the map's second derivatives across an interior element boundary, relative to their
/// largest value (or the first derivatives over the parameter's range, if larger; 0 for an affine map), and
/// where: sampled on both sides of every boundary along each direction, at the midpoints of up to 8 elements
/// spread across each other direction and at the ends there.
struct SecondDerivativeJump {
  double relative = 0;
  int direction = 0;
  double at = 0;
};
SecondDerivativeJump second_derivative_jump(const geometry::Patch& patch) {
  const int dim = patch.param_dim();
  // Transverse samples per direction: the two ends and the midpoints of up to 8 elements.
  std::array<std::vector<double>, 3> across;
  for (int d = 0; d < dim; ++d) {
    const KnotVector& kv = patch.knots(d);
    const int n = kv.n_elements(), m = std::min(n, 8);
    across[d] = {kv.a(), kv.b()};
    for (int j = 0; j < m; ++j) {
      const int e = (2 * j + 1) * n / (2 * m);
      across[d].push_back(0.5 * (kv.element_begin(e) + kv.element_end(e)));
    }
  }
  double largest = 0;
  SecondDerivativeJump worst;
  for (int d = 0; d < dim; ++d) {
    const KnotVector& kv = patch.knots(d);
    const double eps = 1e-9 * (kv.b() - kv.a());
    const int o1 = (d + 1) % dim, o2 = (d + 2) % dim;
    const std::vector<double> none{0.0};
    const std::vector<double>& s2 = dim == 3 ? across[o2] : none;
    for (int e = 1; e < kv.n_elements(); ++e) {
      const double u = kv.element_begin(e);
      for (double t1 : across[o1])
        for (double t2 : s2) {
          geometry::Param lo{0, 0, 0}, hi{0, 0, 0};
          lo[d] = u - eps, hi[d] = u + eps;
          lo[o1] = hi[o1] = t1;
          if (dim == 3) lo[o2] = hi[o2] = t2;
          const geometry::MapValues a = patch.evaluate(lo, 2), b = patch.evaluate(hi, 2);
          double jump = 0;
          // (the first derivatives over the parameter's range bound the scale from below: an affine map's
          // second derivatives are round-off)
          for (int c = 0; c < dim; ++c)
            largest = std::max(largest,
                               a.dx.col(c).cwiseAbs().maxCoeff() / (patch.knots(c).b() - patch.knots(c).a()));
          for (int i = 0; i < dim; ++i) {
            largest = std::max({largest, a.d2x[i].cwiseAbs().maxCoeff(), b.d2x[i].cwiseAbs().maxCoeff()});
            jump = std::max(jump, (a.d2x[i] - b.d2x[i]).cwiseAbs().maxCoeff());
          }
          if (jump > worst.relative) worst = {jump, d, u};
        }
    }
  }
  if (largest > 0) worst.relative /= largest;
  return worst;
}

}  // namespace

DivConformingSpace DivConformingSpace::from_patch(const geometry::Patch& patch, int k) {
  const auto map = geometry::affine_map(patch);
  require(map.has_value(),
          "the patch is not an axis-aligned affine box (geometry::rectangle or geometry::box); a curved one "
          "takes DivConformingSpace::mapped (the contravariant Piola map)");
  const ParametricGrid g = parametric_grid(patch);
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
  for (int d = 0; d < g.dim; ++d) {
    lo[d] = map->offset[d] + map->scale[d] * g.a[d];
    hi[d] = map->offset[d] + map->scale[d] * g.b[d];
  }
  return DivConformingSpace(g.dim, k, g.n, lo, hi, g.periodic);
}

DivConformingSpace DivConformingSpace::mapped(std::shared_ptr<const geometry::Patch> patch, int k) {
  require(patch != nullptr, "mapped: no patch");
  const ParametricGrid g = parametric_grid(*patch);
  // The mapped gradient takes the map's second derivatives (dc_piola.hpp): where they jump between elements,
  // so do the immersed terms and the velocity gradient at a point on that boundary, and a coupled step can
  // stall with the point changing element back and forth (measured on the narrowing at degree 2; tests/
  // unit/fluid/test_div_conforming.cpp, DcPiola.AMapWhoseSecondDerivativesJumpBetweenElementsIsRefused).
  // Affine maps (0) and maps of continuity 2 or more (of the order of the sampling's offset, 1e-9) pass.
  const SecondDerivativeJump jump = second_derivative_jump(*patch);
  require(jump.relative <= 1e-6,
          "the map's second derivatives jump by " + std::to_string(jump.relative) +
              " of their largest value across the element boundary at xi_" + std::to_string(jump.direction) +
              " = " + std::to_string(jump.at) +
              ": the Piola map needs them continuous (a map of degree 3 or more without repeated interior "
              "knots, or an affine one)");
  // The space's coordinates s_d = c_d xi_d, c_d the patch's length along d per unit parameter (the distance
  // between its mid-line's ends, or the period shift's length): then F = dx/ds and J are of order 1 and the
  // velocity coefficients (J F^{-1} v) have the physical velocity's size. In the patch's own parameters
  // (the paper's domains map [0, 1]) they were J F^{-1} ~ 1e-3 of it at 0.003 x 0.001 cm, while the
  // pressure's stayed, and Newton's update test (relative to the largest unknown) read the pressure's
  // round-off as 1e-10 of the velocity (measured on a channel at an angle).
  Vec3 scale = Vec3::Ones();
  for (int d = 0; d < g.dim; ++d) {
    double length = 0;
    if (g.periodic[d]) {
      length = patch->shift(d).norm();
    } else {
      geometry::Param lo{0, 0, 0}, hi{0, 0, 0};
      for (int e = 0; e < g.dim; ++e) lo[e] = hi[e] = 0.5 * (g.a[e] + g.b[e]);
      lo[d] = g.a[d], hi[d] = g.b[d];
      length = (patch->evaluate(hi, 0).x - patch->evaluate(lo, 0).x).norm();
    }
    require(length > 0, "mapped: the patch has no length along direction " + std::to_string(d));
    scale[d] = length / (g.b[d] - g.a[d]);
  }
  DivConformingSpace space(g.dim, k, g.n, g.a.cwiseProduct(scale), g.b.cwiseProduct(scale), g.periodic);
  space.map_ = std::move(patch);
  space.param_scale_ = scale;
  return space;
}

Index3 DivConformingSpace::element_multi_index(int e) const {
  const int n0 = n_elements(0), n1 = n_elements(1);
  return {e % n0, (e / n0) % n1, e / (n0 * n1)};
}

Index3 DivConformingSpace::multi_index(int c, int global) const {
  const int local = global - offset_[c];
  const int n0 = n_basis(c, 0), n1 = n_basis(c, 1);
  return {local % n0, (local / n0) % n1, local / (n0 * n1)};
}

void DivConformingSpace::average_periodic(std::vector<double>& U) const {
  if (static_cast<int>(U.size()) != n_dofs())
    throw std::invalid_argument("average_periodic: " + std::to_string(U.size()) +
                                " coefficients for a space of " + std::to_string(n_dofs()));
  for (int c = 0; c <= dim_; ++c) {
    const std::array<int, 3> n{n_basis(c, 0), n_basis(c, 1), n_basis(c, 2)};
    std::array<int, 3> span{1, 1, 1};  // the functions averaged together per direction
    for (int d = 0; d < dim_; ++d)
      if (periodic_[d]) span[d] = n[d];
    const double count = static_cast<double>(span[0]) * span[1] * span[2];
    // Each class of functions (the same index in the non-periodic directions): its first member's index,
    // stepping by the members of a period.
    for (int b2 = 0; b2 < n[2]; b2 += (span[2] == 1 ? 1 : n[2]))
      for (int b1 = 0; b1 < n[1]; b1 += (span[1] == 1 ? 1 : n[1]))
        for (int b0 = 0; b0 < n[0]; b0 += (span[0] == 1 ? 1 : n[0])) {
          double sum = 0;
          for (int i2 = 0; i2 < span[2]; ++i2)
            for (int i1 = 0; i1 < span[1]; ++i1)
              for (int i0 = 0; i0 < span[0]; ++i0) sum += U[index(c, {b0 + i0, b1 + i1, b2 + i2})];
          for (int i2 = 0; i2 < span[2]; ++i2)
            for (int i1 = 0; i1 < span[1]; ++i1)
              for (int i0 = 0; i0 < span[0]; ++i0) U[index(c, {b0 + i0, b1 + i1, b2 + i2})] = sum / count;
        }
  }
}

std::vector<int> DivConformingSpace::wall_normal_dofs() const {
  std::vector<int> dofs;
  for (int d = 0; d < dim_; ++d) {
    if (periodic_[d]) continue;
    const int last = n_basis(d, d) - 1;
    for (int i2 = 0; i2 < n_basis(d, 2); ++i2)
      for (int i1 = 0; i1 < n_basis(d, 1); ++i1)
        for (int i0 = 0; i0 < n_basis(d, 0); ++i0) {
          const Index3 i{i0, i1, i2};
          if (i[d] == 0 || i[d] == last) dofs.push_back(index(d, i));
        }
  }
  return dofs;
}

TensorRule DivConformingSpace::element_rule(const Index3& e, int n_gauss) const {
  TensorRule r;
  const geometry::GaussRule& g = geometry::gauss_legendre(n_gauss);
  for (int d = 0; d < 3; ++d) {
    if (d >= dim_) {
      r.points[d] = {0.0};
      r.weights[d] = {1.0};
      continue;
    }
    const double a = low_[d].element_begin(e[d]), b = low_[d].element_end(e[d]);
    for (int q = 0; q < n_gauss; ++q) {
      r.points[d].push_back(a + 0.5 * (b - a) * (g.points[q] + 1.0));
      r.weights[d].push_back(0.5 * (b - a) * g.weights[q]);
    }
  }
  return r;
}

Index3 DivConformingSpace::find_element(const Vec3& x) const {
  Index3 e{0, 0, 0};
  for (int d = 0; d < dim_; ++d) e[d] = low_[d].find_element(x[d]);
  return e;
}

TensorRule DivConformingSpace::point_rule(const Vec3& x) const {
  TensorRule r;
  for (int d = 0; d < 3; ++d) {
    r.points[d] = {d < dim_ ? low_[d].normalize(x[d]) : 0.0};
    r.weights[d] = {1.0};
  }
  return r;
}

TensorRule DivConformingSpace::face_rule(const Index3& e, int d, int side, int n_gauss) const {
  TensorRule r = element_rule(e, n_gauss);
  r.points[d] = {side == 0 ? low_[d].element_begin(e[d]) : low_[d].element_end(e[d])};
  r.weights[d] = {1.0};
  return r;
}

void DivConformingSpace::evaluate(const Index3& e, const TensorRule& rule, ElementBasis& out,
                                  bool with_indices) const {
  const int nq[3] = {static_cast<int>(rule.points[0].size()), static_cast<int>(rule.points[1].size()),
                     static_cast<int>(rule.points[2].size())};
  const int n_points = nq[0] * nq[1] * nq[2];
  out.n_points = n_points;
  out.x.resize(n_points);
  out.weight.resize(n_points);
  for (int q2 = 0; q2 < nq[2]; ++q2)
    for (int q1 = 0; q1 < nq[1]; ++q1)
      for (int q0 = 0; q0 < nq[0]; ++q0) {
        const int q = q0 + nq[0] * (q1 + nq[1] * q2);
        out.x[q] = Vec3(rule.points[0][q0], dim_ > 1 ? rule.points[1][q1] : 0.0,
                        dim_ > 2 ? rule.points[2][q2] : 0.0);
        out.weight[q] = rule.weights[0][q0] * rule.weights[1][q1] * rule.weights[2][q2];
      }

  // Univariate values uni[d][(q * (p + 1) + j) * 2 + m] (m = 0 value, 1 derivative) of the two spaces.
  constexpr int kMax = geometry::kMaxDegree + 1;
  thread_local std::vector<double> uni[2][3];  // [space: 0 low, 1 high][direction] (kept: no allocation)
  int first[2][3] = {{0, 0, 0}, {0, 0, 0}};
  for (int s = 0; s < 2; ++s)
    for (int d = 0; d < 3; ++d) {
      if (d >= dim_) {
        uni[s][d].assign({1.0, 0.0});
        continue;
      }
      const KnotVector& kv = s ? high_[d] : low_[d];
      const int p = kv.degree(), span = kv.element_span(e[d]);
      first[s][d] = span - p;
      uni[s][d].resize(nq[d] * (p + 1) * 2);
      double value[kMax], deriv[kMax];
      for (int q = 0; q < nq[d]; ++q) {
        univariate(s, d, e[d], rule.points[d][q], value, deriv);
        for (int j = 0; j <= p; ++j) {
          uni[s][d][(q * (p + 1) + j) * 2] = value[j];
          uni[s][d][(q * (p + 1) + j) * 2 + 1] = deriv[j];
        }
      }
    }

  for (int c = 0; c <= dim_; ++c) {
    ComponentBasis& cb = out.comp[c];
    int np[3], sp[3];
    for (int d = 0; d < 3; ++d) {
      sp[d] = (c == d) ? 1 : 0;
      np[d] = d < dim_ ? knots(c, d).degree() + 1 : 1;
    }
    cb.n = np[0] * np[1] * np[2];
    cb.value.resize(static_cast<size_t>(n_points) * cb.n);
    cb.grad.resize(static_cast<size_t>(n_points) * cb.n * 3);
    if (with_indices) {
      cb.index.resize(cb.n);
      for (int j2 = 0; j2 < np[2]; ++j2)
        for (int j1 = 0; j1 < np[1]; ++j1)
          for (int j0 = 0; j0 < np[0]; ++j0) {
            const int a = j0 + np[0] * (j1 + np[1] * j2);
            const int j[3] = {j0, j1, j2};
            Index3 folded{0, 0, 0};
            for (int d = 0; d < dim_; ++d) folded[d] = knots(c, d).fold(first[sp[d]][d] + j[d]);
            cb.index[a] = index(c, folded);
          }
    }
    // The products built outward in: per (j2, j1) the factors of directions 1 and 2 once, then a run over j0
    // (the functions a = j0 + np0 (j1 + np1 j2) are consecutive). (Indexing each factor per function took
    // 14 % of a 3D coupled step at 32^3, most of it at the immersed points' one-point rules; perf.)
    for (int q2 = 0; q2 < nq[2]; ++q2)
      for (int q1 = 0; q1 < nq[1]; ++q1)
        for (int q0 = 0; q0 < nq[0]; ++q0) {
          const int q = q0 + nq[0] * (q1 + nq[1] * q2);
          const double* f0 = &uni[sp[0]][0][q0 * np[0] * 2];
          const double* f1 = &uni[sp[1]][1][q1 * np[1] * 2];
          const double* f2 = &uni[sp[2]][2][q2 * np[2] * 2];
          double* value = &cb.value[static_cast<size_t>(q) * cb.n];
          double* grad = &cb.grad[static_cast<size_t>(q) * cb.n * 3];
          for (int j2 = 0; j2 < np[2]; ++j2) {
            const double v2 = f2[2 * j2], d2 = f2[2 * j2 + 1];
            for (int j1 = 0; j1 < np[1]; ++j1) {
              const double v1 = f1[2 * j1], d1 = f1[2 * j1 + 1];
              const double v12 = v1 * v2, d1v2 = d1 * v2, v1d2 = v1 * d2;
              for (int j0 = 0; j0 < np[0]; ++j0) {
                const double v0 = f0[2 * j0], d0 = f0[2 * j0 + 1];
                *value++ = v0 * v12;
                grad[0] = d0 * v12;
                grad[1] = v0 * d1v2;
                grad[2] = v0 * v1d2;
                grad += 3;
              }
            }
          }
        }
  }
  // A mapped space: the physical points, the map there, and the measure J dxi.
  out.piola.clear();
  if (!map_) return;
  out.piola.resize(n_points);
  thread_local geometry::BasisValues bv;
  geometry::MapValues mv;
  for (int q = 0; q < n_points; ++q) {
    const geometry::Param xi = to_patch(out.x[q]);
    map_->basis(xi, 2, bv, &e);  // (the element's span: points on its faces belong to it)
    map_->map(bv, mv);
    for (int a = 0; a < 3; ++a) {  // (d/ds_a = d/dxi_a / c_a)
      mv.dx.col(a) /= param_scale_[a];
      for (int i = 0; i < 3; ++i) {
        mv.d2x[i].row(a) /= param_scale_[a];
        mv.d2x[i].col(a) /= param_scale_[a];
      }
    }
    out.piola[q] = piola_point(mv, dim_);
    out.x[q] = mv.x;
    out.weight[q] *= out.piola[q].J;
  }
}

namespace {

/// interpolate's sums with the dimension fixed, so that the gradient's loop unrolls (it ran a loop of
/// run-time length per function: 20 % of a 3D coupled step at 32^3, measured with perf).
template <int D>
DivConformingSpace::PointValues interpolate_fixed(const ElementBasis& eb, int q, const double* coeffs) {
  DivConformingSpace::PointValues pv;
  for (int c = 0; c < D; ++c) {
    const ComponentBasis& cb = eb.comp[c];
    const double* value = cb.value.data() + static_cast<size_t>(q) * cb.n;
    const double* grad = cb.grad.data() + static_cast<size_t>(q) * cb.n * 3;
    double v = 0, g[3] = {0, 0, 0};
    for (int a = 0; a < cb.n; ++a) {
      const double u = coeffs[cb.index[a]];
      v += u * value[a];
      for (int j = 0; j < D; ++j) g[j] += u * grad[3 * a + j];
    }
    pv.v[c] = v;
    for (int j = 0; j < D; ++j) pv.grad[c][j] = g[j];
  }
  const ComponentBasis& cp = eb.comp[D];
  const double* value = cp.value.data() + static_cast<size_t>(q) * cp.n;
  for (int a = 0; a < cp.n; ++a) pv.p += coeffs[cp.index[a]] * value[a];
  if (!eb.piola.empty()) {  // the parametric fields to the physical ones (the pressure is mapped plainly)
    double v_hat[3], g_hat[3][3], v[3], g[3][3];
    for (int c = 0; c < 3; ++c) {
      v_hat[c] = pv.v[c];
      for (int j = 0; j < 3; ++j) g_hat[c][j] = pv.grad[c][j];
    }
    piola_values(eb.piola[q], v_hat, g_hat, v, g);
    for (int c = 0; c < 3; ++c) {
      pv.v[c] = v[c];
      for (int j = 0; j < 3; ++j) pv.grad[c][j] = g[c][j];
    }
  }
  return pv;
}

}  // namespace

DivConformingSpace::PointValues DivConformingSpace::interpolate(const ElementBasis& eb, int q, int dim,
                                                                const double* coeffs) {
  return dim == 3 ? interpolate_fixed<3>(eb, q, coeffs) : interpolate_fixed<2>(eb, q, coeffs);
}

std::array<double, 3> DivConformingSpace::interpolate_velocity(const ElementBasis& eb, int q, int dim,
                                                               const double* coeffs) {
  std::array<double, 3> v{};
  for (int c = 0; c < dim; ++c) {
    const ComponentBasis& cb = eb.comp[c];
    const double* value = cb.value.data() + static_cast<size_t>(q) * cb.n;
    double s = 0;
    for (int a = 0; a < cb.n; ++a) s += coeffs[cb.index[a]] * value[a];
    v[c] = s;
  }
  if (!eb.piola.empty()) {  // v = P v^
    const PiolaPoint& pt = eb.piola[q];
    std::array<double, 3> mapped{};
    for (int i = 0; i < dim; ++i)
      for (int c = 0; c < dim; ++c) mapped[i] += pt.P(i, c) * v[c];
    return mapped;
  }
  return v;
}

std::vector<double> DivConformingSpace::divergence(const std::vector<double>& u) const {
  require(static_cast<int>(u.size()) == n_velocity(), "divergence: u must have n_velocity() entries");
  std::vector<double> div(n_pressure(), 0.0);
  for (int i = 0; i < dim_; ++i) {
    // d/dx_i of high(i) function j: p / (U_{j+p} - U_j) N_{j-1}^low - p / (U_{j+p+1} - U_{j+1}) N_j^low, so
    // the coefficient of low function m is p / (U_{m+1+p} - U_{m+1}) (u_{m+1} - u_m) (indices folded).
    const KnotVector& U = high_[i];
    const int p = U.degree();
    for (int m2 = 0; m2 < n_basis(dim_, 2); ++m2)
      for (int m1 = 0; m1 < n_basis(dim_, 1); ++m1)
        for (int m0 = 0; m0 < n_basis(dim_, 0); ++m0) {
          const Index3 m{m0, m1, m2};
          const int mi = m[i];
          const double c = p / (U.knot(mi + 1 + p) - U.knot(mi + 1));
          Index3 plus = m, minus = m;
          plus[i] = U.fold(mi + 1);
          minus[i] = U.fold(mi);
          div[index(dim_, m) - offset_[dim_]] += c * (u[index(i, plus)] - u[index(i, minus)]);
        }
  }
  return div;
}

}  // namespace cellfsi::fluid::dc
