// The divergence-conforming fluid on a mapped (curved) domain (DivConformingSpace::mapped, the contravariant
// Piola map of dc_piola.hpp; issue 45 part 2):
//   * Poiseuille flow in a channel at an angle whose elements are sheared (an affine map that is not
//     axis-aligned: every term of the map but its second derivatives) is exact to 1e-10, steady and over time
//     steps, k = 2 and 3, Stokes and Navier-Stokes;
//   * a manufactured flow on a channel whose interior elements are curved (straight walls, so that the
//     unit channel's manufactured solution applies) converges at the optimal rates k + 1, k, k + 1;
//   * on the narrowing channel (curved walls, Nitsche with the physical normal) the velocity is
//     divergence-free to round-off and carries the same flow through every cross-section, measured by
//     sampling (NURBS inversion) along vertical lines; the .vts holds the mapped grid.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>
#include <numbers>
#include <vector>

#include <petscsys.h>
#include <vtkNew.h>
#include <vtkStructuredGrid.h>
#include <vtkXMLStructuredGridReader.h>

#include "../../support/dc_manufactured.hpp"
#include "../../support/print_rank0.hpp"
#include "fluid/div_conforming/dc_fluid.hpp"
#include "geometry/builders.hpp"
#include "geometry/quadrature.hpp"

using namespace cellfsi;
using namespace cellfsi::fluid::dc;
using cellfsi::test_support::Manufactured;
using cellfsi::test_support::print0;
using geometry::Mat3;

namespace {

constexpr double kPi = std::numbers::pi;

/// The rectangle [0, lx] x [0, ly] (periodic in x, degree 2) moved by x -> A x, its period shift with it.
std::shared_ptr<const geometry::Patch> linear_image(double lx, double ly, int nx, int ny, const Mat3& A) {
  const geometry::Patch r = geometry::rectangle(lx, ly, nx, ny, 2, {true, false});
  std::vector<Vec3> cp = r.control_points();
  for (Vec3& x : cp) x = A * x;
  std::array<Vec3, 3> shifts = r.shifts();
  shifts[0] = A * shifts[0];
  return std::make_shared<const geometry::Patch>(r.all_knots(), 2, cp, r.weights(), shifts);
}

}  // namespace

TEST(DcMappedFluid, PoiseuilleInAnInclinedShearedChannelIsExact) {
  // The paper's plasma channel (0.003 x 0.001 cm) turned by 30 degrees, its cross lines sheared by 20
  // degrees from the normal and stretched (J = 1.3 cos 20 deg): walls along t = (cos 30, sin 30), a body
  // force G t. v = G / (2 mu) eta (H - eta) t, eta the distance from the lower wall, H = 1.3 ly cos 20, p
  // constant. Along the map v^ = J F^{-1} v = (G / (2 mu) eta (H - eta) J / |F e_0|, 0), quadratic in xi_1:
  // in the space for k >= 2, so the solution is exact up to the LU's round-off.
  const double lx = 0.003, ly = 0.001, mu = 0.012, rho = 1.025, G = 4800;
  const double th = kPi / 6, sh = kPi / 9;
  const Vec3 t(std::cos(th), std::sin(th), 0), n(-std::sin(th), std::cos(th), 0);
  const Vec3 m = 1.3 * (std::cos(sh) * n + std::sin(sh) * t);  // the image of e_1
  Mat3 A = Mat3::Identity();
  A.col(0) = t;
  A.col(1) = m;
  const double H = ly * m.dot(n);
  auto v = [&](const Vec3& x) { return Vec3(G / (2 * mu) * x.dot(n) * (H - x.dot(n)) * t); };
  auto grad = [&](const Vec3& x) { return Mat3(G / (2 * mu) * (H - 2 * x.dot(n)) * t * n.transpose()); };
  for (int k : {2, 3}) {
    const DivConformingSpace sp = DivConformingSpace::mapped(linear_image(lx, ly, 12, 4, A), k);
    for (bool stokes : {true, false}) {
      DcFluidOptions opt;
      opt.density = rho;
      opt.viscosity = mu;
      opt.body_force = G * t;
      opt.stokes = stokes;
      opt.newton_rtol = 0;  // stop on the update alone
      DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
      const DcSolveStats st = fs.solve_steady();
      ASSERT_TRUE(st.converged) << "k=" << k << " Newton " << st.newton_iterations << " residual "
                                << st.residual_norm;
      auto error = [&] {
        const auto er = fs.errors(v, grad, [](const Vec3&) { return 0.0; });
        return er.v_l2 / er.v_l2_norm;
      };
      const double e_steady = error();
      EXPECT_LT(e_steady, 1e-10) << "k=" << k << (stokes ? " Stokes" : " Navier-Stokes");
      EXPECT_LT(fs.divergence_ratio(), 1e-12);
      fs.project_initial_state(v, [](const Vec3&) { return Vec3(Vec3::Zero()); });
      for (int s = 0; s < 3; ++s) ASSERT_TRUE(fs.step().converged);
      const double e_steps = error();
      EXPECT_LT(e_steps, 1e-10) << "k=" << k << (stokes ? " Stokes" : " Navier-Stokes");
      // The samples (found by inversion) give the same flow.
      const std::vector<Vec3> at{0.4 * lx * t + 0.3 * ly * m, 0.9 * lx * t + 0.8 * ly * m};
      const auto smp = fs.sample(at);
      for (size_t i = 0; i < at.size(); ++i) {
        EXPECT_LT((smp[i].v - v(at[i])).norm(), 1e-10 * v(at[i]).norm());
        EXPECT_LT((smp[i].grad_v - grad(at[i])).norm(), 1e-9 * grad(at[i]).norm());
      }
      print0("  inclined Poiseuille k=%d %s: rel L2 error steady %.2e, after 3 steps %.2e\n", k,
             stokes ? "Stokes" : "NS", e_steady, e_steps);
    }
  }
}

