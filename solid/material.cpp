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

/// F's d x d block, refused where the element is inverted; J = det F.
Eigen::MatrixXd deformation_block(const Mat3& F, int d, double& J) {
  const Eigen::MatrixXd Fd = F.topLeftCorner(d, d);
  J = Fd.determinant();
  if (!(J > 0)) throw std::runtime_error("inverted solid element: det F = " + number_text(J) + " <= 0");
  return Fd;
}

/// I1b - d, I1b = J^{-2/d} tr C: zero at rest and under any rotation, >= 0 always (an isochoric C has
/// eigenvalues with product 1, whose mean is at least 1). In 2D it is I1 - 3 of the plane-strain
/// incompressible solid.
double i1_excess(const Mat3& F, int d) {
  double J = 0;
  const Eigen::MatrixXd Fd = deformation_block(F, d, J);
  return std::pow(J, -2.0 / d) * (Fd.transpose() * Fd).trace() - d;
}
}  // namespace

DeviatoricNeoHookean::DeviatoricNeoHookean(double shear_modulus) : G_(shear_modulus) {
  if (!(shear_modulus > 0) || !std::isfinite(shear_modulus))
    throw std::invalid_argument("shear modulus G = " + number_text(shear_modulus) +
                                " is invalid; valid: > 0");
}

Mat3 DeviatoricNeoHookean::second_piola(const Mat3& F, int dim) const {
  const int d = dim;
  double J = 0;
  const Eigen::MatrixXd Fd = deformation_block(F, d, J);
  const Eigen::MatrixXd C = Fd.transpose() * Fd;
  const Eigen::MatrixXd Ci = C.inverse();
  Mat3 S = Mat3::Zero();
  S.topLeftCorner(d, d) =
      G_ * std::pow(J, -2.0 / d) * (Eigen::MatrixXd::Identity(d, d) - (C.trace() / d) * Ci);
  return S;
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
  const Eigen::MatrixXd Fd = deformation_block(F, 3, J);
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
  const Eigen::MatrixXd Fd = deformation_block(F, 3, J);
  const Eigen::Matrix3d C = Fd.transpose() * Fd;
  const double I1 = C.trace(), I2 = 0.5 * (I1 * I1 - (C * C).trace());
  return 0.5 * G_ * ((1 - a_) * (std::pow(J, -2.0 / 3) * I1 - 3) + a_ * (std::pow(J, -4.0 / 3) * I2 - 3));
}

DeviatoricStrainHardening::DeviatoricStrainHardening(double shear_modulus, double c3_ratio)
    : G_(shear_modulus), r_(c3_ratio), neo_hookean_(shear_modulus) {
  if (!(c3_ratio >= 0) || !std::isfinite(c3_ratio))
    throw std::invalid_argument("strain-hardening C3 / G = " + number_text(c3_ratio) +
                                " is invalid; valid: >= 0");
}

Mat3 DeviatoricStrainHardening::second_piola(const Mat3& F, int dim) const {
  const double e = i1_excess(F, dim);
  return (1 + 6 * r_ * e * e) * neo_hookean_.second_piola(F, dim);
}

double DeviatoricStrainHardening::strain_energy(const Mat3& F, int dim) const {
  const double e = i1_excess(F, dim);
  return G_ * (0.5 * e + r_ * e * e * e);
}

}  // namespace cellfsi::solid
