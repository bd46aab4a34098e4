#include "geometry/knot_vector.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace cellfsi::geometry {

namespace {
void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("KnotVector: " + what);
}
}  // namespace

KnotVector KnotVector::open_uniform(int degree, int n_elements, double a, double b, int continuity) {
  require(degree >= 0, "degree must be >= 0, got " + std::to_string(degree));
  require(n_elements >= 1, "n_elements must be >= 1, got " + std::to_string(n_elements));
  require(b > a, "interval [a, b] must have b > a");
  if (continuity == -2) continuity = degree - 1;
  require(continuity >= -1 && continuity <= degree - 1, "continuity must be in [-1, p-1] = [-1, " +
                                                            std::to_string(degree - 1) + "], got " +
                                                            std::to_string(continuity));
  const int interior_mult = degree - continuity;
  KnotVector kv;
  kv.degree_ = degree;
  kv.knots_.assign(degree + 1, a);
  for (int e = 1; e < n_elements; ++e) {
    const double u = a + (b - a) * e / n_elements;
    for (int m = 0; m < interior_mult; ++m) kv.knots_.push_back(u);
  }
  for (int m = 0; m <= degree; ++m) kv.knots_.push_back(b);
  kv.finalize();
  return kv;
}

KnotVector KnotVector::open(int degree, std::vector<double> knots) {
  require(degree >= 0, "degree must be >= 0");
  require(static_cast<int>(knots.size()) >= 2 * (degree + 1),
          "an open knot vector of degree p needs >= 2(p+1) knots");
  KnotVector kv;
  kv.degree_ = degree;
  kv.knots_ = std::move(knots);
  for (int i = 1; i <= degree; ++i) {
    require(kv.knots_[i] == kv.knots_[0], "first knot must be repeated p+1 times");
    require(kv.knots_[kv.knots_.size() - 1 - i] == kv.knots_.back(), "last knot must be repeated p+1 times");
  }
  kv.finalize();
  for (double u : kv.breakpoints())
    if (u > kv.a() && u < kv.b())
      require(kv.multiplicity(u) <= degree,
              "interior knot multiplicity must be <= p (the basis would be discontinuous)");
  return kv;
}

KnotVector KnotVector::periodic_uniform(int degree, int n_elements, double a, double b) {
  require(degree >= 0, "degree must be >= 0");
  require(n_elements >= 1, "n_elements must be >= 1");
  require(n_elements >= degree, "a periodic knot vector needs n_elements >= degree (got " +
                                    std::to_string(n_elements) + " elements for degree " +
                                    std::to_string(degree) + ")");
  require(b > a, "interval [a, b] must have b > a");
  KnotVector kv;
  kv.degree_ = degree;
  kv.periodic_ = true;
  const double h = (b - a) / n_elements;
  // n_basis = n_elements; unwrapped length n_basis + 2p + 1, U_p = a.
  for (int i = -degree; i <= n_elements + degree; ++i) kv.knots_.push_back(a + h * i);
  // Make the active ends exact.
  kv.knots_[degree] = a;
  kv.knots_[degree + n_elements] = b;
  kv.finalize();
  return kv;
}

void KnotVector::finalize() {
  require(std::is_sorted(knots_.begin(), knots_.end()), "knots must be non-decreasing");
  element_spans_.clear();
  const int last = static_cast<int>(knots_.size()) - degree_ - 2;
  for (int i = degree_; i <= last; ++i)
    if (knots_[i + 1] > knots_[i]) element_spans_.push_back(i);
  require(!element_spans_.empty(), "knot vector has no non-empty span");
}

double KnotVector::normalize(double u) const {
  if (periodic_) {
    const double L = period();
    double v = std::fmod(u - a(), L);
    if (v < 0) v += L;
    if (v >= L) v = 0;  // fmod round-off
    return a() + v;
  }
  return std::clamp(u, a(), b());
}

int KnotVector::find_element(double u) const {
  u = normalize(u);
  // Largest element whose begin is <= u. First the element of equal elements (the usual mesh; the point
  // location asks at every immersed point), checked; then a binary search.
  int lo = 0, hi = n_elements() - 1;
  if (u >= element_begin(hi)) return hi;
  const double r = (u - a()) / (b() - a()) * n_elements();
  if (r >= 0 && r < hi) {  // (false for a NaN)
    const int guess = static_cast<int>(r);
    if (element_begin(guess) <= u && u < element_begin(guess + 1)) return guess;
  }
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    if (element_begin(mid) <= u)
      lo = mid;
    else
      hi = mid;
  }
  return lo;
}

std::vector<double> KnotVector::breakpoints() const {
  std::vector<double> bp;
  for (int e = 0; e < n_elements(); ++e) bp.push_back(element_begin(e));
  bp.push_back(element_end(n_elements() - 1));
  return bp;
}

int KnotVector::multiplicity(double u) const {
  int m = 0;
  for (int i = degree_; i < static_cast<int>(knots_.size()) - degree_; ++i)
    if (knots_[i] == u) ++m;
  if (!periodic_ && (u == a() || u == b())) m = degree_ + 1;
  return m;
}

std::vector<double> KnotVector::greville() const {
  std::vector<double> g = greville_unwrapped();
  if (periodic_)
    for (double& u : g) u = normalize(u);
  return g;
}

std::vector<double> KnotVector::greville_unwrapped() const {
  std::vector<double> g(n_basis());
  for (int j = 0; j < n_basis(); ++j) {
    double s = 0;
    for (int k = 1; k <= degree_; ++k) s += knots_[j + k];
    g[j] = degree_ > 0 ? s / degree_ : 0.5 * (knots_[j] + knots_[j + 1]);
  }
  return g;
}

}  // namespace cellfsi::geometry
