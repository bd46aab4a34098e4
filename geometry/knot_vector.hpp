#pragma once
// Knot vectors of B-splines: open (clamped) and periodic, span search, elements, Greville abscissae.
//
// Conventions used throughout cellfsi:
//  - "degree" p is the polynomial degree (order = p + 1).
//  - A span index i satisfies U_i <= u < U_{i+1}; the p + 1 functions nonzero on span i are
//    i - p, ..., i in *unwrapped* numbering. For an open vector the unwrapped numbering is the
//    numbering. A periodic vector is stored unwrapped: the cyclic knots of [a, b) extended by p knots
//    of the periodic continuation on either side, so the same Cox-de Boor recursion serves both kinds;
//    unwrapped function j is the periodic function j mod n_basis().
//  - An "element" is a non-empty knot span inside the active interval [a, b].
#include <vector>

namespace cellfsi::geometry {

class KnotVector {
 public:
  KnotVector() = default;

  /// Open knot vector on [a, b]: end knots repeated p + 1 times, n_elements equal elements, interior
  /// knots repeated p - continuity times (continuity C^k between elements, -1 <= k <= p - 1).
  static KnotVector open_uniform(int degree, int n_elements, double a = 0.0, double b = 1.0,
                                 int continuity = -2);
  /// Open knot vector from the full knot sequence (validated: non-decreasing, ends of multiplicity p + 1,
  /// interior multiplicity <= p).
  static KnotVector open(int degree, std::vector<double> knots);
  /// Periodic knot vector on [a, b) with n_elements equal elements, maximal continuity C^{p-1}.
  static KnotVector periodic_uniform(int degree, int n_elements, double a = 0.0, double b = 1.0);

  int degree() const { return degree_; }
  bool periodic() const { return periodic_; }
  const std::vector<double>& knots() const { return knots_; }  // unwrapped for periodic vectors
  double knot(int i) const { return knots_[i]; }
  double a() const { return knots_[degree_]; }
  double b() const { return knots_[knots_.size() - 1 - degree_]; }
  double period() const { return b() - a(); }

  /// Number of (folded) basis functions: the number of control variables of a field.
  int n_basis() const { return periodic_ ? n_unwrapped() - degree_ : n_unwrapped(); }
  /// Number of functions in unwrapped numbering (equals n_basis() for open vectors).
  int n_unwrapped() const { return static_cast<int>(knots_.size()) - degree_ - 1; }
  /// Folded index of unwrapped function j.
  int fold(int j) const { return periodic_ ? j % n_basis() : j; }
  /// How many periods unwrapped function j lies beyond its folded copy (0 or 1; 0 for open vectors).
  int wrap_count(int j) const { return periodic_ ? j / n_basis() : 0; }

  int n_elements() const { return static_cast<int>(element_spans_.size()); }
  /// Span index of element e (0 <= e < n_elements()).
  int element_span(int e) const { return element_spans_[e]; }
  const std::vector<int>& element_spans() const { return element_spans_; }
  double element_begin(int e) const { return knots_[element_spans_[e]]; }
  double element_end(int e) const { return knots_[element_spans_[e] + 1]; }
  /// Element containing u (u is clamped to [a, b] for open vectors and wrapped into [a, b) for periodic).
  int find_element(double u) const;
  /// Span containing u, same clamping/wrapping as find_element.
  int find_span(double u) const { return element_spans_[find_element(u)]; }
  /// u wrapped into [a, b) for periodic vectors; clamped into [a, b] for open vectors.
  double normalize(double u) const;

  /// Distinct knot values in [a, b] (element boundaries), ascending.
  std::vector<double> breakpoints() const;
  /// Multiplicity of the knot value u inside [a, b] (0 if u is not a knot).
  int multiplicity(double u) const;
  /// Greville abscissae of the n_basis() (folded) functions; for periodic vectors they are wrapped into [a,
  /// b).
  std::vector<double> greville() const;
  /// Greville abscissae of functions 0..n_basis()-1 in unwrapped numbering (not wrapped into [a, b)): the
  /// control-point coordinates of the identity map u -> u, since sum_j tau_j N_j(u) = u.
  std::vector<double> greville_unwrapped() const;

 private:
  void finalize();  // validates and builds element_spans_
  int degree_ = 0;
  bool periodic_ = false;
  std::vector<double> knots_;
  std::vector<int> element_spans_;
};

}  // namespace cellfsi::geometry
