#pragma once
// Hyperelastic materials of the immersed solids, as plain functions of the deformation gradient: swappable
// without touching the solid solver, the fluid or the coupling.
#include <memory>
#include <string>

#include <Eigen/Dense>

namespace cellfsi::solid {

using Mat3 = Eigen::Matrix3d;

class Material {
 public:
  virtual ~Material() = default;
  /// Second Piola-Kirchhoff stress S(F) in dimension dim (2 or 3; F's unused rows/columns are ignored and the
  /// result's are zero). Units: those of the material constants (dyn/cm^2 in CGS).
  virtual Mat3 second_piola(const Mat3& F, int dim) const = 0;
  virtual std::string name() const = 0;
  /// Shear modulus of the linearised material at the reference state (for the coupling's approximate
  /// tangent).
  virtual double tangent_shear_modulus() const = 0;
};

/// The paper's material, Eq. (20): S = G J^{-2/d} (I - (1/d) tr(C) C^{-1}), J = det F, C = F^T F (the right
/// Cauchy-Green tensor; the paper writes F F^T, which cannot be paired with a second Piola-Kirchhoff stress).
/// It is the deviatoric part of an incompressible neo-Hookean solid: the pressure comes from the fluid (paper
/// Eq. (6)).
class DeviatoricNeoHookean final : public Material {
 public:
  explicit DeviatoricNeoHookean(double shear_modulus);
  Mat3 second_piola(const Mat3& F, int dim) const override;
  std::string name() const override { return "deviatoric_neo_hookean"; }
  double tangent_shear_modulus() const override { return G_; }
  double shear_modulus() const { return G_; }

 private:
  double G_;
};

}  // namespace cellfsi::solid
