#include "geometry/builders.hpp"

#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#include "geometry/basis.hpp"
#include "geometry/measures.hpp"
#include "geometry/projection.hpp"
#include "geometry/refine.hpp"

namespace cellfsi::geometry {

namespace {

[[noreturn]] void bad(const std::string& builder, const std::string& arg, double value,
                      const std::string& valid) {
  std::ostringstream os;
  os << builder << ": " << arg << " = " << value << " is invalid; valid: " << valid;
  throw std::invalid_argument(os.str());
}

void check_degree(const std::string& b, int degree, int min_degree) {
  if (degree < min_degree || degree > kMaxDegree)
    bad(b, "degree", degree, std::to_string(min_degree) + " <= degree <= " + std::to_string(kMaxDegree));
}

void check_positive(const std::string& b, const std::string& arg, double v) {
  if (!(v > 0) || !std::isfinite(v)) bad(b, arg, v, "a finite number > 0");
}

void check_count(const std::string& b, const std::string& arg, int n, int multiple_of) {
  if (n < multiple_of || n % multiple_of != 0)
    bad(b, arg, n, "a positive multiple of " + std::to_string(multiple_of));
}

KnotVector axis_knots(int n, int degree, bool periodic) {
  return periodic ? KnotVector::periodic_uniform(degree, n, 0.0, 1.0)
                  : KnotVector::open_uniform(degree, n, 0.0, 1.0);
}

// Unit circle as a rational quadratic with 9 control points (4 quarter arcs, C0 at the quarter knots),
// counter- clockwise from (1, 0).
struct Conic {
  KnotVector knots;
  std::vector<Vec3> points;
  std::vector<double> weights;
};
Conic unit_circle() {
  const double r = std::numbers::sqrt2 / 2;
  Conic c;
  c.knots = KnotVector::open(2, {0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1});
  c.points = {{1, 0, 0},   {1, 1, 0},  {0, 1, 0},  {-1, 1, 0}, {-1, 0, 0},
              {-1, -1, 0}, {0, -1, 0}, {1, -1, 0}, {1, 0, 0}};
  c.weights = {1, r, 1, r, 1, r, 1, r, 1};
  return c;
}
// Half circle in the (rho, z) plane from the south pole to the north pole (profile of a sphere of
// revolution).
Conic unit_half_circle() {
  const double r = std::numbers::sqrt2 / 2;
  Conic c;
  c.knots = KnotVector::open(2, {0, 0, 0, 0.5, 0.5, 1, 1, 1});
  c.points = {{0, 0, -1}, {1, 0, -1}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}};  // (rho, -, z)
  c.weights = {1, r, 1, r, 1};
  return c;
}

Mat3 rotation_z(double angle) { return Eigen::AngleAxisd(angle, Vec3::UnitZ()).toRotationMatrix(); }

/// Elevates the listed directions to `degree` and refines them to the requested element counts.
Patch elevate_and_refine(Patch patch, std::initializer_list<std::pair<int, int>> dir_and_elements,
                         int degree) {
  for (auto [dir, n] : dir_and_elements) {
    patch = elevate_degree(patch, dir, degree - patch.degree(dir));
    patch = refine_uniform(patch, dir, n);
  }
  return patch;
}

/// Membrane/bulky patch in 2D from an angular curve E(theta) (control points and weights of a closed curve):
/// the radial direction interpolates linearly between inner(j) and outer(j) (exact, by the Greville
/// identity).
template <class Inner, class Outer>
Patch radial_patch_2d(const KnotVector& radial, const KnotVector& angular, const std::vector<double>& weights,
                      Inner inner, Outer outer) {
  const std::vector<double> tau = radial.greville_unwrapped();
  const int nr = radial.n_basis(), na = angular.n_basis();
  std::vector<Vec3> cps(nr * na);
  std::vector<double> ws(nr * na);
  for (int j = 0; j < na; ++j)
    for (int i = 0; i < nr; ++i) {
      cps[i + nr * j] = inner(j) + tau[i] * (outer(j) - inner(j));
      ws[i + nr * j] = weights[j];
    }
  return Patch({radial, angular}, 2, std::move(cps), std::move(ws));
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// Eulerian domains

Patch rectangle(double lx, double ly, int nx, int ny, int degree, std::array<bool, 2> periodic,
                const Vec3& origin) {
  const std::string b = "rectangle";
  check_positive(b, "lx", lx);
  check_positive(b, "ly", ly);
  check_count(b, "nx", nx, 1);
  check_count(b, "ny", ny, 1);
  check_degree(b, degree, 1);
  if (periodic[0] && nx < degree) bad(b, "nx", nx, "a periodic direction needs nx >= degree");
  if (periodic[1] && ny < degree) bad(b, "ny", ny, "a periodic direction needs ny >= degree");
  const KnotVector kx = axis_knots(nx, degree, periodic[0]), ky = axis_knots(ny, degree, periodic[1]);
  const auto tx = kx.greville_unwrapped(), ty = ky.greville_unwrapped();
  std::vector<Vec3> cps;
  cps.reserve(tx.size() * ty.size());
  for (double v : ty)
    for (double u : tx) cps.push_back(origin + Vec3(lx * u, ly * v, 0));
  std::vector<double> ws(cps.size(), 1.0);
  return Patch({kx, ky}, 2, std::move(cps), std::move(ws), {Vec3(lx, 0, 0), Vec3(0, ly, 0), Vec3::Zero()});
}

Patch box(double lx, double ly, double lz, int nx, int ny, int nz, int degree, std::array<bool, 3> periodic,
          const Vec3& origin) {
  const std::string b = "box";
  check_positive(b, "lx", lx);
  check_positive(b, "ly", ly);
  check_positive(b, "lz", lz);
  check_count(b, "nx", nx, 1);
  check_count(b, "ny", ny, 1);
  check_count(b, "nz", nz, 1);
  check_degree(b, degree, 1);
  const int n[3] = {nx, ny, nz};
  for (int d = 0; d < 3; ++d)
    if (periodic[d] && n[d] < degree) bad(b, "elements in a periodic direction", n[d], ">= degree");
  const KnotVector kx = axis_knots(nx, degree, periodic[0]), ky = axis_knots(ny, degree, periodic[1]),
                   kz = axis_knots(nz, degree, periodic[2]);
  const auto tx = kx.greville_unwrapped(), ty = ky.greville_unwrapped(), tz = kz.greville_unwrapped();
  std::vector<Vec3> cps;
  cps.reserve(tx.size() * ty.size() * tz.size());
  for (double w : tz)
    for (double v : ty)
      for (double u : tx) cps.push_back(origin + Vec3(lx * u, ly * v, lz * w));
  std::vector<double> ws(cps.size(), 1.0);
  return Patch({kx, ky, kz}, 3, std::move(cps), std::move(ws),
               {Vec3(lx, 0, 0), Vec3(0, ly, 0), Vec3(0, 0, lz)});
}

void NarrowingChannel::validate() const {
  const std::string b = "narrowing_channel";
  check_positive(b, "length", length);
  check_positive(b, "height", height);
  check_positive(b, "throat_height", throat_height);
  check_positive(b, "throat_length", throat_length);
  check_positive(b, "transition_length", transition_length);
  if (throat_height >= height) bad(b, "throat_height", throat_height, "0 < throat_height < height");
  if (throat_length + 2 * transition_length >= length)
    bad(b, "throat_length + 2 transition_length", throat_length + 2 * transition_length,
        "< length (the period)");
  if (throat_center < 0 || throat_center > length) bad(b, "throat_center", throat_center, "in [0, length]");
}

double NarrowingChannel::wall_offset(double x) const {
  // Distance from the throat centre on the periodic line.
  double dx = std::fmod(x - throat_center, length);
  if (dx < -0.5 * length) dx += length;
  if (dx > 0.5 * length) dx -= length;
  dx = std::abs(dx);
  const double half = 0.5 * throat_length;
  double s;
  if (dx <= half) {
    s = 1.0;
  } else if (dx >= half + transition_length) {
    s = 0.0;
  } else {
    // C-infinity smooth step from 1 (t = 0) to 0 (t = 1): f(1-t) / (f(t) + f(1-t)), f(t) = exp(-1/t).
    const double t = (dx - half) / transition_length;
    auto f = [](double u) { return u > 0 ? std::exp(-1.0 / u) : 0.0; };
    s = f(1 - t) / (f(t) + f(1 - t));
  }
  return 0.5 * (height - throat_height) * s;
}

Patch narrowing_channel(const NarrowingChannel& ch, int nx, int ny, int degree) {
  const std::string b = "narrowing_channel";
  ch.validate();
  check_count(b, "nx", nx, 1);
  check_count(b, "ny", ny, 1);
  check_degree(b, degree, 1);
  if (nx < degree) bad(b, "nx", nx, ">= degree (x is periodic)");
  const KnotVector kx = KnotVector::periodic_uniform(degree, nx, 0.0, 1.0);
  const KnotVector ky = KnotVector::open_uniform(degree, ny, 0.0, 1.0);
  const Eigen::MatrixXd offset = l2_project(
      kx, 1, [&](double u) { return Eigen::VectorXd::Constant(1, ch.wall_offset(u * ch.length)); },
      degree + 4);
  const auto tx = kx.greville_unwrapped(), ty = ky.greville_unwrapped();
  std::vector<Vec3> cps;
  for (double v : ty)
    for (int i = 0; i < kx.n_basis(); ++i) {
      const double d = offset(i, 0);
      cps.emplace_back(ch.length * tx[i], -0.5 * ch.height + d + v * (ch.height - 2 * d), 0.0);
    }
  std::vector<double> ws(cps.size(), 1.0);
  return Patch({kx, ky}, 2, std::move(cps), std::move(ws),
               {Vec3(ch.length, 0, 0), Vec3::Zero(), Vec3::Zero()});
}

// ---------------------------------------------------------------------------------------------------------------
// Cells in 2D

Patch hollow_ellipse(double a, double b, double h, int n_angular, int degree, const Vec3& center,
                     double angle) {
  const std::string bl = "hollow_ellipse";
  check_positive(bl, "a", a);
  check_positive(bl, "b", b);
  check_positive(bl, "h", h);
  if (h >= 2 * std::min(a, b)) bad(bl, "h", h, "0 < h < 2 min(a, b)");
  check_count(bl, "n_angular", n_angular, 4);
  check_degree(bl, degree, 2);
  const Conic c = unit_circle();
  const Mat3 R = rotation_z(angle);
  auto ellipse = [&](double sa, double sb, int j) {
    return Vec3(center + R * Vec3(sa * c.points[j][0], sb * c.points[j][1], 0));
  };
  Patch p = radial_patch_2d(
      KnotVector::open_uniform(degree, 1), c.knots, c.weights,
      [&](int j) { return ellipse(a - h / 2, b - h / 2, j); },
      [&](int j) { return ellipse(a + h / 2, b + h / 2, j); });
  return elevate_and_refine(std::move(p), {{1, n_angular}}, degree);
}

Patch bulky_ellipse(double a, double b, int n_radial, int n_angular, int degree, const Vec3& center,
                    double angle) {
  const std::string bl = "bulky_ellipse";
  check_positive(bl, "a", a);
  check_positive(bl, "b", b);
  check_count(bl, "n_radial", n_radial, 1);
  check_count(bl, "n_angular", n_angular, 4);
  check_degree(bl, degree, 2);
  const Conic c = unit_circle();
  const Mat3 R = rotation_z(angle);
  Patch p = radial_patch_2d(
      KnotVector::open_uniform(degree, n_radial), c.knots, c.weights, [&](int) { return center; },
      [&](int j) { return Vec3(center + R * Vec3(a * c.points[j][0], b * c.points[j][1], 0)); });
  return elevate_and_refine(std::move(p), {{1, n_angular}}, degree);
}

Vec3 EvansFung::point(double t) const {
  const double c = std::cos(t), s = std::sin(t), c2 = c * c;
  return {R0 * c, 0.5 * s * (C0 + C2 * c2 + C4 * c2 * c2), 0.0};
}

Vec3 EvansFung::tangent(double t) const {
  const double c = std::cos(t), s = std::sin(t), c2 = c * c;
  const double poly = C0 + C2 * c2 + C4 * c2 * c2, dpoly = -2 * c * s * (C2 + 2 * C4 * c2);
  return {-R0 * s, 0.5 * (c * poly + s * dpoly), 0.0};
}

double EvansFung::area() const { return R0 * std::numbers::pi * (C0 / 2 + C2 / 8 + C4 / 16); }

Patch biconcave_rbc(double h, int n_angular, int degree, const Vec3& center, double angle, double area,
                    const EvansFung& shape) {
  const std::string bl = "biconcave_rbc";
  check_positive(bl, "h", h);
  check_positive(bl, "area", area);
  check_count(bl, "n_angular", n_angular, 4);
  check_degree(bl, degree, 2);
  const double two_pi = 2 * std::numbers::pi;
  const KnotVector ka = KnotVector::open_uniform(degree, n_angular, 0.0, 1.0);
  // Mid-line: Greville interpolation of c(2 pi u); the seam value is taken from u = 0 so the curve closes
  // exactly.
  Eigen::MatrixXd mid = greville_interpolate(ka, 2, [&](double u) {
    const Vec3 x = shape.point(u >= 1.0 ? 0.0 : two_pi * u);
    return Eigen::VectorXd(x.head<2>());
  });
  mid.row(mid.rows() - 1) = mid.row(0);
  // Scale so the mid-line encloses `area` (x y' - y x' is a polynomial of degree 2p - 1 per element: exact).
  std::vector<Vec3> line(ka.n_basis());
  for (int j = 0; j < ka.n_basis(); ++j) line[j] = Vec3(mid(j, 0), mid(j, 1), 0);
  const Patch curve({ka}, 2, line, std::vector<double>(line.size(), 1.0));
  const double scale = std::sqrt(area / enclosed_moments(curve).measure);
  const Mat3 R = rotation_z(angle);
  const auto tau = ka.greville();
  auto offset_point = [&](int j, double side) {
    const Vec3 t = shape.tangent(tau[j] >= 1.0 ? 0.0 : two_pi * tau[j]).normalized();
    const Vec3 n(t[1], -t[0], 0);  // outward for the counter-clockwise curve
    return Vec3(center + R * (scale * line[j] + side * 0.5 * h * n));
  };
  return radial_patch_2d(
      KnotVector::open_uniform(degree, 1), ka, std::vector<double>(ka.n_basis(), 1.0),
      [&](int j) { return offset_point(j, -1.0); }, [&](int j) { return offset_point(j, +1.0); });
}

// ---------------------------------------------------------------------------------------------------------------
// Cells in 3D

namespace {
/// Patch of revolution about the z axis through `center`: direction 0 through the thickness (or from the
/// centre), linear between two layers; direction 1 along a profile with knots `profile` and weights
/// `profile_weights`; direction 2 around the exact unit circle. layer(tau, j) = (sx, sy, z) places the
/// profile's control point j of the layer at tau in [0, 1] at (sx cos phi, sy sin phi, z): sx = sy = rho for
/// a surface of revolution, sx != sy for an ellipsoid. Poles (rho = 0) are collapsed control points.
template <class Layer>
Patch revolved_patch_3d(const KnotVector& radial, const KnotVector& profile,
                        const std::vector<double>& profile_weights, Layer layer, const Vec3& center) {
  const Conic circ = unit_circle();
  const std::vector<double> tau = radial.greville_unwrapped();
  const int nr = radial.n_basis(), np = profile.n_basis(), na = circ.knots.n_basis();
  std::vector<Vec3> cps(nr * np * na);
  std::vector<double> ws(cps.size());
  for (int k = 0; k < na; ++k)
    for (int j = 0; j < np; ++j)
      for (int i = 0; i < nr; ++i) {
        const Vec3 q = layer(tau[i], j);
        const int idx = i + nr * (j + np * k);
        cps[idx] = center + Vec3(q[0] * circ.points[k][0], q[1] * circ.points[k][1], q[2]);
        ws[idx] = profile_weights[j] * circ.weights[k];
      }
  return Patch({radial, profile, circ.knots}, 3, std::move(cps), std::move(ws));
}

/// Radial x polar x azimuth patch: scaled unit spheres interpolated linearly in the radial direction.
Patch radial_patch_3d(const KnotVector& radial, const Vec3& inner_axes, const Vec3& outer_axes,
                      const Vec3& center) {
  const Conic prof = unit_half_circle();
  return revolved_patch_3d(
      radial, prof.knots, prof.weights,
      [&](double tau, int j) {
        const Vec3 axes = inner_axes + tau * (outer_axes - inner_axes);
        return Vec3(axes[0] * prof.points[j][0], axes[1] * prof.points[j][0], axes[2] * prof.points[j][2]);
      },
      center);
}
}  // namespace

Patch hollow_ellipsoid(double a, double b, double c, double h, int n_polar, int n_azimuth, int degree,
                       const Vec3& center) {
  const std::string bl = "hollow_ellipsoid";
  check_positive(bl, "a", a);
  check_positive(bl, "b", b);
  check_positive(bl, "c", c);
  check_positive(bl, "h", h);
  if (h >= 2 * std::min({a, b, c})) bad(bl, "h", h, "0 < h < 2 min(a, b, c)");
  check_count(bl, "n_polar", n_polar, 2);
  check_count(bl, "n_azimuth", n_azimuth, 4);
  check_degree(bl, degree, 2);
  const Vec3 axes(a, b, c), half(h / 2, h / 2, h / 2);
  Patch p = radial_patch_3d(KnotVector::open_uniform(degree, 1), axes - half, axes + half, center);
  return elevate_and_refine(std::move(p), {{1, n_polar}, {2, n_azimuth}}, degree);
}

Patch solid_ellipsoid(double a, double b, double c, int n_radial, int n_polar, int n_azimuth, int degree,
                      const Vec3& center) {
  const std::string bl = "solid_ellipsoid";
  check_positive(bl, "a", a);
  check_positive(bl, "b", b);
  check_positive(bl, "c", c);
  check_count(bl, "n_radial", n_radial, 1);
  check_count(bl, "n_polar", n_polar, 2);
  check_count(bl, "n_azimuth", n_azimuth, 4);
  check_degree(bl, degree, 2);
  Patch p = radial_patch_3d(KnotVector::open_uniform(degree, n_radial), Vec3::Zero(), Vec3(a, b, c), center);
  return elevate_and_refine(std::move(p), {{1, n_polar}, {2, n_azimuth}}, degree);
}

Patch biconcave_rbc_3d(double h, int n_polar, int n_azimuth, int degree, const Vec3& center,
                       const EvansFung& shape) {
  const std::string bl = "biconcave_rbc_3d";
  check_positive(bl, "h", h);
  // The two sheets are closest at the dimples, C0 apart: the inner surfaces must not meet there.
  if (h >= shape.C0)
    bad(bl, "h", h, "0 < h < C0 = " + std::to_string(shape.C0) + " cm (the dimple's thickness)");
  check_count(bl, "n_polar", n_polar, 2);
  check_count(bl, "n_azimuth", n_azimuth, 4);
  check_degree(bl, degree, 2);
  // Profile from the south pole (u = 0, t = -pi/2) through the rim (t = 0) to the north pole: (rho, z) =
  // c(t) of EvansFung, whose x is the distance from the axis. It leaves the axis at a right angle (dz/dt = 0
  // at t = +-pi/2); interpolating those end slopes keeps the surface smooth at its poles, as the ellipsoid's.
  const double pi = std::numbers::pi;
  auto t_of = [pi](double u) { return pi * (u - 0.5); };
  auto xy = [](const Vec3& v) { return Eigen::VectorXd(v.head<2>()); };
  const KnotVector kp = KnotVector::open_uniform(degree, n_polar, 0.0, 1.0);
  Eigen::MatrixXd mid = greville_interpolate_clamped(
      kp, 2, [&](double u) { return xy(shape.point(t_of(u))); }, pi * xy(shape.tangent(-pi / 2)),
      pi * xy(shape.tangent(pi / 2)));
  const int last = kp.n_basis() - 1;
  mid(0, 0) = mid(last, 0) = 0.0;  // the poles exactly on the axis (cos(+-pi/2) is not 0 in doubles)
  const auto tau = kp.greville();
  std::vector<Vec3> normal(kp.n_basis());
  for (int j = 0; j < kp.n_basis(); ++j) {
    const Vec3 t = shape.tangent(t_of(tau[j])).normalized();
    normal[j] = Vec3(t[1], -t[0], 0);  // outward for the profile running south to north
  }
  // At the poles and their neighbours the offset is along the axis: every layer, not only the mid-surface,
  // leaves the axis at a right angle.
  normal[0] = normal[1] = -Vec3::UnitY(), normal[last] = normal[last - 1] = Vec3::UnitY();
  Patch p = revolved_patch_3d(
      KnotVector::open_uniform(degree, 1), kp, std::vector<double>(kp.n_basis(), 1.0),
      [&](double r, int j) {
        const double side = (r - 0.5) * h;
        const double rho = mid(j, 0) + side * normal[j][0], z = mid(j, 1) + side * normal[j][1];
        return Vec3(rho, rho, z);
      },
      center);
  return elevate_and_refine(std::move(p), {{2, n_azimuth}}, degree);
}

namespace {

// The collocation matrix of kv at its Greville points: B(i, j) = N_j(tau_i).
Eigen::MatrixXd greville_matrix(const KnotVector& kv) {
  const int n = kv.n_basis(), p = kv.degree();
  const std::vector<double> tau = kv.greville();
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(n, n);
  double N[(kMaxDeriv + 1) * (kMaxDegree + 1)];
  for (int i = 0; i < n; ++i) {
    const int span = kv.find_span(tau[i]);
    bspline_basis(kv, span, tau[i], 0, N);
    for (int j = 0; j <= p; ++j) B(i, kv.fold(span - p + j)) += N[j];
  }
  return B;
}

}  // namespace

std::vector<Patch> biconcave_rbc_3d_faces(double h, int n_face, int degree, const Vec3& center,
                                          const EvansFung& shape) {
  const std::string bl = "biconcave_rbc_3d_faces";
  check_positive(bl, "h", h);
  if (h >= shape.C0)
    bad(bl, "h", h, "0 < h < C0 = " + std::to_string(shape.C0) + " cm (the dimple's thickness)");
  check_count(bl, "n_face", n_face, 1);
  check_degree(bl, degree, 2);
  const double quarter = std::numbers::pi / 4;
  // The Evans-Fung surface as the image of the unit sphere: the point and its outward unit normal. The normal
  // is J^{-T} s, J = dM/ds (the image of the sphere's tangent plane is that of J, whose cofactor maps the
  // sphere's normal s to the image's; det J = R0^2 P / 2 > 0 keeps it outward).
  auto on_surface = [&](const Vec3& s, Vec3& x, Vec3& n) {
    const double c2 = s[0] * s[0] + s[1] * s[1];
    const double P = shape.C0 + shape.C2 * c2 + shape.C4 * c2 * c2, dP = shape.C2 + 2 * shape.C4 * c2;
    x = Vec3(shape.R0 * s[0], shape.R0 * s[1], 0.5 * s[2] * P);
    Mat3 J = Mat3::Zero();
    J(0, 0) = J(1, 1) = shape.R0;
    J(2, 0) = s[2] * s[0] * dP, J(2, 1) = s[2] * s[1] * dP, J(2, 2) = 0.5 * P;
    n = J.transpose().partialPivLu().solve(s).normalized();
  };
  const KnotVector kb = KnotVector::open_uniform(degree, n_face, 0.0, 1.0);
  const std::vector<double> tau = kb.greville();
  const int nb = kb.n_basis();
  const Eigen::PartialPivLU<Eigen::MatrixXd> lu(greville_matrix(kb));
  std::vector<Patch> faces;
  for (int k : {0, 1, 2})
    for (int sign : {1, -1}) {
      // The face's axes (i, j) with e_i x e_j = sign e_k: directions 1, 2 right-handed with the outward
      // normal.
      const int i = sign > 0 ? (k + 1) % 3 : (k + 2) % 3, j = sign > 0 ? (k + 2) % 3 : (k + 1) % 3;
      std::vector<Vec3> control(2 * nb * nb);
      for (int layer : {0, 1}) {
        Eigen::MatrixXd data[3];
        for (Eigen::MatrixXd& d : data) d.resize(nb, nb);
        for (int a = 0; a < nb; ++a)
          for (int b = 0; b < nb; ++b) {
            Vec3 d = Vec3::Zero();
            d[k] = sign;
            d[i] = std::tan(quarter * (2 * tau[a] - 1));
            d[j] = std::tan(quarter * (2 * tau[b] - 1));
            Vec3 x, n;
            on_surface(d.normalized(), x, n);
            const Vec3 p = x + (layer - 0.5) * h * n;
            for (int c = 0; c < 3; ++c) data[c](a, b) = p[c];
          }
        for (int c = 0; c < 3; ++c) {
          // C = B^{-1} D B^{-T}: along direction 1, then along direction 2.
          const Eigen::MatrixXd C = lu.solve(lu.solve(data[c]).transpose()).transpose();
          for (int a = 0; a < nb; ++a)
            for (int b = 0; b < nb; ++b) control[layer + 2 * (a + nb * b)][c] = C(a, b) + center[c];
        }
      }
      Patch p({KnotVector::open_uniform(1, 1, 0.0, 1.0), kb, kb}, 3, std::move(control),
              std::vector<double>(2 * nb * nb, 1.0));
      faces.push_back(elevate_degree(p, 0, degree - 1));
    }
  return faces;
}

Patch mid_surface(const Patch& shell) {
  if (shell.param_dim() != 3 || shell.physical_dim() != 3)
    throw std::invalid_argument(
        "mid_surface: a solid shell's patch (parametric dimension 3 in 3D) is needed");
  const KnotVector& kv = shell.knots(0);
  const int p = kv.degree();
  const double u = 0.5 * (kv.a() + kv.b());
  const int span = kv.find_span(u);
  std::vector<double> N(static_cast<std::size_t>(p) + 1);
  bspline_basis(kv, span, u, 0, N.data());
  const int n0 = shell.n_control(0), n1 = shell.n_control(1), n2 = shell.n_control(2);
  std::vector<Vec3> cps;
  std::vector<double> weights;
  for (int k = 0; k < n2; ++k)
    for (int j = 0; j < n1; ++j) {
      Vec3 pw = Vec3::Zero();
      double w = 0;
      for (int a = 0; a <= p; ++a) {
        const int i = (span - p + a) % n0;  // (direction 0 is open: unwrapped = folded)
        const int c = i + n0 * (j + n1 * k);
        pw += N[a] * shell.weights()[c] * shell.control_points()[c];
        w += N[a] * shell.weights()[c];
      }
      cps.push_back(pw / w);
      weights.push_back(w);
    }
  return Patch({shell.knots(1), shell.knots(2)}, 3, std::move(cps), std::move(weights),
               {shell.shifts()[1], shell.shifts()[2], Vec3::Zero()});
}

}  // namespace cellfsi::geometry
