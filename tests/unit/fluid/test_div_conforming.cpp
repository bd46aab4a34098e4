// The divergence-conforming B-spline space (fluid/div_conforming/dc_space.hpp) and its Galerkin Navier-Stokes
// solver (dc_fluid.hpp), issue 44 part 1.
//
// The space: partition of unity; div of any velocity lies in the pressure space (pointwise, and as its own L2
// projection); the de Rham property (d/dx maps the degree-(k+1) spline space onto the degree-k one; div maps
// the velocities with zero normal wall values onto the zero-mean pressures). The kernels: tangents against
// central differences. The solver: Couette and Poiseuille flows (in the space: linear and quadratic in y
// along x, the velocity's x component has degree k >= 2 in y) exact to 1e-12, steady and over time steps; a
// body force that is a gradient leaves the velocity at round-off (pressure robustness); divergence-free to
// 1e-9 of the velocity gradient at every time step. The manufactured-solution rates are in
// tests/convergence/test_div_conforming_convergence.cpp. The contravariant Piola map's point kernel
// (dc_piola.hpp, DcPiola.*): the physical gradient against differences, the Piola divergence identity, the
// test map the transpose.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include <petscsys.h>
#include <vtkDataArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkStructuredGrid.h>
#include <vtkXMLStructuredGridReader.h>

#include "../../support/print_rank0.hpp"
#include "common/petsc_error.hpp"
#include "fluid/div_conforming/dc_fluid.hpp"
#include "fluid/div_conforming/dc_fourier.hpp"
#include "fluid/div_conforming/dc_kernel.hpp"
#include "fluid/div_conforming/dc_piola.hpp"
#include "fluid/div_conforming/dc_space.hpp"
#include "fluid/div_conforming/dc_sum_factorization.hpp"
#include "geometry/basis.hpp"
#include "geometry/builders.hpp"
#include "geometry/measures.hpp"

using namespace cellfsi;
using namespace cellfsi::fluid::dc;
using cellfsi::test_support::print0;
using geometry::Mat3;

namespace {

constexpr double kPi = std::numbers::pi;

/// The 2D channel [0, lx] x [0, ly], periodic in x, walls at y = 0 and ly.
DivConformingSpace channel_2d(int k, int nx, int ny, double lx = 1.0, double ly = 1.0) {
  return DivConformingSpace(2, k, {nx, ny, 1}, Vec3(0, 0, 0), Vec3(lx, ly, 0), {true, false, false});
}

/// Calls f(point values) at every Gauss point (degree + extra per direction) of every element, through the
/// whole basis (evaluate, interpolate), for the coefficients c of all the unknowns.
template <class F>
void for_each_gauss_point(const DivConformingSpace& sp, int extra, const std::vector<double>& c, F&& f) {
  ElementBasis eb;
  for (int e = 0; e < sp.n_elements(); ++e) {
    const Index3 ei = sp.element_multi_index(e);
    sp.evaluate(ei, sp.element_rule(ei, sp.degree() + extra), eb);
    for (int q = 0; q < eb.n_points; ++q) f(DivConformingSpace::interpolate(eb, q, sp.dim(), c.data()));
  }
}

/// div v_h and the pressure-space function with coefficients (D u) at every Gauss point; returns the largest
/// difference relative to the largest |grad v_h|.
double divergence_mismatch(const DivConformingSpace& sp, const std::vector<double>& u) {
  const std::vector<double> du = sp.divergence(u);
  std::vector<double> coeffs(u);
  coeffs.resize(sp.n_dofs(), 0.0);
  for (int a = 0; a < sp.n_pressure(); ++a) coeffs[sp.offset(sp.dim()) + a] = du[a];
  double worst = 0, grad_max = 0;
  for_each_gauss_point(sp, 3, coeffs, [&](const auto& pv) {
    double div = 0;
    for (int i = 0; i < sp.dim(); ++i) {
      div += pv.grad[i][i];
      for (int j = 0; j < sp.dim(); ++j) grad_max = std::max(grad_max, std::abs(pv.grad[i][j]));
    }
    worst = std::max(worst, std::abs(div - pv.p));
  });
  return worst / grad_max;
}

std::vector<double> random_velocity(const DivConformingSpace& sp, unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> dist(-1.0, 1.0);
  std::vector<double> u(sp.n_velocity());
  for (double& x : u) x = dist(gen);
  return u;
}

}  // namespace

// --- The space
// ----------------------------------------------------------------------------------------------

/// n random immersed points (random elements, positions, weights, density factors, symmetric stresses and
/// forces; no stiffness) in the space's elements.
std::vector<DivConformingFluid::ImmersedAt> random_immersed_points(const DivConformingSpace& sp, int n,
                                                                   std::mt19937& rng) {
  std::uniform_real_distribution<double> uni(-1.0, 1.0), unit(0.0, 1.0);
  std::vector<DivConformingFluid::ImmersedAt> pts(n);
  for (auto& p : pts) {
    p.element = std::min(static_cast<int>(unit(rng) * sp.n_elements()), sp.n_elements() - 1);
    const Index3 ei = sp.element_multi_index(p.element);
    for (int d = 0; d < sp.dim(); ++d) p.x[d] = sp.lo(d) + (ei[d] + unit(rng)) * sp.element_size(d);
    p.data.weight = 0.01 * (0.5 + unit(rng));
    p.data.beta = 0.2 * uni(rng);
    for (int i = 0; i < sp.dim(); ++i) {
      p.data.force[i] = uni(rng);
      for (int j = 0; j <= i; ++j) p.data.stress[i][j] = p.data.stress[j][i] = uni(rng);
    }
  }
  return pts;
}

TEST(DivConformingSpace, EveryComponentIsAPartitionOfUnity) {
  for (int k : {2, 3}) {
    const DivConformingSpace sp(3, k, {4, 3, 5}, Vec3(0, 0, 0), Vec3(1, 2, 0.5), {true, false, false});
    ElementBasis eb;
    for (int e = 0; e < sp.n_elements(); ++e) {
      const Index3 ei = sp.element_multi_index(e);
      sp.evaluate(ei, sp.element_rule(ei, k + 2), eb);
      for (int c = 0; c <= 3; ++c)
        for (int q = 0; q < eb.n_points; ++q) {
          const ComponentBasis& cb = eb.comp[c];
          double sum = 0, dsum[3] = {0, 0, 0};
          for (int a = 0; a < cb.n; ++a) {
            sum += cb.value[q * cb.n + a];
            for (int j = 0; j < 3; ++j) dsum[j] += cb.grad[(q * cb.n + a) * 3 + j];
          }
          // Sums of at most 5^3 terms of size <= 1 (derivatives <= (k+1) / h ~ 20): round-off 1e-14.
          EXPECT_NEAR(sum, 1.0, 1e-14) << "k=" << k << " component " << c;
          for (int j = 0; j < 3; ++j) EXPECT_NEAR(dsum[j], 0.0, 1e-12) << "k=" << k << " component " << c;
        }
    }
  }
}

TEST(DivConformingSpace, DivergenceOfAnyVelocityIsInThePressureSpace) {
  // Pointwise: div v_h equals the pressure-space function with coefficients divergence(u), for random u, in
  // 2D (channel) and 3D (periodic x, walls y and z), k = 2 and 3. Both sides are sums of O(10^2) products of
  // size ~ (k+1)/h: a difference of 1e-13 relative to |grad v_h| is round-off.
  for (int k : {2, 3}) {
    const DivConformingSpace sp2 = channel_2d(k, 6, 5, 1.0, 0.7);
    EXPECT_LT(divergence_mismatch(sp2, random_velocity(sp2, 1)), 1e-13) << "2D k=" << k;
    const DivConformingSpace sp3(3, k, {4, 3, 5}, Vec3(0, 0, 0), Vec3(1, 2, 0.5), {true, false, false});
    EXPECT_LT(divergence_mismatch(sp3, random_velocity(sp3, 2)), 1e-13) << "3D k=" << k;
    const DivConformingSpace box(2, k, {5, 4, 1}, Vec3(-1, 2, 0), Vec3(0.5, 3, 0), {false, false, false});
    EXPECT_LT(divergence_mismatch(box, random_velocity(box, 3)), 1e-13) << "2D walls k=" << k;
  }
}

TEST(DivConformingSpace, DivergenceEqualsItsL2Projection) {
  // The L2 projection of div v_h onto the pressure space (dense mass matrix, exact Gauss quadrature) gives
  // back div v_h's coefficients: div v_h is in the space. Mass-matrix condition ~1e2 at k = 2: 1e-12.
  const int k = 2;
  const DivConformingSpace sp = channel_2d(k, 5, 4);
  const std::vector<double> u = random_velocity(sp, 7);
  const int np = sp.n_pressure(), off = sp.offset(2);
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(np, np);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(np);
  std::vector<double> coeffs(u);
  coeffs.resize(sp.n_dofs(), 0.0);
  ElementBasis eb;
  for (int e = 0; e < sp.n_elements(); ++e) {
    const Index3 ei = sp.element_multi_index(e);
    sp.evaluate(ei, sp.element_rule(ei, k + 2), eb);
    const ComponentBasis& cb = eb.comp[2];
    for (int q = 0; q < eb.n_points; ++q) {
      const auto pv = DivConformingSpace::interpolate(eb, q, 2, coeffs.data());
      const double div = pv.grad[0][0] + pv.grad[1][1];
      for (int a = 0; a < cb.n; ++a) {
        b[cb.index[a] - off] += eb.weight[q] * cb.value[q * cb.n + a] * div;
        for (int c = 0; c < cb.n; ++c)
          M(cb.index[a] - off, cb.index[c] - off) +=
              eb.weight[q] * cb.value[q * cb.n + a] * cb.value[q * cb.n + c];
      }
    }
  }
  const Eigen::VectorXd proj = M.ldlt().solve(b);
  const std::vector<double> du = sp.divergence(u);
  double worst = 0, scale = 0;
  for (int a = 0; a < np; ++a) {
    worst = std::max(worst, std::abs(proj[a] - du[a]));
    scale = std::max(scale, std::abs(du[a]));
  }
  EXPECT_LT(worst / scale, 1e-12);
}

TEST(DivConformingSpace, DeRhamPropertyDivergenceIsOntoTheZeroMeanPressures) {
  // Exactness at the end of the sequence: with the normal wall values fixed at 0 (and periodic directions),
  // the range of div is the pressure space minus the constants: rank = n_pressure - 1. Also per direction,
  // d/dx maps the degree-(k+1) space onto the degree-k one (open: rank n_low; periodic: n_low - 1).
  for (int k : {2, 3}) {
    for (const auto& sp :
         {channel_2d(k, 5, 4),
          DivConformingSpace(2, k, {4, 5, 1}, Vec3(0, 0, 0), Vec3(1, 1, 0), {false, false, false}),
          DivConformingSpace(3, k, {4, 3, 3}, Vec3(0, 0, 0), Vec3(1, 1, 1), {true, false, false})}) {
      const std::vector<int> fixed = sp.wall_normal_dofs();
      std::vector<char> is_fixed(sp.n_velocity(), 0);
      for (int f : fixed) is_fixed[f] = 1;
      std::vector<int> free;
      for (int i = 0; i < sp.n_velocity(); ++i)
        if (!is_fixed[i]) free.push_back(i);
      Eigen::MatrixXd B(sp.n_pressure(), free.size());
      std::vector<double> u(sp.n_velocity(), 0.0);
      for (size_t j = 0; j < free.size(); ++j) {
        u[free[j]] = 1.0;
        const std::vector<double> du = sp.divergence(u);
        for (int a = 0; a < sp.n_pressure(); ++a) B(a, j) = du[a];
        u[free[j]] = 0.0;
      }
      Eigen::FullPivLU<Eigen::MatrixXd> lu(B);
      lu.setThreshold(1e-10);
      EXPECT_EQ(lu.rank(), sp.n_pressure() - 1) << "dim " << sp.dim() << " k=" << k;
      for (int d = 0; d < sp.dim(); ++d) {
        // The derivative matrix of direction d from the component-d knot vector (high) to the pressure's
        // (low).
        const int nh = sp.high(d).n_basis(), nl = sp.low(d).n_basis();
        Eigen::MatrixXd Dd = Eigen::MatrixXd::Zero(nl, nh);
        for (int m = 0; m < nl; ++m) {
          const int p = sp.high(d).degree();
          const double c = p / (sp.high(d).knot(m + 1 + p) - sp.high(d).knot(m + 1));
          Dd(m, sp.high(d).fold(m + 1)) += c;
          Dd(m, sp.high(d).fold(m)) -= c;
        }
        Eigen::FullPivLU<Eigen::MatrixXd> lud(Dd);
        lud.setThreshold(1e-10);
        EXPECT_EQ(lud.rank(), sp.periodic(d) ? nl - 1 : nl) << "direction " << d;
      }
    }
  }
}

TEST(DivConformingSpace, AveragingAlongThePeriodicDirectionsGivesTheFieldsMeanAlongThem) {
  // Random coefficients of every component (pressure too), then average_periodic: at every Gauss point the
  // new field equals the old field's mean over the periodic directions at that point's non-periodic
  // coordinates (a Gauss sum over the elements of the same layer, exact for the piecewise polynomials). 2D
  // channel (periodic x) and 3D (periodic x and z), k = 2 and 3. Both sides are sums of O(10^3) terms of size
  // <= 1: 1e-13.
  for (int k : {2, 3}) {
    for (const auto& sp :
         {channel_2d(k, 6, 4, 1.0, 0.7),
          DivConformingSpace(3, k, {4, 3, 5}, Vec3(0, 0, 0), Vec3(1, 2, 0.5), {true, false, true})}) {
      std::mt19937 gen(7);
      std::uniform_real_distribution<double> dist(-1.0, 1.0);
      std::vector<double> u(sp.n_dofs());
      for (double& x : u) x = dist(gen);
      std::vector<double> avg = u;
      sp.average_periodic(avg);
      // Per (layer across, point across): the sum of weight * value over the periodic directions, and the
      // weights' sum, of each component (velocity 0..dim-1, pressure dim).
      std::map<std::pair<int, double>, std::array<double, 5>> mean;
      ElementBasis eb;
      for (int e = 0; e < sp.n_elements(); ++e) {
        const Index3 ei = sp.element_multi_index(e);
        sp.evaluate(ei, sp.element_rule(ei, k + 2), eb);
        for (int q = 0; q < eb.n_points; ++q) {
          const auto pv = DivConformingSpace::interpolate(eb, q, sp.dim(), u.data());
          auto& m = mean[{ei[1], eb.x[q][1]}];
          for (int c = 0; c < sp.dim(); ++c) m[c] += eb.weight[q] * pv.v[c];
          m[3] += eb.weight[q] * pv.p;
          m[4] += eb.weight[q];
        }
      }
      double worst = 0;
      for (int e = 0; e < sp.n_elements(); ++e) {
        const Index3 ei = sp.element_multi_index(e);
        sp.evaluate(ei, sp.element_rule(ei, k + 2), eb);
        for (int q = 0; q < eb.n_points; ++q) {
          const auto pv = DivConformingSpace::interpolate(eb, q, sp.dim(), avg.data());
          const auto& m = mean.at({ei[1], eb.x[q][1]});
          for (int c = 0; c < sp.dim(); ++c) worst = std::max(worst, std::abs(pv.v[c] - m[c] / m[4]));
          worst = std::max(worst, std::abs(pv.p - m[3] / m[4]));
        }
      }
      EXPECT_LT(worst, 1e-13) << "dim " << sp.dim() << " k=" << k;
      // Not the identity: the random field is not uniform along x.
      EXPECT_GT(std::abs(avg[0] - u[0]), 1e-3);
    }
  }
  const DivConformingSpace sp = channel_2d(2, 4, 4);
  std::vector<double> wrong(3);
  EXPECT_THROW(sp.average_periodic(wrong), std::invalid_argument);
}

