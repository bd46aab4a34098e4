// The body made of patches (solid/composite_solid.hpp): the red cell's six faces stepped in a prescribed
// flow, without a fluid.
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "../../support/step_in_flow.hpp"
#include "geometry/builders.hpp"
#include "solid/composite_solid.hpp"
#include "solid/material.hpp"

using namespace cellfsi;
using solid::Mat3;
using solid::Vec3;

namespace {

std::vector<std::unique_ptr<solid::NurbsSolid>> face_solids(const std::vector<geometry::Patch>& faces) {
  std::vector<std::unique_ptr<solid::NurbsSolid>> parts;
  for (std::size_t k = 0; k < faces.size(); ++k)
    parts.push_back(std::make_unique<solid::NurbsSolid>(
        "rbc", faces[k], std::make_shared<solid::DeviatoricNeoHookean>(189.74), 1.1));
  return parts;
}

}  // namespace

// In a simple shear the exact motion is x = X + gammadot t (Y - c_y) e_x, a displacement linear in X and in
// t, which the collocation and the time integration reproduce to round-off: every point of every face follows
// it, the faces stay joined along the cube's edges, and each part moves as it does alone.
TEST(CompositeSolid, SixFacesFollowASimpleShearAsOneBodyAndStayJoined) {
  const geometry::EvansFung ef;
  const Vec3 c(6e-4, 6e-4, 6e-4);
  const std::vector<geometry::Patch> faces = geometry::biconcave_rbc_3d_faces(3.1623e-5, 4, 2, c);
  solid::CompositeSolid cell("rbc", face_solids(faces));
  solid::NurbsSolid alone("rbc", faces[2], std::make_shared<solid::DeviatoricNeoHookean>(189.74), 1.1);
  ASSERT_EQ(cell.n_parts(), 6);
  int points = 0, quadrature = 0, control = 0;
  for (int k = 0; k < 6; ++k)
    points += cell.part(k).n_points(), quadrature += cell.part(k).n_quadrature_points(),
        control += cell.part(k).n_control();
  EXPECT_EQ(static_cast<int>(cell.collocation_points().size()), points);
  EXPECT_EQ(static_cast<int>(cell.quadrature_data(1.025, false).size()), quadrature);
  EXPECT_EQ(cell.n_control(), control);
  EXPECT_TRUE(cell.is_membrane());
  EXPECT_THROW(cell.reference_patch(), std::logic_error);

  const double gammadot = 70, dt = 1e-3;
  Mat3 L = Mat3::Zero();
  L(0, 1) = gammadot;
  std::vector<Vec3> rate;
  for (const Vec3& X : cell.collocation_points()) rate.push_back(L * (X - c));
  cell.set_rate(rate);
  std::vector<Vec3> rate_alone;
  for (const Vec3& X : alone.collocation_points()) rate_alone.push_back(L * (X - c));
  alone.set_rate(rate_alone);
  const int steps = 20;
  for (int n = 0; n < steps; ++n) test::step_in_flow(cell, L, c, dt), test::step_in_flow(alone, L, c, dt);

  // Every point of every face where the exact motion puts it, and the part as it moves alone.
  const double t = steps * dt;
  const std::vector<geometry::Patch> now = cell.current_patches();
  double worst = 0;
  for (int k = 0; k < 6; ++k)
    for (double r : {0.0, 0.5, 1.0})
      for (int a = 0; a <= 8; ++a)
        for (int b = 0; b <= 8; ++b) {
          const geometry::Param xi{r, a / 8.0, b / 8.0};
          const Vec3 X = faces[k].point(xi);
          worst =
              std::max(worst, (now[k].point(xi) - (X + gammadot * t * (X[1] - c[1]) * Vec3::UnitX())).norm());
        }
  EXPECT_LT(worst, 1e-12 * ef.R0);
  double apart = 0;
  const geometry::Patch alone_now = alone.current_patch();
  for (const Vec3& x : alone_now.control_points()) {
    double nearest = 1e300;
    for (const Vec3& y : now[2].control_points()) nearest = std::min(nearest, (x - y).norm());
    apart = std::max(apart, nearest);
  }
  EXPECT_EQ(apart, 0.0) << "the part stepped inside the body and alone";

  // The state round-trips; the control increments and basis gradients are the parts' in turn.
  const std::vector<double> state = cell.state();
  cell.set_state(state);
  EXPECT_EQ(cell.state(), state);
  EXPECT_THROW(cell.set_state(std::vector<double>(state.size() - 1)), std::invalid_argument);
  const std::vector<Vec3> dv(static_cast<std::size_t>(points), Vec3(1, 2, 3));
  Eigen::MatrixXd dc, dc_part;
  ASSERT_TRUE(cell.control_increment(dv, dc));
  int row = 0;
  for (int k = 0; k < 6; ++k) {
    ASSERT_TRUE(cell.part(k).control_increment(
        std::vector<Vec3>(static_cast<std::size_t>(cell.part(k).n_points()), Vec3(1, 2, 3)), dc_part));
    EXPECT_EQ((dc.middleRows(row, dc_part.rows()) - dc_part).norm(), 0.0) << "part " << k;
    row += static_cast<int>(dc_part.rows());
  }
  std::vector<int> begin, unknown;
  std::vector<double> grad;
  std::vector<char> wanted(static_cast<std::size_t>(quadrature), 0);
  for (std::size_t q = 0; q < wanted.size(); q += 7) wanted[q] = 1;
  ASSERT_TRUE(cell.basis_gradients(begin, unknown, grad, &wanted));
  EXPECT_EQ(begin.size(), static_cast<std::size_t>((quadrature + 6) / 7 + 1));
  EXPECT_EQ(static_cast<int>(unknown.size()), begin.back());
  EXPECT_EQ(grad.size(), 3 * unknown.size());
  EXPECT_LT(*std::max_element(unknown.begin(), unknown.end()), control);
  EXPECT_GE(unknown.back(), control - cell.part(5).n_control()) << "the last part's unknowns come last";
  // Each part's run of the lists is the part's own (written in place), its unknowns after the earlier parts'.
  std::size_t point = 0, entry = 0;
  int first_unknown = 0, first_point = 0;
  for (int k = 0; k < 6; ++k) {
    const int n_q = cell.part(k).n_quadrature_points();
    const std::vector<char> part_wanted(wanted.begin() + first_point, wanted.begin() + first_point + n_q);
    std::vector<int> b, u;
    std::vector<double> g;
    ASSERT_TRUE(cell.part(k).basis_gradients(b, u, g, &part_wanted));
    for (std::size_t i = 1; i < b.size(); ++i)
      ASSERT_EQ(begin[point + i] - begin[point], b[i]) << "part " << k << ", listed point " << i;
    double worst = 0, largest = 0;
    for (std::size_t i = 0; i < u.size(); ++i) {
      ASSERT_EQ(unknown[entry + i], u[i] + first_unknown) << "part " << k;
      for (int c = 0; c < 3; ++c) {
        worst = std::max(worst, std::abs(grad[3 * (entry + i) + c] - g[3 * i + c]));
        largest = std::max(largest, std::abs(g[3 * i + c]));
      }
    }
    EXPECT_LE(worst, 1e-14 * largest) << "part " << k;  // (the same arithmetic: equal to round-off)
    point += b.size() - 1, entry += u.size();
    first_unknown += cell.part(k).n_control(), first_point += n_q;
  }
  EXPECT_EQ(point + 1, begin.size());
  EXPECT_EQ(entry, unknown.size());
  std::vector<std::size_t> visited;
  std::vector<solid::QuadratureData> q;
  cell.quadrature_data(
      1.025, false, [&](std::size_t i, const Vec3&) { return visited.push_back(i), true; }, q);
  ASSERT_EQ(visited.size(), static_cast<std::size_t>(quadrature));
  for (std::size_t i = 0; i < visited.size(); ++i) ASSERT_EQ(visited[i], i);
  // With `only`, the points not flagged are not evaluated and keep what they held (another rank's points).
  std::vector<solid::QuadratureData> some = q;
  for (std::size_t i = 0; i < some.size(); ++i) some[i].weight = -1.0;
  visited.clear();
  cell.quadrature_data(
      1.025, false, [&](std::size_t i, const Vec3&) { return visited.push_back(i), true; }, some, &wanted);
  EXPECT_EQ(visited.size(), static_cast<std::size_t>((quadrature + 6) / 7));
  for (std::size_t i = 0; i < some.size(); ++i) {
    ASSERT_EQ(some[i].weight < 0, !wanted[i]) << "point " << i;
    if (wanted[i]) {
      ASSERT_LE((some[i].x - q[i].x).norm(), 1e-14 * q[i].x.norm()) << "point " << i;
    }
  }
}
