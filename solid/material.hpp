#pragma once
// Hyperelastic materials of the immersed solids, as plain functions of the deformation gradient: swappable
// without touching the solid solver, the fluid or the coupling. Each law is the deviatoric (isochoric) part
// of an incompressible solid: the pressure comes from the fluid (paper Eq. (6)). The laws, their constants
// and the tests against the exact uniaxial-stretch answers: docs/materials.md.
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
  /// Strain energy per unit reference volume W(F), of which the stress is the derivative: S = 2 dW/dC.
  virtual double strain_energy(const Mat3& F, int dim) const = 0;
  virtual std::string name() const = 0;
  /// Shear modulus of the linearised material at the reference state (for the coupling's approximate
  /// tangent). Every law here has the same one, G: laws given the same G agree at small strains.
  virtual double tangent_shear_modulus() const = 0;
};

/// The paper's material, Eq. (20): S = G J^{-2/d} (I - (1/d) tr(C) C^{-1}), J = det F, C = F^T F (the right
/// Cauchy-Green tensor; the paper writes F F^T, which cannot be paired with a second Piola-Kirchhoff stress).
/// It is the deviatoric part of an incompressible neo-Hookean solid: the pressure comes from the fluid (paper
/// Eq. (6)). W = G/2 (I1b - d), I1b = J^{-2/d} tr C.
class DeviatoricNeoHookean final : public Material {
 public:
  explicit DeviatoricNeoHookean(double shear_modulus);
  Mat3 second_piola(const Mat3& F, int dim) const override;
  double strain_energy(const Mat3& F, int dim) const override;
  std::string name() const override { return "deviatoric_neo_hookean"; }
  double tangent_shear_modulus() const override { return G_; }
  double shear_modulus() const { return G_; }

 private:
  double G_;
};

/// Mooney-Rivlin, deviatoric: W = G/2 [(1 - a) (I1b - 3) + a (I2b - 3)], I2b = J^{-4/3} (tr(C)^2 -
/// tr(C^2))/2, a = `fraction` of the I2 term in [0, 1] (C10 = (1 - a) G/2, C01 = a G/2; a = 0 is the
/// neo-Hookean law). Its small-strain shear modulus is G for every a. In 2D (plane strain of an
/// incompressible solid) I2 = I1, so the law is the neo-Hookean one whatever a: there it returns
/// DeviatoricNeoHookean's stress.
class DeviatoricMooneyRivlin final : public Material {
 public:
  DeviatoricMooneyRivlin(double shear_modulus, double fraction);
  Mat3 second_piola(const Mat3& F, int dim) const override;
  double strain_energy(const Mat3& F, int dim) const override;
  std::string name() const override { return "deviatoric_mooney_rivlin"; }
  double tangent_shear_modulus() const override { return G_; }
  double fraction() const { return a_; }

 private:
  double G_, a_;
  DeviatoricNeoHookean neo_hookean_;
};

/// Strain hardening (the form Mills et al. 2004 fitted to red blood cells stretched by optical tweezers; a
/// Yeoh law): W = G/2 (I1b - d) + C3 (I1b - d)^3, C3 = `c3_ratio` G (their C3 = G/30). Then
/// S = (1 + 6 (C3/G) (I1b - d)^2) S_neo-Hookean: the neo-Hookean law at small strains, stiffer at large ones.
/// In 2D, I1b - 2 is I1 - 3 of the incompressible plane-strain solid.
class DeviatoricStrainHardening final : public Material {
 public:
  DeviatoricStrainHardening(double shear_modulus, double c3_ratio);
  Mat3 second_piola(const Mat3& F, int dim) const override;
  double strain_energy(const Mat3& F, int dim) const override;
  std::string name() const override { return "deviatoric_strain_hardening"; }
  double tangent_shear_modulus() const override { return G_; }
  double c3_ratio() const { return r_; }

 private:
  double G_, r_;
  DeviatoricNeoHookean neo_hookean_;
};

}  // namespace cellfsi::solid
