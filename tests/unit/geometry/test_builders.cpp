// Builders: exact conics and quadrics, affine Eulerian domains, periodic wraps, and argument checking.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

#include "geometry/builders.hpp"
#include "geometry/measures.hpp"
#include "geometry/quadrature.hpp"
#include "geometry/refine.hpp"

using namespace cellfsi::geometry;

namespace {
template <class F>
void expect_invalid(F&& f, const std::string& mentions) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one naming '" << mentions << "'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(mentions), std::string::npos) << e.what();
  }
}
}  // namespace

TEST(Builders, RectangleIsAffineAndPeriodicInX) {
  const double lx = 2.4e-3, ly = 1.2e-3;
  const Patch r = rectangle(lx, ly, 12, 6, 3, {true, false}, Vec3(0, -6e-4, 0));
  EXPECT_TRUE(r.knots(0).periodic());
  EXPECT_FALSE(r.knots(1).periodic());
  EXPECT_EQ(r.n_control(0), 12);  // periodic: one control variable per element
  EXPECT_EQ(r.n_control(1), 9);
  EXPECT_TRUE(r.closed(0));
  EXPECT_FALSE(r.closed(1));
  for (double u : {0.0, 0.123, 0.5, 0.99})
    for (double v : {0.0, 0.31, 1.0}) {
      const MapValues m = r.evaluate({u, v, 0});
      EXPECT_NEAR(m.x[0], lx * u, 1e-17);
      EXPECT_NEAR(m.x[1], -6e-4 + ly * v, 1e-17);
      EXPECT_NEAR(m.dx(0, 0), lx, 1e-15);
      EXPECT_NEAR(m.dx(1, 1), ly, 1e-15);
      EXPECT_NEAR(m.dx(0, 1), 0.0, 1e-15);
      // One period further the map moves by the period shift.
      EXPECT_NEAR(r.point({u + 1.0, v, 0})[0], lx * (u + 1.0), 1e-17);
    }
}

TEST(Builders, BoxIsAffine) {
  const Patch b = box(1.2e-3, 1.2e-3, 1.2e-3, 4, 5, 6, 2, {true, true, false});
  const Vec3 x = b.point({0.3, 0.6, 0.9});
  EXPECT_LT((x - Vec3(0.36e-3, 0.72e-3, 1.08e-3)).norm(), 1e-17);
  EXPECT_EQ(b.n_elements(), 120);
}

TEST(Builders, BoxesAreTranslationInvariantAlongTheirPeriodicDirections) {
  // The Fourier solver's precondition (coupling: fourier_inapplicable).
  EXPECT_TRUE(translation_invariant(rectangle(2.4e-3, 1.2e-3, 12, 6, 3, {true, false})));
  EXPECT_TRUE(translation_invariant(box(1.2e-3, 1.2e-3, 1.2e-3, 4, 5, 6, 2, {true, false, true})));
  EXPECT_TRUE(
      translation_invariant(rectangle(2.4e-3, 1.2e-3, 12, 6, 3, {false, false})));  // nothing to shift
  // The narrowing's walls move along x: a shift by one element changes the map.
  EXPECT_FALSE(translation_invariant(narrowing_channel(NarrowingChannel{}, 24, 6, 2)));
  // One control point off the lattice.
  Patch r = rectangle(2.4e-3, 1.2e-3, 12, 6, 3, {true, false});
  r.control_points()[20][0] += 1e-6;
  EXPECT_FALSE(translation_invariant(r));
}

