#include "solid/composite_solid.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace cellfsi::solid {

CompositeSolid::CompositeSolid(std::string name, std::vector<std::unique_ptr<NurbsSolid>> parts)
    : name_(std::move(name)), parts_(std::move(parts)) {
  if (parts_.empty()) throw std::invalid_argument("CompositeSolid '" + name_ + "': no parts");
  point_begin_ = quadrature_begin_ = control_begin_ = {0};
  for (const auto& p : parts_) {
    if (!p) throw std::invalid_argument("CompositeSolid '" + name_ + "': a part is missing");
    if (p->dim() != parts_[0]->dim() || p->is_membrane() != parts_[0]->is_membrane())
      throw std::invalid_argument("CompositeSolid '" + name_ +
                                  "': the parts must share the dimension and be all membranes or all bulky");
    point_begin_.push_back(point_begin_.back() + p->n_points());
    quadrature_begin_.push_back(quadrature_begin_.back() + p->n_quadrature_points());
    control_begin_.push_back(control_begin_.back() + p->n_control());
  }
}

void CompositeSolid::begin_step(const TimeParameters& time) {
  for (auto& p : parts_) p->begin_step(time);
}

std::vector<Vec3> CompositeSolid::collocation_points() const {
  std::vector<Vec3> out;
  out.reserve(static_cast<std::size_t>(point_begin_.back()));
  for (const auto& p : parts_) {
    const std::vector<Vec3> x = p->collocation_points();
    out.insert(out.end(), x.begin(), x.end());
  }
  return out;
}

double CompositeSolid::kinematic_update(const std::vector<VelocitySample>& samples) {
  if (static_cast<int>(samples.size()) != point_begin_.back())
    throw std::invalid_argument("kinematic_update: body '" + name_ + "' expected " +
                                std::to_string(point_begin_.back()) + " samples, got " +
                                std::to_string(samples.size()));
  // The parts' residual norms make the body's: the square root of their squares' sum.
  double sum = 0;
  for (int k = 0; k < n_parts(); ++k) {
    const double r = parts_[k]->kinematic_update(run(samples, k));
    sum += r * r;
  }
  return std::sqrt(sum);
}

double CompositeSolid::kinematic_update(const std::vector<VelocitySample>& samples,
                                        const KinematicShare& share) {
  (void)share;  // (every rank that holds the body does all of it: the same state on each)
  return kinematic_update(samples);
}

std::vector<QuadratureData> CompositeSolid::quadrature_data(double fluid_density, bool with_tangent) const {
  std::vector<QuadratureData> out;
  out.reserve(static_cast<std::size_t>(quadrature_begin_.back()));
  for (const auto& p : parts_) {
    const std::vector<QuadratureData> q = p->quadrature_data(fluid_density, with_tangent);
    out.insert(out.end(), q.begin(), q.end());
  }
  return out;
}

void CompositeSolid::quadrature_data(double fluid_density, bool with_tangent,
                                     const std::function<bool(std::size_t, const Vec3&)>& wanted,
                                     std::vector<QuadratureData>& out, const std::vector<char>* only) const {
  const std::size_t n = static_cast<std::size_t>(quadrature_begin_.back());
  if (only && only->size() != n)
    throw std::logic_error("body '" + name_ + "': " + std::to_string(only->size()) + " point flags for " +
                           std::to_string(n) + " quadrature points");
  out.resize(n);
  // Each part writes its run of `out` in place (through buffers of their own, at a red cell of six patches
  // the copies were a twentieth of the run: perf).
  for (int k = 0; k < n_parts(); ++k) {
    const std::size_t first = static_cast<std::size_t>(quadrature_begin_[k]);
    parts_[k]->quadrature_data_into(
        fluid_density, with_tangent, [&](std::size_t q, const Vec3& x) { return wanted(first + q, x); },
        out.data() + first, only ? only->data() + first : nullptr);
  }
}

bool CompositeSolid::control_increment(const std::vector<Vec3>& dv, Eigen::MatrixXd& dc, int column) const {
  if (static_cast<int>(dv.size()) != point_begin_.back())
    throw std::invalid_argument("control_increment: body '" + name_ + "' expected " +
                                std::to_string(point_begin_.back()) + " velocities, got " +
                                std::to_string(dv.size()));
  dc.setZero(control_begin_.back(), dim());
  Eigen::MatrixXd part_dc;
  for (int k = 0; k < n_parts(); ++k) {
    if (!parts_[k]->control_increment(run(dv, k), part_dc, column)) return false;
    dc.middleRows(control_begin_[k], control_begin_[k + 1] - control_begin_[k]) = part_dc;
  }
  return true;
}

double CompositeSolid::control_increment_operations() const {
  double ops = 0;
  for (const auto& p : parts_) ops += p->control_increment_operations();
  return ops;
}

