#pragma once
// The contravariant Piola map of the divergence-conforming space on a mapped (curved) domain, at one point
// (issue 45 part 2), tested alone (tests/unit/fluid/test_div_conforming.cpp, DcPiola.*) and used by
// DivConformingFluid on a space made by DivConformingSpace::mapped.
//
// On the parametric box the space is the one of dc_space.hpp, with its knot vectors in the parameters xi; the
// geometry x(xi) (a geometry::Patch, e.g. the narrowing channel) has F = dx/dxi, J = det F > 0 and G =
// F^{-1}. A parametric velocity v^ (component c along xi_c) is the physical one
//   v(x) = P v^(xi),   P = F / J                                   (Evans & Hughes, M3AS 2013, Sec. 4)
// so that div_x v = (1/J) div_xi v^ (zero where v^ is divergence-free: the space stays divergence-free
// pointwise), and v . n dA = v^ . n^ dA^ (a wall's normal velocity is its parametric normal component, fixed
// as on the box). The pressure is mapped plainly: p(x) = p^(xi), so int q div v dx = int q^ div_xi v^ dxi.
//
// At a point the physical fields are a linear map L of the parametric ones (v^, grad_xi v^):
//   v_i       = P_ic v^_c
//   dv_i/dx_j = (dP_ic/dx_j) v^_c + P_ic (dv^_c/dxi_a) G_aj,
//   dP_ic/dx_j = (dP_ic/dxi_b) G_bj,  dP_ic/dxi_b = (d2x_i/dxi_c dxi_b) / J - P_ic (dJ/dxi_b) / J,
//   dJ/dxi_b  = J G_ai d2x_i/dxi_a dxi_b (Jacobi's formula),
// which needs the map's second derivatives. A weak form's point terms w . r0 + grad w : r1 (dc_kernel.hpp)
// against a test function w = P w^ are then (L^T (r0, r1)) . (w^, grad_xi w^), integrated with the measure
// J dxi: piola_test is L's transpose.
//
// A kernel of dc_kernel.hpp then runs unchanged on a mapped space: the fields at the point mapped by L, its
// residual taken back by L^T (piola_residual), its tangent K by L^T K L (piola_tangent), and the parametric
// basis with weight J dxi assembles them as on a box. Two terms vanish by the Piola identity (the columns of
// P are divergence-free, sum_i dP_ic/dx_i = 0: div_x of P e_c is div_xi e_c / J = 0) and are left out:
// the pressure's -p I in r1 reaches r0^ only as -p sum_i dP_ic/dx_i, and div v = tr(grad v) depends on v^
// only through the same sum; PointTangent has no place for either (d r0 / d p, d rq / d v), and on a map of
// second derivatives computed to round-off they are round-off.
#include <array>

#include "fluid/div_conforming/dc_kernel.hpp"
#include "geometry/patch.hpp"

namespace cellfsi::fluid::dc {

/// The map's quantities at one point. In 2D only the first two rows and columns are meaningful (F's third
/// direction is the identity, so P(2, 2) = 1 / J); piola_values and piola_test read those alone.
struct PiolaPoint {
  int dim = 3;
  double J = 1;                      // det F
  geometry::Mat3 P;                  // P(i, c) = F_ic / J
  geometry::Mat3 G;                  // G(a, j) = d xi_a / d x_j
  std::array<geometry::Mat3, 3> dP;  // dP[j](i, c) = d P_ic / d x_j
};

/// From the map and its first and second parametric derivatives at the point (geometry::Patch::evaluate(xi,
/// 2)). Throws std::invalid_argument where J <= 0 (a folded or degenerate map).
PiolaPoint piola_point(const geometry::MapValues& m, int dim);

/// L: the physical velocity v[i] and gradient grad[i][j] = d v_i / d x_j from the parametric ones v_hat[c]
/// and grad_hat[c][a] = d v^_c / d xi_a.
void piola_values(const PiolaPoint& pt, const double* v_hat, const double (*grad_hat)[3], double* v,
                  double (*grad)[3]);

/// L^T: r0_hat[c] and r1_hat[c][a] with sum_i r0_i v_i + sum_ij r1_ij dv_i/dx_j = sum_c r0_hat_c v^_c +
/// sum_ca r1_hat_ca dv^_c/dxi_a for every parametric field (multiply the quadrature weight by J).
void piola_test(const PiolaPoint& pt, const double* r0, const double (*r1)[3], double* r0_hat,
                double (*r1_hat)[3]);

/// The physical fields of a point from its parametric ones (v, a by P; grad v by L; p unchanged).
PointState piola_state(const PiolaPoint& pt, const PointState& hat);
/// A kernel's residual at the physical fields, as the parametric test side's: (r0^, r1^) = L^T (r0, r1), rq
/// unchanged (the caller's weight carries J).
PointResidual piola_residual(const PiolaPoint& pt, const PointResidual& r);
/// A kernel's tangent at the physical fields as the derivative of piola_residual with respect to the
/// parametric fields: L^T K L (a by P, p unchanged; the two terms of the Piola identity left out, above).
PointTangent piola_tangent(const PiolaPoint& pt, const PointTangent& t);

}  // namespace cellfsi::fluid::dc