TEST(Builders, TheBoxesAreAffineAndNothingElseIs) {
  // The locator's closed form (coupling::Locator): x_d = offset_d + scale_d xi_d, found for the paper's boxes
  // and channels, refused for the narrowing channel and any curved, rotated, sheared or rational patch.
  const Vec3 origin(0.003, -5e-4, 2e-4);
  const Patch r = rectangle(2.4e-3, 1.2e-3, 12, 6, 3, {true, false}, origin);
  const Patch b = box(1.2e-3, 0.9e-3, 0.6e-3, 4, 5, 6, 2, {true, false, true}, origin);
  for (const Patch* p : {&r, &b}) {
    const std::optional<AffineMap> m = affine_map(*p);
    ASSERT_TRUE(m.has_value());
    const Vec3 size = p == &r ? Vec3(2.4e-3, 1.2e-3, 0) : Vec3(1.2e-3, 0.9e-3, 0.6e-3);
    EXPECT_LT((m->scale - size).norm(), 1e-18);
    EXPECT_LT((m->offset - origin).norm(), 1e-18);
    for (const Param xi : {Param{0.1, 0.7, 0.3}, Param{0.999, 0.0, 1.0}, Param{1.3, 0.5, 0.25}})
      EXPECT_LT((p->point(xi) - m->point(xi)).norm(), 1e-18);  // 1.3: one period on
  }
  EXPECT_TRUE(affine_map(box(1e-3, 1e-3, 1e-3, 3, 3, 3, 1)).has_value());  // open, linear
  // Non-uniform knots with the control points at their Greville abscissae: still the identity in xi.
  EXPECT_TRUE(affine_map(insert_knots(r, 1, {0.05, 0.05, 0.41})).has_value());

  EXPECT_FALSE(affine_map(narrowing_channel(NarrowingChannel{}, 24, 6, 2)).has_value());
  EXPECT_FALSE(affine_map(hollow_ellipse(2e-4, 1e-4, 5e-7, 16, 2)).has_value());
  EXPECT_FALSE(affine_map(bulky_ellipse(2e-4, 1e-4, 2, 8, 2)).has_value());
  EXPECT_FALSE(affine_map(solid_ellipsoid(2e-4, 2e-4, 2e-4, 2, 4, 4, 2)).has_value());
  const Mat3 rotation = Eigen::AngleAxisd(1e-3, Vec3::UnitZ()).toRotationMatrix();
  EXPECT_FALSE(affine_map(transformed(r, rotation, Vec3::Zero())).has_value());
  Mat3 shear = Mat3::Identity();
  shear(0, 1) = 1e-3;
  EXPECT_FALSE(affine_map(transformed(b, shear, Vec3::Zero())).has_value());
  // Scaling and translating an affine patch keeps it affine.
  EXPECT_TRUE(affine_map(transformed(b, Vec3(2, 3, 0.5).asDiagonal(), Vec3(1, 0, 0))).has_value());
  // One control point off the lattice by 1e-12 cm (6e-10 of the box), one weight changed, a period shift
  // other than the period's image.
  Patch bent = b;
  bent.control_points()[40][1] += 1e-12;
  EXPECT_FALSE(affine_map(bent).has_value());
  Patch rational = r;
  rational.weights()[30] = 1.01;
  EXPECT_FALSE(affine_map(rational).has_value());
  const Patch wrong_shift(r.all_knots(), 2, r.control_points(), r.weights(),
                          {Vec3(2.5e-3, 0, 0), Vec3::Zero(), Vec3::Zero()});
  EXPECT_FALSE(affine_map(wrong_shift).has_value());
  // A uniform scaling of all weights changes nothing.
  Patch weighted = b;
  for (double& w : weighted.weights()) w = 2.5;
  EXPECT_TRUE(affine_map(weighted).has_value());
}

TEST(Builders, HollowEllipseBoundariesAreExactEllipses) {
  const double a = 2e-4, b = 1e-4, h = 5e-7, angle = 1.1;
  const Vec3 c(1.2e-3, 6e-4, 0);
  const Patch e = hollow_ellipse(a, b, h, 208, 3, c, angle);
  EXPECT_EQ(e.n_elements(0), 1);
  EXPECT_EQ(e.n_elements(1), 208);
  EXPECT_EQ(e.degree(0), 3);
  EXPECT_EQ(e.degree(1), 3);
  EXPECT_TRUE(e.closed(1));
  const Mat3 Rt = Eigen::AngleAxisd(-angle, Vec3::UnitZ()).toRotationMatrix();
  for (double r : {0.0, 0.5, 1.0}) {
    const double sa = a - h / 2 + r * h, sb = b - h / 2 + r * h;
    for (int s = 0; s < 97; ++s) {
      const Vec3 y = Rt * (e.point({r, (s + 0.3) / 97, 0}) - c);
      EXPECT_NEAR(y[0] * y[0] / (sa * sa) + y[1] * y[1] / (sb * sb), 1.0, 1e-13);
    }
  }
}

