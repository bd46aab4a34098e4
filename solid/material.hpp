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
/// A symmetric fourth-order tensor in Voigt form, components ordered 11, 22, 33, 23, 13, 12.
using Voigt6 = Eigen::Matrix<double, 6, 6>;

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
  /// The spatial tangent c of the Kirchhoff stress tau = F S F^T (c_ijkl = F_iI F_jJ F_kK F_lL C_IJKL, C =
  /// 2 dS/dC): a variation dF = L F changes tau by L tau + tau L^T + c : sym(L). In Voigt form, c : D =
  /// c_voigt [D11, D22, D33, 2 D23, 2 D13, 2 D12] (components 11, 22, 33, 23, 13, 12); in 2D only the
  /// in-plane rows and columns (11, 22, 12) are nonzero. This default differentiates second_piola by
  /// central differences (12 evaluations, relative error about 1e-9); a law with an exact expression
  /// overrides it. The coupling's consistent tangent (coupling::SolidTangent) uses it.
  virtual Voigt6 spatial_tangent(const Mat3& F, int dim) const;
  /// True for a law of a membrane's surface (SkalakMembrane), whose energy depends on the membrane's
  /// reference normal N. Such a law is given F in a reference frame whose third axis is N: F Q, with Q's
  /// columns an orthonormal T1, T2, N, which the solid computes at each of its points (NurbsSolid). The
  /// Kirchhoff stress F S F^T and the spatial tangent are the same in any reference frame, so the result
  /// needs no turning back. The isotropic laws do not depend on the frame and are given F as it is.
  virtual bool membrane_surface_law() const { return false; }
  /// The refusal every law makes before it evaluates (an inverted element: det of F's dim x dim block not
  /// > 0, NaN included), alone: for a point whose stress is not needed on this rank.
  static void check_deformation(const Mat3& F, int dim);
};

/// The Kirchhoff stress tau = F S F^T of a material.
inline Mat3 kirchhoff_stress(const Material& m, const Mat3& F, int dim) {
  return F * m.second_piola(F, dim) * F.transpose();
}

/// A symmetric tensor's Voigt components 11, 22, 33, 23, 13, 12 (no factor 2: a stress, not a strain).
Eigen::Matrix<double, 6, 1> voigt(const Mat3& t);

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
  /// Exact: c = (2/d) G J^{-2/d} tr(b) (I - (1/d) 1 x 1) - (2/d) (tau x 1 + 1 x tau), b = F F^T.
  Voigt6 spatial_tangent(const Mat3& F, int dim) const override;
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
  /// Exact: with f = 1 + 6 (C3/G) e^2, e = I1b - d: c = f c_nH + 24 (C3/G) e / G tau_nH x tau_nH.
  Voigt6 spatial_tangent(const Mat3& F, int dim) const override;
  double c3_ratio() const { return r_; }

 private:
  double G_, r_;
  DeviatoricNeoHookean neo_hookean_;
};

/// Skalak, Tozeren, Zarda & Chien's (1973) surface law, written for this code's thick membrane (3D only; F in
/// the membrane's frame, axis 3 along the reference normal, membrane_surface_law()):
///   W = G/4 (I1s^2 + 2 I1s - 2 I2s + C I2s^2) + G/2 (C13^2 + C23^2),
/// I1s = C11 + C22 - 2 = lambda1^2 + lambda2^2 - 2 and I2s = C11 C22 - C12^2 - 1 = lambda1^2 lambda2^2 - 1
/// the in-plane invariants. W is Skalak's W_s / h per reference volume: G h is his surface shear modulus G_s
/// and G h (1 + 2C) the area-dilation modulus, C = `area_ratio`. The energy leaves the thickness direction
/// free (the fluid's incompressibility ties it to the area); the second term holds the transverse shear,
/// which Skalak's surface energy leaves free and without which a thick shell would lose its bending stiffness
/// to layers sliding over one another (docs/materials.md). In the frame, with cof(C_s) = [C22, -C12; -C12,
/// C11]:
///   S_ab = G [(I1s + 1) delta_ab + (C I2s - 1) cof(C_s)_ab] (a, b in-plane), S_a3 = G C_a3, S_33 = 0.
class SkalakMembrane final : public Material {
 public:
  SkalakMembrane(double shear_modulus, double area_ratio);
  /// dim must be 3 (a surface law has no meaning in plane strain: docs/materials.md).
  Mat3 second_piola(const Mat3& F, int dim) const override;
  double strain_energy(const Mat3& F, int dim) const override;
  std::string name() const override { return "skalak_membrane"; }
  double tangent_shear_modulus() const override { return G_; }
  bool membrane_surface_law() const override { return true; }
  double area_ratio() const { return C_; }

 private:
  double G_, C_;
};

/// Mills et al.'s strain hardening with an area term, a surface law for this code's thick membrane (3D only;
/// F in the membrane's frame as for SkalakMembrane):
///   W = G (beta/2 + r beta^3) + G (1 + 2C)/8 I2s^2 + G/2 (C13^2 + C23^2),
/// beta = (C11 + C22) / J_s - 2 = lambda1/lambda2 + lambda2/lambda1 - 2 the in-plane change of shape (zero
/// for any change of area alone), J_s = sqrt(C11 C22 - C12^2) = lambda1 lambda2 the area stretch, I2s = J_s^2
/// - 1, r = `c3_ratio` (Mills': 1/30) and C = `area_ratio`. Where the area is kept (J_s = 1) beta is I1b - 3
/// of the incompressible sheet, so the shape term is Mills' Yeoh law on the same stretches; the area term
/// gives the area-dilation modulus G h (1 + 2C) of Skalak's law with the same C, so at small strains the two
/// laws are the same (shear G h, area G h (1 + 2C), bending G (1 + C) h^3 / 6) and they part only at large
/// ones. With cof(C_s) = [C22, -C12; -C12, C11] = J_s^2 C_s^{-1}:
///   S_ab = G (1 + 6 r beta^2) (delta_ab - (tr C_s / 2) C_s^{-1}_ab) / J_s + G (1 + 2C)/2 I2s cof(C_s)_ab,
///   S_a3 = G C_a3, S_33 = 0.
class StrainHardeningMembrane final : public Material {
 public:
  StrainHardeningMembrane(double shear_modulus, double c3_ratio, double area_ratio);
  /// dim must be 3, as for SkalakMembrane.
  Mat3 second_piola(const Mat3& F, int dim) const override;
  double strain_energy(const Mat3& F, int dim) const override;
  std::string name() const override { return "strain_hardening_membrane"; }
  double tangent_shear_modulus() const override { return G_; }
  bool membrane_surface_law() const override { return true; }
  double c3_ratio() const { return r_; }
  double area_ratio() const { return C_; }

 private:
  double G_, r_, C_;
};

}  // namespace cellfsi::solid