TEST(DivConformingSpace, RejectsBadInputWithAMessage) {
  EXPECT_THROW(DivConformingSpace(2, 2, {2, 4, 1}, Vec3(0, 0, 0), Vec3(1, 1, 0), {true, false, false}),
               std::invalid_argument);  // periodic with fewer than k + 1 elements
  EXPECT_THROW(DivConformingSpace(4, 2, {4, 4, 4}, Vec3(0, 0, 0), Vec3(1, 1, 1), {false, false, false}),
               std::invalid_argument);
  const geometry::Patch rect = geometry::rectangle(2.0, 1.0, 6, 3, 2, {true, false});
  const DivConformingSpace sp = DivConformingSpace::from_patch(rect, 3);
  EXPECT_EQ(sp.n_elements(0), 6);
  EXPECT_TRUE(sp.periodic(0));
  EXPECT_FALSE(sp.periodic(1));
  EXPECT_DOUBLE_EQ(sp.hi(0), 2.0);
  // v_x: 6 periodic x 6 open degree-3 functions; v_y: 6 x 7 (degree 4 in y); pressure: 6 x 6.
  EXPECT_EQ(sp.n_dofs(), 6 * 6 + 6 * 7 + 6 * 6);
  // Curved geometry needs the Piola map: refused.
  EXPECT_THROW(DivConformingSpace::from_patch(geometry::narrowing_channel({}, 12, 4, 2), 2),
               std::invalid_argument);
}

TEST(DivConformingSpace, ElementPolynomialsEqualTheCoxDeBoorRecursion) {
  // univariate()'s power-basis tables against geometry::bspline_basis at the element ends and inside, for
  // open and periodic directions, pressure degrees 1 to 3, both spaces: values and derivatives to 1e-13 of
  // their scale (1 and 1/h).
  for (int k = 1; k <= 3; ++k) {
    const DivConformingSpace sp(3, k, {7, 5, 4}, Vec3(-0.3, 0, 1), Vec3(0.4, 2, 3), {false, true, true});
    for (int d = 0; d < 3; ++d)
      for (int s = 0; s < 2; ++s) {
        const KnotVector& kv = s ? sp.high(d) : sp.low(d);
        const int p = kv.degree();
        ASSERT_EQ(p, k + s);
        const double h = sp.element_size(d);
        for (int e = 0; e < sp.n_elements(d); ++e)
          for (double t : {0.0, 0.13, 0.5, 0.77, 1.0}) {
            const double x = kv.element_begin(e) + t * h;
            double ders[2 * geometry::kMaxDegree + 2], value[geometry::kMaxDegree + 1],
                deriv[geometry::kMaxDegree + 1];
            geometry::bspline_basis(kv, kv.element_span(e), x, 1, ders);
            sp.univariate(s, d, e, x, value, deriv);
            for (int j = 0; j <= p; ++j) {
              EXPECT_NEAR(value[j], ders[j], 1e-13) << "k " << k << " d " << d << " s " << s << " e " << e;
              EXPECT_NEAR(deriv[j] * h, ders[p + 1 + j] * h, 1e-13) << "k " << k << " d " << d << " e " << e;
            }
          }
      }
  }
}

namespace {
/// A curved 2D map (the narrowing channel, its transitions in view) and a curved 3D one (a box whose control
/// points are all moved), for the Piola kernel's tests.
std::vector<std::pair<geometry::Patch, int>> curved_maps() {
  std::vector<std::pair<geometry::Patch, int>> maps;
  maps.emplace_back(geometry::narrowing_channel({}, 12, 4, 3), 2);
  geometry::Patch b = geometry::box(2.0, 1.0, 1.5, 3, 3, 3, 2);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.08, 0.08);
  for (Vec3& x : b.control_points()) x += Vec3(u(rng), u(rng), u(rng));
  maps.emplace_back(std::move(b), 3);
  return maps;
}

/// A smooth parametric velocity and its parametric gradient (not divergence-free).
void parametric_field(const geometry::Param& xi, double* v, double (*g)[3]) {
  const double c[3][4] = {{0.3, 1.1, -0.7, 0.4}, {-0.2, 0.5, 0.9, -1.3}, {0.8, -0.6, 0.2, 0.7}};
  for (int k = 0; k < 3; ++k) {
    v[k] = c[k][0] + c[k][1] * xi[0] * xi[1] + c[k][2] * std::sin(xi[1] + xi[2]) + c[k][3] * xi[0] * xi[0];
    g[k][0] = c[k][1] * xi[1] + 2 * c[k][3] * xi[0];
    g[k][1] = c[k][1] * xi[0] + c[k][2] * std::cos(xi[1] + xi[2]);
    g[k][2] = c[k][2] * std::cos(xi[1] + xi[2]);
  }
}
}  // namespace

TEST(DcPiola, GradientMatchesDifferencesAndDivergenceIsTheParametricOneOverJ) {
  // The physical gradient of P v^ against central differences along each parameter (d v / d xi_a = grad v
  // F_a), and the Piola identity div_x v = (1/J) div_xi v^ to round-off: both need the map's second
  // derivatives right.
  for (const auto& [patch, D] : curved_maps())
    for (const geometry::Param xi0 : {geometry::Param{0.31, 0.27, 0.6}, geometry::Param{0.62, 0.85, 0.2},
                                      geometry::Param{0.45, 0.05, 0.45}}) {
      geometry::Param xi = xi0;
      if (D == 2) xi[2] = 0;
      auto physical = [&](const geometry::Param& at, double* v, double(*g)[3], PiolaPoint* out) {
        double vh[3], gh[3][3];
        parametric_field(at, vh, gh);
        if (D == 2) vh[2] = 0, gh[0][2] = gh[1][2] = gh[2][0] = gh[2][1] = gh[2][2] = 0;
        const PiolaPoint pt = piola_point(patch.evaluate(at, 2), D);
        piola_values(pt, vh, gh, v, g);
        if (out) *out = pt;
      };
      double v[3], g[3][3], vh[3], gh[3][3];
      PiolaPoint pt;
      physical(xi, v, g, &pt);
      parametric_field(xi, vh, gh);
      const geometry::MapValues m = patch.evaluate(xi, 1);
      double scale = 0;
      for (int i = 0; i < D; ++i)
        for (int j = 0; j < D; ++j) scale = std::max(scale, std::abs(g[i][j]));
      const double h = 1e-5;
      for (int a = 0; a < D; ++a) {
        geometry::Param p = xi, q = xi;
        p[a] += h, q[a] -= h;
        double vp[3], vq[3], gp[3][3];
        physical(p, vp, gp, nullptr);
        physical(q, vq, gp, nullptr);
        for (int i = 0; i < D; ++i) {
          double chain = 0;
          for (int j = 0; j < D; ++j) chain += g[i][j] * m.dx(j, a);
          double fa = 0;
          for (int j = 0; j < D; ++j) fa = std::max(fa, std::abs(m.dx(j, a)));
          EXPECT_NEAR((vp[i] - vq[i]) / (2 * h), chain, 1e-7 * scale * fa) << "dim " << D << " a " << a;
        }
      }
      double div = 0, div_hat = 0;
      for (int i = 0; i < D; ++i) div += g[i][i], div_hat += gh[i][i];
      print0("Piola, dim %d: div_x v - div_xi v^ / J = %.2e of |grad v|\n", D,
             std::abs(div - div_hat / pt.J) / scale);
      EXPECT_NEAR(div, div_hat / pt.J, 1e-12 * scale) << "dim " << D;
    }
}

TEST(DcPiola, TheTestMapIsTheTransposeAndAWallKeepsItsParametricNormalVelocity) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const auto& [patch, D] : curved_maps()) {
    // Adjoint: r . L(u) = L^T(r) . u for random r and parametric fields u.
    const PiolaPoint pt = piola_point(patch.evaluate({0.37, 0.71, D == 3 ? 0.52 : 0.0}, 2), D);
    for (int trial = 0; trial < 5; ++trial) {
      double vh[3] = {}, gh[3][3] = {}, r0[3] = {}, r1[3][3] = {};
      for (int i = 0; i < D; ++i) {
        vh[i] = u(rng), r0[i] = u(rng);
        for (int j = 0; j < D; ++j) gh[i][j] = u(rng), r1[i][j] = u(rng);
      }
      double v[3], g[3][3], r0h[3], r1h[3][3];
      piola_values(pt, vh, gh, v, g);
      piola_test(pt, r0, r1, r0h, r1h);
      double lhs = 0, rhs = 0, size = 0;
      for (int i = 0; i < D; ++i) {
        lhs += r0[i] * v[i], rhs += r0h[i] * vh[i], size += std::abs(r0[i] * v[i]);
        for (int j = 0; j < D; ++j)
          lhs += r1[i][j] * g[i][j], rhs += r1h[i][j] * gh[i][j], size += std::abs(r1[i][j] * g[i][j]);
      }
      EXPECT_NEAR(lhs, rhs, 1e-13 * size) << "dim " << D;
    }
    // On the wall xi_1 = 0 the outward normal is along -G^T e_1: v . n = -v^_1 / (J |G^T e_1|), zero with
    // v^_1.
    for (double x0 : {0.1, 0.35, 0.5, 0.8}) {
      const PiolaPoint w = piola_point(patch.evaluate({x0, 0.0, D == 3 ? 0.4 : 0.0}, 2), D);
      double vh[3] = {u(rng), 0.0, D == 3 ? u(rng) : 0.0}, gh[3][3] = {}, v[3], g[3][3];
      piola_values(w, vh, gh, v, g);
      double vn = 0, speed = 0;
      for (int i = 0; i < D; ++i) vn += v[i] * w.G(1, i), speed += std::abs(v[i]);
      EXPECT_GT(speed, 0.0);
      EXPECT_NEAR(vn, 0.0, 1e-14 * speed * w.G.norm()) << "dim " << D << " xi_0 " << x0;
      vh[1] = 0.25;
      piola_values(w, vh, gh, v, g);
      vn = 0;
      for (int i = 0; i < D; ++i) vn += v[i] * w.G(1, i);
      EXPECT_NEAR(vn, 0.25 / w.J, 1e-12 * 0.25 / w.J);
    }
  }
  // A folded map is refused.
  geometry::MapValues folded;
  folded.dx = geometry::Mat3::Identity();
  folded.dx(1, 1) = -1;
  EXPECT_THROW(piola_point(folded, 2), std::invalid_argument);
}

TEST(DcPiola, AMapWhoseSecondDerivativesJumpBetweenElementsIsRefused) {
  // The mapped gradient takes the map's second derivatives (dP). On the narrowing at degree 2 (continuity 1)
  // they jump across an element boundary in the transition, so the gradient of a mapped field at a point
  // there depends on the element the point is given to: a coupled step stalled with a membrane point on
  // such a boundary changing element back and forth (|R_MC| alternating between 1.2e-8 and 3.3e-8 for
  // 30 iterations, in step 44 of the CTC among red cells at 96 x 32). At degree 3 (continuity 2) they agree
  // to the sampling's offset. mapped() refuses the first and takes the second.
  for (int degree : {2, 3}) {
    const geometry::Patch ch = geometry::narrowing_channel({}, 12, 4, degree);
    const double u = 4.0 / 12, eps = 1e-9;  // (x = 0.002 cm, inside the upstream transition)
    const PiolaPoint a = piola_point(ch.evaluate({u - eps, 0.25, 0}, 2), 2);
    const PiolaPoint b = piola_point(ch.evaluate({u + eps, 0.25, 0}, 2), 2);
    double jump = 0, size = 0;
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i)
        for (int c = 0; c < 2; ++c) {
          jump = std::max(jump, std::abs(a.dP[j](i, c) - b.dP[j](i, c)));
          size = std::max(size, std::abs(a.dP[j](i, c)));
        }
    print0("narrowing, degree %d: dP jumps by %.2e of its size across x = 0.002 cm\n", degree, jump / size);
    auto patch = std::make_shared<const geometry::Patch>(ch);
    if (degree == 2) {
      EXPECT_GT(jump, 0.05 * size);
      try {
        (void)DivConformingSpace::mapped(patch, 2);
        ADD_FAILURE() << "a map of continuity 1 was taken";
      } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("second derivatives jump"), std::string::npos) << e.what();
        print0("  mapped(): %s\n", e.what());
      }
    } else {
      EXPECT_LT(jump, 1e-6 * size);
      EXPECT_NO_THROW((void)DivConformingSpace::mapped(patch, 2));
    }
  }
}