TEST(Builders, EllipsoidShellAndSphereSurfacesAreExactQuadrics) {
  const double a = 3e-4, b = 2e-4, c = 2e-4, h = 5e-7;
  const Patch shell = hollow_ellipsoid(a, b, c, h, 32, 96, 2);
  EXPECT_EQ(shell.n_elements(), 3072);  // the paper's membrane mesh size (Sec. 3.6)
  for (double r : {0.0, 0.5, 1.0})
    for (double u : {0.05, 0.5, 0.77})
      for (double v : {0.1, 0.6}) {
        const Vec3 x = shell.point({r, u, v});
        const double sa = a - h / 2 + r * h, sb = b - h / 2 + r * h, sc = c - h / 2 + r * h;
        EXPECT_NEAR(x[0] * x[0] / (sa * sa) + x[1] * x[1] / (sb * sb) + x[2] * x[2] / (sc * sc), 1.0, 1e-13);
      }
  const Patch ball = solid_ellipsoid(1e-4, 1e-4, 1e-4, 7, 32, 32, 2);
  EXPECT_EQ(ball.n_elements(), 7168);  // the paper's inclusion mesh size (Sec. 3.6)
  EXPECT_NEAR(ball.point({1.0, 0.3, 0.8}).norm(), 1e-4, 1e-17);
  EXPECT_NEAR(ball.point({0.5, 0.3, 0.8}).norm(), 0.5e-4, 1e-17);
}

TEST(Builders, Rbc3dShellHasItsThicknessAndSmoothPoles) {
  // The scene's shell (scenes/rbc_shear_3d.yaml: h = 3.16e-5 cm; 1 x 20 x 40 elements, the automatic count at
  // 16^3), its symmetry axis along z through c.
  const double h = 3.1623e-5;
  const Vec3 c(6e-4, 6e-4, 6e-4);
  const Patch rbc = biconcave_rbc_3d(h, 20, 40, 2, c);
  EXPECT_EQ(rbc.n_elements(0), 1);
  EXPECT_EQ(rbc.n_elements(1), 20);
  EXPECT_EQ(rbc.n_elements(2), 40);
  // Thickness: the outer face's point against the inner face's at the same surface parameters. The offset is
  // along the normals at the Greville points, not an exact offset surface: where the profile bends most
  // (between dimple and rim) the band is thinner. Measured: 4.0 % at 14 elements pole to pole, 1.9 % at 20,
  // 1.1 % at 28, 0.6 % at 40, 0.3 % at 56.
  auto thickness_error = [&](const Patch& shell) {
    double worst = 0;
    for (int i = 0; i <= 400; ++i)
      for (double v : {0.0, 0.13, 0.6}) {
        const double u = i / 400.0;
        worst = std::max(worst, std::abs((shell.point({1, u, v}) - shell.point({0, u, v})).norm() - h) / h);
      }
    return worst;
  };
  EXPECT_LT(thickness_error(rbc), 0.02);
  EXPECT_LT(thickness_error(biconcave_rbc_3d(h, 40, 40, 2, c)), 0.006);
  // A surface of revolution: the distance from the axis does not depend on the angle around it.
  for (double u : {0.1, 0.37, 0.5, 0.81}) {
    const Vec3 a = rbc.point({0.5, u, 0.0}) - c, b = rbc.point({0.5, u, 0.29}) - c;
    EXPECT_NEAR(a.head<2>().norm(), b.head<2>().norm(), 1e-15);
    EXPECT_NEAR(a[2], b[2], 1e-15);
  }
  // The rim (u = 1/2) is the Evans-Fung radius R0 on the mid-surface; the poles are on the axis, C0/2 from the centre, and every face meets the axis
  // at a right angle: near a pole the normal is along z.
  const EvansFung ef;
  EXPECT_NEAR((rbc.point({0.5, 0.5, 0.3}) - c).norm(), ef.R0, 5e-5 * ef.R0);
  for (double r : {0.0, 0.5, 1.0})
    for (double u : {0.0, 1.0}) {
      const Vec3 pole = rbc.point({r, u, 0.4}) - c;
      EXPECT_LT(pole.head<2>().norm(), 1e-18);
      EXPECT_NEAR(std::abs(pole[2]), 0.5 * ef.C0 + (r - 0.5) * h, 1e-15);
      const MapValues d = rbc.evaluate({r, std::abs(u - 1e-6), 0.4});
      const Vec3 n = d.dx.col(1).cross(d.dx.col(2)).normalized();
      EXPECT_GT(std::abs(n[2]), 1 - 1e-8) << "r=" << r << " u=" << u;
    }
}

