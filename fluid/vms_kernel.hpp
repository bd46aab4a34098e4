#pragma once
// Pointwise kernels of the VMS Navier-Stokes formulation (paper Eqs. (8), (14)-(17); Bazilevs et al. 2007)
// and of the immersed-solid terms of Eq. (10). Plain functions of plain data at one quadrature point: no
// mesh, no PETSc.
//
// Unknowns per basis function A: velocity v_A (dim components) then kinematic pressure p_A (pressure /
// rho_1); a residual or tangent row/column index is A * (dim + 1) + c, c < dim velocity, c == dim pressure.
// Time discretisation (generalized-alpha, docs/design.md §3): the caller evaluates the fields at
// v = v_{n+alpha_f}, vdot = vdot_{n+alpha_m}, p = p_{n+1}; TangentScales carries d(field)/d(unknown at n+1).
//
// Residual (test functions w = N_A e_i, q = N_A), with r_M = vdot + (v.grad)v + grad p - nu lap v
// - grad nu . (grad v + grad v^T) - g, r_C = div v, v' = -tau_M r_M, p' = -tau_C r_C:
//   R^M_{A,i} = N_A (vdot_i + (v.grad)v_i - g_i) + nu d_j N_A (d_j v_i + d_i v_j) - d_i N_A p (Galerkin)
//             + N_A (v'.grad)v_i (cross)
//             - ((v + v').grad N_A) v'_i                                                   (SUPG and
//             Reynolds)
//             - d_i N_A p'                                                                             (LSIC)
//   R^C_A     = N_A div v - grad N_A . v'                                                              (PSPG)
// In Stokes mode every convective term is dropped: (v.grad)v in r_M and in the Galerkin term, the cross term,
// the whole SUPG/Reynolds line, and v.G v in tau_M (the PSPG and LSIC terms stay: they stabilise equal-order
// pairs).
//
// Viscosity: prm.nu is the kinematic viscosity at the point. A viscosity that varies in space (a spline field
// nu^h = sum_A nu_A N_A, docs/fluid.md "The viscosity field") is handled by the caller setting prm.nu to
// nu^h at each point and f.dnu to grad nu^h there: the Galerkin term, tau_M's C_I nu^2 G:G and the immersed
// terms then all use the same local nu. The strong residual of -div(2 nu eps(v)) is -nu lap v - nu grad(div
// v) - grad nu . (grad v + grad v^T); the grad(div v) part is dropped as for a uniform nu (div v = 0 up to
// the discretisation), the grad nu part is kept exactly (nu^h is smooth within an element, and without it
// r_M of the exact solution is not zero, so the stabilisation is not consistent: the manufactured solution
// of tests/convergence/test_fluid_convergence.cpp converges at rates 3.00 and 4.04 for p = 2 and 3 with it,
// 1.98 for both without). With f.dnu zero (the default) every formula is the uniform viscosity's.
#include <array>

#include "fluid/immersed_point.hpp"

