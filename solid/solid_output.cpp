#include "solid/solid_output.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>

#include "solid/composite_solid.hpp"

namespace cellfsi::solid {

namespace {

/// The output's samples of `ref`, just off every open end of the parameter domain: degenerate faces (a bulky
/// body's centre; in 3D the poles, the ends of the polar direction) have F undefined there.
std::vector<geometry::Param> output_samples(const geometry::Patch& ref, int samples) {
  std::vector<geometry::Param> xi = geometry::sample_grid(ref, samples);
  for (int d = 0; d < ref.param_dim(); ++d) {
    const geometry::KnotVector& k = ref.knots(d);
    if (k.periodic() || ref.closed(d)) continue;
    const double eps = 1e-9 * (k.b() - k.a());
    for (geometry::Param& p : xi) p[d] = std::clamp(p[d], k.a() + eps, k.b() - eps);
  }
  return xi;
}

double jacobian_ratio(const geometry::MapValues& X, const geometry::MapValues& x, int D) {
  return x.dx.topLeftCorner(D, D).determinant() / X.dx.topLeftCorner(D, D).determinant();
}

}  // namespace

SolidSeriesWriter::SolidSeriesWriter(std::string dir, bool writes, int samples_per_element)
    : dir_(std::move(dir)), writes_(writes), samples_(samples_per_element) {}

void SolidSeriesWriter::write(double time, const std::vector<SolidSolver*>& bodies) {
  if (writes_) {
    smallest_.assign(bodies.size(), {std::numeric_limits<double>::infinity(), geometry::Vec3::Zero(), time});
    history_.resize(bodies.size());
  }
  int dataset = 0;  // the collection's part index: a body's, or each patch's of a body made of patches
  for (size_t b = 0; b < bodies.size(); ++b) {
    const auto* composite = dynamic_cast<const CompositeSolid*>(bodies[b]);
    const int n_parts = composite ? composite->n_parts() : 1;
    for (int k = 0; k < n_parts; ++k, ++dataset) {
      const SolidSolver& body = composite ? static_cast<const SolidSolver&>(composite->part(k)) : *bodies[b];
      write_body(time, b, dataset, body, bodies[b]->name() + (composite ? "_p" + std::to_string(k) : ""));
    }
  }
  ++count_;
  if (writes_) geometry::write_pvd(dir_ + "/solid.pvd", entries_);
}

void SolidSeriesWriter::write_body(double time, std::size_t b, int dataset, const SolidSolver& body,
                                   const std::string& file_name) {
  const geometry::Patch ref = body.reference_patch();
  const geometry::Patch cur = body.current_patch();
  const std::vector<geometry::Param> xi = output_samples(ref, samples_);
  const std::vector<Mat3> sigma = body.cauchy_stress(xi);
  if (!writes_) return;
  const int D = ref.physical_dim();
  geometry::PointField disp{"displacement", 3, {}}, jac{"J", 1, {}}, stress{"stress", 9, {}};
  for (size_t i = 0; i < xi.size(); ++i) {
    const geometry::MapValues X = ref.evaluate(xi[i], 1), x = cur.evaluate(xi[i], 1);
    const geometry::Vec3 u = x.x - X.x;
    disp.values.insert(disp.values.end(), u.data(), u.data() + 3);
    jac.values.push_back(jacobian_ratio(X, x, D));
    if (jac.values.back() < smallest_[b].J) smallest_[b] = {jac.values.back(), x.x, time};
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) stress.values.push_back(sigma[i](r, c));
  }
  JHistory& h = history_[b];
  if (smallest_[b].J < h.least.J) h.least = smallest_[b];
  if (!h.folded && smallest_[b].J <= 0) {
    h.folded = true;
    h.first_fold = smallest_[b];
  }
  char name[512];
  std::snprintf(name, sizeof name, "solid_%s_%06d.vts", file_name.c_str(), count_);
  geometry::write_patch_vts(cur, dir_ + "/" + name, samples_, {disp, jac, stress});
  entries_.push_back({name, time, dataset, file_name});
}

}  // namespace cellfsi::solid
