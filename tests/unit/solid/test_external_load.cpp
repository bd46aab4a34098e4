// External loads and the stretching test's measures (solid/external_load.hpp, issue 28, item 4): the forces
// spread over a patch add up to the given force with the right sign and nothing elsewhere, the patches are
// where the ends are, bad patches are refused, the diameters of known shapes, the equilibrium test.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "geometry/builders.hpp"
#include "solid/external_load.hpp"
#include "solid/nurbs_solid.hpp"

using namespace cellfsi;
using solid::Vec3;

namespace {

// A cigar-shaped capsule along x (mid-surface semi-axes 3, 1.5, 1.5 um), its ends at x = -+3 um.
const double kA = 3e-4, kB = 1.5e-4, kH = 2e-5;
geometry::Patch capsule() { return geometry::hollow_ellipsoid(kA, kB, kB, kH, 12, 16, 2); }

}  // namespace

TEST(ExternalLoad, PatchForcesAddUpToTheGivenForceAtTheEnds) {
  const geometry::Patch p = capsule();
  const std::array<Vec3, 2> ends = solid::membrane_ends(p, Vec3::UnitX());
  EXPECT_NEAR(ends[0][0], -kA, 1e-12);
  EXPECT_NEAR(ends[1][0], kA, 1e-12);
  EXPECT_NEAR(ends[1].tail<2>().norm(), 0, 1e-12);
  solid::NurbsSolid s("cell", p, std::make_shared<solid::DeviatoricNeoHookean>(189.74), 1.1);
  const double F = 1e-5, r = 1e-4, rho1 = 1.025;               // 100 pN on a 2 um bead
  // No load: zero, as before loads existed.
  EXPECT_TRUE(s.quadrature_data(rho1, false).back().force.isZero());
  s.set_loads({{ends[0], r, -F * Vec3::UnitX()}, {ends[1], r, F * Vec3::UnitX()}});
  Vec3 plus = Vec3::Zero(), minus = Vec3::Zero();
  int n_plus = 0, n_minus = 0;
  double density = 0;
  for (const solid::QuadratureData& q : s.quadrature_data(rho1, false)) {
    const Vec3 f = q.weight * q.force * rho1;  // the force the point carries [dyn]
    if (q.force.isZero()) {
      // Unloaded points lie outside both patches.
      EXPECT_GT((q.x - ends[0]).norm(), r * (1 - 1e-12));
      EXPECT_GT((q.x - ends[1]).norm(), r * (1 - 1e-12));
      continue;
    }
    const bool far = q.force[0] > 0;
    EXPECT_LE((q.x - ends[far ? 1 : 0]).norm(), r) << "a loaded point outside its patch";
    (far ? plus : minus) += f;
    (far ? n_plus : n_minus)++;
    // Uniform per unit reference volume: the same density on every point of a patch.
    if (density == 0) density = q.force.norm();
    EXPECT_NEAR(q.force.norm(), density, 1e-12 * density);
    EXPECT_NEAR(q.force[1], 0, 1e-300);
  }
  std::printf("  patch points: %d and %d; forces %.15g and %.15g dyn\n", n_plus, n_minus, plus[0], minus[0]);
  EXPECT_GT(n_plus, 10);
  EXPECT_EQ(n_plus, n_minus);  // the capsule is symmetric
  EXPECT_NEAR(plus[0], F, 1e-12 * F);
  EXPECT_NEAR(minus[0], -F, 1e-12 * F);
  EXPECT_NEAR((plus + minus).norm(), 0, 1e-12 * F);  // no net force
  // A ramp: the forces grow linearly to their size at t = ramp, taken at the step's t_{n+alpha_f}.
  const std::vector<solid::QuadratureData> full = s.quadrature_data(rho1, false);
  s.set_loads({{ends[0], r, -F * Vec3::UnitX()}, {ends[1], r, F * Vec3::UnitX()}}, 4e-3);
  EXPECT_EQ(s.load_factor(), 0.0);                                                  // no step yet: t = 0
  const solid::TimeParameters tp = solid::TimeParameters::from_rho_inf(0.5, 1e-3);  // alpha_f = 2/3
  for (const auto& [t_n, share] :
       {std::pair{0.0, 1.0 / 6}, std::pair{2e-3, 2.0 / 3}, std::pair{4e-3, 1.0}, std::pair{9e-3, 1.0}}) {
    s.begin_step({tp, t_n});
    EXPECT_NEAR(s.load_factor(), share, 1e-12) << "t_n = " << t_n;
    const std::vector<solid::QuadratureData> q = s.quadrature_data(rho1, false);
    for (size_t i = 0; i < q.size(); ++i)
      EXPECT_NEAR((q[i].force - share * full[i].force).norm(), 0, 1e-12 * density);
  }
  EXPECT_THROW(s.set_loads({}, -1.0), std::invalid_argument);
  // Loads are replaced, not added; none clears them.
  s.set_loads({});
  EXPECT_TRUE(s.load_densities().empty());
  EXPECT_EQ(s.load_factor(), 1.0);
}