TEST(DcPiola, AMappedSpaceMeasuresTheDomainDividesByJAndHoldsItsCurvedWalls) {
  // The space on the narrowing channel through the Piola map (DivConformingSpace::mapped), k = 2 and 3,
  // random coefficients with the walls' normal unknowns at 0: the weights sum to the channel's area; at every
  // element's Gauss points div_x v = (1/J) times the pressure-space function of divergence() (the parametric
  // divergence), to 1e-10 of |grad v|; on both curved walls v . n = 0 to 1e-12 of |v| (with the walls' normal
  // unknowns at 0: an identity of the map, v . G^T e_1 = v^_1 / J, checked through evaluate and interpolate).
  auto patch = std::make_shared<const geometry::Patch>(geometry::narrowing_channel({}, 12, 4, 3));
  const double area = geometry::patch_measure(*patch);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 2; k <= 3; ++k) {
    const DivConformingSpace sp = DivConformingSpace::mapped(patch, k);
    ASSERT_TRUE(sp.is_mapped());
    std::vector<double> U(sp.n_dofs());
    for (double& c : U) c = u(rng);
    for (int r : sp.wall_normal_dofs()) U[r] = 0;
    const std::vector<double> div_hat =
        sp.divergence(std::vector<double>(U.begin(), U.begin() + sp.n_velocity()));
    double measure = 0, worst_div = 0, worst_wall = 0;
    ElementBasis eb;
    for (int e = 0; e < sp.n_elements(); ++e) {
      const Index3 ei = sp.element_multi_index(e);
      sp.evaluate(ei, sp.element_rule(ei, k + 2), eb);
      ASSERT_EQ(eb.piola.size(), static_cast<size_t>(eb.n_points));
      for (int q = 0; q < eb.n_points; ++q) {
        measure += eb.weight[q];
        const auto pv = DivConformingSpace::interpolate(eb, q, 2, U.data());
        const ComponentBasis& cp = eb.comp[2];
        double dh = 0;
        for (int a = 0; a < cp.n; ++a)
          dh += div_hat[cp.index[a] - sp.offset(2)] * cp.value[static_cast<size_t>(q) * cp.n + a];
        const double scale = std::max({std::abs(pv.grad[0][0]), std::abs(pv.grad[0][1]),
                                       std::abs(pv.grad[1][0]), std::abs(pv.grad[1][1])});
        const double div_error = std::abs(pv.grad[0][0] + pv.grad[1][1] - dh / eb.piola[q].J) / scale;
        if (!(div_error <= worst_div)) worst_div = div_error;  // (a NaN stays)
      }
      for (int side = 0; side < 2; ++side) {
        if (ei[1] != (side == 0 ? 0 : sp.n_elements(1) - 1)) continue;
        sp.evaluate(ei, sp.face_rule(ei, 1, side, k + 2), eb);
        for (int q = 0; q < eb.n_points; ++q) {
          const auto v = DivConformingSpace::interpolate_velocity(eb, q, 2, U.data());
          const double n0 = eb.piola[q].G(1, 0), n1 = eb.piola[q].G(1, 1);  // normal direction G^T e_1
          const double vn = (v[0] * n0 + v[1] * n1) / std::hypot(n0, n1);
          const double wall_error = std::abs(vn) / std::hypot(v[0], v[1]);
          if (!(wall_error <= worst_wall)) worst_wall = wall_error;  // (a NaN stays)
        }
      }
    }
    print0("mapped narrowing channel, k = %d: area %.2e relative, div %.2e, wall v.n %.2e\n", k,
           std::abs(measure - area) / area, worst_div, worst_wall);
    EXPECT_NEAR(measure, area, 1e-12 * area) << "k " << k;
    EXPECT_LT(worst_div, 1e-10) << "k " << k;
    EXPECT_LT(worst_wall, 1e-12) << "k " << k;
    // find_element takes the space's coordinates s: the element of s = c xi.
    const Vec3 s = sp.from_patch_parameters({0.51, 0.26, 0});
    EXPECT_EQ(sp.find_element(s)[0], 6);
    EXPECT_EQ(sp.find_element(s)[1], 1);
  }
  // The box keeps its plain basis.
  const DivConformingSpace box(2, 2, {4, 3, 1}, Vec3(0, 0, 0), Vec3(1, 1, 0), {true, false, false});
  ElementBasis eb;
  box.evaluate({1, 1, 0}, box.element_rule({1, 1, 0}, 3), eb);
  EXPECT_TRUE(eb.piola.empty());
}

TEST(DivConformingSpace, SumFactorisationEqualsTheWholeBasisAndItsTransposeIsTheAdjoint) {
  // The sum-factorised kernels (dc_sum_factorization.hpp) on a block of 13 elements with random coefficients:
  // values and gradients at the element rule's points against DivConformingSpace::evaluate's products (each
  // element's own coefficients through its whole basis), to 1e-13 of the largest; the test kernel against the
  // transpose, <values(u), r> = <u, test(r)>, to 1e-13. Every component (velocity, pressure), in 2D and 3D,
  // for k' = 1, 2, 3, on an element at a wall and one inside (their factors differ).
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (int dim : {2, 3})
    for (int k : {1, 2, 3}) {
      const int n = k + 3;
      const DivConformingSpace sp(dim, k, {n, n, dim == 3 ? n : 1}, Vec3(0, 0, 0),
                                  Vec3(1.0, 0.7, dim == 3 ? 0.9 : 0.0), {true, false, false});
      for (const Index3 ei : {Index3{0, 0, 0}, Index3{1, n / 2, dim == 3 ? n / 2 : 0}}) {
        const TensorRule rule = sp.element_rule(ei, k + 2);
        ElementBasis eb;
        sp.evaluate(ei, rule, eb);
        for (int c = 0; c <= dim; ++c) {
          const ComponentFactors f = component_factors(sp, c, ei, rule);
          const ComponentBasis& cb = eb.comp[c];
          ASSERT_EQ(f.n_functions(), cb.n);
          ASSERT_EQ(f.n_points(), eb.n_points);
          const int m = 13, nq = eb.n_points;  // (13: a vectorised loop's main part and its remainder)
          std::vector<double> u(static_cast<size_t>(cb.n) * m), value(static_cast<size_t>(nq) * m), scratch;
          std::array<std::vector<double>, 3> grad;
          for (auto& gj : grad) gj.assign(static_cast<size_t>(nq) * m, 0.0);
          for (double& x : u) x = uni(rng);
          const std::array<double*, 3> gp{grad[0].data(), grad[1].data(), grad[2].data()};
          sum_factorized_values(f, m, u.data(), value.data(), &gp, scratch);
          double worst = 0, scale = 0;
          for (int e = 0; e < m; ++e)
            for (int q = 0; q < nq; ++q) {
              double v = 0, gr[3] = {0, 0, 0};
              for (int a = 0; a < cb.n; ++a) {
                const double ua = u[static_cast<size_t>(a) * m + e];
                v += ua * cb.value[static_cast<size_t>(q) * cb.n + a];
                for (int j = 0; j < 3; ++j)
                  gr[j] += ua * cb.grad[(static_cast<size_t>(q) * cb.n + a) * 3 + j];
              }
              const size_t i = static_cast<size_t>(q) * m + e;
              worst = std::max(worst, std::abs(value[i] - v));
              scale = std::max(scale, std::abs(v));
              for (int j = 0; j < 3; ++j) {
                worst = std::max(worst, std::abs(grad[j][i] - gr[j]));
                scale = std::max(scale, std::abs(gr[j]));
              }
            }
          EXPECT_LT(worst, 1e-13 * scale) << "dim " << dim << " k " << k << " component " << c;
          // The adjoint: random point values r (value and gradient rows).
          std::vector<double> r(static_cast<size_t>(nq) * m), out(u.size());
          std::array<std::vector<double>, 3> rg;
          for (double& x : r) x = uni(rng);
          for (auto& rj : rg) {
            rj.resize(r.size());
            for (double& x : rj) x = uni(rng);
          }
          const std::array<const double*, 3> rgp{rg[0].data(), rg[1].data(), rg[2].data()};
          sum_factorized_test(f, m, r.data(), &rgp, out.data(), scratch);
          double left = 0, right = 0, size = 0;
          for (size_t i = 0; i < r.size(); ++i) {
            left += value[i] * r[i];
            size += std::abs(value[i] * r[i]);
            for (int j = 0; j < 3; ++j)
              left += grad[j][i] * rg[j][i], size += std::abs(grad[j][i] * rg[j][i]);
          }
          for (size_t i = 0; i < u.size(); ++i) right += u[i] * out[i];
          EXPECT_LT(std::abs(left - right), 1e-13 * size)
              << "dim " << dim << " k " << k << " component " << c;
          // At one point (point_value, point_test): element e's first coefficients, its first rule point.
          PointFactors pf;
          point_factors(sp, ei, eb.x[0], pf);
          std::vector<double> ue(cb.n), te(cb.n, 0.0);
          for (int a = 0; a < cb.n; ++a) ue[a] = u[static_cast<size_t>(a) * m];
          double pg[3];
          const double pv = point_value(pf, c, ue.data(), pg);
          EXPECT_NEAR(pv, value[0], 1e-13 * scale) << "dim " << dim << " k " << k << " component " << c;
          for (int j = 0; j < 3; ++j) EXPECT_NEAR(pg[j], grad[j][0], 1e-13 * scale) << "gradient " << j;
          const double r0 = 0.7, rgrad[3] = {-0.3, 1.1, dim == 3 ? 0.4 : 0.0};
          point_test(pf, c, r0, rgrad, te.data());
          for (int a = 0; a < cb.n; ++a) {
            double t = r0 * cb.value[a];
            for (int j = 0; j < 3; ++j) t += rgrad[j] * cb.grad[3 * a + j];
            EXPECT_NEAR(te[a], t, 1e-13 * (1 + std::abs(t)))
                << "dim " << dim << " component " << c << " a " << a;
          }
        }
      }
    }
}

TEST(DivConformingFluid, OptionsAreReadAndChecked) {
  DcFluidOptions opt;
  PetscOptionsSetValue(nullptr, "-fluid_viscosity", "0.02");
  PetscOptionsSetValue(nullptr, "-fluid_stokes", "true");
  opt.set_from_options();
  EXPECT_DOUBLE_EQ(opt.viscosity, 0.02);
  EXPECT_TRUE(opt.stokes);
  PetscOptionsSetValue(nullptr, "-fluid_dc_penalty", "1.5");  // below the coercivity bound 2
  EXPECT_THROW(opt.set_from_options(), std::invalid_argument);
  for (const char* k : {"-fluid_viscosity", "-fluid_stokes", "-fluid_dc_penalty"})
    PetscOptionsClearValue(nullptr, k);
  const DivConformingSpace all_periodic(2, 2, {4, 4, 1}, Vec3(0, 0, 0), Vec3(1, 1, 0), {true, true, false});
  DivConformingFluid no_walls(PETSC_COMM_WORLD, all_periodic, DcFluidOptions{});
  EXPECT_THROW(no_walls.solve_steady(), std::invalid_argument);  // singular: constant velocities
  DcFluidOptions moving_normal;
  moving_normal.wall_velocity[1][0] = Vec3(0, 0.1, 0);  // a wall y = const moving along y
  EXPECT_THROW(moving_normal.validate(), std::invalid_argument);
}

// --- The kernels
// ----------------------------------------------------------------------------------------------

namespace {

/// Largest difference between a kernel's tangent and central differences of its residual, relative to the
/// tangent's largest entry (differences with step 1e-6 of quadratic residuals: round-off ~1e-10); rq's
/// differences with respect to v and a, which PointTangent has no place for, count as differences from 0.
template <class Residual>
double tangent_mismatch(const PointState& s0, const PointTangent& t, int D, Residual&& residual) {
  const double h = 1e-6;
  double worst = 0, scale = 1e-300;
  auto compare = [&](const std::function<void(PointState&, double)>& perturb,
                     const std::function<double(const PointResidual&, int, int)>& comp, auto&& exact) {
    PointState sp = s0, sm = s0;
    perturb(sp, h);
    perturb(sm, -h);
    const PointResidual rp = residual(sp), rm = residual(sm);
    for (int i = 0; i < D; ++i)
      for (int j = -1; j < D; ++j) {  // j = -1: r0_i; j >= 0: r1_ij; (i, j) = (0, -2) never
        const double fd = (comp(rp, i, j) - comp(rm, i, j)) / (2 * h);
        const double ex = exact(i, j);
        worst = std::max(worst, std::abs(fd - ex));
        scale = std::max(scale, std::abs(ex));
      }
    const double fdq = (rp.rq - rm.rq) / (2 * h);
    return fdq;
  };
  auto comp = [](const PointResidual& r, int i, int j) { return j < 0 ? r.r0[i] : r.r1[i][j]; };
  for (int k = 0; k < D; ++k) {
    // (rq depends on the gradient alone: PointTangent has no d rq / d v or d a, so their differences must be
    // 0; on a mapped space the Piola identity's term, dc_piola.hpp)
    const double fdq_v = compare([&](PointState& s, double e) { s.v[k] += e; }, comp,
                                 [&](int i, int j) { return j < 0 ? t.dr0_dv[i][k] : t.dr1_dv[i][j][k]; });
    const double fdq_a = compare([&](PointState& s, double e) { s.a[k] += e; }, comp,
                                 [&](int i, int j) { return j < 0 ? t.dr0_da[i][k] : 0.0; });
    worst = std::max({worst, std::abs(fdq_v), std::abs(fdq_a)});
    for (int l = 0; l < D; ++l) {
      const double fdq =
          compare([&](PointState& s, double e) { s.dv[k][l] += e; }, comp,
                  [&](int i, int j) { return j < 0 ? t.dr0_ddv[i][k][l] : t.dr1_ddv[i][j][k][l]; });
      worst = std::max(worst, std::abs(fdq - t.drq_ddv[k][l]));
    }
  }
  compare([&](PointState& s, double e) { s.p += e; }, comp,
          [&](int i, int j) { return j < 0 ? 0.0 : t.dr1_dp[i][j]; });
  return worst / scale;
}

PointState random_state(unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> dist(-1.0, 1.0);
  PointState s;
  for (int i = 0; i < 3; ++i) {
    s.v[i] = dist(gen);
    s.a[i] = dist(gen);
    for (int j = 0; j < 3; ++j) s.dv[i][j] = dist(gen);
  }
  s.p = dist(gen);
  return s;
}

}  // namespace

