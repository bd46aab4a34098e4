// The scene's body builder (apps/scene.hpp): the options that place and size a body do what they say.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "apps/scene.hpp"
#include "geometry/measures.hpp"

using namespace cellfsi;
using geometry::Vec3;

namespace {

constexpr double kPi = std::numbers::pi;

app::SceneSettings box_scene() {
  app::SceneSettings s;
  s.dim = 3;
  s.domain = "box";
  s.size = {0.0012, 0.0012, 0.0012};
  s.periodic = {true, false, true};
  s.elements = {8, 8, 8};
  s.degree = 2;
  return s;
}

/// The paper's 3D ellipsoid (Sec. 3.6, 3e-4 x 2e-4 x 2e-4 cm) at the centre of box_scene().
app::BodySettings paper_ellipsoid(const std::string& shape, std::array<int, 3> elements) {
  app::BodySettings b;
  b.name = "cell";
  b.shape = shape;
  b.semi_axes = {3e-4, 2e-4, 2e-4};
  b.center = Vec3(6e-4, 6e-4, 6e-4);
  b.elements = elements;
  return b;
}

}  // namespace

TEST(SceneBody, RotatedEllipsoidKeepsItsVolumeAndTurnsItsAxes) {
  // The paper's 3D ellipsoid (Sec. 3.6, 3e-4 x 2e-4 x 2e-4 cm) turned by 90 deg about z and by 30 deg about a
  // tilted axis: the volume stays 4/3 pi a b c (to the quadrature), the long axis is the rotated x axis.
  const app::SceneSettings s = box_scene();
  app::BodySettings b = paper_ellipsoid("ellipsoid", {2, 8, 16});
  const double exact = 4.0 / 3.0 * kPi * 3e-4 * 2e-4 * 2e-4;
  for (const auto& [angle, axis] :
       {std::pair{90.0, Vec3(0, 0, 1)}, std::pair{30.0, Vec3(1, 1, 1).normalized()}}) {
    b.angle_deg = angle;
    b.axis = axis;
    const geometry::Patch p = app::build_body_patch(s, b);
    const geometry::RegionMoments m = geometry::patch_moments(p);
    EXPECT_NEAR(m.measure, exact, 1e-6 * exact) << angle;
    EXPECT_LT((m.centroid - b.center).norm(), 1e-12) << angle;
    const geometry::PrincipalAxes ax = geometry::principal_axes(m, 3);
    const Vec3 expected = Eigen::AngleAxisd(angle * kPi / 180, axis) * Vec3::UnitX();
    EXPECT_NEAR(std::abs(ax.axes.col(0).dot(expected)), 1.0, 1e-9) << angle;
  }
}

TEST(SceneBody, RbcAreaOptionSetsTheEnclosedArea) {
  app::SceneSettings s;
  app::BodySettings b;
  b.name = "rbc";
  b.shape = "rbc";
  b.semi_axes.clear();
  b.center = Vec3(0.0012, 0.0006, 0);
  b.elements = {1, 0, 0};  // automatic around: a multiple of 4 (the builder's rule)
  for (double area : {0.0, 2e-7}) {
    b.area = area;
    const geometry::Patch p = app::build_body_patch(s, b);
    EXPECT_EQ(p.n_elements(1) % 4, 0) << p.n_elements(1);
    const double target = area > 0 ? area : geometry::kRbcArea2d;
    EXPECT_NEAR(geometry::membrane_shape(p, 0).enclosed, target, 1e-3 * target);
  }
}

TEST(SceneBody, RotatedHollowEllipsoidEnclosesItsVolumeWithItsAxes) {
  // The 3D compound capsule's membrane (Sec. 3.6): the region its mid-surface encloses has the volume
  // 4/3 pi a b c and the long axis of the rotated x axis.
  const app::SceneSettings s = box_scene();
  app::BodySettings b = paper_ellipsoid("hollow_ellipsoid", {1, 14, 28});
  b.angle_deg = 90;
  const geometry::Patch p = app::build_body_patch(s, b);
  const geometry::MembraneShape m = geometry::membrane_shape(p, 0);
  const double exact = 4.0 / 3.0 * kPi * 3e-4 * 2e-4 * 2e-4;
  EXPECT_NEAR(m.enclosed, exact, 1e-4 * exact);
  EXPECT_LT((m.moments.centroid - b.center).norm(), 1e-9);
  const geometry::PrincipalAxes ax = geometry::principal_axes(m.moments, 3);
  std::printf("  values %.4e %.4e %.4e, axis 0 = (%.3f %.3f %.3f)\n", ax.values[0], ax.values[1],
              ax.values[2], ax.axes(0, 0), ax.axes(1, 0), ax.axes(2, 0));
  EXPECT_NEAR(std::abs(ax.axes(1, 0)), 1.0, 1e-6);
}

TEST(SceneBody, MaterialOptionChoosesTheLawWithItsConstants) {
  // -solid_NAME_material and its constants reach the law: the same stress as the law built directly, at a 3D
  // stretch where the laws differ.
  app::BodySettings b;
  b.shear_modulus = 40;
  b.mooney_rivlin_fraction = 0.25;
  b.hardening_c3 = 0.2;
  b.area_dilation = 7;
  const solid::Mat3 F = Eigen::Vector3d(1.6, 0.8, 1 / 1.28).asDiagonal();
  const std::vector<std::pair<std::string, std::shared_ptr<const solid::Material>>> laws = {
      {"neo_hookean", std::make_shared<solid::DeviatoricNeoHookean>(40)},
      {"mooney_rivlin", std::make_shared<solid::DeviatoricMooneyRivlin>(40, 0.25)},
      {"strain_hardening", std::make_shared<solid::DeviatoricStrainHardening>(40, 0.2)},
      {"skalak", std::make_shared<solid::SkalakMembrane>(40, 7)}};
  for (const auto& [word, law] : laws) {
    b.material = word;
    const std::shared_ptr<const solid::Material> m = app::make_material(b);
    EXPECT_EQ(m->name(), law->name());
    EXPECT_EQ(m->second_piola(F, 3), law->second_piola(F, 3)) << word;
    EXPECT_EQ(m->tangent_shear_modulus(), 40.0) << word;
  }
  EXPECT_NE(laws[0].second->second_piola(F, 3), laws[1].second->second_piola(F, 3));
  EXPECT_NE(laws[0].second->second_piola(F, 3), laws[2].second->second_piola(F, 3));
  EXPECT_NE(laws[0].second->second_piola(F, 3), laws[3].second->second_piola(F, 3));
  b.material = "hooke";
  EXPECT_THROW(app::make_material(b), std::invalid_argument);
}
