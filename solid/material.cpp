#include "solid/material.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace cellfsi::solid {

namespace {
/// %g: std::to_string's %f printed a huge number with 300 digits and a tiny one as 0.000000.
std::string number_text(double v) {
  char s[32];
  std::snprintf(s, sizeof s, "%g", v);
  return s;
}

/// F's d x d block, the rest the identity (so that det and inverse are the block's; fixed size: this runs at
/// every solid quadrature point in every coupling iteration), refused where the element is inverted; J = det F.
Mat3 deformation_block(const Mat3& F, int d, double& J) {
  Mat3 Fd = Mat3::Identity();
  Fd.topLeftCorner(d, d) = F.topLeftCorner(d, d);
  J = Fd.determinant();
  if (!(J > 0)) throw std::runtime_error("inverted solid element: det F = " + number_text(J) + " <= 0");
  return Fd;
}

/// A material constant's refusal: "WHAT = v is invalid; valid: > 0" (or ">= 0"), also for a value not finite.
void require_constant(double v, bool zero_allowed, const std::string& what) {
  if ((zero_allowed ? v >= 0 : v > 0) && std::isfinite(v)) return;
  throw std::invalid_argument(what + " = " + number_text(v) +
                              " is invalid; valid: " + (zero_allowed ? ">= 0" : "> 0"));
}

}  // namespace

void Material::check_deformation(const Mat3& F, int dim) {
  double J = 0;
  deformation_block(F, dim, J);
}

namespace {

/// The d x d block of a padded 3 x 3 tensor, zero elsewhere.
Mat3 leading_block(const Mat3& m, int d) {
  Mat3 out = Mat3::Zero();
  out.topLeftCorner(d, d) = m.topLeftCorner(d, d);
  return out;
}

/// I1b - d, I1b = J^{-2/d} tr C: zero at rest and under any rotation, >= 0 always (an isochoric C has
/// eigenvalues with product 1, whose mean is at least 1). In 2D it is I1 - 3 of the plane-strain
/// incompressible solid.
double i1_excess(const Mat3& F, int d) {
  double J = 0;
  const Mat3 Fd = deformation_block(F, d, J);
  return std::pow(J, -2.0 / d) * leading_block(Fd.transpose() * Fd, d).trace() - d;
}

// Voigt index pairs in the order 11, 22, 33, 23, 13, 12, and the in-plane ones of 2D.
constexpr int kVoigtPair[6][2] = {{0, 0}, {1, 1}, {2, 2}, {1, 2}, {0, 2}, {0, 1}};
constexpr bool in_plane(int a) { return a == 0 || a == 1 || a == 5; }

/// 1 in Voigt form (over the d x d block).
Eigen::Matrix<double, 6, 1> voigt_identity(int d) {
  Eigen::Matrix<double, 6, 1> one = Eigen::Matrix<double, 6, 1>::Zero();
  for (int i = 0; i < d; ++i) one(i) = 1;
  return one;
}

/// The neo-Hookean spatial tangent (Voigt) and Kirchhoff stress of a deformation F in dimension d.
Voigt6 neo_hookean_tangent(double G, const Mat3& F, int d, Eigen::Matrix<double, 6, 1>* tau_out) {
  double J = 0;
  const Mat3 Fd = deformation_block(F, d, J);
  const Mat3 b = leading_block(Fd * Fd.transpose(), d);
  const double mu = G * std::pow(J, -2.0 / d), tr = b.trace();
  Mat3 tau = mu * b;
  for (int i = 0; i < d; ++i) tau(i, i) -= mu * tr / d;
  const Eigen::Matrix<double, 6, 1> t = voigt(tau), one = voigt_identity(d);
  Voigt6 c = Voigt6::Zero();
  for (int a = 0; a < 6; ++a) {
    if (d == 2 && !in_plane(a)) continue;
    c(a, a) = (2.0 / d) * mu * tr * (a < 3 ? 1.0 : 0.5);  // the symmetric identity acts on 2 D_ij by 1/2
  }
  c -= (2.0 / d) * (mu * tr / d * one * one.transpose() + t * one.transpose() + one * t.transpose());
  if (tau_out) *tau_out = t;
  return c;
}
}  // namespace

Eigen::Matrix<double, 6, 1> voigt(const Mat3& t) {
  Eigen::Matrix<double, 6, 1> v;
  for (int a = 0; a < 6; ++a) v(a) = t(kVoigtPair[a][0], kVoigtPair[a][1]);
  return v;
}