TEST(DivConformingKernel, TangentsMatchCentralDifferences) {
  for (int D : {2, 3}) {
    const PointState s = random_state(11 + D);
    InteriorParameters ip;
    ip.dim = D;
    ip.nu = 0.37;
    ip.g = {0.3, -0.2, 0.1};
    for (double c : {0.0, 1.0}) {
      ip.convection = c;
      EXPECT_LT(tangent_mismatch(s, dc_interior_tangent(s, ip), D,
                                 [&](const PointState& x) { return dc_interior_residual(x, ip); }),
                1e-8)
          << "interior D=" << D << " convection " << c;
    }
    NitscheParameters np;
    np.dim = D;
    np.nu = 0.37;
    np.beta = 12.5;
    np.n = {0, -1, 0};
    np.v_wall = {0.4, 0, -0.3};
    EXPECT_LT(tangent_mismatch(s, dc_nitsche_tangent(np), D,
                               [&](const PointState& x) { return dc_nitsche_residual(x, np); }),
              1e-8)
        << "Nitsche D=" << D;
    // An immersed point: with the isotropic stiffness (a viscosity nu_s) the tangent is the residual's
    // derivative with nu - nu_s; with the consistent one the stress's change c : sym(L) + L S + S L^T. The
    // residual holds the stress fixed, so both are checked against a residual that moves it as the tangent
    // says: stress + stiffness_time (c : grad dv + grad dv S + S grad dv^T) for the perturbed gradient.
    fluid::ImmersedPoint pt;
    pt.beta = -0.07;
    pt.force = {0.5, -0.25, 0.125};
    for (int r = 0; r < 3; ++r)
      for (int q = 0; q < 3; ++q) pt.stress[r][q] = 0.1 * (r + 1) * (q + 1) + (r == q ? 0.3 : 0.0);
    ImmersedParameters mp;
    mp.dim = D;
    mp.nu = 0.37;
    mp.g = {0.3, -0.2, 0.1};
    for (double c : {0.0, 1.0}) {
      mp.convection = c;
      pt.stiffness_viscosity = 0;
      pt.stiffness_time = 0;
      EXPECT_LT(tangent_mismatch(s, dc_immersed_tangent(s, mp, pt), D,
                                 [&](const PointState& x) { return dc_immersed_residual(x, mp, pt); }),
                1e-8)
          << "immersed D=" << D << " convection " << c;
      pt.stiffness_viscosity = 0.11;  // the tangent's nu is then nu - nu_s
      ImmersedParameters lower = mp;
      lower.nu = mp.nu - pt.stiffness_viscosity;
      fluid::ImmersedPoint plain = pt;
      plain.stiffness_viscosity = 0;
      EXPECT_LT(tangent_mismatch(s, dc_immersed_tangent(s, mp, pt), D,
                                 [&](const PointState& x) { return dc_immersed_residual(x, lower, plain); }),
                1e-8)
          << "immersed, isotropic stiffness, D=" << D;
      // Consistent: an isotropic c (lambda, mu) in Voigt form.
      pt.stiffness_time = 0.02;
      const double lam = 2.0, mu = 1.5;
      pt.stiffness.fill(0.0);
      for (int r = 0, t = 0; r < 6; ++r)
        for (int q = r; q < 6; ++q, ++t)
          pt.stiffness[t] = (r < 3 && q < 3 ? lam : 0.0) + (r == q ? (r < 3 ? 2 * mu : mu) : 0.0);
      const PointState s0 = s;
      auto moved = [&](const PointState& x) {
        fluid::ImmersedPoint m = pt;
        double L[3][3] = {};  // stiffness_time times the gradient's change
        for (int i = 0; i < D; ++i)
          for (int j = 0; j < D; ++j) L[i][j] = pt.stiffness_time * (x.dv[i][j] - s0.dv[i][j]);
        double tr = 0;
        for (int i = 0; i < D; ++i) tr += L[i][i];
        for (int i = 0; i < D; ++i)
          for (int j = 0; j < D; ++j) {
            double ds = lam * tr * (i == j) + mu * (L[i][j] + L[j][i]);
            for (int l = 0; l < D; ++l) ds += L[i][l] * pt.stress[l][j] + pt.stress[i][l] * L[j][l];
            m.stress[i][j] += ds;
          }
        m.stiffness_time = 0;
        m.stiffness_viscosity = 0;
        return dc_immersed_residual(x, mp, m);
      };
      EXPECT_LT(tangent_mismatch(s, dc_immersed_tangent(s, mp, pt), D, moved), 1e-8)
          << "immersed, consistent stiffness, D=" << D;
      pt.stiffness_time = 0;
    }
  }
}

// --- Exact flows
// ---------------------------------------------------------------------------------------------------

TEST(DcPiola, TheMappedKernelsTangentsMatchDifferencesOfTheirMappedResiduals) {
  // On a mapped space a kernel runs at the physical fields of the parametric ones and its residual goes back
  // through L^T (piola_state, piola_residual); piola_tangent is that composition's derivative with respect
  // to the parametric fields, L^T K L. Checked against central differences for the interior (Stokes and
  // Navier-Stokes), Nitsche and immersed (consistent stiffness) kernels at points of the narrowing channel
  // and of the curved 3D box. The two terms the Piola identity removes (dc_piola.hpp) are round-off there.
  for (const auto& [patch, D] : curved_maps())
    for (const geometry::Param xi : {geometry::Param{0.37, 0.71, 0.52}, geometry::Param{0.55, 0.12, 0.3}}) {
      geometry::Param at = xi;
      if (D == 2) at[2] = 0;
      const PiolaPoint pt = piola_point(patch.evaluate(at, 2), D);
      const PointState hat = random_state(5 + D);
      auto check = [&](const char* what, auto&& residual, auto&& tangent) {
        const PointTangent t = piola_tangent(pt, tangent(piola_state(pt, hat)));
        const double m = tangent_mismatch(
            hat, t, D, [&](const PointState& x) { return piola_residual(pt, residual(piola_state(pt, x))); });
        EXPECT_LT(m, 1e-7) << what << " D=" << D;
        return m;
      };
      InteriorParameters ip;
      ip.dim = D;
      ip.nu = 0.37;
      ip.g = {0.3, -0.2, 0.1};
      double worst = 0;
      for (double c : {0.0, 1.0}) {
        ip.convection = c;
        worst =
            std::max(worst, check(
                                "interior", [&](const PointState& s) { return dc_interior_residual(s, ip); },
                                [&](const PointState& s) { return dc_interior_tangent(s, ip); }));
      }
      NitscheParameters np;
      np.dim = D;
      np.nu = 0.37;
      np.beta = 12.5;
      np.n = {0.6, -0.8, 0};
      np.v_wall = {0.4, 0.3, D == 3 ? -0.3 : 0.0};
      worst = std::max(worst, check(
                                  "Nitsche", [&](const PointState& s) { return dc_nitsche_residual(s, np); },
                                  [&](const PointState&) { return dc_nitsche_tangent(np); }));
      fluid::ImmersedPoint ipt;
      ipt.beta = -0.07;
      ipt.force = {0.5, -0.25, 0.125};
      for (int r = 0; r < 3; ++r)
        for (int q = 0; q < 3; ++q) ipt.stress[r][q] = 0.1 * (r + 1) * (q + 1) + (r == q ? 0.3 : 0.0);
      ImmersedParameters mp;
      mp.dim = D;
      mp.nu = 0.37;
      worst = std::max(worst,
                       check(
                           "immersed", [&](const PointState& s) { return dc_immersed_residual(s, mp, ipt); },
                           [&](const PointState& s) { return dc_immersed_tangent(s, mp, ipt); }));
      print0("mapped kernels, dim %d: tangent against differences %.1e of its largest entry\n", D, worst);
    }
}

namespace {

/// The paper's plasma in a 0.003 x 0.001 cm channel (periodic in x), k and ny elements across.
struct ChannelCase {
  double lx = 0.003, ly = 0.001, mu = 0.012, rho = 1.025;
};

double relative_velocity_error(const DivConformingFluid& fs, const std::function<Vec3(const Vec3&)>& v,
                               const std::function<Mat3(const Vec3&)>& g) {
  const auto er = fs.errors(v, g, [](const Vec3&) { return 0.0; });
  return er.v_l2 / er.v_l2_norm;
}

/// The flow v(y) of a 12 x 4 channel (with options opt) for k = 2, 3, Stokes and Navier-Stokes: the relative
/// L2 velocity errors of the steady solve and of three time steps from the exact state's divergence-free
/// projection, each below 1e-12.
void expect_exact_channel_flow(const char* name, DcFluidOptions opt,
                               const std::function<Vec3(const Vec3&)>& v,
                               const std::function<Mat3(const Vec3&)>& grad) {
  const ChannelCase c;
  opt.density = c.rho;
  opt.viscosity = c.mu;
  opt.newton_rtol = 0;  // stop on the update alone: the last update is applied, the state is round-off exact
  for (int k : {2, 3})
    for (bool stokes : {true, false}) {
      const DivConformingSpace sp = channel_2d(k, 12, 4, c.lx, c.ly);
      opt.stokes = stokes;
      DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
      ASSERT_TRUE(fs.solve_steady().converged);
      const double e_steady = relative_velocity_error(fs, v, grad);
      EXPECT_LT(e_steady, 1e-12) << name << " k=" << k << (stokes ? " Stokes" : " Navier-Stokes");
      fs.project_initial_state(v, [](const Vec3&) { return Vec3(Vec3::Zero()); });
      for (int s = 0; s < 3; ++s) ASSERT_TRUE(fs.step().converged);
      const double e_steps = relative_velocity_error(fs, v, grad);
      EXPECT_LT(e_steps, 1e-12) << name << " k=" << k << (stokes ? " Stokes" : " Navier-Stokes");
      print0("  %s k=%d %s: rel L2 error steady %.2e, after 3 steps %.2e\n", name, k,
             stokes ? "Stokes" : "NS", e_steady, e_steps);
    }
}

}  // namespace

TEST(DivConformingFluid, CouetteFlowIsExactSteadyAndOverTimeSteps) {
  // v = (U y / H, 0), p = const: v_x is linear in y and constant in x, in the space for every k >= 1; Nitsche
  // is consistent, so the discrete solution is the exact one up to the LU's round-off.
  const ChannelCase c;
  const double U = 0.05;  // cm/s, the top wall's speed
  DcFluidOptions opt;
  opt.wall_velocity[1][1] = Vec3(U, 0, 0);
  expect_exact_channel_flow(
      "Couette", opt, [&](const Vec3& x) { return Vec3(U * x[1] / c.ly, 0, 0); },
      [&](const Vec3&) {
        Mat3 m = Mat3::Zero();
        m(0, 1) = U / c.ly;
        return m;
      });
}

TEST(DivConformingFluid, PoiseuilleFlowIsExactSteadyAndOverTimeSteps) {
  // A body force G along x between walls at rest: v = (G / (2 mu) y (H - y), 0), p = const. v_x is quadratic
  // in y and constant in x: in the space for k >= 2 (its degree along y is k).
  const ChannelCase c;
  const double G = 4800;  // dyn/cm^3: v_max = G H^2 / (8 mu) = 0.05 cm/s
  DcFluidOptions opt;
  opt.body_force = Vec3(G, 0, 0);
  expect_exact_channel_flow(
      "Poiseuille", opt, [&](const Vec3& x) { return Vec3(G / (2 * c.mu) * x[1] * (c.ly - x[1]), 0, 0); },
      [&](const Vec3& x) {
        Mat3 m = Mat3::Zero();
        m(0, 1) = G / (2 * c.mu) * (c.ly - 2 * x[1]);
        return m;
      });
}

TEST(DivConformingFluid, AProfileIsProjectedWithoutTheSaddlePointSolveToTheSameCoefficients) {
  // project_columnar against project_saddle_point, for a profile not in the space (sin and exp of y along x,
  // periodic in x, walls in y), k = 2 and 3: the same coefficients (two solves of different systems: a
  // profile's mass matrix by sparse Cholesky against the saddle-point LU; measured agreement 2.5e-14 (k = 2)
  // and 5e-15 (k = 3) of the largest coefficient; asserted 1e-12) and a divergence-free result. A field that
  // varies along x, or has a y component, is not taken by the columnar path.
  const ChannelCase c;
  auto profile = [&](const Vec3& x) {
    return Vec3(0.05 * std::sin(3.0 * x[1] / c.ly) + 0.01 * std::exp(x[1] / c.ly), 0, 0);
  };
  for (int k : {2, 3}) {
    const DivConformingSpace sp = channel_2d(k, 12, 4, c.lx, c.ly);
    DivConformingFluid fs(PETSC_COMM_WORLD, sp, DcFluidOptions{});
    std::vector<double> columnar;
    ASSERT_TRUE(fs.project_columnar(profile, columnar));
    const std::vector<double> saddle = fs.project_saddle_point(profile);
    ASSERT_EQ(columnar.size(), saddle.size());
    double largest = 0, difference = 0;
    for (size_t i = 0; i < saddle.size(); ++i) {
      largest = std::max(largest, std::abs(saddle[i]));
      difference = std::max(difference, std::abs(columnar[i] - saddle[i]));
    }
    EXPECT_LT(difference, 1e-12 * largest) << "k=" << k;
    const std::vector<double> u(columnar.begin(), columnar.begin() + sp.n_velocity());
    for (double d : sp.divergence(u)) EXPECT_LT(std::abs(d), 1e-12 * largest / (c.ly / 4));
    print0("  k=%d: columnar against saddle-point projection %.2e of the largest coefficient\n", k,
           difference / largest);
    std::vector<double> untouched;
    EXPECT_FALSE(fs.project_columnar([&](const Vec3& x) { return Vec3(profile(x)[0] * (1 + x[0] / c.lx), 0, 0); },
                                     untouched));
    EXPECT_FALSE(fs.project_columnar([&](const Vec3& x) { return Vec3(profile(x)[0], 1e-3, 0); }, untouched));
    EXPECT_TRUE(untouched.empty());
    std::vector<double> rest;
    ASSERT_TRUE(fs.project_columnar([](const Vec3&) { return Vec3(Vec3::Zero()); }, rest));
    for (double r : rest) EXPECT_EQ(r, 0.0);
  }
}