namespace cellfsi::fluid {

/// Physical and numerical parameters of the fluid at a point.
struct VmsParameters {
  int dim = 2;                // spatial dimension, 2 or 3
  double nu = 0;              // kinematic viscosity mu / rho_1 [cm^2/s]
  std::array<double, 3> g{};  // body force per unit mass [cm/s^2] (f / rho_1 for a force f per volume)
  double dt = 0;              // time step, in tau_M's 4 / dt^2
  double c_i = 36.0;          // C_I of tau_M (paper: 36)
  bool stokes = false;        // drop convection (inertia negligible)
};

/// Values at the point of the n basis functions whose support contains it, in physical coordinates.
struct PointBasis {
  int n = 0;
  const double* N = nullptr;     // N[A]
  const double* dN = nullptr;    // dN[A * 3 + j] = d N_A / d x_j
  const double* lapN = nullptr;  // lapN[A] = Laplacian of N_A (second derivatives needed by nu lap v)
};

/// Coarse-scale fields at the point (at the generalized-alpha levels) and the element metric.
struct PointFields {
  std::array<double, 3> v{};                  // velocity
  std::array<std::array<double, 3>, 3> dv{};  // dv[i][j] = d v_i / d x_j
  std::array<double, 3> lap_v{};              // Laplacian of each velocity component
  std::array<double, 3> vdot{};               // time derivative of velocity
  double p = 0;                               // kinematic pressure
  std::array<double, 3> dp{};                 // its gradient
  std::array<std::array<double, 3>, 3>
      G{};                      // G_ij = sum_k dxi_k/dx_i dxi_k/dx_j, parent coordinates xi in [-1,1]^d
  double s = 1.0;               // scaling field s^h at the point (paper Eq. (16))
  std::array<double, 3> dnu{};  // gradient of the kinematic viscosity at the point (zero: uniform nu)
  /// Whether dnu is nonzero (the terms it adds are skipped otherwise, so a uniform nu costs nothing).
  bool has_dnu() const { return dnu[0] != 0.0 || dnu[1] != 0.0 || dnu[2] != 0.0; }
};

/// tau_M and tau_C of Eqs. (16)-(17).
struct Stabilization {
  double tau_m = 0;
  double tau_c = 0;
};
Stabilization vms_stabilization(const VmsParameters& prm, const PointFields& f);

/// Derivatives of the point fields with respect to the unknowns at t_{n+1}: d v / d V_B = velocity N_B,
/// d vdot / d V_B = velocity_rate N_B, d p / d P_B = pressure N_B (generalized-alpha: alpha_f, alpha_m/(gamma
/// dt), 1).
struct TangentScales {
  double velocity = 1.0;
  double velocity_rate = 0.0;
  double pressure = 1.0;
};

/// Adds weight * (the residual above) to R[A * (dim + 1) + c], A < basis.n.
/// If `frozen` is given, its tau_M and tau_C are used instead of computing them from the fields.
void vms_residual(const VmsParameters& prm, const PointBasis& basis, const PointFields& f, double weight,
                  double* R, const Stabilization* frozen = nullptr);

/// Adds weight * (the approximate tangent) to K, row-major, size (n (dim+1))^2:
/// K[(A (dim+1) + c) * n (dim+1) + B (dim+1) + e] = d R_{A,c} / d U_{B,e}.
/// The approximation (documented, tested): the exact derivative of vms_residual with tau_M and tau_C held
/// fixed. In Stokes mode tau_M does not depend on v, so the tangent is exact.
void vms_tangent(const VmsParameters& prm, const PointBasis& basis, const PointFields& f,
                 const TangentScales& ts, double weight, double* K);

/// The n basis functions of one element at its nq quadrature points, laid out as in ElementValues, and the
/// fields the caller evaluated at each point.
struct ElementPoints {
  int n = 0, nq = 0;
  const double* N = nullptr;            // N[q * n + k]
  const double* dN = nullptr;           // dN[(q * n + k) * 3 + j] = d N_k / d x_j
  const double* lapN = nullptr;         // lapN[q * n + k]
  const double* weight = nullptr;       // weight[q]: quadrature weight times |det dx/dxi|
  const PointFields* fields = nullptr;  // fields[q]
};

/// Instruction set of vms_tangent_element's inner loops: the best the CPU has (on x86-64: AVX2 and FMA if
/// present, detected at run time), or the baseline the build targets (SSE2 on x86-64); the choice changes
/// round-off only. For tests and timings.
enum class ElementKernelIsa { best, baseline };

/// True where the CPU has AVX2 and FMA (x86-64, detected once at run time): the element kernels' and the
/// residual's point fields' fast versions are chosen by it.
bool cpu_has_avx2_fma();

/// Element tangent: adds to K (layout of vms_tangent; K is accumulated into, not overwritten) the sum over
/// the nq points of vms_tangent(prm, {n, N + q n, dN + 3 q n, lapN + q n}, fields[q], ts, weight[q], K),
/// formed as small matrix products over the points instead of pair by pair (same result up to round-off).
/// Thread safe; per-thread scratch memory, kept between calls. The viscosity must be uniform over the element
/// (prm.nu at every point, every fields[q].dnu zero): an element where a viscosity field varies is assembled
/// point by point with vms_tangent (FluidSolver::assemble).
void vms_tangent_element(const VmsParameters& prm, const ElementPoints& points, const TangentScales& ts,
                         double* K, ElementKernelIsa isa = ElementKernelIsa::best);

/// Univariate factors of a tensor-product element whose physical basis is a product too (an axis-affine
/// patch). With A = a_0 + np_0 (a_1 + np_1 a_2) and q = q_0 + nq_0 (q_1 + nq_1 q_2) (points.n = prod np,
/// points.nq = prod nq): N_A(q) = prod_d value[d][q_d np_d + a_d], and d N_A / d x_j (q) is that product with
/// deriv[j] in place of value[j].
struct TensorFactors {
  int np[3] = {1, 1, 1}, nq[3] = {1, 1, 1};
  const double* value[3] = {nullptr, nullptr, nullptr};
  const double* deriv[3] = {nullptr, nullptr, nullptr};
};

/// The same element tangent in node blocks, as PETSc's BAIJ matrices store them (each (dim+1) x (dim+1)
/// block column-major), and written, not added: Kb[(A n + B) (dim+1)^2 + e (dim+1) + c] = d R_{A,c} / d
/// U_{B,e}. Without `tensor`, the same sums as vms_tangent_element. With it (2D; ignored in 3D), the products
/// over the points are sum-factorised on the test-function side: fewer operations, same values to round-off.
void vms_tangent_element_blocks(const VmsParameters& prm, const ElementPoints& points,
                                const TangentScales& ts, double* Kb, const TensorFactors* tensor = nullptr,
                                ElementKernelIsa isa = ElementKernelIsa::best);

/// Adds the Eq. (10) terms of one immersed point to the momentum rows of R (continuity rows untouched):
///   R^M_{A,i} += weight * [ -beta N_A (vdot_i + (v.grad)v_i - g_i) - nu d_j N_A (d_j v_i + d_i v_j)
///                           + d_j N_A stress_ij - N_A force_i ]
/// (the convective term is dropped in Stokes mode; the force, like g, is a load: R = B - L, so summed over
/// A, with sum_A N_A = 1, it gives -weight force). basis and f are the Eulerian basis and fields at the
/// point.
void immersed_residual(const VmsParameters& prm, const PointBasis& basis, const PointFields& f,
                       const ImmersedPoint& ip, double* R);
/// Its exact tangent with respect to the Eulerian unknowns (the stress is held fixed: it depends on the
/// solid).
void immersed_tangent(const VmsParameters& prm, const PointBasis& basis, const PointFields& f,
                      const TangentScales& ts, const ImmersedPoint& ip, double* K);

}  // namespace cellfsi::fluid