namespace {

/// The unit channel (periodic x, walls y = 0, 1) with curved interior elements: x = xi + eps (sin(2 pi xi_0)
/// sin(pi xi_1), sin(2 pi xi_0) sin(pi xi_1) / 2) on its n x n degree-3 patch, each control point moved by
/// the offset at its Greville abscissa (the walls stay the lines y = 0, 1: the offsets vanish there).
std::shared_ptr<const geometry::Patch> warped_unit_channel(int n) {
  geometry::Patch r = geometry::rectangle(1.0, 1.0, n, n, 3, {true, false});
  const auto greville = [](const geometry::KnotVector& kv, int i) {
    double s = 0;
    for (int j = 1; j <= kv.degree(); ++j) s += kv.knots()[i + j];
    return s / kv.degree();
  };
  const double eps = 0.06;
  for (int j = 0; j < r.n_control(1); ++j)
    for (int i = 0; i < r.n_control(0); ++i) {
      const double a = greville(r.knots(0), i), b = greville(r.knots(1), j);
      const double f = eps * std::sin(2 * kPi * a) * std::sin(kPi * b);
      r.control_points()[r.control_index(i, j)] += Vec3(f, 0.5 * f, 0);
    }
  return std::make_shared<const geometry::Patch>(std::move(r));
}

}  // namespace

TEST(DcMappedFluid, AManufacturedFlowOnCurvedElementsConvergesAtTheOptimalRates) {
  const Manufactured mf;
  const int k = 2;
  std::vector<double> e[3];
  for (int n : {8, 16, 32}) {
    const DivConformingSpace sp = DivConformingSpace::mapped(warped_unit_channel(n), k);
    DcFluidOptions opt;
    opt.density = 1.0;
    opt.viscosity = 1.0;
    opt.stokes = true;
    opt.body_force_field = [&](const Vec3& x, double) { return mf.force(x, 0.0); };
    opt.wall_velocity_field = [&](const Vec3& x, double) { return mf.v(x); };
    DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
    ASSERT_TRUE(fs.solve_steady().converged);
    EXPECT_LT(fs.divergence_ratio(), 1e-10) << n;
    const auto er =
        fs.errors([&](const Vec3& x) { return mf.v(x); }, [&](const Vec3& x) { return mf.grad(x); },
                  [&](const Vec3& x) { return mf.p(x); });
    e[0].push_back(er.v_l2 / er.v_l2_norm);
    e[1].push_back(er.v_h1 / er.v_h1_norm);
    e[2].push_back(er.p_l2 / er.p_l2_norm);
    print0("  warped channel k=%d %2dx%-2d: rel errors v L2 %.3e, v H1 %.3e, p L2 %.3e, div ratio %.1e\n", k,
           n, n, e[0].back(), e[1].back(), e[2].back(), fs.divergence_ratio());
  }
  const double optimal[3] = {k + 1.0, k + 0.0, k + 1.0};
  const char* what[3] = {"v L2", "v H1", "p L2"};
  for (int i = 0; i < 3; ++i) {
    const double rate = std::log2(e[i][1] / e[i][2]);
    print0("  warped channel rate (16 -> 32) %s: %.2f\n", what[i], rate);
    EXPECT_GT(rate, optimal[i] - 0.15) << what[i];
    EXPECT_LT(rate, optimal[i] + 0.5) << what[i];
  }
}