TEST(DivConformingFluid, StepResidualDifferencesEqualTheStepTangent) {
  // The residual-only assembly (interior_residual, with its sizes fixed at compile time for 2D k' = 2, 3 and
  // 3D k' = 2, at run time otherwise) against the generic assembly's tangent: the step residual is quadratic
  // in U, so central differences equal J dU up to round-off (measured 1.1e-10 .. 3.4e-10 of |J dU|; asserted 1e-8).
  // Random U (velocity and pressure), random dU zero at the fixed rows; one case with a viscosity field.
  struct Case {
    int dim, k;
    bool field;
  };
  for (const Case cs : {Case{2, 2, false}, Case{2, 3, false}, Case{2, 2, true}, Case{3, 2, false},
                        Case{3, 3, false}}) {
    const int n = cs.dim == 2 ? 6 : 4;
    const DivConformingSpace sp(cs.dim, cs.k, {n, n - 1, cs.dim == 3 ? n : 1}, Vec3(0, 0, 0),
                                Vec3(1.0, 0.8, cs.dim == 3 ? 0.9 : 0.0), {true, false, cs.dim == 3});
    DcFluidOptions opt;
    opt.density = 1.0;
    opt.viscosity = 0.3;
    opt.dt = 0.01;
    DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
    if (cs.field) fs.project_viscosity([](const Vec3& x) { return 0.3 * (1.5 + std::sin(6 * x[0]) * x[1]); });
    std::mt19937 rng(7 + cs.dim * 10 + cs.k);
    // Immersed points too: their residual (sum-factorised at each point) against their tangent (the whole
    // basis at each point).
    fs.set_immersed_points(random_immersed_points(sp, 40, rng));
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    std::vector<double> U(sp.n_dofs()), dU(sp.n_dofs());
    for (double& u : U) u = uni(rng);
    for (double& d : dU) d = uni(rng);
    for (int r : sp.wall_normal_dofs()) U[r] = dU[r] = 0.0;
    dU[sp.offset(cs.dim)] = 0.0;  // the pressure pin
    fs.set_state(U);
    fs.begin_step();
    Mat J = fs.jacobian(true, true);
    fs.step_tangent(U, J);
    Vec Fp, Fm, JdU, dX;
    CELLFSI_PETSC(MatCreateVecs(J, &dX, &JdU));
    CELLFSI_PETSC(VecDuplicate(JdU, &Fp));
    CELLFSI_PETSC(VecDuplicate(JdU, &Fm));
    const std::vector<PetscInt>& num = fs.petsc_numbering();
    for (size_t i = 0; i < dU.size(); ++i) CELLFSI_PETSC(VecSetValue(dX, num[i], dU[i], INSERT_VALUES));
    CELLFSI_PETSC(VecAssemblyBegin(dX));
    CELLFSI_PETSC(VecAssemblyEnd(dX));
    CELLFSI_PETSC(MatMult(J, dX, JdU));
    const double eps = 1e-6;
    std::vector<double> Up(U), Um(U);
    for (size_t i = 0; i < U.size(); ++i) {
      Up[i] += eps * dU[i];
      Um[i] -= eps * dU[i];
    }
    fs.step_residual(Up, Fp);
    fs.step_residual(Um, Fm);
    CELLFSI_PETSC(VecAXPY(Fp, -1.0, Fm));
    CELLFSI_PETSC(VecScale(Fp, 1.0 / (2 * eps)));
    PetscReal scale, diff;
    CELLFSI_PETSC(VecNorm(JdU, NORM_INFINITY, &scale));
    CELLFSI_PETSC(VecAXPY(Fp, -1.0, JdU));
    CELLFSI_PETSC(VecNorm(Fp, NORM_INFINITY, &diff));
    EXPECT_LT(diff, 1e-8 * scale) << "dim " << cs.dim << " k " << cs.k << (cs.field ? " field" : "");
    print0("  %dD k'=%d%s: |dF/eps - J dU| / |J dU| = %.2e\n", cs.dim, cs.k, cs.field ? " field" : "",
           diff / scale);
    VecDestroy(&Fp);
    VecDestroy(&Fm);
    VecDestroy(&JdU);
    VecDestroy(&dX);
  }
}

TEST(DivConformingFluid, TheSumFactorisedResidualEqualsThePointByPointOne) {
  // The step residual of a uniform body force (interior_residual_batched: sum factorisation over blocks of
  // elements) against the same force given as a field (interior_residual_sized: the whole basis point by
  // point), at a random state, with and without a viscosity field: equal to 1e-12 of the residual's size
  // (they differ only in the order of the sums).
  // The last case is periodic in every direction, 12 x 12: its 144 elements are one class, whose blocks of
  // 128 and 16 elements run the vectorised loops' main parts.
  struct Case {
    int dim, k;
    bool field, periodic = false;
  };
  for (const Case cs : {Case{2, 2, false}, Case{2, 3, true}, Case{3, 2, false}, Case{3, 2, true},
                        Case{3, 3, false}, Case{2, 2, true, true}}) {
    const int n = cs.periodic ? 12 : cs.dim == 2 ? 7 : 5;
    const DivConformingSpace sp(cs.dim, cs.k, {n, cs.periodic ? n : n + 1, cs.dim == 3 ? n : 1},
                                Vec3(0, 0, 0), Vec3(1.0, 0.8, cs.dim == 3 ? 0.9 : 0.0),
                                {true, cs.periodic, cs.dim == 3});
    const Vec3 force(1.5, -0.7, cs.dim == 3 ? 0.4 : 0.0);
    DcFluidOptions uniform;
    uniform.density = 1.0;
    uniform.viscosity = 0.3;
    uniform.dt = 0.01;
    uniform.body_force = force;
    DcFluidOptions as_field = uniform;
    as_field.body_force = Vec3::Zero();
    as_field.body_force_field = [force](const Vec3&, double) { return force; };
    std::mt19937 rng(3 + cs.dim * 10 + cs.k);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    std::vector<double> U(sp.n_dofs());
    for (double& u : U) u = uni(rng);
    for (int r : sp.wall_normal_dofs()) U[r] = 0.0;
    double norms[2], diff = 0;
    Vec F[2];
    int i = 0;
    std::unique_ptr<DivConformingFluid> fluids[2];
    for (const DcFluidOptions* opt : {&uniform, &as_field}) {
      fluids[i] = std::make_unique<DivConformingFluid>(PETSC_COMM_WORLD, sp, *opt);
      DivConformingFluid& fs = *fluids[i];
      if (cs.field)
        fs.project_viscosity([](const Vec3& x) { return 0.3 * (1.5 + std::sin(6 * x[0]) * x[1]); });
      fs.set_state(U);
      fs.begin_step();
      F[i] = fs.create_vector();
      fs.step_residual(U, F[i]);
      CELLFSI_PETSC(VecNorm(F[i], NORM_INFINITY, &norms[i]));
      ++i;
    }
    CELLFSI_PETSC(VecAXPY(F[0], -1.0, F[1]));
    CELLFSI_PETSC(VecNorm(F[0], NORM_INFINITY, &diff));
    EXPECT_GT(norms[0], 0.0);
    EXPECT_LT(diff, 1e-12 * norms[1]) << "dim " << cs.dim << " k " << cs.k << (cs.field ? " field" : "");
    print0("  %dD k'=%d%s%s: |F_sum-factorised - F_point-by-point| / |F| = %.2e\n", cs.dim, cs.k,
           cs.field ? " field" : "", cs.periodic ? " periodic 12 x 12" : "", diff / norms[1]);
    VecDestroy(&F[0]);
    VecDestroy(&F[1]);
  }
}

TEST(DivConformingFluid, TheImmersedPointsResidualEqualsTheirSumsThroughTheWholeBasis) {
  // The points' part of the step residual (immersed_residual: sum factorisation at each point) against the
  // same sums written out in the test through DivConformingSpace::evaluate's whole basis and interpolate (the
  // code they replace): 60 random points at a random state (the step's first iterate, so that the levels are
  // the state and the rate 0), with and without a viscosity field, 2D and 3D: equal to 1e-12 of the largest
  // entry.
  for (const int dim : {2, 3})
    for (const bool field : {false, true}) {
      const int n = dim == 2 ? 6 : 4;
      const DivConformingSpace sp(dim, 2, {n, n - 1, dim == 3 ? n : 1}, Vec3(0, 0, 0),
                                  Vec3(1.0, 0.8, dim == 3 ? 0.9 : 0.0), {true, false, dim == 3});
      DcFluidOptions opt;
      opt.density = 1.0;
      opt.viscosity = 0.3;
      DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
      auto nu = [](const Vec3& x) { return 0.3 * (1.5 + std::sin(6 * x[0]) * x[1]); };
      if (field) fs.project_viscosity(nu);
      std::mt19937 rng(5 + dim + (field ? 10 : 0));
      std::uniform_real_distribution<double> uni(-1.0, 1.0);
      std::vector<double> U(sp.n_dofs());
      for (double& u : U) u = uni(rng);
      for (int r : sp.wall_normal_dofs()) U[r] = 0.0;
      fs.set_state(U);
      fs.begin_step();
      Vec F0 = fs.create_vector(), F1 = fs.create_vector();
      fs.step_residual(U, F0);
      const auto pts = random_immersed_points(sp, 60, rng);
      fs.set_immersed_points(pts);
      fs.step_residual(U, F1);
      CELLFSI_PETSC(VecAXPY(F1, -1.0, F0));
      // The reference: each point's kernel at the fields through the whole basis, tested by it.
      std::vector<double> ref(sp.n_dofs(), 0.0), nu_coeffs;
      ElementBasis eb;
      for (const auto& p : pts) {
        TensorRule rule;
        for (int d = 0; d < 3; ++d) rule.points[d] = {d < dim ? p.x[d] : 0.0}, rule.weights[d] = {1.0};
        sp.evaluate(sp.element_multi_index(p.element), rule, eb);
        const auto pv = DivConformingSpace::interpolate(eb, 0, dim, U.data());
        PointState st;
        for (int i = 0; i < dim; ++i) {
          st.v[i] = pv.v[i];
          for (int j = 0; j < dim; ++j) st.dv[i][j] = pv.grad[i][j];
        }
        ImmersedParameters prm;
        prm.dim = dim;
        prm.nu = 0.3;
        if (field) {  // the projected field at the point, through the pressure functions
          const ComponentBasis& cp = eb.comp[dim];
          const std::vector<double>& nf = fs.viscosity_field();
          prm.nu = 0;
          for (int a = 0; a < cp.n; ++a) prm.nu += nf[cp.index[a] - sp.offset(dim)] * cp.value[a];
        }
        const PointResidual r = dc_immersed_residual(st, prm, p.data);
        for (int i = 0; i < dim; ++i) {
          const ComponentBasis& cb = eb.comp[i];
          for (int a = 0; a < cb.n; ++a) {
            double t = cb.value[a] * r.r0[i];
            for (int j = 0; j < dim; ++j) t += cb.grad[3 * a + j] * r.r1[i][j];
            ref[cb.index[a]] += p.data.weight * t;
          }
        }
      }
      for (int row : sp.wall_normal_dofs()) ref[row] = 0.0;  // (fixed rows: the residual's are zeroed)
      const std::vector<PetscInt>& num = fs.petsc_numbering();
      const PetscScalar* f;
      CELLFSI_PETSC(VecGetArrayRead(F1, &f));
      double worst = 0, scale = 0;
      for (size_t i = 0; i < ref.size(); ++i) {
        worst = std::max(worst, std::abs(f[num[i]] - ref[i]));
        scale = std::max(scale, std::abs(ref[i]));
      }
      CELLFSI_PETSC(VecRestoreArrayRead(F1, &f));
      EXPECT_GT(scale, 0.0);
      EXPECT_LT(worst, 1e-12 * scale) << dim << "D" << (field ? " field" : "");
      print0("  %dD%s: |F_points - sums through the whole basis| / max = %.2e\n", dim, field ? " field" : "",
             worst / scale);
      VecDestroy(&F0);
      VecDestroy(&F1);
    }
}

TEST(DivConformingFluid, TheDivergenceRatioEqualsItsPointByPointValue) {
  // divergence_ratio (sum factorisation over blocks of elements) against max |div v_h| / max |grad v_h| over
  // every element's Gauss points through the whole basis (evaluate, interpolate), for a random velocity that
  // is not divergence-free: equal to 1e-12, in 2D and 3D.
  for (const int dim : {2, 3}) {
    const int n = dim == 2 ? 6 : 4;
    const DivConformingSpace sp(dim, 2, {n, n - 1, dim == 3 ? n : 1}, Vec3(0, 0, 0),
                                Vec3(1.0, 0.8, dim == 3 ? 0.9 : 0.0), {true, false, dim == 3});
    DivConformingFluid fs(PETSC_COMM_WORLD, sp, DcFluidOptions{});
    std::mt19937 rng(17 + dim);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    std::vector<double> U(sp.n_dofs());
    for (double& u : U) u = uni(rng);
    fs.set_state(U);
    double max_div = 0, max_grad = 0;
    for_each_gauss_point(sp, 2, U, [&](const auto& pv) {
      double div = 0, g2 = 0;
      for (int i = 0; i < dim; ++i) {
        div += pv.grad[i][i];
        for (int j = 0; j < dim; ++j) g2 += pv.grad[i][j] * pv.grad[i][j];
      }
      max_div = std::max(max_div, std::abs(div));
      max_grad = std::max(max_grad, std::sqrt(g2));
    });
    const double want = max_div / max_grad, got = fs.divergence_ratio();
    EXPECT_GT(want, 0.01);  // (a random field is far from divergence-free)
    EXPECT_NEAR(got, want, 1e-12 * want) << dim << "D";
    print0("  %dD: divergence ratio %.6f, point by point %.6f\n", dim, got, want);
  }
}

TEST(DivConformingFluid, ShearFlowWithAViscosityFieldIsExact) {
  // A viscosity that varies across the unit channel, mu = 1 + y / 2 (rho = 1; linear: the projection onto the
  // pressure space is exact), walls at rest, v = (y (1 - y), 0): -(mu v_x')' = 1.5 + 2 y is the body force
  // along x, p = const. v_x is quadratic in y: the discrete solution is the exact one (k = 2, 3; Stokes and
  // Navier-Stokes).
  const auto v = [](const Vec3& x) { return Vec3(x[1] * (1 - x[1]), 0, 0); };
  const auto grad = [](const Vec3& x) {
    Mat3 m = Mat3::Zero();
    m(0, 1) = 1 - 2 * x[1];
    return m;
  };
  for (int k : {2, 3})
    for (bool stokes : {true, false}) {
      const DivConformingSpace sp = channel_2d(k, 8, 6);
      DcFluidOptions opt;
      opt.density = 1.0;
      opt.viscosity = 5.0;  // replaced by the field
      opt.stokes = stokes;
      opt.newton_rtol = 0;
      opt.body_force_field = [](const Vec3& x, double) { return Vec3(1.5 + 2 * x[1], 0, 0); };
      DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
      fs.project_viscosity([](const Vec3& x) { return 1 + 0.5 * x[1]; });
      ASSERT_TRUE(fs.has_viscosity_field());
      ASSERT_TRUE(fs.solve_steady().converged);
      const double e = relative_velocity_error(fs, v, grad);
      print0("  viscosity field mu = 1 + y/2, k=%d %s: rel L2 error %.2e\n", k, stokes ? "Stokes" : "NS", e);
      EXPECT_LT(e, 1e-12) << "k=" << k;
      fs.clear_viscosity();  // back to the uniform 5: the same force gives another flow
      ASSERT_TRUE(fs.solve_steady().converged);
      EXPECT_GT(relative_velocity_error(fs, v, grad), 0.1);
    }
  EXPECT_THROW(
      DivConformingFluid(PETSC_COMM_WORLD, channel_2d(2, 4, 4), DcFluidOptions{}).set_viscosity({1.0}),
      std::invalid_argument);
}