Voigt6 Material::spatial_tangent(const Mat3& F, int dim) const {
  // Column a: c : D for the unit symmetric D of component a (D_ij = D_ji = 1/2 for a shear, so that its
  // 2 D_ij is 1), from tau((I +- h D) F) = tau +- h (D tau + tau D + c : D) + O(h^2).
  const double h = 1e-5;
  const Mat3 tau = kirchhoff_stress(*this, F, dim);
  Voigt6 c = Voigt6::Zero();
  for (int a = 0; a < 6; ++a) {
    if (dim == 2 && !in_plane(a)) continue;
    Mat3 D = Mat3::Zero();
    const int i = kVoigtPair[a][0], j = kVoigtPair[a][1];
    D(i, j) += i == j ? 1.0 : 0.5;
    if (i != j) D(j, i) += 0.5;
    const Mat3 Fp = (Mat3::Identity() + h * D) * F, Fm = (Mat3::Identity() - h * D) * F;
    const Mat3 dtau = (kirchhoff_stress(*this, Fp, dim) - kirchhoff_stress(*this, Fm, dim)) / (2 * h);
    c.col(a) = voigt(dtau - D * tau - tau * D);
  }
  return 0.5 * (c + c.transpose());  // symmetric exactly (a hyperelastic c is), to round-off
}

DeviatoricNeoHookean::DeviatoricNeoHookean(double shear_modulus) : G_(shear_modulus) {
  require_constant(shear_modulus, false, "shear modulus G");
}

Mat3 DeviatoricNeoHookean::second_piola(const Mat3& F, int dim) const {
  const int d = dim;
  double J = 0;
  const Mat3 Fd = deformation_block(F, d, J);
  const Mat3 C = Fd.transpose() * Fd;  // the padding's C_33 = 1 (2D) is left out of the trace and the result
  const double trC = leading_block(C, d).trace();
  return leading_block(G_ * std::pow(J, -2.0 / d) * (Mat3::Identity() - (trC / d) * C.inverse()), d);
}

Voigt6 DeviatoricNeoHookean::spatial_tangent(const Mat3& F, int dim) const {
  return neo_hookean_tangent(G_, F, dim, nullptr);
}

double DeviatoricNeoHookean::strain_energy(const Mat3& F, int dim) const {
  return 0.5 * G_ * i1_excess(F, dim);
}

DeviatoricMooneyRivlin::DeviatoricMooneyRivlin(double shear_modulus, double fraction)
    : G_(shear_modulus), a_(fraction), neo_hookean_(shear_modulus) {
  // a outside [0, 1] makes C10 or C01 negative: the energy then falls along some large deformations.
  if (!(fraction >= 0 && fraction <= 1))
    throw std::invalid_argument("Mooney-Rivlin fraction of the I2 term a = " + number_text(fraction) +
                                " is invalid; valid: 0 ... 1");
}

Mat3 DeviatoricMooneyRivlin::second_piola(const Mat3& F, int dim) const {
  if (dim == 2) return neo_hookean_.second_piola(F, dim);  // plane strain: I2 = I1
  double J = 0;
  const Mat3 Fd = deformation_block(F, 3, J);
  const Eigen::Matrix3d C = Fd.transpose() * Fd;
  const Eigen::Matrix3d Ci = C.inverse();
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  const double I1 = C.trace(), I2 = 0.5 * (I1 * I1 - (C * C).trace());
  // 2 dI1b/dC and 2 dI2b/dC, times G/2 and the weights of the two terms.
  const Mat3 dI1 = std::pow(J, -2.0 / 3) * (I - (I1 / 3) * Ci);
  const Mat3 dI2 = std::pow(J, -4.0 / 3) * (I1 * I - C - (2 * I2 / 3) * Ci);
  return G_ * ((1 - a_) * dI1 + a_ * dI2);
}

double DeviatoricMooneyRivlin::strain_energy(const Mat3& F, int dim) const {
  if (dim == 2) return neo_hookean_.strain_energy(F, dim);
  double J = 0;
  const Mat3 Fd = deformation_block(F, 3, J);
  const Eigen::Matrix3d C = Fd.transpose() * Fd;
  const double I1 = C.trace(), I2 = 0.5 * (I1 * I1 - (C * C).trace());
  return 0.5 * G_ * ((1 - a_) * (std::pow(J, -2.0 / 3) * I1 - 3) + a_ * (std::pow(J, -4.0 / 3) * I2 - 3));
}

DeviatoricStrainHardening::DeviatoricStrainHardening(double shear_modulus, double c3_ratio)
    : G_(shear_modulus), r_(c3_ratio), neo_hookean_(shear_modulus) {
  require_constant(c3_ratio, true, "strain-hardening C3 / G");
}

Mat3 DeviatoricStrainHardening::second_piola(const Mat3& F, int dim) const {
  const double e = i1_excess(F, dim);
  return (1 + 6 * r_ * e * e) * neo_hookean_.second_piola(F, dim);
}

Voigt6 DeviatoricStrainHardening::spatial_tangent(const Mat3& F, int dim) const {
  // tau = f tau_nH, f = 1 + 6 r e^2; a variation D changes e = I1b - d by (2 / G) tau_nH : D.
  Eigen::Matrix<double, 6, 1> t;
  const Voigt6 c = neo_hookean_tangent(G_, F, dim, &t);
  const double e = i1_excess(F, dim);
  return (1 + 6 * r_ * e * e) * c + (24 * r_ * e / G_) * t * t.transpose();
}

double DeviatoricStrainHardening::strain_energy(const Mat3& F, int dim) const {
  const double e = i1_excess(F, dim);
  return G_ * (0.5 * e + r_ * e * e * e);
}