TEST(ExternalLoad, PatchesWithoutMaterialOrOverlappingAreRefused) {
  const std::vector<Vec3> X{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)};
  const std::vector<double> w{1, 2, 3};
  // A patch with no point, patches sharing a point.
  EXPECT_THROW(solid::load_densities(X, w, {{Vec3(0.5, 0, 0), 0.1, Vec3::UnitX()}}), std::invalid_argument);
  EXPECT_THROW(solid::load_densities(
                   X, w, {{Vec3(0, 0, 0), 1.5, Vec3::UnitX()}, {Vec3(2, 0, 0), 1.5, -Vec3::UnitX()}}),
               std::invalid_argument);
  // Two points in one patch: F over their weights' sum.
  const std::vector<Vec3> f = solid::load_densities(X, w, {{Vec3(1.5, 0, 0), 0.6, Vec3(5, 0, 0)}});
  EXPECT_EQ(f[0], Vec3::Zero());
  EXPECT_DOUBLE_EQ(f[1][0], 1.0);
  EXPECT_DOUBLE_EQ(f[2][0], 1.0);
}

TEST(ExternalLoad, DiametersOfAnEllipsoidAlongAndAcrossTheAxis) {
  // Mid-surface semi-axes 3, 1.5, 1 um: along x 6 um; across x the widest is 3 um (along y). Along y: 3 um,
  // across it 6 um (along x).
  const geometry::Patch p = geometry::hollow_ellipsoid(3e-4, 1.5e-4, 1e-4, kH, 12, 16, 2);
  const std::vector<Vec3> pts = solid::mid_surface_points(p);
  const solid::StretchDiameters dx = solid::stretch_diameters(pts, Vec3::UnitX());
  EXPECT_NEAR(dx.axial, 6e-4, 1e-9);
  EXPECT_NEAR(dx.transverse, 3e-4, 1e-8);
  const solid::StretchDiameters dy = solid::stretch_diameters(pts, Vec3::UnitY());
  EXPECT_NEAR(dy.axial, 3e-4, 1e-9);
  EXPECT_NEAR(dy.transverse, 6e-4, 1e-8);
  // The 3D RBC at rest: D_A = D_T = 2 x 3.91 um (the Evans-Fung R0) in its plane.
  const std::vector<Vec3> rbc = solid::mid_surface_points(geometry::biconcave_rbc_3d(3.1623e-5, 20, 40, 2));
  const solid::StretchDiameters d = solid::stretch_diameters(rbc, Vec3::UnitX());
  std::printf("  rest RBC: D_A = %.6f um, D_T = %.6f um\n", d.axial * 1e4, d.transverse * 1e4);
  EXPECT_NEAR(d.axial, 7.82e-4, 1e-7);
  EXPECT_NEAR(d.transverse, 7.82e-4, 1e-7);
}