TEST(DivConformingFluid, AGradientBodyForceLeavesTheVelocityAtRest) {
  // Pressure robustness: f = rho grad phi is balanced by the pressure alone, v_h = 0 exactly, because
  // (w, grad phi) = -(div w, phi) with w.n = 0 on walls and div w in the pressure space (the integrals are
  // exact: phi is a polynomial). The VMS equal-order space gives a velocity error ~ h^k |phi| / nu instead.
  // nu = 1, |grad phi| ~ 1 on the unit square: any velocity above round-off would be a failure.
  struct Case {
    std::array<bool, 3> periodic;
    std::function<Vec3(const Vec3&)> grad_phi;
    const char* name;
  };
  const Case cases[] = {
      {{false, false, false},
       [](const Vec3& x) { return Vec3(3 * x[0] * x[0] * x[1] * x[1], 2 * std::pow(x[0], 3) * x[1], 0); },
       "cavity, phi = x^3 y^2"},
      {{true, false, false},
       [](const Vec3& x) { return Vec3(0, 3 * x[1] * x[1] - 1, 0); },
       "channel, phi = y^3 - y"}};
  for (const Case& cs : cases)
    for (int k : {2, 3})
      for (bool stokes : {true, false}) {
        const DivConformingSpace sp(2, k, {8, 8, 1}, Vec3(0, 0, 0), Vec3(1, 1, 0), cs.periodic);
        DcFluidOptions opt;
        opt.density = 1.0;
        opt.viscosity = 1.0;
        opt.stokes = stokes;
        opt.dt = 0.1;
        opt.body_force_field = [&](const Vec3& x, double) { return cs.grad_phi(x); };
        DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
        ASSERT_TRUE(fs.solve_steady().converged);
        const double v_steady = fs.max_velocity();
        EXPECT_LT(v_steady, 1e-12) << cs.name << " k=" << k;
        // From rest, over time steps.
        fs.set_state(std::vector<double>(sp.n_dofs(), 0.0));
        for (int s = 0; s < 3; ++s) ASSERT_TRUE(fs.step().converged);
        EXPECT_LT(fs.max_velocity(), 1e-12) << cs.name << " k=" << k << " (time steps)";
        print0("  gradient force, %s, k=%d %s: max|v_h| steady %.2e, after 3 steps %.2e\n", cs.name, k,
               stokes ? "Stokes" : "NS", v_steady, fs.max_velocity());
      }
}

TEST(DivConformingFluid, In3dPoiseuilleIsExactAndAGradientForceLeavesTheVelocityAtRest) {
  // The 3D path (dimension-generic code). (1) A body force G along x between walls y = 0, H at rest, periodic
  // in x and z: Poiseuille's v = (G / (2 mu) y (H - y), 0, 0), in the space for k = 2 (steady, Stokes and
  // Navier-Stokes), and the start-up from rest over 3 steps divergence-free to 1e-9 at every step.
  // (2) A cavity (walls in x, y, z) with f = grad phi, phi = x^2 y z^3: v_h = 0 to round-off.
  const double G = 2.0, mu = 0.5, H = 1.0;
  const DivConformingSpace sp(3, 2, {3, 2, 3}, Vec3(0, 0, 0), Vec3(2, H, 1), {true, false, true});
  const auto v = [&](const Vec3& x) { return Vec3(G / (2 * mu) * x[1] * (H - x[1]), 0, 0); };
  const auto grad = [&](const Vec3& x) {
    Mat3 m = Mat3::Zero();
    m(0, 1) = G / (2 * mu) * (H - 2 * x[1]);
    return m;
  };
  for (bool stokes : {true, false}) {
    DcFluidOptions opt;
    opt.density = 1.0;
    opt.viscosity = mu;
    opt.stokes = stokes;
    opt.newton_rtol = 0;
    opt.dt = 0.05;
    opt.body_force = Vec3(G, 0, 0);
    DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
    ASSERT_TRUE(fs.solve_steady().converged);
    const double e = relative_velocity_error(fs, v, grad);
    EXPECT_LT(e, 1e-12) << (stokes ? "Stokes" : "Navier-Stokes");
    print0("  3D Poiseuille k=2 %s: rel L2 error %.2e\n", stokes ? "Stokes" : "NS", e);
    if (stokes) continue;
    fs.set_state(std::vector<double>(sp.n_dofs(), 0.0));
    for (int s = 0; s < 3; ++s) ASSERT_TRUE(fs.step().converged);
    double worst = 0;
    for (double r : fs.divergence_history()) worst = std::max(worst, r);
    EXPECT_LE(worst, 1e-9);
    print0("  3D Poiseuille k=2 NS start-up: worst div ratio over 3 steps %.2e\n", worst);
  }
  const DivConformingSpace cavity(3, 2, {2, 3, 2}, Vec3(0, 0, 0), Vec3(1, 1, 1), {false, false, false});
  DcFluidOptions opt;
  opt.density = 1.0;
  opt.viscosity = 1.0;
  opt.body_force_field = [](const Vec3& x, double) {
    return Vec3(2 * x[0] * x[1] * std::pow(x[2], 3), x[0] * x[0] * std::pow(x[2], 3),
                3 * x[0] * x[0] * x[1] * x[2] * x[2]);
  };
  DivConformingFluid fs(PETSC_COMM_WORLD, cavity, opt);
  ASSERT_TRUE(fs.solve_steady().converged);
  print0("  3D cavity, gradient force: max|v_h| %.2e\n", fs.max_velocity());
  EXPECT_LT(fs.max_velocity(), 1e-12);
}

// --- Time stepping: divergence at every step
// -------------------------------------------------------------------

TEST(DivConformingFluid, TaylorGreenStaysDivergenceFreeAtEveryStep) {
  // The Taylor-Green vortex on the 2 pi-periodic square (Navier-Stokes, nu = 0.1), k = 2 on 12 x 12, 10 steps
  // of dt = 0.05 from the divergence-free projection of the exact field: max|div v_h| / max|grad v_h| <= 1e-9
  // at every step (observed ~1e-14), and the velocity close to the exact decay.
  const double nu = 0.1, two_pi = 2 * kPi;
  const auto v = [&](const Vec3& x, double t) {
    const double F = std::exp(-2 * nu * t);
    return Vec3(std::sin(x[0]) * std::cos(x[1]) * F, -std::cos(x[0]) * std::sin(x[1]) * F, 0);
  };
  const DivConformingSpace sp(2, 2, {12, 12, 1}, Vec3(0, 0, 0), Vec3(two_pi, two_pi, 0), {true, true, false});
  DcFluidOptions opt;
  opt.density = 1.0;
  opt.viscosity = nu;
  opt.dt = 0.05;
  DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
  fs.project_initial_state([&](const Vec3& x) { return v(x, 0); },
                           [&](const Vec3& x) { return Vec3(-2 * nu * v(x, 0)); });
  const double div0 = fs.divergence_ratio();
  EXPECT_LE(div0, 1e-9);
  const auto grad = [&](const Vec3& x) {
    const double F = std::exp(-2 * nu * fs.time());
    Mat3 m = Mat3::Zero();
    m(0, 0) = std::cos(x[0]) * std::cos(x[1]) * F;
    m(0, 1) = -std::sin(x[0]) * std::sin(x[1]) * F;
    m(1, 0) = std::sin(x[0]) * std::sin(x[1]) * F;
    m(1, 1) = -std::cos(x[0]) * std::cos(x[1]) * F;
    return m;
  };
  const double e0 = relative_velocity_error(
      fs, [&](const Vec3& x) { return v(x, 0); }, grad);
  for (int s = 0; s < 10; ++s) ASSERT_TRUE(fs.step().converged) << "step " << s;
  ASSERT_EQ(fs.divergence_history().size(), 10u);
  double worst = 0;
  for (double r : fs.divergence_history()) {
    EXPECT_LE(r, 1e-9);
    worst = std::max(worst, r);
  }
  const double e = relative_velocity_error(
      fs, [&](const Vec3& x) { return v(x, fs.time()); }, grad);
  print0(
      "  Taylor-Green k=2 12x12, 10 steps: div ratio initial %.2e, worst step %.2e; rel L2 error initial "
      "%.3e, final %.3e\n",
      div0, worst, e0, e);
  // The error is the initial projection's (spatial, ~h^3); ten steps (time error ~(nu dt)^2) add little to
  // it.
  EXPECT_LT(e, 1.1 * e0);
}

// --- Sampling, restart, output
// ---------------------------------------------------------------------------------

TEST(DivConformingFluid, SamplesRestartsAndWritesVtk) {
  // Poiseuille (exact in the space): samples at points anywhere (periodic x beyond the period too) give the
  // exact v and grad v to 1e-12 of their scale. A restart (restore of state, rate and step count into a new
  // solver) then three steps equals six steps of one solver: the same operations in the same order, so equal
  // to the last bit up to BLAS threading (asserted 1e-15 of max|U|). The VTK file has the sampled velocity at
  // its points.
  const ChannelCase c;
  const double G = 4800;
  DcFluidOptions opt;
  opt.density = c.rho;
  opt.viscosity = c.mu;
  opt.body_force = Vec3(G, 0, 0);
  opt.dt = 1e-3;
  const DivConformingSpace sp = channel_2d(2, 12, 4, c.lx, c.ly);
  DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
  ASSERT_TRUE(fs.solve_steady().converged);
  const std::vector<Vec3> pts{Vec3(0.0011, 0.0003, 0), Vec3(-0.002, 0.0009, 0), Vec3(0.0075, 0.0005, 0),
                              Vec3(0.003, 0.001, 0)};
  const auto smp = fs.sample(pts);
  const double vmax = G * c.ly * c.ly / (8 * c.mu), gmax = G * c.ly / (2 * c.mu);
  for (size_t i = 0; i < pts.size(); ++i) {
    const double y = pts[i][1];
    EXPECT_NEAR(smp[i].v[0], G / (2 * c.mu) * y * (c.ly - y), 1e-12 * vmax) << "point " << i;
    EXPECT_NEAR(smp[i].v[1], 0.0, 1e-12 * vmax) << "point " << i;
    EXPECT_NEAR(smp[i].grad_v(0, 1), G / (2 * c.mu) * (c.ly - 2 * y), 1e-12 * gmax) << "point " << i;
    EXPECT_NEAR(smp[i].grad_v(0, 0), 0.0, 1e-12 * gmax) << "point " << i;
  }

  // Restart: from rest, 6 steps in one go, or 3 steps, a restore into a new solver and 3 more.
  DivConformingFluid one(PETSC_COMM_WORLD, sp, opt), first(PETSC_COMM_WORLD, sp, opt);
  for (int s = 0; s < 6; ++s) ASSERT_TRUE(one.step().converged);
  for (int s = 0; s < 3; ++s) ASSERT_TRUE(first.step().converged);
  DivConformingFluid second(PETSC_COMM_WORLD, sp, opt);
  second.restore(first.state(), first.state_rate(), first.steps_taken());
  for (int s = 0; s < 3; ++s) ASSERT_TRUE(second.step().converged);
  EXPECT_EQ(second.steps_taken(), 6);
  EXPECT_DOUBLE_EQ(second.time(), one.time());
  double diff = 0, scale = 0;
  for (size_t i = 0; i < one.state().size(); ++i) {
    diff = std::max(diff, std::abs(one.state()[i] - second.state()[i]));
    scale = std::max(scale, std::abs(one.state()[i]));
  }
  print0("  restart after 3 of 6 steps: max|U_restarted - U| / max|U| = %.2e\n", diff / scale);
  EXPECT_LE(diff, 1e-15 * scale);

  // VTK: 2 samples per element -> 25 x 9 points; the file's velocity equals sample() at its points.
  const std::string path = ::testing::TempDir() + "dc_poiseuille.vts";
  fs.write_vtk(path, 2);
  vtkNew<vtkXMLStructuredGridReader> reader;
  reader->SetFileName(path.c_str());
  reader->Update();
  vtkStructuredGrid* grid = reader->GetOutput();
  int dims[3];
  grid->GetDimensions(dims);
  EXPECT_EQ(dims[0], 25);
  EXPECT_EQ(dims[1], 9);
  vtkDataArray* vel = grid->GetPointData()->GetArray("velocity");
  ASSERT_NE(vel, nullptr);
  ASSERT_NE(grid->GetPointData()->GetArray("divergence"), nullptr);
  for (vtkIdType id : {vtkIdType(0), vtkIdType(30), vtkIdType(25 * 9 - 1)}) {
    double x[3];
    grid->GetPoint(id, x);
    const auto s = fs.sample({Vec3(x[0], x[1], x[2])});
    EXPECT_NEAR(vel->GetComponent(id, 0), s[0].v[0], 1e-14 * vmax) << "point " << id;
  }
}

// --- The Fourier solver
// ------------------------------------------------------------------------------------------

