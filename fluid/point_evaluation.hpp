#pragma once
// The fluid's fields at one point of the Eulerian patch, written once for every user: the immersed points of
// the assembly (fluid_assembly.cpp), the coupling's samples at t_{n+alpha} (FluidSolver::sample_alpha),
// samples at positions (FluidSolver::sample), the output pieces and the section data (fluid_output.cpp).
//
// physical_point gives the basis in physical coordinates at (element, xi); interpolate sums nodal values
// against it, whatever array they come from: the caller's `value(k, c)` returns component c of the point's
// k-th function (the functions in basis order, direction 0 fastest; c < dim velocity, c == dim the scalar).
#include <petscsys.h>

#include <array>
#include <vector>

#include "geometry/patch.hpp"

namespace cellfsi::fluid {

using geometry::Index3;
using geometry::Mat3;
using geometry::Param;
using geometry::Vec3;

/// The basis functions of one point in physical coordinates.
struct PhysicalPoint {
  int n = 0;
  int first[3] = {0, 0, 0};  // first basis function per direction (unwrapped index; see element_nodes)
  std::vector<int> index;    // folded control-point (natural node) index of each function
  Vec3 x = Vec3::Zero();
  std::vector<double> N, dN,
      lapN;  // dN[3 k + j] = d N_k / d x_j; lapN (order 2 only) = sum_j d2 N_k / d x_j^2
  double detJ = 0;
  std::array<std::array<double, 3>, 3> G{};  // tau_M's metric (order 2 only), parent coordinates in [-1, 1]
};

/// The basis at parametric point xi of element e. order 1: N, dN; order 2: also lapN and G. The scratch
/// bv, mv are reused between calls. `affine`: the patch's map if it is axis-aligned affine
/// (geometry::affine_map: the paper's boxes), for a fast path that forms the basis from univariate B-splines
/// scaled by the map, with no rational basis, no map and no inverse (the same values to round-off; tested).
void physical_point(const geometry::Patch& patch, const Index3& e, const Param& xi, int order,
                    geometry::BasisValues& bv, geometry::MapValues& mv, PhysicalPoint& out,
                    const geometry::AffineMap* affine = nullptr);

/// The element that contains xi (per direction; the last element for the end of the interval).
Index3 element_of(const geometry::Patch& patch, const Param& xi);

/// The first basis function per direction of the element that basis values bv were evaluated in.
inline void first_functions(const geometry::Patch& patch, const geometry::BasisValues& bv, int first[3]) {
  for (int d = 0; d < 3; ++d) first[d] = d < patch.param_dim() ? bv.span[d] - patch.degree(d) : 0;
}

/// Local (ghosted DMDA) offset of the node with unwrapped indices m.
inline PetscInt local_node(const PetscInt m[3], const PetscInt gxs[3], const PetscInt gxm[3]) {
  return ((m[2] - gxs[2]) * gxm[1] + (m[1] - gxs[1])) * gxm[0] + (m[0] - gxs[0]);
}

/// Calls f(k, node) for each of the (p+1)^d functions of the element whose first functions are `first`: k in
/// basis order (direction 0 fastest), node its local (ghosted) offset.
template <class F>
void for_each_element_node(const geometry::Patch& patch, const int first[3], const PetscInt gxs[3],
                           const PetscInt gxm[3], F&& f) {
  int np[3] = {1, 1, 1};
  for (int d = 0; d < patch.param_dim(); ++d) np[d] = patch.degree(d) + 1;
  int k = 0;
  for (int c2 = 0; c2 < np[2]; ++c2)
    for (int b1 = 0; b1 < np[1]; ++b1)
      for (int a0 = 0; a0 < np[0]; ++a0, ++k) {
        const PetscInt m[3] = {first[0] + a0, first[1] + b1, first[2] + c2};
        f(k, local_node(m, gxs, gxm));
      }
}

/// The local (ghosted) offsets of the point's functions, in basis order.
inline void element_nodes(const geometry::Patch& patch, const PhysicalPoint& pp, const PetscInt gxs[3],
                          const PetscInt gxm[3], std::vector<PetscInt>& nodes) {
  nodes.resize(pp.n);
  for_each_element_node(patch, pp.first, gxs, gxm, [&](int k, PetscInt node) { nodes[k] = node; });
}

/// Velocity (dim components), its gradient (grad_v(i, j) = d v_i / d x_j) and the scalar (component dim: the
/// kinematic pressure, or a scalar field with dim = 0) at the point.
struct PointValues {
  Vec3 x = Vec3::Zero();
  Vec3 v = Vec3::Zero();
  Mat3 grad_v = Mat3::Zero();
  double scalar = 0;
};

template <class Value>
PointValues interpolate(const PhysicalPoint& pp, int dim, Value&& value) {
  PointValues r;
  r.x = pp.x;
  for (int k = 0; k < pp.n; ++k) {
    const double N = pp.N[k];
    for (int c = 0; c < dim; ++c) {
      const double val = value(k, c);
      r.v[c] += N * val;
      for (int j = 0; j < dim; ++j) r.grad_v(c, j) += pp.dN[3 * k + j] * val;
    }
    r.scalar += N * value(k, dim);
  }
  return r;
}

}  // namespace cellfsi::fluid