TEST(Builders, Rbc3dShellOnSixFacesIsClosedAndHasNoPoles) {
  const double h = 3.1623e-5;
  const Vec3 c(6e-4, 6e-4, 6e-4);
  const EvansFung ef;
  const std::vector<Patch> faces = biconcave_rbc_3d_faces(h, 8, 2, c);
  ASSERT_EQ(faces.size(), 6u);
  // Closed: every point of a face's edge (inner face, mid-surface, outer face; 21 points an edge) is a point
  // of another face's edge, at the same parameter up to its direction.
  std::vector<std::vector<Vec3>> edge_points(6);
  for (int f = 0; f < 6; ++f)
    for (double r : {0.0, 0.5, 1.0})
      for (int k = 0; k <= 20; ++k)
        for (double side : {0.0, 1.0}) {
          edge_points[f].push_back(faces[f].point({r, side, k / 20.0}));
          edge_points[f].push_back(faces[f].point({r, k / 20.0, side}));
        }
  double worst_gap = 0;
  for (int f = 0; f < 6; ++f)
    for (const Vec3& x : edge_points[f]) {
      double nearest = 1e300;
      for (int g = 0; g < 6; ++g)
        if (g != f)
          for (const Vec3& y : edge_points[g]) nearest = std::min(nearest, (x - y).norm());
      worst_gap = std::max(worst_gap, nearest);
    }
  EXPECT_LT(worst_gap, 1e-12 * ef.R0);
  // The mid-surface interpolates the exact map at the Greville points; between them it is measured against it
  // at the same face coordinates (the sphere's point tan-mapped as the builder does); and the faces are
  // right-handed (det dx/dxi > 0 on both faces of the shell).
  auto exact = [&](int f, double u, double v) -> Vec3 {
    const int k = f / 2, sign = f % 2 == 0 ? 1 : -1;
    const int i = sign > 0 ? (k + 1) % 3 : (k + 2) % 3, j = sign > 0 ? (k + 2) % 3 : (k + 1) % 3;
    Vec3 d = Vec3::Zero();
    d[k] = sign, d[i] = std::tan(M_PI / 4 * (2 * u - 1)), d[j] = std::tan(M_PI / 4 * (2 * v - 1));
    const Vec3 s = d.normalized();
    const double c2 = s[0] * s[0] + s[1] * s[1];
    return Vec3(ef.R0 * s[0], ef.R0 * s[1], 0.5 * s[2] * (ef.C0 + ef.C2 * c2 + ef.C4 * c2 * c2)) + c;
  };
  double worst = 0, right_handed = 1e300;
  for (int f = 0; f < 6; ++f)
    for (int a = 0; a <= 32; ++a)
      for (int b = 0; b <= 32; ++b) {
        worst = std::max(worst,
                         (faces[f].point({0.5, a / 32.0, b / 32.0}) - exact(f, a / 32.0, b / 32.0)).norm());
        for (double r : {0.0, 1.0})
          right_handed = std::min(right_handed, faces[f].evaluate({r, a / 32.0, b / 32.0}).dx.determinant());
      }
  EXPECT_LT(worst, 2e-3 * ef.R0);
  EXPECT_GT(right_handed, 0.0);
  // Area and enclosed volume of the mid-surface, summed over the faces (surface integrals, the volume by the
  // divergence theorem about the centre), against the Evans-Fung cell's 134.09 um^2 and 94.09 um^3
  // (docs/geometry.md).
  double area = 0, volume = 0;
  for (const Patch& face : faces) {
    const Patch mid = isoparametric(face, 0, 0.5);
    std::vector<QuadraturePoint> qp;
    for (int e = 0; e < mid.n_elements(); ++e) {
      element_quadrature(mid, mid.element_multi_index(e), default_gauss(mid, 2), qp);
      for (const QuadraturePoint& q : qp) {
        const MapValues m = mid.evaluate(q.xi, 1);
        const Vec3 n = m.dx.col(0).cross(m.dx.col(1));
        area += q.weight * n.norm(), volume += q.weight * (m.x - c).dot(n) / 3;
      }
    }
  }
  // No slivers: the shortest element edge of the mid-surface against the longest, over the six faces (the
  // polar shell's is 0: its poles are element edges of length 0).
  double shortest = 1e300, longest = 0;
  for (const Patch& face : faces) {
    const std::vector<double> u = face.knots(1).breakpoints(), v = face.knots(2).breakpoints();
    for (std::size_t a = 0; a < u.size(); ++a)
      for (std::size_t b = 0; b < v.size(); ++b) {
        const Vec3 x = face.point({0.5, u[a], v[b]});
        std::vector<double> edges;
        if (a + 1 < u.size()) edges.push_back((face.point({0.5, u[a + 1], v[b]}) - x).norm());
        if (b + 1 < v.size()) edges.push_back((face.point({0.5, u[a], v[b + 1]}) - x).norm());
        for (double e : edges) shortest = std::min(shortest, e), longest = std::max(longest, e);
      }
  }
  std::printf("interpolation %.3e R0; area %.4f um^2, volume %.4f um^3; edges %.4f-%.4f um (ratio %.3f)\n",
              worst / ef.R0, area * 1e8, volume * 1e12, shortest * 1e4, longest * 1e4, shortest / longest);
  // Measured at 8 elements a face: 8.3e-4 R0 between the Greville points; 134.082 um^2 and 94.099 um^3; edges
  // 0.30-0.80 um.
  EXPECT_NEAR(area * 1e8, 134.09, 1e-3 * 134.09);
  EXPECT_NEAR(volume * 1e12, 94.09, 1e-3 * 94.09);
  EXPECT_GT(shortest / longest, 0.3);
}

