#pragma once
// The contravariant Piola map of the divergence-conforming space on a mapped (curved) domain, at one point:
// issue 45 part 2's kernel, tested alone (tests/unit/fluid/test_div_conforming.cpp, DcPiola.*). Not yet used
// by the fluid, which takes axis-aligned boxes only (DivConformingSpace::from_patch refuses others).
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
#include <array>

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

}  // namespace cellfsi::fluid::dc