TEST(DcMappedFluid, TheNarrowingCarriesTheSameFlowThroughEverySection) {
  // The narrowing channel (curved walls) with the channel scenes' body force, steady Stokes, k = 2: div v = 0
  // at every Gauss point to round-off, and the flow through vertical lines (the patch's lines xi_0 = const:
  // its x is xi_0) upstream, in the transition, in the throat and downstream equal, by samples (NURBS
  // inversion) on a Gauss rule per element between the walls (v_x dy/dxi_1 = v^_0 there: a polynomial).
  auto patch = std::make_shared<const geometry::Patch>(geometry::narrowing_channel({}, 48, 16, 3));
  const DivConformingSpace sp = DivConformingSpace::mapped(patch, 2);
  DcFluidOptions opt;
  opt.body_force = Vec3(1666.66, 0, 0);
  opt.stokes = true;
  DivConformingFluid fs(PETSC_COMM_WORLD, sp, opt);
  ASSERT_TRUE(fs.solve_steady().converged);
  EXPECT_LT(fs.divergence_ratio(), 1e-11);
  const geometry::GaussRule& g = geometry::gauss_legendre(6);
  const geometry::KnotVector& k1 = patch->knots(1);
  std::vector<double> flux;
  for (double x : {0.0005, 0.0021, 0.0026, 0.003, 0.0047}) {
    const geometry::KnotVector& k0 = patch->knots(0);  // (the channel's x is affine in xi_0)
    const double xi0 = k0.a() + (k0.b() - k0.a()) * x / 0.006;
    ASSERT_NEAR(patch->evaluate({xi0, 0.5 * (k1.a() + k1.b()), 0}, 0).x[0], x, 1e-15);
    std::vector<Vec3> pts;
    std::vector<double> w;  // Gauss weight times dy/dxi_1
    for (int e = 0; e < k1.n_elements(); ++e) {
      const double a = k1.element_begin(e), b = k1.element_end(e);
      for (size_t q = 0; q < g.points.size(); ++q) {
        const geometry::MapValues mv = patch->evaluate({xi0, a + 0.5 * (b - a) * (g.points[q] + 1), 0}, 1);
        pts.push_back(mv.x);
        w.push_back(0.5 * (b - a) * g.weights[q] * mv.dx(1, 1));
      }
    }
    const auto smp = fs.sample(pts);
    double q = 0;
    for (size_t i = 0; i < pts.size(); ++i) q += w[i] * smp[i].v[0];
    flux.push_back(q);
    print0("  narrowing, k = 2, 48 x 16: flow through x = %.4f (height %.5f): %.12e cm^2/s\n", x,
           pts.back()[1] - pts.front()[1], q);
  }
  for (double q : flux) EXPECT_NEAR(q, flux[0], 1e-11 * std::abs(flux[0]));
  // The .vts: the mapped grid's points, the velocity there.
  const std::string path = std::filesystem::temp_directory_path() / "cellfsi_dc_mapped.vts";
  fs.write_vtk(path, 2);
  vtkNew<vtkXMLStructuredGridReader> reader;
  reader->SetFileName(path.c_str());
  reader->Update();
  std::filesystem::remove(path);
  vtkStructuredGrid* grid = reader->GetOutput();
  int n[3];
  grid->GetDimensions(n);
  ASSERT_EQ(n[0], 48 * 2 + 1);
  ASSERT_EQ(n[1], 16 * 2 + 1);
  double first[3], last[3];
  grid->GetPoint(0, first);
  grid->GetPoint(n[0] - 1, last);
  EXPECT_NEAR(first[0], 0.0, 1e-15);
  EXPECT_NEAR(last[0], 0.006, 1e-15);  // (the periodic end at x = L, not folded onto x = 0)
  EXPECT_NEAR(first[1], -0.001, 1e-7);
}
