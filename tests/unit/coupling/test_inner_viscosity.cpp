// The inside of a membrane (coupling/inner_viscosity.hpp): the indicator against exact ellipses and
// ellipsoids, the viscosity field's control values, how sharp nu^h is across a membrane, and the checks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>

#include "coupling/inner_viscosity.hpp"
#include "geometry/builders.hpp"

using namespace cellfsi;
using geometry::Vec3;

namespace {

// nu^h at a point of the unit-parameter rectangle [0, lx] x [0, ly] from the control values mu.
double field_at(const geometry::Patch& box, const std::vector<double>& mu, double lx, double ly,
                const Vec3& x) {
  geometry::BasisValues bv;
  box.basis({x[0] / lx, x[1] / ly, 0}, 0, bv);
  double v = 0;
  for (int k = 0; k < bv.n; ++k) v += bv.value[k] * mu[bv.index[k]];
  return v;
}

struct Count {
  int checked = 0, inside = 0;
};

// inside_membrane against the exact mid-surface, level(x) < 1 inside, at the points farther than `band` (in
// level) from it: closer ones are within the sampled polygon's or triangles' chord error.
template <class Level>
Count compare_with_exact(const geometry::Patch& m, const std::vector<Vec3>& pts, double band, Level&& level) {
  const std::vector<char> in = coupling::inside_membrane(m, pts);
  Count n;
  for (size_t i = 0; i < pts.size(); ++i) {
    const double l = level(pts[i]);
    if (std::abs(l - 1) < band) continue;
    ++n.checked;
    n.inside += l < 1;
    EXPECT_EQ(in[i] != 0, l < 1) << "point " << i << " at level " << l;
  }
  return n;
}

}  // namespace

TEST(InnerViscosity, InsideAHollowEllipseIsInsideItsMidLine) {
  const double a = 2e-4, b = 1e-4, h = 5e-6, angle = 0.4;
  const Vec3 c(1.2e-3, 6e-4, 0);
  const geometry::Patch m = geometry::hollow_ellipse(a, b, h, 32, 2, c, angle);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> ux(c[0] - 1.5 * a, c[0] + 1.5 * a),
      uy(c[1] - 1.5 * a, c[1] + 1.5 * a);
  std::vector<Vec3> pts;
  for (int i = 0; i < 4000; ++i) pts.emplace_back(ux(rng), uy(rng), 0);
  const Count n = compare_with_exact(m, pts, 0.01, [&](const Vec3& x) {
    const Vec3 d = x - c;
    const double xr = std::cos(angle) * d[0] + std::sin(angle) * d[1];
    const double yr = -std::sin(angle) * d[0] + std::cos(angle) * d[1];
    return std::sqrt(xr * xr / (a * a) + yr * yr / (b * b));
  });
  std::printf("  hollow ellipse: %d of %d points inside, all as the exact mid-line says\n", n.inside,
              n.checked);
  EXPECT_GT(n.inside, 500);
}

TEST(InnerViscosity, InsideAHollowEllipsoidIsInsideItsMidSurface) {
  const double a = 3e-4, b = 2e-4, cz = 1.5e-4, h = 5e-6;
  const Vec3 c(5e-4, 5e-4, 5e-4);
  const geometry::Patch m = geometry::hollow_ellipsoid(a, b, cz, h, 8, 16, 2, c);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.3, 1.3);
  std::vector<Vec3> pts;
  for (int i = 0; i < 600; ++i) pts.push_back(c + Vec3(a * u(rng), b * u(rng), cz * u(rng)));
  const Count n = compare_with_exact(m, pts, 0.02, [&](const Vec3& x) {
    const Vec3 d = x - c;
    return std::sqrt(d[0] * d[0] / (a * a) + d[1] * d[1] / (b * b) + d[2] * d[2] / (cz * cz));
  });
  std::printf("  hollow ellipsoid: %d of %d points inside, all as the exact mid-surface says\n", n.inside,
              n.checked);
  EXPECT_GT(n.inside, 100);
}

