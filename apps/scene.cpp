#include "apps/scene.hpp"

#include <petscsys.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>

#include "common/option_table.hpp"
#include "common/petsc_error.hpp"
#include "coupling/inner_viscosity.hpp"
#include "coupling/locator.hpp"
#include "coupling/placement.hpp"
#include "coupling/repulsion.hpp"
#include "geometry/measures.hpp"
#include "geometry/refine.hpp"
#include "solid/composite_solid.hpp"

namespace cellfsi::app {

using geometry::Vec3;

geometry::Patch build_domain(const SceneSettings& s) {
  if (s.domain == "rectangle")
    return geometry::rectangle(s.size[0], s.size[1], s.elements[0], s.elements[1], s.degree,
                               {s.periodic[0], s.periodic[1]}, s.origin);
  if (s.domain == "box")
    return geometry::box(s.size[0], s.size[1], s.size[2], s.elements[0], s.elements[1], s.elements[2],
                         s.degree, {s.periodic[0], s.periodic[1], s.periodic[2]}, s.origin);
  return geometry::narrowing_channel(s.channel, s.elements[0], s.elements[1], s.degree);
}

namespace {

/// The smallest Eulerian element extent of the scene's (uniform or channel) mesh.
double fluid_element_size(const SceneSettings& s) {
  if (s.domain == "narrowing")
    return std::min({s.channel.length / s.elements[0], s.channel.throat_height / s.elements[1]});
  double h = 1e300;
  for (int d = 0; d < s.dim; ++d) h = std::min(h, s.size[d] / s.elements[d]);
  return h;
}

std::vector<geometry::Patch> make_body_parts(const SceneSettings& s, const BodySettings& b,
                                             const std::array<int, 3>& n);

/// A membrane's patch raised to -thickness_degree through its thickness (direction 0; the map is unchanged).
geometry::Patch through_thickness(geometry::Patch p, const BodySettings& b) {
  if (b.membrane() && b.degree_through() > p.degree(0))
    p = geometry::elevate_degree(p, 0, b.degree_through() - p.degree(0));
  return p;
}

geometry::Patch make_body(const SceneSettings& s, const BodySettings& b, const std::array<int, 3>& n) {
  if (b.patches > 1)
    throw std::logic_error("body '" + b.name + "' is made of " + std::to_string(b.patches) +
                           " patches: build its parts");
  Vec3 c = b.center;
  if (!std::isfinite(c[0])) {
    Vec3 lo, hi;
    build_domain(s).bounding_box(lo, hi);
    c = 0.5 * (lo + hi);
  }
  const double angle = b.angle_deg * std::numbers::pi / 180;
  const std::vector<double>& a = b.semi_axes;
  if (b.shape == "hollow_ellipse")
    return through_thickness(geometry::hollow_ellipse(a[0], a[1], b.thickness, n[1], b.degree, c, angle), b);
  if (b.shape == "ellipse") return geometry::bulky_ellipse(a[0], a[1], n[0], n[1], b.degree, c, angle);
  if (b.shape == "rbc")
    return through_thickness(geometry::biconcave_rbc(b.thickness, n[1], b.degree, c, angle,
                                                     b.area > 0 ? b.area : geometry::kRbcArea2d),
                             b);
  // 3D: built axis-aligned at c, then turned about c.
  const geometry::Mat3 A = Eigen::AngleAxisd(angle, b.axis).toRotationMatrix();
  const geometry::Patch axis_aligned =
      b.shape == "hollow_ellipsoid"
          ? geometry::hollow_ellipsoid(a[0], a[1], a[2], b.thickness, n[1], n[2], b.degree, c)
      : b.shape == "rbc_3d" ? geometry::biconcave_rbc_3d(b.thickness, n[1], n[2], b.degree, c)
                            : geometry::solid_ellipsoid(a[0], a[1], a[2], n[0], n[1], n[2], b.degree, c);
  return through_thickness(geometry::transformed(axis_aligned, A, c - A * c), b);
}

/// The body's patches: one, or the rbc_3d's six faces (n[1] x n[1] elements each), turned as make_body turns.
std::vector<geometry::Patch> make_body_parts(const SceneSettings& s, const BodySettings& b,
                                             const std::array<int, 3>& n) {
  if (b.patches == 1) return {make_body(s, b, n)};
  Vec3 c = b.center;
  if (!std::isfinite(c[0])) {
    Vec3 lo, hi;
    build_domain(s).bounding_box(lo, hi);
    c = 0.5 * (lo + hi);
  }
  const geometry::Mat3 A = Eigen::AngleAxisd(b.angle_deg * std::numbers::pi / 180, b.axis).toRotationMatrix();
  std::vector<geometry::Patch> parts;
  for (const geometry::Patch& p : geometry::biconcave_rbc_3d_faces(b.thickness, n[1], b.degree, c))
    parts.push_back(through_thickness(geometry::transformed(p, A, c - A * c), b));
  return parts;
}

}  // namespace

std::array<int, 3> body_element_counts(const SceneSettings& s, const BodySettings& b) {
  // Automatic counts: elements slightly smaller (0.9) than the smallest fluid element (paper Sec. 3.4),
  // scaled from a trial mesh (element size ~ 1 / count). On the divergence-conforming space the cell's area
  // follows the fluid's divergence-free velocity, and what is left of its error is the membrane's own
  // interpolation of that velocity between its collocation points, so 2D membranes get 0.1125 (measured on
  // the capsule, k' = 2: at 64 x 32 to t = 0.1 s r_A -7.1e-3 at 0.9, +1.8e-4 at 0.45, -1.4e-4 at 0.225; at dt
  // 2.5e-4 r_A drifts by +1.2e-4 per second at 0.225 on 128 x 64 and 256 x 128, by -0.6e-5 at 0.1125;
  // docs/validation.md, "The divergence-conforming space"). Bulk bodies and 3D keep 0.225, not measured finer
  // (in 3D a membrane's elements grow as the square: 0.1125 gave the 3D compound capsule 22 k of them at
  // 16^3).
  // -solid_NAME_element_ratio replaces the rule (a scene whose cells need less than the rule's margin).
  const double factor = s.fluid_space != "div_conforming" ? 0.9 : b.membrane() && s.dim == 2 ? 0.1125 : 0.225;
  const double ratio = b.element_ratio > 0 ? b.element_ratio : factor * std::min(1.0, s.max_mesh_ratio);
  const double target = ratio * fluid_element_size(s);
  std::array<int, 3> n = b.elements;
  const int D = s.dim;
  const int mult = 4;  // elements around: every builder needs a multiple of 4
  if (b.membrane()) n[0] = 1;
  std::array<int, 3> trial{b.membrane() ? 1 : 2, 16, 16};
  if (D == 3) trial[1] = b.patches > 1 ? 16 : 8;
  bool any_auto = false;
  for (int d = 0; d < D; ++d) any_auto = any_auto || n[d] == 0;
  if (!any_auto) return n;
  // The trial's element sizes do not depend on where it is: drawn at the origin, not at the domain's centre
  // (which would build the fluid patch).
  BodySettings at_origin = b;
  if (!std::isfinite(at_origin.center[0])) at_origin.center = Vec3::Zero();
  const std::vector<geometry::Patch> parts = make_body_parts(s, at_origin, trial);
  for (int d = 0; d < D; ++d) {
    if (n[d] != 0) continue;
    // Largest extent along direction d of the trial mesh (measured as the Remark 3 check measures it).
    double ext = 0;
    for (const geometry::Patch& t : parts)
      for (int e = 0; e < t.n_elements(); ++e) ext = std::max(ext, geometry::element_extents(t, e)[d]);
    // Capped where int ends (a throat far narrower than the cell asks for billions): the memory check
    // refuses such a count with its estimate.
    const double m = std::min(std::max(d == 0 ? 2.0 : 4.0, std::ceil(trial[d] * ext / target)), 1e9);
    const int step = d == 0 || b.patches > 1 ? 1 : (D == 3 && d == 1 ? 2 : mult);
    n[d] = (static_cast<int>(m) + step - 1) / step * step;
  }
  // The cube's faces: n x n on each (the larger of the two directions' counts).
  if (b.patches > 1) n[1] = n[2] = std::max(n[1], n[2]);
  return n;
}

geometry::Patch build_body_patch(const SceneSettings& s, const BodySettings& b) {
  return make_body(s, b, body_element_counts(s, b));
}

std::vector<geometry::Patch> build_body_parts(const SceneSettings& s, const BodySettings& b) {
  return make_body_parts(s, b, body_element_counts(s, b));
}

std::shared_ptr<const solid::Material> make_material(const BodySettings& b) {
  if (b.material == "mooney_rivlin")
    return std::make_shared<solid::DeviatoricMooneyRivlin>(b.shear_modulus, b.mooney_rivlin_fraction);
  if (b.material == "strain_hardening")
    return std::make_shared<solid::DeviatoricStrainHardening>(b.shear_modulus, b.hardening_c3);
  if (b.material == "skalak")
    return std::make_shared<solid::SkalakMembrane>(b.shear_modulus, b.area_dilation);
  if (b.material == "strain_hardening_membrane")
    return std::make_shared<solid::StrainHardeningMembrane>(b.shear_modulus, b.hardening_c3, b.area_dilation);
  if (b.material != "neo_hookean") throw std::invalid_argument("unknown material law '" + b.material + "'");
  return std::make_shared<solid::DeviatoricNeoHookean>(b.shear_modulus);
}

std::vector<solid::PatchLoad> stretch_loads(const BodySettings& b,
                                            const std::vector<geometry::Patch>& reference) {
  if (!b.stretched || b.stretch_force == 0) return {};
  std::vector<Vec3> points;
  for (const geometry::Patch& p : reference) {
    const std::vector<Vec3> some = solid::mid_surface_points(p);
    points.insert(points.end(), some.begin(), some.end());
  }
  const std::array<Vec3, 2> ends = solid::membrane_ends(points, b.stretch_axis);
  const double r = b.stretch_patch / 2;
  return {{ends[0], r, -b.stretch_force * b.stretch_axis}, {ends[1], r, b.stretch_force * b.stretch_axis}};
}

/// Body::set_loads, a refusal said as the contact diameter's.
template <class Body>
void set_stretch_loads(Body& body, const BodySettings& b, const std::vector<solid::PatchLoad>& loads) {
  try {
    body.set_loads(loads, b.stretch_ramp);
  } catch (const std::invalid_argument& e) {
    bad_option("solid_" + b.name + "_stretch_patch", option_value_text(b.stretch_patch),
               std::string("a contact diameter whose two patches hold material and do not overlap (") +
                   e.what() + ")");
  }
}

void check_bodies_on_solid_ranks(const SceneSettings& s) {
  for (const BodySettings& b : s.bodies)
    if (b.patches > 1)
      bad_option(
          "solid_" + b.name + "_patches", std::to_string(b.patches),
          "1 with the bodies on solid ranks (-solid_ranks, cellfsi-solid): a body of several patches runs "
          "in the fluid's ranks");
}

std::vector<std::unique_ptr<solid::SolidSolver>> build_bodies(const SceneSettings& s) {
  std::vector<std::unique_ptr<solid::SolidSolver>> out;
  for (const BodySettings& b : s.bodies) {
    if (b.patches > 1) {
      // One NurbsSolid a face, one body; each face named as its output files are (NAME_pK), so that a
      // part's error says which face.
      std::vector<geometry::Patch> faces = build_body_parts(s, b);
      const std::vector<solid::PatchLoad> loads = stretch_loads(b, faces);
      std::vector<std::unique_ptr<solid::NurbsSolid>> parts;
      for (std::size_t k = 0; k < faces.size(); ++k) {
        const std::string part = b.name + "_p" + std::to_string(k);
        parts.push_back(b.thin_shell
                            ? std::make_unique<solid::NurbsSolid>(part, geometry::mid_surface(faces[k]),
                                                                  b.thickness, make_material(b), b.density)
                            : std::make_unique<solid::NurbsSolid>(part, std::move(faces[k]), make_material(b),
                                                                  b.density));
      }
      auto body = std::make_unique<solid::CompositeSolid>(b.name, std::move(parts));
      set_stretch_loads(*body, b, loads);
      out.push_back(std::move(body));
      continue;
    }
    geometry::Patch patch = build_body_patch(s, b);
    const std::vector<solid::PatchLoad> loads = stretch_loads(b, std::vector<geometry::Patch>{patch});
    // (a thin shell is refused on one patch: a polar mid-surface has no normal at its poles)
    auto body = std::make_unique<solid::NurbsSolid>(b.name, std::move(patch), make_material(b), b.density);
    solid::NurbsSolid& nurbs = *body;
    out.push_back(std::move(body));
    // The direction-by-direction solve is several times faster: say so when a body cannot have it.
    if (const solid::CollocationSolver& cs = nurbs.collocation_solver(); !cs.by_direction())
      CELLFSI_PETSC(
          PetscPrintf(PETSC_COMM_WORLD,
                      "cellfsi: body '%s': collocation solves by a sparse LU of the whole matrix (%s)\n",
                      b.name.c_str(), cs.fallback_reason().c_str()));
    set_stretch_loads(nurbs, b, loads);
  }
  return out;
}

namespace {

/// A body as place_scattered_copies sees it: points on its surface (a membrane's mid-surface, a bulky body's
/// outer face), their box, and the membrane's patch (for what it encloses).
struct Outline {
  std::vector<Vec3> points;
  Vec3 lo, hi;
  std::vector<geometry::Patch> membrane;  // (empty: a bulky body)
};

Outline outline_of(const std::vector<geometry::Patch>& parts, bool membrane, int dim) {
  Outline o;
  const geometry::Patch& p = parts[0];
  const int n1 = 8 * p.n_elements(1), n2 = dim == 3 ? 4 * p.n_elements(2) : 1;
  if (membrane) {
    for (const geometry::Patch& part : parts) {
      const std::vector<Vec3> x = solid::mid_surface_points(part, n1 + 1, n2 + 1);
      o.points.insert(o.points.end(), x.begin(), x.end());
    }
    o.membrane = parts;
  } else {
    const geometry::KnotVector &k1 = p.knots(1), &k2 = p.knots(dim == 3 ? 2 : 1);
    for (int i = 0; i <= n1; ++i)
      for (int j = 0; j <= (dim == 3 ? n2 : 0); ++j)
        o.points.push_back(p.point({p.knots(0).b(), k1.a() + (k1.b() - k1.a()) * i / n1,
                                    dim == 3 ? k2.a() + (k2.b() - k2.a()) * j / n2 : 0.0}));
  }
  o.lo = o.hi = o.points.front();
  for (const Vec3& x : o.points) o.lo = o.lo.cwiseMin(x), o.hi = o.hi.cwiseMax(x);
  return o;
}

/// Whether outline a, moved by t, keeps at least `gap` from b and neither encloses the other.
bool apart(const Outline& a, const Vec3& t, const Outline& b, double gap, int dim) {
  for (int d = 0; d < dim; ++d)
    if (a.lo[d] + t[d] > b.hi[d] + gap || b.lo[d] > a.hi[d] + t[d] + gap) return true;
  const double g2 = gap * gap;
  for (const Vec3& x : a.points)
    for (const Vec3& y : b.points)
      if ((x + t - y).squaredNorm() < g2) return false;
  // Boundaries apart: one lies wholly inside the other or neither does; one point of each tells.
  if (!b.membrane.empty() && coupling::inside_membrane(b.membrane, {a.points.front() + t})[0]) return false;
  if (!a.membrane.empty() && coupling::inside_membrane(a.membrane, {b.points.front() - t})[0]) return false;
  return true;
}

}  // namespace

void place_scattered_copies(SceneSettings& s) {
  if (std::none_of(s.bodies.begin(), s.bodies.end(), [](const BodySettings& b) { return b.scattered; }))
    return;
  const int D = s.dim;
  const geometry::Patch domain = build_domain(s);
  const double gap = geometry::smallest_element_extent(domain);
  const coupling::Locator locator(domain);
  const coupling::Repulsion walls(domain, gap, 0.0);
  Vec3 lo, hi;
  domain.bounding_box(lo, hi);
  // The periodic images a body can meet another through.
  const std::vector<Vec3> shifts = geometry::neighbour_image_shifts(domain);
  std::vector<Outline> placed;
  for (BodySettings& b : s.bodies) {
    if (!b.scattered) {
      placed.push_back(outline_of(build_body_parts(s, b), b.membrane(), D));
      continue;
    }
    b.elements = body_element_counts(s, b);  // (once, not at every draw)
    std::mt19937 rng(b.scatter_seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    bool found = false;
    for (int k = 0; k < kScatterTries && !found; ++k) {
      for (int d = 0; d < D; ++d) b.center[d] = lo[d] + (hi[d] - lo[d]) * uni(rng);
      Outline o = outline_of(build_body_parts(s, b), b.membrane(), D);
      found = std::all_of(o.points.begin(), o.points.end(), [&](const Vec3& x) {
        Vec3 n;
        return locator.locate(x).found && walls.wall_distance(x, n) >= gap;
      });
      for (size_t j = 0; j < placed.size() && found; ++j)
        for (const Vec3& t : shifts) found = found && apart(o, t, placed[j], gap, D);
      if (found) placed.push_back(std::move(o));
    }
    if (!found) {
      const std::string row = b.name.substr(0, b.name.rfind('_'));
      int placed_copies = 0;  // the row's copies before this one
      for (const BodySettings* o = s.bodies.data(); o != &b; ++o)
        placed_copies += o->scattered && o->name.rfind(row + "_", 0) == 0;
      std::ostringstream w;
      w << "fewer copies: only " << placed_copies << " found a place (" << kScatterTries
        << " random draws each) at least " << gap
        << " cm (one fluid element) from the walls and every other body; or smaller cells, or a larger "
           "domain";
      int count = 0;
      for (const BodySettings& o : s.bodies) count += o.scattered && o.name.rfind(row + "_", 0) == 0;
      bad_option("solid_" + row + "_count", std::to_string(count), w.str());
    }
  }
}

void check_bodies(const SceneSettings& s, const geometry::Patch& domain) {
  if (s.bodies.empty()) return;
  // The cheap checks of every body (its centre, its mesh against the fluid's) come before the costly ones
  // (its points located in the fluid mesh, the overlaps): a mesh the ratio refuses must not first be
  // located point by point.
  std::vector<coupling::BodyPlacement> placed;
  Vec3 lo, hi;
  domain.bounding_box(lo, hi);
  const double fluid_element = geometry::smallest_element_extent(domain);
  for (const BodySettings& b : s.bodies) {
    // A periodic direction wraps every point into the domain (the locator finds their images), but the body
    // is drawn where its centre is: the centre itself must lie inside.
    for (int d = 0; d < s.dim && std::isfinite(b.center[0]); ++d)
      if (s.periodic[d] && !(b.center[d] >= lo[d] && b.center[d] < hi[d])) {
        std::ostringstream v, w;
        for (int e = 0; e < s.dim; ++e) v << (e ? "," : "") << b.center[e];
        w << "a centre inside the domain, " << lo[d] << " <= "
          << "xyz"[d] << " < " << hi[d] << " cm in the periodic direction "
          << "xyz"[d];
        bad_option("solid_" + b.name + "_center", v.str(), w.str());
      }
    // (A body of several patches: a placement each, of the body's name, which check_no_overlap does not set
    // against each other.)
    std::vector<coupling::BodyPlacement> pls;
    for (geometry::Patch& p : build_body_parts(s, b)) pls.push_back({b.name, std::move(p), b.membrane()});
    coupling::Resolution r;
    for (const coupling::BodyPlacement& p : pls) {
      const coupling::Resolution q = coupling::resolution(fluid_element, p);
      if (q.ratio() >= r.ratio() || r.fluid_element == 0) r = q;
    }
    const coupling::BodyPlacement& pl = pls[0];
    if (r.ratio() > s.max_mesh_ratio) {
      std::ostringstream os;
      os << "Lagrangian elements no larger than " << s.max_mesh_ratio
         << " x the fluid's (paper Remark 3): body '" << b.name << "' has elements of " << r.solid_element
         << " cm, the fluid " << r.fluid_element
         << " cm; use more body elements (0: automatic) or -coupling_max_mesh_ratio";
      std::ostringstream v;
      for (int d = 0; d < s.dim; ++d) v << (d ? "," : "") << pl.patch.n_elements(d);
      bad_option("solid_" + b.name + "_elements", v.str(), os.str());
    }
    // The cell must span the fluid mesh: its smallest semi-axis at least one fluid element.
    if (!b.semi_axes.empty()) {
      const double amin = *std::min_element(b.semi_axes.begin(), b.semi_axes.end());
      if (amin < r.fluid_element) {
        std::ostringstream v, w;
        for (int d = 0; d < s.dim; ++d) v << (d ? "," : "") << s.elements[d];
        w << "a fluid mesh with elements no larger than the smallest semi-axis of body '" << b.name << "' ("
          << amin << " cm; now " << r.fluid_element << " cm)";
        bad_option("fluid_elements", v.str(), w.str());
      }
    }
    for (coupling::BodyPlacement& p : pls) placed.push_back(std::move(p));
  }
  const coupling::Locator locator(domain);
  for (const coupling::BodyPlacement& pl : placed) coupling::check_inside(locator, pl);
  coupling::check_no_overlap(placed);
}

Scene::Scene(MPI_Comm comm, const SceneSettings& settings) : s_(settings) {
  const int D = s_.dim;
  profile_from_ = average_from();
  patch_ = build_domain(s_);
  for (int d = D - 1; d >= 0 && wall_dir_ < 0; --d)
    if (!patch_.knots(d).periodic()) wall_dir_ = d;

  fluid::FluidOptions fo;
  fo.dt = s_.dt;
  fo.set_from_options(D);
  Vec3 lo, hi;
  patch_.bounding_box(lo, hi);
  if (s_.flow == "shear") {
    if (wall_dir_ <= 0)
      throw std::invalid_argument("option -flow = shear needs a wall direction other than x");
    // Walls move at -+ gammadot H / 2 along x, so a centred cell stays put (docs/design.md §3).
    const double H = s_.size[wall_dir_];
    fo.wall_velocity[wall_dir_][0] = Vec3(-s_.shear_rate * H / 2, 0, 0);
    fo.wall_velocity[wall_dir_][1] = Vec3(s_.shear_rate * H / 2, 0, 0);
  }
  fluid_ = fluid::create_fluid(comm, patch_, fo);
  const double mid = s_.flow == "shear" ? s_.origin[wall_dir_] + s_.size[wall_dir_] / 2 : 0.0;
  const int wd = wall_dir_;
  const double rate = s_.shear_rate;
  const bool shear = s_.flow == "shear";
  // Initial state: the undisturbed flow for shear, and for a channel that starts developed (the plasma's
  // plane Poiseuille flow, so that at a finite Reynolds number the bulk Jacobian a Fourier solver keeps is
  // the developed flow's), rest otherwise.
  if (shear) undisturbed_ = [=](const Vec3& x) { return Vec3(rate * (x[wd] - mid), 0, 0); };
  if (s_.flow_start == "developed") {
    const Vec3 f = fo.body_force;
    for (int d = 1; d < D; ++d)
      if (f[d] != 0)
        throw std::invalid_argument(
            "option -flow_start = developed is invalid here: the body force (-fluid_body_force) "
            "must be along x, the channel's axis");
    const double y0 = s_.origin[wd], H = s_.size[wd], c = f[0] / (2 * fo.viscosity);
    undisturbed_ = [=](const Vec3& x) { return Vec3(c * (x[wd] - y0) * (H - (x[wd] - y0)), 0, 0); };
    fluid_->project_initial_velocity(undisturbed_);  // (the parabola exactly, on degree >= 2)
  } else {
    fluid_->set_initial_velocity(undisturbed_ ? undisturbed_
                                              : [](const Vec3&) { return Vec3(Vec3::Zero()); });
  }
}

void Scene::attach_bodies(std::vector<solid::SolidSolver*> bodies) {
  if (coupler_) throw std::logic_error("Scene::attach_bodies called twice");
  bodies_ = std::move(bodies);
  if (bodies_.empty()) return;
  coupling::CouplerOptions co = s_.coupling;
  co.inner_viscosity.clear();
  for (const BodySettings& b : s_.bodies) co.inner_viscosity.push_back(b.inner_viscosity);
  coupler_ = std::make_unique<coupling::FsiCoupler>(*fluid_, bodies_, co);
  coupler_->initialize();
  for (const solid::SolidSolver* b : bodies_) membranes_ += b->is_membrane();
  raise_threshold_ = s_.s_interface_target / 2;
  const int plane = wall_dir_ > 0 ? wall_dir_ : 1;
  for (solid::SolidSolver* b : bodies_) {
    trackers_.emplace_back(b->reference_patches(), b->is_membrane(), plane);
    trackers_.back().record(fluid_->time(), b->current_patches(), metric_share());
    equilibrium_.emplace_back();
    if (body_settings(b->name()).stretched)
      equilibrium_.back().emplace(s_.equilibrium_tolerance, s_.equilibrium_window,
                                  body_settings(b->name()).stretch_ramp);
  }
  record_diameters();
  suspension_on_ =
      s_.flow == "poiseuille" && s_.domain == "rectangle" && s_.dim == 2 && wall_dir_ == 1 &&
      std::any_of(bodies_.begin(), bodies_.end(), [](const auto* b) { return b->is_membrane(); });
  if (suspension_on_) record_suspension();
}

std::vector<std::vector<double>> Scene::body_states() const {
  std::vector<std::vector<double>> out;
  for (const solid::SolidSolver* b : bodies_) out.push_back(b->state());
  return out;
}

std::vector<std::vector<double>> Scene::tracker_states() const {
  std::vector<std::vector<double>> out;
  for (const solid::BodyTracker& t : trackers_) out.push_back(t.state());
  return out;
}

void Scene::restore(const std::vector<std::vector<double>>& bodies,
                    const std::vector<std::vector<double>>& trackers) {
  if (bodies.size() != bodies_.size() || trackers.size() != bodies_.size())
    throw std::invalid_argument("option -restart is invalid here: the checkpoint has " +
                                std::to_string(bodies.size()) + " bodies, the scene " +
                                std::to_string(bodies_.size()));
  for (size_t b = 0; b < bodies_.size(); ++b) {
    try {
      bodies_[b]->set_state(bodies[b]);
      trackers_[b].restore(trackers[b]);
    } catch (const std::exception& e) {
      // Also a remote body's refusal, which arrives as a runtime error: the checkpoint is bad input.
      throw std::invalid_argument(std::string("option -restart is invalid here: ") + e.what());
    }
  }
  if (coupler_) coupler_->restart();
}

SceneStep Scene::step() {
  SceneStep r;
  if (!coupler_) {
    const fluid::StepStats st = fluid_->step();
    r.iterations = st.newton_iterations, r.linear_iterations = st.linear_iterations;
    r.converged = st.converged, r.reason = st.reason;
    if (r.converged) accumulate_profile();
    return r;
  }
  const coupling::CouplerStats st = coupler_->step();
  r.iterations = st.iterations, r.linear_iterations = st.linear_iterations;
  r.factorizations = st.factorizations, r.bulk_factorizations = st.bulk_factorizations;
  r.converged = st.converged, r.reason = st.reason;
  if (st.converged) {
    // (-log_view: the bodies' metrics of the step, on every rank)
    static const PetscLogEvent track_event = register_log_event("cellfsi app", "CellfsiTrack");
    EventScope ev(track_event);
    contact_last_ = st.repulsion;
    contact_cell_min_ = std::min(contact_cell_min_, st.repulsion.cell_gap);
    contact_wall_min_ = std::min(contact_wall_min_, st.repulsion.wall_gap);
    solid::MetricShare share = metric_share();
    double operations = 0;  // (the integrals' estimate, each rank its share's: -log_view's count)
    share.elements.operations = &operations;
    for (size_t b = 0; b < bodies_.size(); ++b)
      trackers_[b].record(fluid_->time(), bodies_[b]->current_patches(), share);
    CELLFSI_PETSC(PetscLogFlops(operations));
    record_diameters();
    if (suspension_on_) record_suspension();
    accumulate_profile();
    if (s_.s_interface_raise) raise_interface_scaling();
  }
  return r;
}

solid::MetricShare Scene::metric_share() const {
  const MPI_Comm comm = fluid_->comm();
  int rank = 0, size = 1;
  CELLFSI_PETSC(MPI_Comm_rank(comm, &rank));
  CELLFSI_PETSC(MPI_Comm_size(comm, &size));
  solid::MetricShare share;
  share.elements = {rank, size};
  if (size > 1) {
    // Reduced on rank 0 and broadcast, not MPI_Allreduce (which only recommends the same result on every
    // rank): the metrics steer the run (-s_interface_raise), so every rank must see the same bits.
    const auto reduce = [comm, rank](double* v, int n, MPI_Op op) {
      CELLFSI_PETSC(MPI_Reduce(rank == 0 ? MPI_IN_PLACE : v, v, n, MPI_DOUBLE, op, 0, comm));
      CELLFSI_PETSC(MPI_Bcast(v, n, MPI_DOUBLE, 0, comm));
    };
    share.sum = [reduce](double* v, int n) { reduce(v, n, MPI_SUM); };
    share.max = [reduce](double* v, int n) { reduce(v, n, MPI_MAX); };
  }
  return share;
}

void Scene::raise_interface_scaling() {
  double r_a = 0;
  for (size_t b = 0; b < bodies_.size(); ++b)
    if (bodies_[b]->is_membrane())
      for (const auto& [k, v] : trackers_[b].metrics())
        if (k == "r_A") r_a = std::max(r_a, std::abs(v));
  // Only a growing error is a drift: the first step's (the start from rest; 4.7e-4 to 6.3e-4 in shear at
  // 96 x 48 to 256 x 128, whatever s_I) decays (raise_previous_ starts at infinity).
  const bool growing = r_a > raise_previous_;
  raise_previous_ = r_a;
  if (!growing) return;
  double s_i = coupler_->interface_scaling();
  const double before = s_i;
  // r_A ~ s_I^(-1/2) (docs/validation.md, "The automatic s_I"): 4 times s_I halves its drift from here on.
  while (r_a > raise_threshold_ && s_i < coupling::kMaxInterfaceScaling) {
    s_i = std::min(4 * s_i, coupling::kMaxInterfaceScaling);
    raise_threshold_ = (raise_threshold_ + s_.s_interface_target) / 2;
    ++s_interface_raises_;
  }
  if (s_i == before) return;
  coupler_->set_interface_scaling(s_i);
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                            "cellfsi: note: |r_A| = %.3g at t = %g s: s_I raised from %.3g to %.3g "
                            "(-s_interface_raise; next at |r_A| = %.3g)\n",
                            r_a, fluid_->time(), before, s_i, raise_threshold_));
}

void Scene::record_diameters() {
  for (size_t b = 0; b < bodies_.size(); ++b)
    if (equilibrium_[b]) {
      std::vector<Vec3> points;  // (every part's mid-surface)
      for (const geometry::Patch& p : bodies_[b]->current_patches()) {
        const std::vector<Vec3> some = solid::mid_surface_points(p);
        points.insert(points.end(), some.begin(), some.end());
      }
      equilibrium_[b]->record(
          fluid_->time(), solid::stretch_diameters(points, body_settings(bodies_[b]->name()).stretch_axis));
    }
}

bool Scene::at_equilibrium() const {
  bool any = false;
  for (const auto& e : equilibrium_) {
    if (e && !e->reached()) return false;
    any = any || e.has_value();
  }
  return any;
}

const BodySettings& Scene::body_settings(const std::string& name) const {
  for (const BodySettings& b : s_.bodies)
    if (b.name == name) return b;
  throw std::logic_error("no settings for body '" + name + "'");
}

}  // namespace cellfsi::app