TEST(ExternalLoad, TheMidSurfaceExtentIsTheBoundingBoxOfAnEllipsoidAndAnRbc) {
  // Semi-axes 3, 1.5, 1 um: 6, 3, 2 um. The rest RBC (axis along z): 7.82, 7.82 um in its plane and 2.565 um
  // across it, the Evans-Fung profile's largest thickness (near r = 0.71 R0; the mid-surface is that
  // profile).
  const Vec3 e = solid::mid_surface_extent(geometry::hollow_ellipsoid(3e-4, 1.5e-4, 1e-4, kH, 12, 16, 2));
  EXPECT_NEAR(e[0], 6e-4, 1e-9);
  EXPECT_NEAR(e[1], 3e-4, 1e-9);
  EXPECT_NEAR(e[2], 2e-4, 1e-9);
  const Vec3 r = solid::mid_surface_extent(geometry::biconcave_rbc_3d(3.1623e-5, 20, 40, 2));
  std::printf("  rest RBC: extent %.4f x %.4f x %.4f um\n", r[0] * 1e4, r[1] * 1e4, r[2] * 1e4);
  EXPECT_NEAR(r[0], 7.82e-4, 1e-7);
  EXPECT_NEAR(r[1], 7.82e-4, 1e-7);
  EXPECT_NEAR(r[2], 2.565e-4, 1e-7);
  // In 2D (256 samples of a 24-element ring, which its axes fall between: 3e-5 short) the z extent is 0.
  const Vec3 c = solid::mid_surface_extent(geometry::hollow_ellipse(2e-4, 1e-4, 5e-6, 24, 2), 256, 1);
  EXPECT_NEAR(c[0], 4e-4, 2e-8);
  EXPECT_NEAR(c[1], 2e-4, 1e-8);
  EXPECT_EQ(c[2], 0.0);
}

TEST(ExternalLoad, EquilibriumIsTheFirstRecordStillForAWindow) {
  // The diameters move until t = 5 and stay from there: with a window of 2, equilibrium at t = 7 exactly (at
  // t = 6 the record two before, t = 4, still differs); a tolerance above the last change is reached earlier.
  solid::EquilibriumMonitor m(1e-3, 2.0);
  for (int k = 0; k <= 10; ++k) {
    const double t = k, D = t < 5 ? 10 - (5 - t) : 10;
    m.record(t, {D, D / 2});
    if (k < 2) {
      EXPECT_TRUE(std::isnan(m.last_change()));
    }
    if (k < 7) {
      EXPECT_FALSE(m.reached()) << t;
    }
  }
  EXPECT_TRUE(m.reached());
  EXPECT_DOUBLE_EQ(m.time(), 7.0);
  EXPECT_DOUBLE_EQ(m.last_change(), 0.0);
  EXPECT_DOUBLE_EQ(m.last().axial, 10.0);
  solid::EquilibriumMonitor loose(0.24, 2.0);  // the change over t = 1 ... 3 is 2 / 8, over 2 ... 4 2 / 9
  for (int k = 0; k <= 10; ++k) loose.record(k, {k < 5 ? 10.0 - (5 - k) : 10.0, 5.0});
  EXPECT_DOUBLE_EQ(loose.time(), 4.0);
  // A checkpoint's numbers bring the records back.
  solid::EquilibriumMonitor again(1e-3, 2.0);
  again.restore(m.state());
  EXPECT_EQ(again.state(), m.state());
  EXPECT_DOUBLE_EQ(again.time(), 7.0);
  EXPECT_THROW(again.restore({1.0}), std::invalid_argument);
  // Not with a window that starts before the force's ramp has ended (t = 8: the first window wholly after it
  // ends at 10): a body that follows a slow ramp closely is not at rest.
  solid::EquilibriumMonitor ramped(1e-3, 2.0, 8.0);
  for (int k = 0; k <= 12; ++k) ramped.record(k, {k < 5 ? 10.0 - (5 - k) : 10.0, 5.0});
  EXPECT_DOUBLE_EQ(ramped.time(), 10.0);
}