TEST(Builders, MidSurfaceIsTheShellsMiddleExactly) {
  // A face of the cell's shell, quadratic and cubic: the mid-surface patch equals the shell at the middle of
  // direction 0 wherever it is evaluated, its normal towards increasing xi_0 (outward).
  const double h = 3.1623e-5;
  for (int degree : {2, 3}) {
    const Patch face = biconcave_rbc_3d_faces(h, 6, degree)[4];
    const Patch mid = mid_surface(face);
    ASSERT_EQ(mid.param_dim(), 2);
    ASSERT_EQ(mid.n_control(), face.n_control(1) * face.n_control(2));
    double worst = 0;
    for (double s : {0.0, 0.13, 0.5, 0.71, 1.0})
      for (double t : {0.0, 0.29, 0.5, 0.93, 1.0}) {
        worst = std::max(worst, (mid.point({s, t, 0}) - face.point({0.5, s, t})).norm() / h);
        const MapValues m = mid.evaluate({s, t, 0}, 1), f = face.evaluate({0.5, s, t}, 1);
        const Vec3 n = m.dx.col(0).cross(m.dx.col(1)).normalized();
        EXPECT_GT(n.dot(f.dx.col(0)), 0) << "the normal points to increasing xi_0";
      }
    EXPECT_LT(worst, 1e-12) << "degree " << degree;
  }
  EXPECT_THROW(mid_surface(mid_surface(biconcave_rbc_3d_faces(h, 6, 2)[0])), std::invalid_argument);
}