namespace {

struct FourierCase {
  int k, nx, ny;
  bool periodic_y, time_step;
  const char* name;
  int nz = 0;  // 3D (periodic in z) when > 0
};

/// The tangent of `cs` (fluid on `comm`) solved by DcFourierSolver on `comm` and by MUMPS on one rank (the
/// fluid on PETSC_COMM_SELF, the operator with its pressure pin) for a consistent random right-hand side:
/// max|x_F - x_D| / max|x_D| after both pressures are shifted to zero mean. deviation: the Fourier solver's.
double fourier_vs_direct(const FourierCase& cs, MPI_Comm comm, double& deviation) {
  const int D = cs.nz > 0 ? 3 : 2;
  const DivConformingSpace sp(D, cs.k, {cs.nx, cs.ny, std::max(1, cs.nz)}, Vec3(0, 0, 0),
                              Vec3(1, 0.5, D == 3 ? 0.75 : 0), {true, cs.periodic_y, D == 3});
  DcFluidOptions opt;
  opt.density = 1.0;
  opt.viscosity = 0.1;
  opt.dt = 0.01;
  opt.stokes = !cs.time_step;
  opt.newton_rtol = 0;  // both fluids end on the update criterion: the same state to round-off
  if (!cs.periodic_y) opt.wall_velocity[1][1] = Vec3(1.0, 0, 0);

  // b: random, 0 on the wall-normal rows (unit rows, 0 as in a Newton update), pressure rows summing to 0:
  // then b is consistent (the continuity rows' sum is int div w = the flux through the walls, 0 for these w).
  std::vector<double> b = random_velocity(sp, 5);
  b.resize(sp.n_dofs());
  std::mt19937 gen(9);
  std::uniform_real_distribution<double> dist(-1.0, 1.0);
  double mean_p = 0;
  for (int a = sp.offset(D); a < sp.n_dofs(); ++a) mean_p += (b[a] = dist(gen)) / sp.n_pressure();
  for (int a = sp.offset(D); a < sp.n_dofs(); ++a) b[a] -= mean_p;
  for (int r : sp.wall_normal_dofs()) b[r] = 0.0;

  std::vector<double> xf, xd(sp.n_dofs());
  {
    DivConformingFluid fs(comm, sp, opt);
    if (!cs.periodic_y) {
      EXPECT_TRUE(fs.solve_steady().converged);  // Couette: uniform in x
    }
    DcFourierSolver fourier(sp, comm, fs.petsc_numbering());
    Mat A = fs.jacobian(cs.time_step, false);
    fourier.build(A, true);
    fourier.solve(b, xf);
    deviation = fourier.deviation();
    // Its stencil's product (no matrix) against the matrix's, on b: equal to round-off, the operator being
    // circulant to round-off (asserted 1e-13 of max|y|).
    std::vector<double> ys, ym;
    fourier.multiply(b, ys);
    Vec bv, yv;
    CELLFSI_PETSC(MatCreateVecs(A, &bv, &yv));
    fs.scatter(b, bv);
    CELLFSI_PETSC(MatMult(A, bv, yv));
    fs.gather(yv, ym);
    double dy = 0, sy = 0;
    for (size_t a = 0; a < ym.size(); ++a) {
      dy = std::max(dy, std::abs(ys[a] - ym[a]));
      sy = std::max(sy, std::abs(ym[a]));
    }
    EXPECT_LT(dy, 1e-13 * sy) << cs.name << " k=" << cs.k << ": the stencil's product";
    EXPECT_GT(sy, 0);
    // Only this rank's rows (what the coupled operator takes): the same operations in the same order on those
    // rows, so the same values, and zeros on the runs without one.
    std::vector<double> yo;
    fourier.multiply(b, yo, true);
    PetscInt r0 = 0, r1 = 0;
    CELLFSI_PETSC(MatGetOwnershipRange(A, &r0, &r1));
    int owned = 0, differ = 0;
    for (size_t a = 0; a < yo.size(); ++a) {
      const PetscInt r = fs.petsc_numbering()[a];
      if (r < r0 || r >= r1) continue;
      ++owned;
      differ += yo[a] != ys[a];
    }
    // Every row checked on some rank (a rank may own none: on 3 ranks, 6 x 4 x 5 elements).
    int checked = owned;
    MPI_Allreduce(MPI_IN_PLACE, &checked, 1, MPI_INT, MPI_SUM, comm);
    EXPECT_EQ(checked, static_cast<int>(yo.size()));
    EXPECT_EQ(differ, 0) << cs.name << " k=" << cs.k << ": the product on this rank's rows";
    // The solve of PETSc vectors (each rank reads and writes its own lines only) against the solve of whole
    // vectors: the same transforms and exchanges, so equal to 1e-14 of max|x| on every row.
    Vec xv = nullptr;
    CELLFSI_PETSC(VecDuplicate(bv, &xv));
    fourier.solve(bv, xv);
    std::vector<double> xg;
    fs.gather(xv, xg);
    double dx = 0, sx = 0;
    for (size_t a = 0; a < xg.size(); ++a) {
      dx = std::max(dx, std::abs(xg[a] - xf[a]));
      sx = std::max(sx, std::abs(xf[a]));
    }
    EXPECT_LE(dx, 1e-14 * sx) << cs.name << " k=" << cs.k << ": the solve of PETSc vectors";
    EXPECT_GT(sx, 0);
    VecDestroy(&xv);
    VecDestroy(&bv);
    VecDestroy(&yv);
  }
  DivConformingFluid fs(PETSC_COMM_SELF, sp, opt);
  if (!cs.periodic_y) {
    EXPECT_TRUE(fs.solve_steady().converged);
  }
  Mat J = fs.jacobian(cs.time_step, true);
  Vec bv, xv;
  MatCreateVecs(J, &xv, &bv);
  for (int a = 0; a < sp.n_dofs(); ++a)  // the pin's unit row gets 0: its continuity equation is implied
    VecSetValue(bv, a, a == sp.offset(D) ? 0.0 : b[a], INSERT_VALUES);
  VecAssemblyBegin(bv);
  VecAssemblyEnd(bv);
  KSP ksp;
  KSPCreate(PETSC_COMM_SELF, &ksp);
  KSPSetOperators(ksp, J, J);
  KSPSetType(ksp, KSPPREONLY);
  PC pc;
  KSPGetPC(ksp, &pc);
  PCSetType(pc, PCLU);
  PCFactorSetMatSolverType(pc, MATSOLVERMUMPS);
  PCFactorSetUpMatSolverType(pc);
  Mat factor;
  PCFactorGetMatrix(pc, &factor);
  MatMumpsSetCntl(factor, 1, 0.5);  // as DivConformingFluid: little pivot growth on this saddle-point matrix
  KSPSolve(ksp, bv, xv);
  const PetscScalar* xp;
  VecGetArrayRead(xv, &xp);
  std::copy(xp, xp + sp.n_dofs(), xd.begin());
  VecRestoreArrayRead(xv, &xp);
  KSPDestroy(&ksp);
  VecDestroy(&bv);
  VecDestroy(&xv);

  double mf = 0, md = 0;
  for (int a = sp.offset(D); a < sp.n_dofs(); ++a) {
    mf += xf[a] / sp.n_pressure();
    md += xd[a] / sp.n_pressure();
  }
  double diff = 0, scale = 0;
  for (int a = 0; a < sp.n_dofs(); ++a) {
    const double shift = a >= sp.offset(D) ? mf - md : 0.0;
    diff = std::max(diff, std::abs(xf[a] - xd[a] - shift));
    scale = std::max(scale, std::abs(xd[a]));
  }
  return diff / scale;
}

}  // namespace

TEST(DcFourierSolver, BuildsFromTheStencilRowsAloneAsFromTheWholeOperator) {
  // DivConformingFluid::bulk_stencil_tangent holds only the rows at three x (and z) positions, assembled from
  // the elements that touch them: those rows equal the whole operator's (bulk_tangent_of_mean) to round-off
  // (asserted 1e-14 of the row's largest entry), the others are empty, and a solver built from it solves as
  // one built from the whole matrix (1e-13 of max|x|). Its check still sees a row that is not the stencil's:
  // one entry of a checked row changed by 1e-3 of the row's largest shows as a deviation of 1e-3.
  for (int D : {2, 3}) {
    const int nx = 8, ny = 5, nz = D == 3 ? 7 : 1;
    const DivConformingSpace sp(D, 2, {nx, ny, nz}, Vec3(0, 0, 0), Vec3(1, 0.5, D == 3 ? 0.75 : 0),
                                {true, false, D == 3});
    DcFluidOptions opt;
    opt.density = 1.0;
    opt.viscosity = 0.1;
    opt.dt = 0.01;
    opt.wall_velocity[1][1] = Vec3(1.0, 0, 0);
    DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
    ASSERT_TRUE(fs.solve_steady().converged);  // Couette: a state with convection, uniform in x
    Mat A = fs.matrix();
    fs.bulk_tangent_of_mean(fs.state(), A);
    Mat S = fs.bulk_stencil_tangent(fs.state());
    PetscInt r0 = 0, r1 = 0;
    CELLFSI_PETSC(MatGetOwnershipRange(S, &r0, &r1));
    double worst = 0;
    int held = 0;
    for (PetscInt r = r0; r < r1; ++r) {
      PetscInt na = 0, ns = 0;
      const PetscInt *ca = nullptr, *cs = nullptr;
      const PetscScalar *va = nullptr, *vs = nullptr;
      CELLFSI_PETSC(MatGetRow(S, r, &ns, &cs, &vs));
      if (ns > 0) {
        ++held;
        CELLFSI_PETSC(MatGetRow(A, r, &na, &ca, &va));
        EXPECT_EQ(na, ns) << "row " << r;
        double row_max = 0, diff = 0;
        for (PetscInt k = 0; k < std::min(na, ns); ++k) {
          EXPECT_EQ(ca[k], cs[k]) << "row " << r;
          row_max = std::max(row_max, std::abs(va[k]));
          diff = std::max(diff, std::abs(va[k] - vs[k]));
        }
        worst = std::max(worst, diff / row_max);
        CELLFSI_PETSC(MatRestoreRow(A, r, &na, &ca, &va));
      }
      CELLFSI_PETSC(MatRestoreRow(S, r, &ns, &cs, &vs));
    }
    CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &held, 1, MPI_INT, MPI_SUM, PETSC_COMM_WORLD));
    int line = 0;  // unknowns of one (x, z) position: every component's y functions
    for (int c = 0; c <= D; ++c) line += sp.n_basis(c, 1);
    EXPECT_EQ(held, 3 * line) << D << "D";  // positions (0, 0), (4, 3), (2, 4); in 2D x = 0, 4, 2
    EXPECT_LT(worst, 1e-14) << D << "D";

    std::vector<double> b = random_velocity(sp, 5);
    b.resize(sp.n_dofs());
    for (int a = sp.offset(D); a < sp.n_dofs(); ++a) b[a] = 0.0;
    for (int r : sp.wall_normal_dofs()) b[r] = 0.0;
    DcFourierSolver whole(sp, PETSC_COMM_WORLD, fs.petsc_numbering()),
        rows(sp, PETSC_COMM_WORLD, fs.petsc_numbering());
    whole.build(A, true);
    rows.build(S, true);
    EXPECT_LT(whole.deviation(), 1e-13) << D << "D";
    EXPECT_LT(rows.deviation(), 1e-13) << D << "D";
    std::vector<double> xw, xr;
    whole.solve(b, xw);
    rows.solve(b, xr);
    double dx = 0, sx = 0;
    for (size_t a = 0; a < xw.size(); ++a) {
      dx = std::max(dx, std::abs(xw[a] - xr[a]));
      sx = std::max(sx, std::abs(xw[a]));
    }
    EXPECT_GT(sx, 0);
    EXPECT_LT(dx, 1e-13 * sx) << D << "D";

    // v_x's function at (n_x/2, y index 2, n_z/2): a checked row; its diagonal changed.
    const int g = sp.offset(0) + nx / 2 + nx * (2 + sp.n_basis(0, 1) * (nz / 2));
    const PetscInt row = fs.petsc_numbering()[g];
    if (row >= r0 && row < r1) {
      PetscInt ns = 0;
      const PetscScalar* vs = nullptr;
      CELLFSI_PETSC(MatGetRow(S, row, &ns, nullptr, &vs));
      double row_max = 0;
      for (PetscInt k = 0; k < ns; ++k) row_max = std::max(row_max, std::abs(vs[k]));
      CELLFSI_PETSC(MatRestoreRow(S, row, &ns, nullptr, &vs));
      CELLFSI_PETSC(MatSetValue(S, row, row, 1e-3 * row_max, ADD_VALUES));
    }
    CELLFSI_PETSC(MatAssemblyBegin(S, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(S, MAT_FINAL_ASSEMBLY));
    rows.build(S, true);
    EXPECT_NEAR(rows.deviation(), 1e-3, 1e-5) << D << "D";  // (1e-3 of the row's largest before the change)
    MatDestroy(&S);
  }
}

TEST(DcFourierSolver, EqualsTheDirectSolve) {
  // Tangents that are translation-invariant in x (and z): a Navier-Stokes time step at a Couette state
  // (moving top wall) in the channel, the steady Stokes operator there, and a time step on the all-periodic
  // square at rest; k = 2 and 3; in 3D the channel (periodic in x and z) and the periodic box, odd n_z. The
  // Fourier solve (mode 0 pinned) against MUMPS on the same operator with its pressure pin: velocities and
  // zero-mean pressures agree to 1e-12 of max|x| (measured 2.6e-15 .. 7.2e-14; with MUMPS's default pivot
  // threshold 0.01 instead of 0.5 its own solve was off by 4e-12). The stencil is circulant to 1e-13.
  const FourierCase cases[] = {{2, 16, 8, false, true, "channel, NS step at Couette"},
                               {3, 12, 6, false, true, "channel, NS step at Couette"},
                               {2, 16, 8, false, false, "channel, steady Stokes"},
                               {2, 12, 12, true, true, "periodic square, NS step at rest"},
                               {2, 6, 4, false, true, "3D channel, NS step at Couette", 5},
                               {2, 4, 4, true, true, "periodic cube, NS step at rest", 3}};
  for (const FourierCase& cs : cases) {
    double deviation = 0;
    const double diff = fourier_vs_direct(cs, PETSC_COMM_SELF, deviation);
    print0("  Fourier vs MUMPS, %s, k=%d %dx%d: stencil deviation %.1e, max|x_F - x_D| / max|x| = %.1e\n",
           cs.name, cs.k, cs.nx, cs.ny, deviation, diff);
    EXPECT_LE(deviation, 1e-13) << cs.name;
    EXPECT_LE(diff, 1e-12) << cs.name << " k=" << cs.k;
  }
  const DivConformingSpace not_periodic_in_x(2, 2, {4, 4, 1}, Vec3(0, 0, 0), Vec3(1, 1, 0),
                                             {false, true, false});
  EXPECT_THROW(DcFourierSolver{not_periodic_in_x}, std::invalid_argument);
  // A singular wave-number system (LAPACK's zgbtrf finds an exactly zero pivot: here the operator's entries
  // are all zero, the pin's unit row apart) is refused, not solved.
  const DivConformingSpace square(2, 2, {6, 6, 1}, Vec3(0, 0, 0), Vec3(1, 1, 0), {true, true, false});
  DcFluidOptions opt;
  DivConformingFluid fs(PETSC_COMM_SELF, square, opt);
  Mat zero = fs.jacobian(true, false);
  MatZeroEntries(zero);
  DcFourierSolver singular(square, PETSC_COMM_SELF, fs.petsc_numbering());
  EXPECT_THROW(singular.build(zero, true), std::runtime_error);
}

// --- MPI
// -------------------------------------------------------------------------------------------------------