bool CompositeSolid::basis_gradients(std::vector<int>& begin, std::vector<int>& unknown,
                                     std::vector<double>& grad, const std::vector<char>* wanted) const {
  const std::size_t n = static_cast<std::size_t>(quadrature_begin_.back());
  if (wanted && wanted->size() != n)
    throw std::invalid_argument("basis_gradients: " + std::to_string(wanted->size()) + " flags for " +
                                std::to_string(n) + " points");
  begin.assign(1, 0);
  unknown.clear();
  grad.clear();
  // The parts append theirs in place (reserved at once: this runs at every refresh of the Jacobian).
  std::size_t listed = 0;
  for (int k = 0; k < n_parts(); ++k)
    listed += parts_[k]->listed_entries(wanted ? wanted->data() + quadrature_begin_[k] : nullptr);
  begin.reserve(n + 1);
  unknown.reserve(listed);
  grad.reserve(3 * listed);
  for (int k = 0; k < n_parts(); ++k)
    if (!parts_[k]->append_basis_gradients(begin, unknown, grad,
                                           wanted ? wanted->data() + quadrature_begin_[k] : nullptr,
                                           control_begin_[k]))
      return false;
  return true;
}

std::vector<Vec3> CompositeSolid::interface_points() const {
  std::vector<Vec3> out;
  for (const auto& p : parts_) {
    const std::vector<Vec3> x = p->interface_points();
    out.insert(out.end(), x.begin(), x.end());
  }
  return out;
}

void CompositeSolid::end_step() {
  for (auto& p : parts_) p->end_step();
}

void CompositeSolid::set_rate(const std::vector<Vec3>& rate) {
  if (static_cast<int>(rate.size()) != point_begin_.back())
    throw std::invalid_argument("set_rate: one value per point");
  for (int k = 0; k < n_parts(); ++k) parts_[k]->set_rate(run(rate, k));
}

std::vector<double> CompositeSolid::state() const {
  std::vector<double> out;
  for (const auto& p : parts_) {
    const std::vector<double> s = p->state();
    out.insert(out.end(), s.begin(), s.end());
  }
  return out;
}

void CompositeSolid::set_state(const std::vector<double>& state) {
  std::size_t at = 0;
  std::vector<std::size_t> sizes;
  for (const auto& p : parts_) sizes.push_back(p->state().size());
  std::size_t total = 0;
  for (std::size_t s : sizes) total += s;
  if (state.size() != total)
    throw std::invalid_argument("body '" + name_ + "': a state of " + std::to_string(state.size()) +
                                " numbers does not fit its " + std::to_string(total) +
                                " (another mesh or shape?)");
  for (int k = 0; k < n_parts(); ++k) {
    parts_[k]->set_state(std::vector<double>(state.begin() + static_cast<long>(at),
                                             state.begin() + static_cast<long>(at + sizes[k])));
    at += sizes[k];
  }
}

geometry::Patch CompositeSolid::reference_patch() const {
  throw std::logic_error("body '" + name_ + "' is made of " + std::to_string(n_parts()) +
                         " patches: ask for reference_patches()");
}

geometry::Patch CompositeSolid::current_patch() const {
  throw std::logic_error("body '" + name_ + "' is made of " + std::to_string(n_parts()) +
                         " patches: ask for current_patches()");
}

std::vector<geometry::Patch> CompositeSolid::reference_patches() const {
  std::vector<geometry::Patch> out;
  for (const auto& p : parts_) out.push_back(p->reference_patch());
  return out;
}

void CompositeSolid::set_loads(const std::vector<PatchLoad>& loads, double ramp) {
  std::vector<Vec3> X, part_X;
  std::vector<double> w, part_w;
  std::vector<std::size_t> begin{0};
  for (const auto& p : parts_) {
    p->reference_quadrature(part_X, part_w);
    X.insert(X.end(), part_X.begin(), part_X.end());
    w.insert(w.end(), part_w.begin(), part_w.end());
    begin.push_back(X.size());
  }
  std::vector<Vec3> density;
  try {
    if (!loads.empty()) density = load_densities(X, w, loads);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("body '" + name_ + "': " + e.what());
  }
  for (std::size_t k = 0; k < parts_.size(); ++k)
    parts_[k]->set_load_densities(
        density.empty() ? std::vector<Vec3>{}
                        : std::vector<Vec3>(density.begin() + static_cast<std::ptrdiff_t>(begin[k]),
                                            density.begin() + static_cast<std::ptrdiff_t>(begin[k + 1])),
        ramp);
}

std::vector<geometry::Patch> CompositeSolid::current_patches() const {
  std::vector<geometry::Patch> out;
  for (const auto& p : parts_) out.push_back(p->current_patch());
  return out;
}

std::vector<Mat3> CompositeSolid::cauchy_stress(const std::vector<geometry::Param>& xi) const {
  return parts_[0]->cauchy_stress(xi);
}

}  // namespace cellfsi::solid