TEST(Builders, NucleusMeshOfThePaper) {
  const Patch nucleus = bulky_ellipse(2e-4, 2e-4, 40, 192, 2);  // CTC inclusion, paper Sec. 4.4
  EXPECT_EQ(nucleus.n_elements(0), 40);
  EXPECT_EQ(nucleus.n_elements(1), 192);
  EXPECT_NEAR(nucleus.point({1.0, 0.37, 0}).norm(), 2e-4, 1e-17);
  EXPECT_NEAR(nucleus.point({0.25, 0.37, 0}).norm(), 0.5e-4, 1e-17);
}

TEST(Builders, NarrowingChannelWallsFollowTheProfile) {
  const NarrowingChannel ch;
  auto wall_error = [&](int nx, int p) {
    const Patch channel = narrowing_channel(ch, nx, 8, p);
    double worst = 0;
    for (int s = 0; s < 1000; ++s) {
      const double u = (s + 0.5) / 1000;
      const Vec3 top = channel.point({u, 1.0, 0}), bottom = channel.point({u, 0.0, 0});
      EXPECT_NEAR(top[0], u * ch.length, 1e-17);
      EXPECT_NEAR(top[1], -bottom[1], 1e-17);  // symmetric
      worst = std::max(worst, std::abs(top[1] - (0.5 * ch.height - ch.wall_offset(top[0]))));
    }
    return worst;
  };
  // Converges under refinement at about the optimal rate p + 1 of an L2 projection.
  for (int p : {2, 3}) {
    const double e1 = wall_error(96, p), e2 = wall_error(192, p);
    EXPECT_GT(std::log2(e1 / e2), p + 0.5) << "p=" << p << " errors " << e1 << " " << e2;
  }
  EXPECT_LT(wall_error(384, 3), 1e-4 * ch.height);  // the paper's channel resolution
  // The throat is narrower than the CTC's diameter.
  EXPECT_LT(ch.throat_height, 2 * 0.0005);
}

TEST(Builders, InvalidArgumentsAreNamed) {
  expect_invalid([] { hollow_ellipse(2e-4, 1e-4, 5e-7, 10, 2); }, "n_angular");
  expect_invalid([] { hollow_ellipse(2e-4, 1e-4, 3e-4, 8, 2); }, "h");
  expect_invalid([] { hollow_ellipse(-2e-4, 1e-4, 5e-7, 8, 2); }, "a = -0.0002");
  expect_invalid([] { hollow_ellipse(2e-4, 1e-4, 5e-7, 8, 1); }, "degree");
  expect_invalid([] { rectangle(1, 1, 0, 4, 2); }, "nx");
  expect_invalid([] { hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 3, 8, 2); }, "n_polar");
  NarrowingChannel ch;
  ch.throat_height = 0.003;
  expect_invalid([&] { narrowing_channel(ch, 32, 8, 2); }, "throat_height");
  expect_invalid([] { biconcave_rbc(5e-7, 64, 2, Vec3::Zero(), 0.0, -1.0); }, "area");
  expect_invalid([] { biconcave_rbc_3d(1e-4, 16, 32, 2); }, "h = 0.0001");  // thicker than the dimple
  expect_invalid([] { biconcave_rbc_3d(3e-5, 15, 32, 2); }, "n_polar");
  expect_invalid([] { biconcave_rbc_3d(3e-5, 16, 30, 2); }, "n_azimuth");
  expect_invalid([] { biconcave_rbc_3d_faces(1e-4, 8, 2); }, "h = 0.0001");
  expect_invalid([] { biconcave_rbc_3d_faces(3e-5, 0, 2); }, "n_face");
  expect_invalid([] { biconcave_rbc_3d_faces(3e-5, 8, 1); }, "degree");
}
