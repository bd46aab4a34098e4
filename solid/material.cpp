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
}  // namespace

DeviatoricNeoHookean::DeviatoricNeoHookean(double shear_modulus) : G_(shear_modulus) {
  if (!(shear_modulus > 0) || !std::isfinite(shear_modulus))
    throw std::invalid_argument("shear modulus G = " + number_text(shear_modulus) +
                                " is invalid; valid: > 0");
}

Mat3 DeviatoricNeoHookean::second_piola(const Mat3& F, int dim) const {
  const int d = dim;
  const Eigen::MatrixXd Fd = F.topLeftCorner(d, d);
  const double J = Fd.determinant();
  if (!(J > 0)) throw std::runtime_error("inverted solid element: det F = " + number_text(J) + " <= 0");
  const Eigen::MatrixXd C = Fd.transpose() * Fd;
  const Eigen::MatrixXd Ci = C.inverse();
  Mat3 S = Mat3::Zero();
  S.topLeftCorner(d, d) =
      G_ * std::pow(J, -2.0 / d) * (Eigen::MatrixXd::Identity(d, d) - (C.trace() / d) * Ci);
  return S;
}

}  // namespace cellfsi::solid