TEST(DivConformingParallel, OneAndTwoRanksGiveTheSameState) {
  // Inside a 2-rank job (ctest div_conforming_parallel_2ranks): a steady Navier-Stokes flow in the channel (a
  // body force that varies in x and y, a moving top wall), then three time steps, on all ranks of
  // PETSC_COMM_WORLD and on each rank alone (PETSC_COMM_SELF). Both end on Newton's update criterion (rtol
  // 0), so they differ only by the round-off of two LU orderings amplified by the matrix's condition number:
  // measured 7e-15 of max|U|; asserted 1e-10 (eps times a condition number up to 1e6, for other MUMPS/BLAS
  // builds).
  const DivConformingSpace sp = channel_2d(2, 12, 8);
  DcFluidOptions opt;
  opt.density = 1.0;
  opt.viscosity = 0.1;
  opt.dt = 0.05;
  opt.newton_rtol = 0;
  opt.wall_velocity[1][1] = Vec3(1.0, 0, 0);
  opt.body_force_field = [](const Vec3& x, double) {
    return Vec3(std::cos(2 * kPi * x[0]) * std::sin(kPi * x[1]), std::sin(2 * kPi * x[0]), 0);
  };
  std::vector<double> states[2];
  int steps[2] = {0, 0};
  const MPI_Comm comms[2] = {PETSC_COMM_SELF, PETSC_COMM_WORLD};
  for (int c = 0; c < 2; ++c) {
    DivConformingFluid fs(comms[c], sp, opt);
    const DcSolveStats st = fs.solve_steady();
    ASSERT_TRUE(st.converged);
    steps[c] = st.newton_iterations;
    for (int s = 0; s < 3; ++s) ASSERT_TRUE(fs.step().converged);
    for (double r : fs.divergence_history()) EXPECT_LE(r, 1e-9);
    states[c] = fs.state();
  }
  double diff = 0, scale = 0;
  for (size_t i = 0; i < states[0].size(); ++i) {
    diff = std::max(diff, std::abs(states[0][i] - states[1][i]));
    scale = std::max(scale, std::abs(states[0][i]));
  }
  int size = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  print0("  1 rank vs %d ranks: max|U_1 - U_%d| / max|U| = %.2e (steady Newton iterations %d, %d)\n", size,
         size, diff / scale, steps[0], steps[1]);
  EXPECT_LE(diff / scale, 1e-10);
}

/// The 2-rank tests' fluid in channel_2d(2, 12, 8): unit density, viscosity 0.1, dt 0.05.
DcFluidOptions parallel_channel_options() {
  DcFluidOptions opt;
  opt.density = 1.0;
  opt.viscosity = 0.1;
  opt.dt = 0.05;
  return opt;
}

TEST(DivConformingParallel, RowsAndThePointsMatrixAreDealtOutEvenly) {
  // Inside a 2-rank job: the fluid's rows are cut into equal runs, and the immersed points' matrix, whose
  // points lie in one rank's elements only (the first row of elements, all given to rank 0), has rows of its
  // own cut into equal runs too (at most one apart). Lifted to the fluid's rows, its product is the points'
  // part of the whole tangent (with minus without the points) to 1e-12 of its largest entry.
  const DivConformingSpace sp = channel_2d(2, 12, 8);
  DivConformingFluid fs(PETSC_COMM_WORLD, sp, parallel_channel_options());
  int rank = 0, size = 1;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  const auto spread = [&](PetscInt n) {  // largest minus smallest over the ranks
    PetscInt lo = n, hi = n;
    MPI_Allreduce(MPI_IN_PLACE, &lo, 1, MPIU_INT, MPI_MIN, PETSC_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &hi, 1, MPIU_INT, MPI_MAX, PETSC_COMM_WORLD);
    return hi - lo;
  };
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0), uni(-1.0, 1.0);
  std::vector<DivConformingFluid::ImmersedAt> pts = random_immersed_points(sp, 30, rng);
  for (auto& p : pts) {  // (into the first row of elements)
    p.element %= 12;
    p.x[1] = sp.lo(1) + unit(rng) * sp.element_size(1);
    p.x[0] = sp.lo(0) + (p.element + unit(rng)) * sp.element_size(0);
  }
  if (rank != 0) pts.clear();
  fs.set_immersed_points(pts);
  fs.begin_step();
  std::vector<double> U(sp.n_dofs());
  for (double& u : U) u = uni(rng);
  for (int r : sp.wall_normal_dofs()) U[r] = 0.0;
  Vec x = fs.create_vector(), y_whole = nullptr, y_lifted = nullptr;
  PetscInt m = 0;
  CELLFSI_PETSC(VecGetLocalSize(x, &m));
  EXPECT_LE(spread(m), 1);
  DivConformingFluid::ImmersedMatrix C = fs.create_immersed_matrix();
  fs.immersed_tangent(U, C);
  PetscInt rows = 0, n_s = 0;
  CELLFSI_PETSC(MatGetLocalSize(C.C, &rows, nullptr));
  CELLFSI_PETSC(MatGetSize(C.C, &n_s, nullptr));
  EXPECT_GT(n_s, 0);
  EXPECT_LT(n_s, sp.n_velocity());
  EXPECT_LE(spread(rows), 1);
  ASSERT_EQ(static_cast<PetscInt>(C.fluid_rows.size()), rows);
  // The points' part of the whole tangent.
  Mat with = nullptr, without = nullptr;
  CELLFSI_PETSC(MatDuplicate(fs.matrix(), MAT_DO_NOT_COPY_VALUES, &with));
  CELLFSI_PETSC(MatDuplicate(fs.matrix(), MAT_DO_NOT_COPY_VALUES, &without));
  fs.step_tangent(U, with, true, false);
  fs.step_tangent(U, without, false, false);
  CELLFSI_PETSC(VecSetRandom(x, nullptr));
  CELLFSI_PETSC(VecDuplicate(x, &y_whole));
  CELLFSI_PETSC(VecDuplicate(x, &y_lifted));
  CELLFSI_PETSC(MatMult(with, x, y_whole));
  CELLFSI_PETSC(MatMult(without, x, y_lifted));
  CELLFSI_PETSC(VecAXPY(y_whole, -1.0, y_lifted));
  // C lifted: x at S's rows, C's product, added back.
  CELLFSI_PETSC(VecSet(y_lifted, 0.0));
  C.multiply_add(x, y_lifted);
  PetscReal scale = 0, diff = 0;
  CELLFSI_PETSC(VecNorm(y_whole, NORM_INFINITY, &scale));
  CELLFSI_PETSC(VecAXPY(y_lifted, -1.0, y_whole));
  CELLFSI_PETSC(VecNorm(y_lifted, NORM_INFINITY, &diff));
  print0(
      "  the points' matrix: %d of %d velocity unknowns; lifted product against the tangent's part %.2e of "
      "%.2e\n",
      static_cast<int>(n_s), sp.n_velocity(), diff, scale);
  EXPECT_GT(scale, 0.0);
  EXPECT_LE(diff, 1e-12 * scale);
  // The same pattern assembled again, as a refresh does when the points' elements have not changed: the
  // points lie in the wall's row of elements, whose fixed rows immersed_tangent zeroes; their entries keep
  // their room (a 2D capsule pulled onto a wall stopped with "New nonzero ... caused a malloc" here), and the
  // product is the same.
  CELLFSI_PETSC(MatZeroEntries(C.C));
  ASSERT_NO_THROW(fs.immersed_tangent(U, C));
  CELLFSI_PETSC(VecSet(y_lifted, 0.0));
  C.multiply_add(x, y_lifted);
  CELLFSI_PETSC(VecAXPY(y_lifted, -1.0, y_whole));
  CELLFSI_PETSC(VecNorm(y_lifted, NORM_INFINITY, &diff));
  EXPECT_LE(diff, 1e-12 * scale);
  VecDestroy(&x);
  VecDestroy(&y_whole);
  VecDestroy(&y_lifted);
  MatDestroy(&with);
  MatDestroy(&without);
  C.destroy();
}

TEST(DivConformingParallel, APartOfTheIterateServesTheResidualThePointsTangentAndTheSamples) {
  // Inside a 2-rank job (and alone): each rank gathers only the unknowns its residual and points' tangent
  // read (its elements' and its points' elements') or its samples read (gather_part), the others left NaN.
  // The residual, the points' tangent and the samples from that part equal those from the whole iterate to
  // 1e-14 (the same sums; measured equal; U and the part's levels hold NaN where nothing was gathered or
  // stepped, so a read outside the part gives NaN), and on 2 ranks a rank's part is a share of the unknowns
  // (measured 0.68-0.72 with 4 points each anywhere in this small channel, its elements' halo included;
  // asserted at most 0.8).
  const DivConformingSpace sp = channel_2d(2, 12, 8);
  DivConformingFluid fs(PETSC_COMM_WORLD, sp, parallel_channel_options());
  int rank = 0, size = 1;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  std::mt19937 rng(5);  // (the same iterate on every rank)
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::vector<double> U(sp.n_dofs());
  for (double& u : U) u = uni(rng);
  for (int r : sp.wall_normal_dofs()) U[r] = 0.0;
  std::mt19937 mine(17 + rank);  // (each rank's own points and samples, anywhere)
  fs.set_immersed_points(random_immersed_points(sp, 4, mine));
  fs.begin_step();
  Vec X = fs.create_vector(), F_whole = fs.create_vector(), F_part = fs.create_vector();
  fs.scatter(U, X);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> whole, part(sp.n_dofs(), nan);
  fs.gather(X, whole);
  const std::vector<int> elements = fs.immersed_elements();
  fs.gather_part(X, part, DivConformingFluid::kAssemblyPart, elements);
  const auto held =
      static_cast<double>(std::count_if(part.begin(), part.end(), [](double v) { return v == v; }));
  // The residual.
  fs.step_residual(whole, F_whole);
  fs.step_residual(part, F_part, true, DivConformingFluid::kAssemblyPart);
  PetscReal scale = 0, diff = 0;
  CELLFSI_PETSC(VecNorm(F_whole, NORM_INFINITY, &scale));
  CELLFSI_PETSC(VecAXPY(F_part, -1.0, F_whole));
  CELLFSI_PETSC(VecNorm(F_part, NORM_INFINITY, &diff));
  EXPECT_GT(scale, 0.0);
  EXPECT_LE(diff, 1e-14 * scale);  // (NaN fails it)
  // The points' tangent.
  DivConformingFluid::ImmersedMatrix C_whole = fs.create_immersed_matrix(),
                                     C_part = fs.create_immersed_matrix();
  fs.immersed_tangent(whole, C_whole);
  fs.immersed_tangent(part, C_part, DivConformingFluid::kAssemblyPart);
  PetscReal c_scale = 0, c_diff = 0;
  CELLFSI_PETSC(MatNorm(C_whole.C, NORM_INFINITY, &c_scale));
  CELLFSI_PETSC(MatAXPY(C_part.C, -1.0, C_whole.C, SAME_NONZERO_PATTERN));
  CELLFSI_PETSC(MatNorm(C_part.C, NORM_INFINITY, &c_diff));
  EXPECT_GT(c_scale, 0.0);
  EXPECT_LE(c_diff, 1e-14 * c_scale);
  // The samples, from the sample part alone.
  std::vector<int> el;
  std::vector<Vec3> x;
  for (const DivConformingFluid::ImmersedAt& p : random_immersed_points(sp, 15, mine))
    el.push_back(p.element), x.push_back(p.x);
  std::vector<int> sampled = el;
  std::sort(sampled.begin(), sampled.end());
  sampled.erase(std::unique(sampled.begin(), sampled.end()), sampled.end());
  std::vector<double> samples_part(sp.n_dofs(), nan);
  fs.gather_part(X, samples_part, DivConformingFluid::kSamplePart, sampled);
  const auto a = fs.sample_step(whole, el, x),
             b = fs.sample_step(samples_part, el, x, DivConformingFluid::kSamplePart);
  double s_scale = 0, s_diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    s_scale = std::max({s_scale, a[i].v.norm(), a[i].a.norm(), a[i].grad_v.norm()});
    s_diff = std::max(
        {s_diff, (a[i].v - b[i].v).norm(), (a[i].a - b[i].a).norm(), (a[i].grad_v - b[i].grad_v).norm()});
  }
  EXPECT_GT(s_scale, 0.0);
  EXPECT_LE(s_diff, 1e-14 * s_scale);  // (NaN fails it)
  // A share on 2 ranks, all of them on one; every unknown in some rank's part.
  const double share = held / sp.n_dofs();
  double least = share, most = share;
  MPI_Allreduce(MPI_IN_PLACE, &least, 1, MPI_DOUBLE, MPI_MIN, PETSC_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, &most, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
  std::vector<int> covered(sp.n_dofs());
  for (std::size_t i = 0; i < part.size(); ++i) covered[i] = part[i] == part[i];
  MPI_Allreduce(MPI_IN_PLACE, covered.data(), sp.n_dofs(), MPI_INT, MPI_MAX, PETSC_COMM_WORLD);
  print0(
      "  %d rank(s): a rank's part %.2f-%.2f of the unknowns; residual %.1e, points' tangent %.1e, samples "
      "%.1e "
      "of their largest\n",
      size, least, most, diff / scale, c_diff / c_scale, s_diff / s_scale);
  EXPECT_EQ(std::count(covered.begin(), covered.end(), 0), 0);
  if (size == 1) {
    EXPECT_EQ(share, 1.0);
  }
  if (size == 2) {
    EXPECT_LE(most, 0.8);
  }
  VecDestroy(&X);
  VecDestroy(&F_whole);
  VecDestroy(&F_part);
  C_whole.destroy();
  C_part.destroy();
}

TEST(DivConformingParallel, TheFourierSolverOnAllRanksEqualsTheDirectSolve) {
  // As DcFourierSolver.EqualsTheDirectSolve, with the operator assembled and the wave vectors solved on all
  // ranks of PETSC_COMM_WORLD (inside div_conforming_parallel_2ranks: 2), MUMPS on one: 1e-12 of max|x|; the
  // stencil's product on every rank equal to the distributed MatMult.
  int size = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  for (const FourierCase& cs : {FourierCase{2, 16, 8, false, true, "channel, NS step at Couette"},
                                FourierCase{2, 12, 12, true, true, "periodic square, NS step at rest"},
                                FourierCase{2, 6, 4, false, true, "3D channel, NS step at Couette", 5}}) {
    double deviation = 0;
    const double diff = fourier_vs_direct(cs, PETSC_COMM_WORLD, deviation);
    print0(
        "  Fourier on %d rank(s) vs MUMPS on 1, %s: stencil deviation %.1e, max|x_F - x_D| / max|x| = %.1e\n",
        size, cs.name, deviation, diff);
    EXPECT_LE(deviation, 1e-13) << cs.name;
    EXPECT_LE(diff, 1e-12) << cs.name;
  }
}