// The red cell's six faces (geometry::biconcave_rbc_3d_faces) together enclose what the cell does: points a
// tenth inside and outside the exact surface, along rays from the centre in every direction (the dimples
// included), are inside and outside.
TEST(InnerViscosity, InsideTheSixFacesOfARedCellIsInsideTheCell) {
  const geometry::EvansFung ef;
  const Vec3 c(6e-4, 6e-4, 6e-4);
  const std::vector<geometry::Patch> faces = geometry::biconcave_rbc_3d_faces(3.1623e-5, 8, 2, c);
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Vec3> in, out;
  for (int i = 0; i < 300; ++i) {
    const Vec3 s = Vec3(g(rng), g(rng), g(rng)).normalized();
    const double c2 = s[0] * s[0] + s[1] * s[1];
    const Vec3 x(ef.R0 * s[0], ef.R0 * s[1], 0.5 * s[2] * (ef.C0 + ef.C2 * c2 + ef.C4 * c2 * c2));
    in.push_back(c + 0.9 * x), out.push_back(c + 1.1 * x);
  }
  in.push_back(c);
  const std::vector<char> a = coupling::inside_membrane(faces, in), b = coupling::inside_membrane(faces, out);
  EXPECT_EQ(std::count(a.begin(), a.end(), 1), static_cast<long>(in.size()));
  EXPECT_EQ(std::count(b.begin(), b.end(), 1), 0);
  EXPECT_THROW(coupling::inside_membrane(std::vector<geometry::Patch>{}, in), std::invalid_argument);
}

// The field's control values take mu_in at the control points inside; nu^h is mu_in at the centre and mu_out
// far away, and goes from one to the other over p elements across the mid-line (a step in the control values
// of a C^{p-1} spline), measured between 10 % and 90 % of the jump.
TEST(InnerViscosity, FieldIsTheInnerViscosityInsideAndSharpToAboutDegreeElements) {
  const double lx = 0.0024, ly = 0.0012, r = 3e-4, mu_out = 0.012, mu_in = 5 * mu_out;
  const Vec3 c(lx / 2, ly / 2, 0);
  const geometry::Patch m = geometry::hollow_ellipse(r, r, 5e-7, 32, 2, c);
  for (int p : {2, 3}) {
    for (int nx : {96, 192}) {
      const geometry::Patch box = geometry::rectangle(lx, ly, nx, nx / 2, p, {true, false});
      const std::vector<double> mu = coupling::viscosity_values(box, {{&m, mu_in}}, mu_out);
      EXPECT_DOUBLE_EQ(field_at(box, mu, lx, ly, c), mu_in);
      EXPECT_DOUBLE_EQ(field_at(box, mu, lx, ly, Vec3(0.1 * lx, 0.1 * ly, 0)), mu_out);
      const double hx = lx / nx;
      double x10 = NAN, x90 = NAN;  // along y = centre, from outside in
      for (double x = c[0] - 2 * r; x <= c[0]; x += hx / 200) {
        const double f = (field_at(box, mu, lx, ly, Vec3(x, c[1], 0)) - mu_out) / (mu_in - mu_out);
        if (std::isnan(x10) && f >= 0.1) x10 = x;
        if (std::isnan(x90) && f >= 0.9) x90 = x;
      }
      const double width = (x90 - x10) / hx, centre = (0.5 * (x10 + x90) - (c[0] - r)) / hx;
      std::printf(
          "  p=%d, %d x %d: nu^h from 10%% to 90%% of the jump over %.2f elements, centred %.2f elements"
          " from the mid-line\n",
          p, nx, nx / 2, width, centre);
      EXPECT_LT(width, 0.5 * p + 0.5);  // measured 1.1 (p = 2) and 1.3 (p = 3)
      EXPECT_LT(std::abs(centre), 0.5 * p + 1);
    }
  }
}

TEST(InnerViscosity, RefusesABulkyBodyAndANonPositiveViscosity) {
  EXPECT_NO_THROW(coupling::check_inner_viscosity("membrane", true, 0.06));
  for (double bad : {0.0, -1.0, double(NAN), double(INFINITY)})
    EXPECT_THROW(coupling::check_inner_viscosity("membrane", true, bad), std::invalid_argument) << bad;
  try {
    coupling::check_inner_viscosity("nucleus", false, 0.06);
    ADD_FAILURE() << "a bulky body took an inner viscosity";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("only a membrane"), std::string::npos) << e.what();
  }
}
