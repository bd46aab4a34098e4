#include "solid/nurbs_solid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>

#include "geometry/quadrature.hpp"
#include "solid/shell_kinematics.hpp"

namespace cellfsi::solid {

using geometry::BasisValues;
using geometry::Index3;
using geometry::MapValues;
using geometry::Param;

NurbsSolid::NurbsSolid(std::string name, geometry::Patch reference, std::shared_ptr<const Material> material,
                       double density)
    : name_(std::move(name)),
      reference_(std::move(reference)),
      material_(std::move(material)),
      density_(density) {
  dim_ = reference_.physical_dim();
  if (reference_.param_dim() != dim_)
    throw std::invalid_argument("NurbsSolid '" + name_ +
                                "': the patch must fill its space (param dim == dim)");
  set_up();
}

NurbsSolid::NurbsSolid(std::string name, geometry::Patch mid_surface, double thickness,
                       std::shared_ptr<const Material> material, double density)
    : name_(std::move(name)),
      reference_(std::move(mid_surface)),
      material_(std::move(material)),
      density_(density) {
  if (reference_.param_dim() != 2 || reference_.physical_dim() != 3)
    throw std::invalid_argument(
        "NurbsSolid '" + name_ +
        "': a thin shell's mid-surface is a surface patch in 3D (parametric dimension 2, "
        "not " +
        std::to_string(reference_.param_dim()) + " in " + std::to_string(reference_.physical_dim()) + "D)");
  if (!(thickness > 0) || !std::isfinite(thickness))
    throw std::invalid_argument("NurbsSolid '" + name_ + "': a thin shell's thickness must be > 0 cm, not " +
                                std::to_string(thickness));
  dim_ = 3;
  shell_thickness_ = thickness;
  set_up();
}

void NurbsSolid::set_up() {
  if (!material_) throw std::invalid_argument("NurbsSolid '" + name_ + "': no material");
  if (!(density_ > 0)) throw std::invalid_argument("NurbsSolid '" + name_ + "': density must be > 0");
  time_ = TimeParameters::from_rho_inf(0.5, 1.0);

  // Step 3's solver owns the points and the unknowns (a closed direction's last control layer folded onto
  // its first).
  try {
    collocation_solver_ = std::make_unique<CollocationSolver>(reference_);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("NurbsSolid '" + name_ + "': " + e.what());
  }
  const CollocationSolver& cs = *collocation_solver_;
  const int m[3] = {cs.n_points(0), cs.n_points(1), cs.n_points(2)};
  n_reduced_ = m[0] * m[1] * m[2];
  reduced_.resize(reference_.n_control());
  for (int k = 0; k < reference_.n_control(); ++k) reduced_[k] = cs.unknown(k);
  const std::array<std::vector<double>, 3> tau = {cs.abscissae(0), cs.abscissae(1), cs.abscissae(2)};
  const auto abscissa = [&](int d, int i) { return d < reference_.param_dim() ? tau[d][i] : 0.0; };
  int p = 0;
  for (int c = 0; c < m[2]; ++c)
    for (int b = 0; b < m[1]; ++b)
      for (int a = 0; a < m[0]; ++a, ++p) {
        const Param xi{abscissa(0, a), abscissa(1, b), abscissa(2, c)};
        point_xi_.push_back(xi);
        reference_points_.push_back(reference_.point(xi));
        // Interface faces: both ends of direction 0, unless a face collapses to a point (a body's centre).
        // A thin shell's faces are not collocated: they lie at +-h/2 from its mid-surface.
        if ((a == 0 || a == m[0] - 1) && !(shell_thickness_ > 0)) face_points_.push_back(p);
      }
  // Drop a degenerate face (all its points coincide).
  bool degenerate = false;
  geometry::Vec3 lo, hi;
  reference_.bounding_box(lo, hi);
  const double size = (hi - lo).norm();
  for (int side = 0; side < 2; ++side) {
    const int a = side == 0 ? 0 : m[0] - 1;
    double spread = 0;
    for (int q : face_points_)
      if (q % m[0] == a) spread = std::max(spread, (reference_points_[q] - reference_points_[a]).norm());
    // Zero up to round-off of the evaluation (relative to the body's size).
    if (spread <= 1e-12 * size) {
      degenerate = true;
      std::vector<int> keep;
      for (int q : face_points_)
        if (q % m[0] != a) keep.push_back(q);
      face_points_ = keep;
    }
  }
  membrane_ = !degenerate || shell_thickness_ > 0;
  if (material_->membrane_surface_law() && !(membrane_ && dim_ == 3))
    throw std::invalid_argument("NurbsSolid '" + name_ + "': the " + material_->name() +
                                " law is a law of a 3D membrane's surface; this body is " +
                                (membrane_ ? "a 2D membrane" : "not a membrane"));

  u_ = Eigen::MatrixXd::Zero(n_reduced_, dim_);
  u_n_ = u_;
  rate_n_ = u_;
  c_ = Eigen::MatrixXd::Zero(n_reduced_, dim_);
  c_n_ = c_;
  if (shell_thickness_ > 0)
    tabulate_shell_quadrature();
  else
    tabulate_quadrature();
}

namespace {
/// A membrane's reference frame at a point (columns T1, T2, N): N the unit normal of the surface of constant
/// xi_0 through it (direction 0 runs through the thickness: N is grad xi_0, row 0 of d xi / d X, normalised),
/// T1, T2 any orthonormal pair across it (a membrane surface law is isotropic in its plane).
Mat3 membrane_frame(const Mat3& dXdxi) {
  const Vec3 N = dXdxi.inverse().row(0).transpose().normalized();
  const Vec3 t1 = N.unitOrthogonal();
  Mat3 Q;
  Q.col(0) = t1;
  Q.col(1) = N.cross(t1);
  Q.col(2) = N;
  return Q;
}
}  // namespace

void NurbsSolid::tabulate_quadrature() {
  std::vector<geometry::QuadraturePoint> qp;
  const Index3 ng = geometry::default_gauss(reference_);
  BasisValues bv;
  MapValues mv;
  // Exact sizes (no doubling by push_back): at 64^3 the tables are 0.3 GB.
  const std::size_t n_points = static_cast<std::size_t>(reference_.n_elements()) * ng[0] * ng[1] * ng[2];
  std::size_t n_functions = 1;
  for (int d = 0; d < dim_; ++d) n_functions *= reference_.degree(d) + 1;
  q_begin_.reserve(n_points + 1);
  q_unknown_.reserve(n_points * n_functions);
  q_N_.reserve(n_points * n_functions);
  q_dN_.reserve(n_points * n_functions * dim_);
  q_X_.reserve(n_points);
  q_weight_.reserve(n_points);
  if (membrane_) q_area_.reserve(n_points);
  // A membrane's thickness at a point: |dX / dxi_0| times direction 0's parameter range (the builders map
  // it linearly across the thickness, one element through it).
  const double range0 = reference_.knots(0).b() - reference_.knots(0).a();
  q_begin_.assign(1, 0);
  for (int e = 0; e < reference_.n_elements(); ++e) {
    const Index3 m = reference_.element_multi_index(e);
    geometry::element_quadrature(reference_, m, ng, qp);
    for (const auto& q : qp) {
      reference_.basis(q.xi, 1, bv, &m);
      reference_.map(bv, mv);
      const Mat3 dXdxi = mv.dx;
      Mat3 inv = Mat3::Identity();  // d xi / d X
      inv.topLeftCorner(dim_, dim_) = dXdxi.topLeftCorner(dim_, dim_).inverse();
      for (int k = 0; k < bv.n; ++k) {
        q_unknown_.push_back(reduced_[bv.index[k]]);
        q_N_.push_back(bv.value[k]);
        for (int j = 0; j < dim_; ++j) {
          double g = 0;
          for (int a = 0; a < dim_; ++a) g += bv.d1[3 * k + a] * inv(a, j);
          q_dN_.push_back(g);
        }
      }
      q_begin_.push_back(static_cast<int>(q_N_.size()));
      q_X_.push_back(mv.x);
      q_weight_.push_back(q.weight * std::abs(dXdxi.topLeftCorner(dim_, dim_).determinant()));
      if (membrane_) q_area_.push_back(q_weight_.back() / (dXdxi.col(0).norm() * range0));
      if (material_->membrane_surface_law()) q_frame_.push_back(membrane_frame(dXdxi));
    }
  }
}

namespace {
/// A thin shell's function at a point, as tabulated: R, dR / dtheta_0, dR / dtheta_1 and the second derivatives
/// 00, 01, 11, from the patch's basis values (function k).
std::array<double, 6> shell_basis(const BasisValues& bv, int k) {
  const double* d2 = &bv.d2[9 * static_cast<std::size_t>(k)];
  return {bv.value[k], bv.d1[3 * k], bv.d1[3 * k + 1], d2[0], d2[1], d2[4]};
}

/// Adds one function's share of a control displacement c (3 values) to a mid-surface's map values (the map is
/// linear in the control points, the weights fixed).
void add_shell_displacement(geometry::MapValues& m, const double* b, const double* c) {
  for (int i = 0; i < 3; ++i) {
    m.x[i] += b[0] * c[i];
    m.dx(i, 0) += b[1] * c[i];
    m.dx(i, 1) += b[2] * c[i];
    m.d2x[i](0, 0) += b[3] * c[i];
    m.d2x[i](0, 1) += b[4] * c[i];
    m.d2x[i](1, 0) += b[4] * c[i];
    m.d2x[i](1, 1) += b[5] * c[i];
  }
}
}  // namespace

void NurbsSolid::tabulate_shell_quadrature() {
  // Three Gauss heights through the thickness: the energy through it, of a law's stress at F linear in zeta
  // to first order, is integrated exactly to degree 5 (the thick shell's quadratic direction had three too).
  const geometry::GaussRule& layers = geometry::gauss_legendre(3);
  const double h = shell_thickness_;
  s_zeta_.clear();
  for (double z : layers.points) s_zeta_.push_back(0.5 * h * z);
  std::vector<geometry::QuadraturePoint> qp;
  const Index3 ng = geometry::default_gauss(reference_);
  BasisValues bv;
  s_begin_.assign(1, 0);
  for (int e = 0; e < reference_.n_elements(); ++e) {
    const Index3 m = reference_.element_multi_index(e);
    geometry::element_quadrature(reference_, m, ng, qp);
    for (const auto& q : qp) {
      reference_.basis(q.xi, 2, bv, &m);
      MapValues ref;
      reference_.map(bv, ref);
      for (int k = 0; k < bv.n; ++k) {
        s_unknown_.push_back(reduced_[bv.index[k]]);
        for (double v : shell_basis(bv, k)) s_basis_.push_back(v);
      }
      s_begin_.push_back(static_cast<int>(s_unknown_.size()));
      s_ref_.push_back(ref);
      s_area_.push_back(q.weight * ref.dx.col(0).cross(ref.dx.col(1)).norm());
      for (std::size_t l = 0; l < s_zeta_.size(); ++l) {
        // The reference shell's point (the same map values twice: no deformation).
        const ShellPoint p = shell_point(ref, ref, s_zeta_[l]);
        const double w = q.weight * 0.5 * h * layers.weights[l] * p.ref_jacobian;
        q_X_.push_back(p.x);
        q_weight_.push_back(w);
        // (the area this point stands for: its column's share of the mid-surface's, as for the solid shell)
        q_area_.push_back(q.weight * 0.5 * layers.weights[l] * ref.dx.col(0).cross(ref.dx.col(1)).norm());
        if (material_->membrane_surface_law()) q_frame_.push_back(p.frame);
      }
    }
  }
  // The reference mid-surface's mass matrix in the reduced unknowns (the force density's projection).
  std::vector<Eigen::Triplet<double>> entries;
  for (std::size_t s = 0; s + 1 < s_begin_.size(); ++s)
    for (int k = s_begin_[s]; k < s_begin_[s + 1]; ++k)
      for (int l = s_begin_[s]; l < s_begin_[s + 1]; ++l)
        entries.emplace_back(s_unknown_[k], s_unknown_[l],
                             s_area_[s] * s_basis_[6 * static_cast<std::size_t>(k)] *
                                 s_basis_[6 * static_cast<std::size_t>(l)]);
  Eigen::SparseMatrix<double> mass(n_reduced_, n_reduced_);
  mass.setFromTriplets(entries.begin(), entries.end());
  s_mass_ = std::make_unique<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>>(mass);
  if (s_mass_->info() != Eigen::Success)
    throw std::invalid_argument("NurbsSolid '" + name_ +
                                "': the thin shell's mid-surface mass matrix is singular");
}

void NurbsSolid::shell_quadrature_data(double fluid_density, bool with_tangent,
                                       const std::function<bool(std::size_t, const Vec3&)>& wanted,
                                       QuadratureData* out, const char* only) const {
  const double beta = 1.0 - density_ / fluid_density;
  const Eigen::MatrixXd c = displacement_control_alpha();
  std::vector<double> rows(3 * static_cast<std::size_t>(c.rows()), 0.0);
  for (Eigen::Index r = 0; r < c.rows(); ++r)
    for (int i = 0; i < 3; ++i) rows[3 * r + i] = c(r, i);
  const int layers = static_cast<int>(s_zeta_.size());
  const int middle = layers / 2;  // (zeta = 0: an odd Gauss rule)
  const int n_surface = static_cast<int>(s_ref_.size());
  // The internal force -dE / dc / rho_1, row by row: each point's dE / dm (m: the mid-surface's derivatives,
  // ShellBasisDerivative) through its functions' derivatives.
  Eigen::MatrixXd f = Eigen::MatrixXd::Zero(n_reduced_, 3);
  Eigen::Matrix<double, 15, 1> dE;
  Eigen::Matrix<double, 9, 1> Q;
  MapValues cur;
  for (int s = 0; s < n_surface; ++s) {
    cur = s_ref_[s];
    for (int k = s_begin_[s]; k < s_begin_[s + 1]; ++k)
      add_shell_displacement(cur, s_basis_.data() + 6 * static_cast<std::size_t>(k),
                             rows.data() + 3 * static_cast<std::size_t>(s_unknown_[k]));
    const auto where = [&](int l) { return shell_where(s, l, cur.x); };
    ShellBasisDerivative D;
    try {
      D = shell_basis_derivative(s_ref_[s], cur);
    } catch (const std::invalid_argument& e) {  // (the current mid-surface collapsed here: inverted)
      throw std::runtime_error(std::string("inverted solid element: ") + e.what() + where(middle));
    }
    dE.setZero();
    for (int l = 0; l < layers; ++l) {
      const int q = s * layers + l;
      const double zeta = s_zeta_[l];
      ShellPoint p;
      try {
        p = shell_point(s_ref_[s], cur, zeta);
      } catch (const std::invalid_argument& e) {
        throw std::runtime_error(std::string("inverted solid element: ") + e.what() + where(l));
      }
      const Mat3 F = q_frame_.empty() ? p.F : Mat3(p.F * q_frame_[q]);
      Mat3 tau;
      try {
        tau = F * material_->second_piola(F, 3) * F.transpose() / fluid_density;
      } catch (const std::runtime_error& e) {  // an inverted element (the material refuses det F <= 0)
        throw std::runtime_error(e.what() + where(l));
      }
      // P : dF = (tau g^-T) : dg, g = g0 + zeta g1 (F = g G^-1, P = tau F^-T)
      const Mat3 g = D.g0 + zeta * D.g1;
      Eigen::Map<Mat3>(Q.data()) = tau * g.inverse().transpose();
      dE.noalias() += q_weight_[q] * (D.d_g0 + zeta * D.d_g1).transpose() * Q;
      if (only && !only[q]) continue;
      QuadratureData& d = out[q];
      d = QuadratureData{};
      d.x = p.x;
      d.weight = q_weight_[q];
      d.beta = beta;
      d.shear_modulus = material_->tangent_shear_modulus();
      d.area = q_area_[q];
      if (with_tangent) {
        d.has_tangent = true;
        const Voigt6 tangent = material_->spatial_tangent(F, 3);
        for (int r = 0, t = 0; r < 6; ++r)
          for (int k = r; k < 6; ++k, ++t) d.tangent[t] = tangent(r, k) / fluid_density;
      }
      if (!load_density_.empty()) d.force = load_factor() * load_density_[q] / fluid_density;
      wanted(q, p.x);  // (the caller locates the point; every point is evaluated here whatever it answers)
    }
    for (int k = s_begin_[s]; k < s_begin_[s + 1]; ++k) {
      const double* b = s_basis_.data() + 6 * static_cast<std::size_t>(k);
      Vec3 fk = Vec3::Zero();
      for (int j = 0; j < 5; ++j) fk += b[1 + j] * dE.segment<3>(3 * j);
      f.row(s_unknown_[k]) -= fk.transpose();
    }
  }
  // The force density's coefficients, and its value at each surface point on the middle layer's point.
  const Eigen::MatrixXd density = s_mass_->solve(f);
  for (int s = 0; s < n_surface; ++s) {
    const int q = s * layers + middle;
    if (only && !only[q]) continue;
    Vec3 fs = Vec3::Zero();
    for (int k = s_begin_[s]; k < s_begin_[s + 1]; ++k)
      fs += s_basis_[6 * static_cast<std::size_t>(k)] * density.row(s_unknown_[k]).transpose();
    out[q].force += fs * (s_area_[s] / q_weight_[q]);
  }
}

double NurbsSolid::strain_energy() const {
  double energy = 0;
  for_each_quadrature_point(
      c_n_,
      [&](int q, const Vec3&, const Mat3& F, double weight) {
        energy += weight * material_->strain_energy(q_frame_.empty() ? F : Mat3(F * q_frame_[q]), dim_);
      },
      static_cast<const char*>(nullptr));
  return energy;
}

std::string NurbsSolid::shell_where(int s, int l, const Vec3& x) const {
  const Index3 m =
      reference_.element_multi_index(s / (static_cast<int>(s_ref_.size()) / reference_.n_elements()));
  char text[200];
  std::snprintf(
      text, sizeof text,
      "; body '%s', thin-shell element (%d, %d) of %d x %d, at x = (%.4g, %.4g, %.4g) cm, %.3g of the "
      "thickness above its mid-surface",
      name_.c_str(), m[0], m[1], reference_.n_elements(0), reference_.n_elements(1), x[0], x[1], x[2],
      s_zeta_[l] / shell_thickness_);
  return text;
}

void NurbsSolid::for_each_shell_point(const double* rows,
                                      const std::function<void(int, const Vec3&, const Mat3&, double)>& visit,
                                      const char* only) const {
  const int layers = static_cast<int>(s_zeta_.size());
  const int n_surface = static_cast<int>(s_ref_.size());
  MapValues cur;
  for (int s = 0; s < n_surface; ++s) {
    bool any = !only;
    for (int l = 0; l < layers && !any; ++l) any = only[s * layers + l] != 0;
    if (!any) continue;
    // The current mid-surface: the reference's map values plus the displacement's.
    cur = s_ref_[s];
    for (int k = s_begin_[s]; k < s_begin_[s + 1]; ++k)
      add_shell_displacement(cur, s_basis_.data() + 6 * static_cast<std::size_t>(k),
                             rows + 3 * static_cast<std::size_t>(s_unknown_[k]));
    for (int l = 0; l < layers; ++l) {
      const int q = s * layers + l;
      if (only && !only[q]) continue;
      const auto where = [&] { return shell_where(s, l, cur.x); };
      ShellPoint p;
      try {
        p = shell_point(s_ref_[s], cur, s_zeta_[l]);
      } catch (const std::invalid_argument& e) {  // (the current mid-surface collapsed here: inverted)
        throw std::runtime_error(std::string("inverted solid element: ") + e.what() + where());
      }
      try {
        visit(q, p.x, p.F, q_weight_[q]);
      } catch (const std::runtime_error& e) {  // an inverted element (the material refuses det F <= 0)
        throw std::runtime_error(e.what() + where());
      }
    }
  }
}

Eigen::MatrixXd NurbsSolid::control_from_points(const Eigen::MatrixXd& values) const {
  const CollocationSolver& cs = *collocation_solver_;
  Eigen::MatrixXd c = cs.solve(values);
  c += cs.solve(values - cs.matrix() * c);  // one refinement step: exact to round-off
  return c;
}

Eigen::MatrixXd NurbsSolid::points_from_control(const Eigen::MatrixXd& control) const {
  return collocation_solver_->matrix() * control;
}

void NurbsSolid::set_rate(const std::vector<Vec3>& rate) {
  if (static_cast<int>(rate.size()) != n_points())
    throw std::invalid_argument("set_rate: one value per point");
  for (int i = 0; i < n_points(); ++i) rate_n_.row(i) = rate[i].head(dim_).transpose();
}

std::vector<double> NurbsSolid::state() const {
  std::vector<double> out;
  out.reserve(2 * u_n_.size() + c_n_.size());
  for (const Eigen::MatrixXd* m : {&u_n_, &rate_n_, &c_n_})
    for (Eigen::Index r = 0; r < m->rows(); ++r)
      for (Eigen::Index c = 0; c < m->cols(); ++c) out.push_back((*m)(r, c));
  return out;
}

void NurbsSolid::set_state(const std::vector<double>& state) {
  const std::size_t expected = static_cast<std::size_t>(2 * u_n_.size() + c_n_.size());
  if (state.size() != expected)
    throw std::invalid_argument("body '" + name_ + "': a state of " + std::to_string(state.size()) +
                                " numbers does not fit its " + std::to_string(expected) +
                                " (another mesh or shape?)");
  std::size_t k = 0;
  for (Eigen::MatrixXd* m : {&u_n_, &rate_n_, &c_n_})
    for (Eigen::Index r = 0; r < m->rows(); ++r)
      for (Eigen::Index c = 0; c < m->cols(); ++c) (*m)(r, c) = state[k++];
  u_ = u_n_;
  c_ = c_n_;
}

void NurbsSolid::begin_step(const TimeParameters& time) {
  time_ = time;
  stepping_ = true;
  u_ = u_n_ +
       time.dt * rate_n_;  // predictor with unchanged rate: consistent with the generalized-alpha update
  c_ = control_from_points(u_);
}

std::vector<Vec3> NurbsSolid::collocation_points() const {
  std::vector<Vec3> x(n_points());
  for (int i = 0; i < n_points(); ++i) {
    x[i] = reference_points_[i];
    x[i].head(dim_) += (u_n_.row(i) + time_.alpha_f * (u_.row(i) - u_n_.row(i))).transpose();
  }
  return x;
}

Vec3 NurbsSolid::kinematic_residual(const Vec3& u, const Vec3& u_n, const Vec3& rate_n,
                                    const TimeParameters& t, const Vec3& v) {
  const Vec3 rate = (u - u_n) / (t.gamma * t.dt) - (1.0 - t.gamma) / t.gamma * rate_n;
  return rate_n + t.alpha_m * (rate - rate_n) - v;
}

Mat3 NurbsSolid::kinematic_tangent(const TimeParameters& t, const Mat3& grad_v, int dim) {
  Mat3 T = Mat3::Identity() * (t.alpha_m / (t.gamma * t.dt)) - t.alpha_f * grad_v;
  for (int i = dim; i < 3; ++i) T.row(i).setZero(), T.col(i).setZero(), T(i, i) = 1.0;
  return T;
}

double NurbsSolid::kinematic_update(const std::vector<VelocitySample>& samples) {
  return kinematic_update(samples, KinematicShare{});
}

double NurbsSolid::kinematic_update(const std::vector<VelocitySample>& samples, const KinematicShare& share) {
  if (static_cast<int>(samples.size()) != n_points())
    throw std::invalid_argument("kinematic_update: expected " + std::to_string(n_points()) +
                                " samples, got " + std::to_string(samples.size()));
  if (share.parts < 1 || share.part < 0 || share.part >= share.parts ||
      (share.parts > 1 && (!share.gather || !share.sum)))
    throw std::invalid_argument("kinematic_update: part " + std::to_string(share.part) + " of " +
                                std::to_string(share.parts) + " (and, for more than one, gather and sum)");
  const int n = n_points();
  const auto first = [&](int r) { return static_cast<int>(static_cast<long>(n) * r / share.parts); };
  const int i0 = first(share.part), i1 = first(share.part + 1);
  double norm2 = 0;
  kinematic_inverse_.resize(n);
  for (int i = i0; i < i1; ++i) {
    Vec3 u = Vec3::Zero(), un = Vec3::Zero(), rn = Vec3::Zero();
    u.head(dim_) = u_.row(i).transpose();
    un.head(dim_) = u_n_.row(i).transpose();
    rn.head(dim_) = rate_n_.row(i).transpose();
    Vec3 R = kinematic_residual(u, un, rn, time_, samples[i].v);
    for (int c = dim_; c < 3; ++c) R[c] = 0;
    norm2 += R.squaredNorm();
    // Step 2: a d x d solve per point, by the closed-form inverse (T = alpha_m / (gamma dt) I - alpha_f
    // grad v: the identity's multiple dominates at the paper's steps; a pivoted LU per point took 3 times as
    // long).
    const Mat3 T = kinematic_tangent(time_, samples[i].grad_v, dim_);
    kinematic_inverse_[i] = T.inverse();
    const Vec3 du = kinematic_inverse_[i] * (-R);
    u_.row(i) += du.head(dim_).transpose();
  }
  // (about 80 operations a point: the residual, the inverse and its products)
  double operations = 80.0 * (i1 - i0);
  if (share.parts > 1) {  // every rank's points: their displacement and tangent inverse
    const int width = dim_ + 9;
    std::vector<double>& packed = kinematic_packed_;  // (kept: this runs at every coupling iteration)
    packed.resize(static_cast<std::size_t>(n) * width);
    for (int i = i0; i < i1; ++i) {
      double* p = packed.data() + static_cast<std::size_t>(i) * width;
      for (int c = 0; c < dim_; ++c) p[c] = u_(i, c);
      for (int k = 0; k < 9; ++k) p[dim_ + k] = kinematic_inverse_[i](k / 3, k % 3);
    }
    share.gather(packed.data(), width);
    for (int i = 0; i < n; ++i) {
      if (i >= i0 && i < i1) continue;
      const double* p = packed.data() + static_cast<std::size_t>(i) * width;
      for (int c = 0; c < dim_; ++c) u_(i, c) = p[c];
      for (int k = 0; k < 9; ++k) kinematic_inverse_[i](k / 3, k % 3) = p[dim_ + k];
    }
    share.sum(&norm2, 1);
  }
  // Step 3, column by column on more than one rank (each column is its own collocation solve).
  const CollocationSolver& cs = *collocation_solver_;
  const double column_operations =
      2.0 * cs.solve_operations(1) + 2.0 * static_cast<double>(cs.matrix().nonZeros());
  if (share.parts == 1) {
    c_ = control_from_points(u_);
    operations += dim_ * column_operations;
  } else {
    Eigen::MatrixXd c = Eigen::MatrixXd::Zero(n_reduced_, dim_);
    for (int col = 0; col < dim_; ++col) {
      if ((share.first_column + col) % share.parts != share.part) continue;
      c.col(col) = control_from_points(u_.col(col));
      operations += column_operations;
    }
    share.sum(c.data(), static_cast<int>(c.size()));  // (one rank's column, zeros elsewhere: exact)
    c_ = std::move(c);
  }
  if (share.operations) *share.operations += operations;
  return std::sqrt(norm2);
}

bool NurbsSolid::control_increment(const std::vector<Vec3>& dv, Eigen::MatrixXd& dc, int column) const {
  if (static_cast<int>(dv.size()) != n_points())
    throw std::invalid_argument("control_increment: expected " + std::to_string(n_points()) +
                                " velocities, got " + std::to_string(dv.size()));
  if (static_cast<int>(kinematic_inverse_.size()) != n_points()) return false;  // no update made yet
  // Step 2 linearised: T du = dv at each point (kinematic_residual's derivative in v is -I); step 3: the
  // collocation solve; the control at t_{n+alpha_f} moves by alpha_f of it.
  if (column >= dim_)
    throw std::invalid_argument("control_increment: column " + std::to_string(column) + " of " +
                                std::to_string(dim_));
  if (column < 0) {
    Eigen::MatrixXd du(n_points(), dim_);
    for (int i = 0; i < n_points(); ++i) {
      const Vec3 d = kinematic_inverse_[i] * dv[i];
      du.row(i) = d.head(dim_).transpose();
    }
    dc = time_.alpha_f * collocation_solver_->solve(du);
  } else {  // (that component of the tangents' products alone)
    Eigen::MatrixXd du(n_points(), 1);
    for (int i = 0; i < n_points(); ++i) du(i, 0) = kinematic_inverse_[i].row(column).dot(dv[i]);
    dc.setZero(n_reduced_, dim_);
    dc.col(column) = time_.alpha_f * collocation_solver_->solve(du);
  }
  return true;
}

double NurbsSolid::control_increment_operations() const {
  // One component of the tangents' products (a row of a 3 x 3 matrix times a vector per point) and one
  // column's solve.
  return 5.0 * n_points() + collocation_solver_->solve_operations(1);
}

bool NurbsSolid::basis_gradients(std::vector<int>& begin, std::vector<int>& unknown,
                                 std::vector<double>& grad, const std::vector<char>* wanted) const {
  if (wanted && wanted->size() != q_X_.size())
    throw std::invalid_argument("basis_gradients: " + std::to_string(wanted->size()) + " flags for " +
                                std::to_string(q_X_.size()) + " points");
  begin.assign(1, 0);
  unknown.clear();
  grad.clear();
  const char* w = wanted ? wanted->data() : nullptr;
  const std::size_t n_listed = listed_entries(w);  // (reserved at once: this runs at every refresh)
  begin.reserve(q_X_.size() + 1);
  unknown.reserve(n_listed);
  grad.reserve(3 * n_listed);
  return append_basis_gradients(begin, unknown, grad, w, 0);
}

std::size_t NurbsSolid::listed_entries(const char* wanted) const {
  if (shell_thickness_ > 0) return 0;  // (not available for a thin shell: append_basis_gradients says so)
  if (!wanted) return q_unknown_.size();
  std::size_t n = 0;
  for (std::size_t p = 0; p < q_X_.size(); ++p)
    if (wanted[p]) n += static_cast<std::size_t>(q_begin_[p + 1] - q_begin_[p]);
  return n;
}

bool NurbsSolid::append_basis_gradients(std::vector<int>& begin, std::vector<int>& unknown,
                                        std::vector<double>& grad, const char* wanted,
                                        int unknown_offset) const {
  if (begin.empty()) throw std::logic_error("append_basis_gradients: begin must hold where the list starts");
  // A thin shell's point moves with the normal's and lambda3's variation too: not written yet, so the
  // coupler gives it the consistent tangent instead of the collocation one.
  if (shell_thickness_ > 0) return false;
  const int n_q = static_cast<int>(q_X_.size());
  int visited = 0;
  // d N / d x = F^{-T} d N / d X at the configuration quadrature_data() describes (the points not wanted
  // are not evaluated).
  for_each_quadrature_point(
      displacement_control_alpha(),
      [&](int q, const Vec3&, const Mat3& F, double) {
        ++visited;
        Mat3 Fd = Mat3::Identity();
        Fd.topLeftCorner(dim_, dim_) = F.topLeftCorner(dim_, dim_);
        const Mat3 Finv = Fd.inverse();
        for (int k = q_begin_[q]; k < q_begin_[q + 1]; ++k) {
          const double* dN = q_dN_.data() + static_cast<std::size_t>(k) * dim_;
          unknown.push_back(q_unknown_[k] + unknown_offset);
          for (int l = 0; l < 3; ++l) {
            double g = 0;
            for (int a = 0; a < dim_ && l < dim_; ++a) g += dN[a] * Finv(a, l);
            grad.push_back(g);
          }
        }
        begin.push_back(static_cast<int>(unknown.size()));
      },
      wanted);
  return visited ==
         (wanted ? static_cast<int>(std::count_if(wanted, wanted + n_q, [](char f) { return f != 0; }))
                 : n_q);
}

Eigen::MatrixXd NurbsSolid::displacement_control_alpha() const { return c_n_ + time_.alpha_f * (c_ - c_n_); }

void NurbsSolid::kinematics(const Eigen::MatrixXd& c, const Param& xi, const Index3* element, Vec3& x,
                            Mat3& F, double& ref_jacobian, Mat3* frame) const {
  if (shell_thickness_ > 0) {  // xi in reference_patch()'s parameters: direction 0 across, over [0, 1]
    const Param theta{xi[1], xi[2], 0};
    thread_local BasisValues sb;
    reference_.basis(theta, 2, sb);
    MapValues ref, cur;
    reference_.map(sb, ref);
    cur = ref;
    for (int k = 0; k < sb.n; ++k) {
      const int r = reduced_[sb.index[k]];
      const double ck[3] = {c(r, 0), c(r, 1), c(r, 2)};
      add_shell_displacement(cur, shell_basis(sb, k).data(), ck);
    }
    const ShellPoint p = shell_point(ref, cur, (xi[0] - 0.5) * shell_thickness_);
    x = p.x;
    F = p.F;
    ref_jacobian = p.ref_jacobian * shell_thickness_;
    if (frame) *frame = p.frame;
    (void)element;
    return;
  }
  thread_local BasisValues bv;
  thread_local MapValues mv;
  reference_.basis(xi, 1, bv, element);
  reference_.map(bv, mv);
  Mat3 dudxi = Mat3::Zero();
  Vec3 u = Vec3::Zero();
  for (int k = 0; k < bv.n; ++k) {
    const int r = reduced_[bv.index[k]];
    for (int i = 0; i < dim_; ++i) {
      u[i] += bv.value[k] * c(r, i);
      for (int a = 0; a < dim_; ++a) dudxi(i, a) += bv.d1[3 * k + a] * c(r, i);
    }
  }
  const Eigen::MatrixXd dXdxi = mv.dx.topLeftCorner(dim_, dim_);
  F = Mat3::Identity();
  F.topLeftCorner(dim_, dim_) += dudxi.topLeftCorner(dim_, dim_) * dXdxi.inverse();
  x = mv.x + u;
  ref_jacobian = dXdxi.determinant();
  if (frame) *frame = membrane_ && dim_ == 3 ? membrane_frame(mv.dx) : Mat3(Mat3::Identity());
}

namespace {

/// x = X + sum_k N_k c_k and F = I + sum_k c_k (dN_k/dX)^T over a point's functions [begin, end): c
/// row-major, 3 values per reduced unknown; dN: D values per function. The dimension is a template argument,
/// so that the sums unroll (3.4x fewer instructions per point than with it at run time, measured with
/// callgrind); the sums run in the same order as before, so the numbers are the same to the bit.
template <int D>
void point_kinematics(const double* c, const int* unknown, const double* N, const double* dN, int begin,
                      int end, Vec3& x, Mat3& F) {
  double xs[3] = {x[0], x[1], x[2]};
  double Fs[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int k = begin; k < end; ++k) {
    const double* ck = c + 3 * static_cast<std::size_t>(unknown[k]);
    const double n = N[k];
    const double* d = dN + static_cast<std::size_t>(k) * D;
    for (int i = 0; i < D; ++i) {
      xs[i] += n * ck[i];
      for (int j = 0; j < D; ++j) Fs[i][j] += ck[i] * d[j];
    }
  }
  for (int i = 0; i < 3; ++i) {
    x[i] = xs[i];
    for (int j = 0; j < 3; ++j) F(i, j) = Fs[i][j];
  }
}

}  // namespace

void NurbsSolid::for_each_quadrature_point(
    const Eigen::MatrixXd& c, const std::function<void(int, const Vec3&, const Mat3&, double)>& visit,
    const std::vector<char>* only) const {
  if (only && only->size() != q_X_.size())
    throw std::logic_error("body '" + name_ + "': " + std::to_string(only->size()) + " point flags for " +
                           std::to_string(q_X_.size()) + " quadrature points");
  for_each_quadrature_point(c, visit, only ? only->data() : nullptr);
}

void NurbsSolid::for_each_quadrature_point(
    const Eigen::MatrixXd& c, const std::function<void(int, const Vec3&, const Mat3&, double)>& visit,
    const char* only) const {
  const int n_q = static_cast<int>(q_X_.size());
  // The control values row by row (c is column-major: a point's 27 functions would read 3 strided columns).
  std::vector<double> rows(3 * static_cast<std::size_t>(c.rows()), 0.0);
  for (Eigen::Index r = 0; r < c.rows(); ++r)
    for (int i = 0; i < dim_; ++i) rows[3 * r + i] = c(r, i);
  if (shell_thickness_ > 0) {
    for_each_shell_point(rows.data(), visit, only);
    return;
  }
  for (int q = 0; q < n_q; ++q) {
    if (only && !only[q]) continue;
    Vec3 x = q_X_[q];
    Mat3 F;
    if (dim_ == 3)
      point_kinematics<3>(rows.data(), q_unknown_.data(), q_N_.data(), q_dN_.data(), q_begin_[q],
                          q_begin_[q + 1], x, F);
    else
      point_kinematics<2>(rows.data(), q_unknown_.data(), q_N_.data(), q_dN_.data(), q_begin_[q],
                          q_begin_[q + 1], x, F);
    try {
      visit(q, x, F, q_weight_[q]);
    } catch (const std::runtime_error& e) {  // an inverted element (the material refuses det F <= 0)
      // Which element and point: the points run elements in turn, the same number in each.
      std::vector<geometry::QuadraturePoint> qp;
      const Index3 m = reference_.element_multi_index(q / (n_q / reference_.n_elements()));
      geometry::element_quadrature(reference_, m, geometry::default_gauss(reference_), qp);
      throw std::runtime_error(e.what() + where_inverted(m, qp[q % qp.size()].xi, x, F));
    }
  }
}

double NurbsSolid::load_factor() const {
  if (!(load_ramp_ > 0)) return 1.0;
  if (!stepping_) return 0.0;  // before the first step: t = 0, where a ramp starts from nothing
  return std::clamp((time_.t_n + time_.alpha_f * time_.dt) / load_ramp_, 0.0, 1.0);
}

void NurbsSolid::set_loads(const std::vector<PatchLoad>& loads, double ramp) {
  if (!(ramp >= 0) || !std::isfinite(ramp))
    throw std::invalid_argument("body '" + name_ + "': the loads' ramp time must be >= 0 s");
  std::vector<Vec3> X;
  std::vector<double> w;
  reference_quadrature(X, w);
  try {
    set_load_densities(loads.empty() ? std::vector<Vec3>{} : solid::load_densities(X, w, loads), ramp);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("body '" + name_ + "': " + e.what());
  }
}

void NurbsSolid::set_load_densities(std::vector<Vec3> density, double ramp) {
  if (!(ramp >= 0) || !std::isfinite(ramp))
    throw std::invalid_argument("body '" + name_ + "': the loads' ramp time must be >= 0 s");
  if (!density.empty() && density.size() != q_X_.size())
    throw std::invalid_argument("body '" + name_ + "': " + std::to_string(density.size()) +
                                " load densities for " + std::to_string(q_X_.size()) + " quadrature points");
  load_ramp_ = ramp;
  load_density_ = std::move(density);
}

void NurbsSolid::reference_quadrature(std::vector<Vec3>& X, std::vector<double>& w) const {
  X.clear();
  w.clear();
  for_each_quadrature_point(Eigen::MatrixXd::Zero(n_reduced_, dim_),
                            [&](int, const Vec3& x, const Mat3&, double weight) {
                              X.push_back(x);
                              w.push_back(weight);
                            });
}

std::vector<QuadratureData> NurbsSolid::quadrature_data(double fluid_density, bool with_tangent) const {
  std::vector<QuadratureData> out;
  quadrature_data(
      fluid_density, with_tangent, [](std::size_t, const Vec3&) { return true; }, out);
  return out;
}

void NurbsSolid::quadrature_data(double fluid_density, bool with_tangent,
                                 const std::function<bool(std::size_t, const Vec3&)>& wanted,
                                 std::vector<QuadratureData>& out, const std::vector<char>* only) const {
  if (only && only->size() != q_X_.size())
    throw std::logic_error("body '" + name_ + "': " + std::to_string(only->size()) + " point flags for " +
                           std::to_string(q_X_.size()) + " quadrature points");
  out.resize(q_X_.size());
  quadrature_data_into(fluid_density, with_tangent, wanted, out.data(), only ? only->data() : nullptr);
}

void NurbsSolid::quadrature_data_into(double fluid_density, bool with_tangent,
                                      const std::function<bool(std::size_t, const Vec3&)>& wanted,
                                      QuadratureData* out, const char* only) const {
  if (!(fluid_density > 0)) throw std::invalid_argument("quadrature_data: fluid density must be > 0");
  if (shell_thickness_ > 0) {  // (every point: the force at one depends on its functions' points)
    shell_quadrature_data(fluid_density, with_tangent, wanted, out, only);
    return;
  }
  const double beta = 1.0 - density_ / fluid_density;
  for_each_quadrature_point(
      displacement_control_alpha(),
      [&](int q, const Vec3& x, const Mat3& F_global, double weight) {
        QuadratureData& d = out[q];
        d = QuadratureData{};
        d.x = x;
        d.weight = weight;
        d.beta = beta;
        d.shear_modulus = material_->tangent_shear_modulus();
        if (membrane_) d.area = q_area_[q];
        // A membrane surface law takes F in the membrane's frame; tau and c come out the same (Material).
        const Mat3 F = q_frame_.empty() ? F_global : Mat3(F_global * q_frame_[q]);
        if (!wanted(q, x)) {
          // Another rank's point: only the laws' own refusal of an inverted element, so that every rank
          // refuses the same configuration.
          Material::check_deformation(F, dim_);
          return;
        }
        d.stress = F * material_->second_piola(F, dim_) * F.transpose() / fluid_density;
        if (with_tangent) {
          d.has_tangent = true;
          const Voigt6 c = material_->spatial_tangent(F, dim_);
          for (int r = 0, t = 0; r < 6; ++r)
            for (int k = r; k < 6; ++k, ++t) d.tangent[t] = c(r, k) / fluid_density;
        }
        if (!load_density_.empty()) d.force = load_factor() * load_density_[q] / fluid_density;
      },
      only);
}

std::string NurbsSolid::where_inverted(const Index3& element, const Param& xi, const Vec3& x, const Mat3& F) const {
  // Says where, and how: which reference direction collapsed (for a membrane direction 0 runs through its
  // thickness), so that a user can tell a thickness crushed between two close sheets from a sheared surface.
  thread_local BasisValues bv;
  thread_local MapValues mv;
  reference_.basis(xi, 1, bv, &element);
  reference_.map(bv, mv);
  char s[400];
  std::string out = "; body '" + name_ + "', element (";
  for (int a = 0; a < dim_; ++a)
    out += std::to_string(element[a]) + (a + 1 < dim_ ? ", " : ") of ");
  for (int a = 0; a < dim_; ++a)
    out += std::to_string(reference_.n_elements(a)) + (a + 1 < dim_ ? " x " : "");
  std::snprintf(s, sizeof s, ", at x = (%.4g, %.4g, %.4g) cm; stretch along the reference directions:", x[0], x[1],
                x[2]);
  out += s;
  for (int a = 0; a < dim_; ++a) {
    const Vec3 t = mv.dx.col(a);
    const double n = t.norm();
    const double stretch = n > 0 ? (F * t).norm() / n : 0.0;
    std::snprintf(s, sizeof s, "%s%.3g", a ? ", " : " ", stretch);
    out += s;
  }
  return out + (is_membrane() ? " (direction 0: through the membrane's thickness)" : "");
}

std::vector<Mat3> NurbsSolid::cauchy_stress(const std::vector<Param>& xi) const {
  std::vector<Mat3> out(xi.size());
  for (size_t i = 0; i < xi.size(); ++i) {
    Vec3 x;
    Mat3 F, frame;
    double jac0 = 0;
    try {
      kinematics(c_n_, xi[i], nullptr, x, F, jac0,
                 q_frame_.empty() ? nullptr : &frame);  // only a surface law's
    } catch (const std::invalid_argument&) {            // (a thin shell's collapsed mid-surface)
      out[i] = Mat3::Constant(std::numeric_limits<double>::quiet_NaN());
      continue;
    }
    if (!q_frame_.empty()) F = F * frame;
    const double J = F.topLeftCorner(dim_, dim_).determinant();
    // Output only: NaN where F is undefined (a degenerate point) or inverted, instead of stopping the run.
    out[i] = J > 0 && std::isfinite(J) ? Mat3(F * material_->second_piola(F, dim_) * F.transpose() / J)
                                       : Mat3::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  return out;
}

std::vector<Vec3> NurbsSolid::interface_points() const {
  if (shell_thickness_ > 0) {  // both faces above and below each collocation point
    std::vector<geometry::Vec3> cps = reference_.control_points();
    const Eigen::MatrixXd c = displacement_control_alpha();
    for (int k = 0; k < reference_.n_control(); ++k)
      for (int i = 0; i < 3; ++i) cps[k][i] += c(reduced_[k], i);
    const geometry::Patch now(reference_.all_knots(), 3, std::move(cps), reference_.weights(),
                              reference_.shifts());
    std::vector<Vec3> out;
    for (const Param& xi : point_xi_)
      for (double side : {-0.5, 0.5})
        out.push_back(
            shell_point(reference_.evaluate(xi, 2), now.evaluate(xi, 2), side * shell_thickness_).x);
    return out;
  }
  const std::vector<Vec3> x = collocation_points();
  std::vector<Vec3> out;
  for (int q : face_points_) out.push_back(x[q]);
  return out;
}

void NurbsSolid::end_step() {
  const double g = time_.gamma, dt = time_.dt;
  const Eigen::MatrixXd rate = (u_ - u_n_) / (g * dt) - (1.0 - g) / g * rate_n_;
  u_n_ = u_;
  rate_n_ = rate;
  c_n_ = c_;
}

geometry::Patch NurbsSolid::reference_patch() const {
  if (shell_thickness_ > 0) return shell_as_thick_patch(Eigen::MatrixXd::Zero(n_reduced_, dim_));
  return reference_;
}

geometry::Patch NurbsSolid::shell_as_thick_patch(const Eigen::MatrixXd& c) const {
  std::vector<geometry::Vec3> mid = reference_.control_points();
  for (int k = 0; k < reference_.n_control(); ++k)
    for (int i = 0; i < 3; ++i) mid[k][i] += c(reduced_[k], i);
  const geometry::Patch now(reference_.all_knots(), 3, mid, reference_.weights(), reference_.shifts());
  const std::vector<double> g0 = reference_.knots(0).greville(), g1 = reference_.knots(1).greville();
  const int n0 = reference_.n_control(0), n1 = reference_.n_control(1);
  std::vector<geometry::Vec3> cps(2 * mid.size());
  std::vector<double> weights(2 * mid.size());
  for (int j = 0; j < n1; ++j)
    for (int i = 0; i < n0; ++i) {
      const int k = i + n0 * j;
      const Param theta{g0[i], g1[j], 0};
      const MapValues r = reference_.evaluate(theta, 1), m = now.evaluate(theta, 1);
      const Vec3 cr = r.dx.col(0).cross(r.dx.col(1)), cm = m.dx.col(0).cross(m.dx.col(1));
      // (where the mid-surface degenerates, no offset: its layers meet there)
      const Vec3 offset = cm.norm() > 0 && cr.norm() > 0
                              ? Vec3(0.5 * shell_thickness_ * cr.norm() / cm.squaredNorm() * cm)
                              : Vec3::Zero();
      for (int a = 0; a < 2; ++a) {
        cps[a + 2 * k] = mid[k] + (a == 0 ? -offset : offset);
        weights[a + 2 * k] = reference_.weights()[k];
      }
    }
  const std::array<geometry::Vec3, 3> shifts = {geometry::Vec3::Zero(), reference_.shifts()[0],
                                                reference_.shifts()[1]};
  return geometry::Patch({geometry::KnotVector::open_uniform(1, 1), reference_.knots(0), reference_.knots(1)},
                         3, std::move(cps), std::move(weights), shifts);
}

geometry::Patch NurbsSolid::current_patch() const {
  if (shell_thickness_ > 0) return shell_as_thick_patch(c_n_);
  std::vector<geometry::Vec3> cps = reference_.control_points();
  for (int k = 0; k < reference_.n_control(); ++k)
    for (int i = 0; i < dim_; ++i) cps[k][i] += c_n_(reduced_[k], i);
  return geometry::Patch(reference_.all_knots(), dim_, std::move(cps), reference_.weights(),
                         reference_.shifts());
}

}  // namespace cellfsi::solid