SkalakMembrane::SkalakMembrane(double shear_modulus, double area_ratio) : G_(shear_modulus), C_(area_ratio) {
  require_constant(shear_modulus, false, "shear modulus G");
  // The area-dilation modulus G h (1 + 2C) must be positive; C >= 0 also keeps W convex in the area.
  require_constant(area_ratio, true, "Skalak area-dilation ratio C");
}

namespace {
/// C = F^T F of a 3D deformation, refused where the element is inverted.
Mat3 right_cauchy_green_3d(const Mat3& F, int dim, const char* law) {
  if (dim != 3)
    throw std::invalid_argument(std::string(law) +
                                " is a law of a 3D membrane's surface; dim = " + std::to_string(dim));
  double J = 0;
  const Mat3 Fd = deformation_block(F, 3, J);
  return Fd.transpose() * Fd;
}
}  // namespace

Mat3 SkalakMembrane::second_piola(const Mat3& F, int dim) const {
  const Mat3 C = right_cauchy_green_3d(F, dim, "the Skalak law");
  const double i1 = C(0, 0) + C(1, 1) - 2, i2 = C(0, 0) * C(1, 1) - C(0, 1) * C(0, 1) - 1;
  const double a = i1 + 1, b = C_ * i2 - 1;
  Mat3 S = Mat3::Zero();
  S(0, 0) = G_ * (a + b * C(1, 1));
  S(1, 1) = G_ * (a + b * C(0, 0));
  S(0, 1) = S(1, 0) = -G_ * b * C(0, 1);
  S(0, 2) = S(2, 0) = G_ * C(0, 2);
  S(1, 2) = S(2, 1) = G_ * C(1, 2);
  return S;
}

double SkalakMembrane::strain_energy(const Mat3& F, int dim) const {
  const Mat3 C = right_cauchy_green_3d(F, dim, "the Skalak law");
  const double i1 = C(0, 0) + C(1, 1) - 2, i2 = C(0, 0) * C(1, 1) - C(0, 1) * C(0, 1) - 1;
  return 0.25 * G_ * (i1 * i1 + 2 * i1 - 2 * i2 + C_ * i2 * i2) +
         0.5 * G_ * (C(0, 2) * C(0, 2) + C(1, 2) * C(1, 2));
}

StrainHardeningMembrane::StrainHardeningMembrane(double shear_modulus, double c3_ratio, double area_ratio)
    : G_(shear_modulus), r_(c3_ratio), C_(area_ratio) {
  require_constant(shear_modulus, false, "shear modulus G");
  require_constant(c3_ratio, true, "strain-hardening C3 / G");
  require_constant(area_ratio, true, "area-dilation ratio C");
}

namespace {
/// The in-plane invariants of the membrane law: the shape change beta, the area stretch J_s and I2s = J_s^2
/// - 1.
struct SurfaceInvariants {
  double beta, area, i2;
};
SurfaceInvariants surface_invariants(const Mat3& C) {
  const double det = C(0, 0) * C(1, 1) - C(0, 1) * C(0, 1), area = std::sqrt(det);
  return {(C(0, 0) + C(1, 1)) / area - 2, area, det - 1};
}
}  // namespace

Mat3 StrainHardeningMembrane::second_piola(const Mat3& F, int dim) const {
  const Mat3 C = right_cauchy_green_3d(F, dim, "the strain-hardening membrane law");
  const SurfaceInvariants v = surface_invariants(C);
  // 2 dW/dC_s: the shape term through dbeta/dC_s = (I - (tr C_s / 2) C_s^{-1}) / J_s, C_s^{-1} = cof / J_s^2;
  // the area term through dI2s/dC_s = cof(C_s).
  const double shape = G_ * (1 + 6 * r_ * v.beta * v.beta) / v.area;
  const double half_trace_over_det = 0.5 * (C(0, 0) + C(1, 1)) / (v.area * v.area);
  const double area = 0.5 * G_ * (1 + 2 * C_) * v.i2;
  Mat3 S = Mat3::Zero();
  S(0, 0) = shape * (1 - half_trace_over_det * C(1, 1)) + area * C(1, 1);
  S(1, 1) = shape * (1 - half_trace_over_det * C(0, 0)) + area * C(0, 0);
  S(0, 1) = S(1, 0) = (shape * half_trace_over_det - area) * C(0, 1);
  S(0, 2) = S(2, 0) = G_ * C(0, 2);
  S(1, 2) = S(2, 1) = G_ * C(1, 2);
  return S;
}

double StrainHardeningMembrane::strain_energy(const Mat3& F, int dim) const {
  const Mat3 C = right_cauchy_green_3d(F, dim, "the strain-hardening membrane law");
  const SurfaceInvariants v = surface_invariants(C);
  return G_ * (0.5 * v.beta + r_ * v.beta * v.beta * v.beta) + 0.125 * G_ * (1 + 2 * C_) * v.i2 * v.i2 +
         0.5 * G_ * (C(0, 2) * C(0, 2) + C(1, 2) * C(1, 2));
}

}  // namespace cellfsi::solid
