// See dc_immersed_fluid.hpp.
#include "fluid/dc_immersed_fluid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <stdexcept>

#include <petsc/private/petscimpl.h>  // PetscObjectStateGet (private in PETSc 3.18; the PC types use it too)
#include <petscblaslapack.h>

#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkStructuredGrid.h>
#include <vtkXMLStructuredGridWriter.h>

#include "common/option_table.hpp"
#include "common/petsc_error.hpp"
#include "common/row_scatter.hpp"
#include "fluid/state_file.hpp"
#include "geometry/patch_vtk.hpp"
#include "geometry/quadrature.hpp"

namespace cellfsi::fluid {

namespace {

dc::DcFluidOptions dc_options(const FluidOptions& o) {
  dc::DcFluidOptions d;
  d.density = o.density;
  d.viscosity = o.viscosity;
  d.body_force = o.body_force;
  d.stokes = o.stokes;
  d.rho_inf = o.rho_inf;
  d.dt = o.dt;
  d.penalty = o.dc_penalty;
  d.wall_velocity = o.wall_velocity;
  return d;
}

/// A vector of the natural numbering (n entries, PETSc's default layout) holding u (on every rank).
Vec natural_vector(MPI_Comm comm, const std::vector<double>& u) {
  Vec v;
  CELLFSI_PETSC(VecCreateMPI(comm, PETSC_DECIDE, static_cast<PetscInt>(u.size()), &v));
  PetscInt lo = 0, hi = 0;
  CELLFSI_PETSC(VecGetOwnershipRange(v, &lo, &hi));
  PetscScalar* a;
  CELLFSI_PETSC(VecGetArray(v, &a));
  for (PetscInt i = lo; i < hi; ++i) a[i - lo] = u[static_cast<std::size_t>(i)];
  CELLFSI_PETSC(VecRestoreArray(v, &a));
  return v;
}

/// All entries of v on every rank.
std::vector<double> all_entries(Vec v) {
  VecScatter to_all;
  Vec all;
  CELLFSI_PETSC(VecScatterCreateToAll(v, &to_all, &all));
  CELLFSI_PETSC(VecScatterBegin(to_all, v, all, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(to_all, v, all, INSERT_VALUES, SCATTER_FORWARD));
  PetscInt n = 0;
  CELLFSI_PETSC(VecGetSize(all, &n));
  const PetscScalar* a;
  CELLFSI_PETSC(VecGetArrayRead(all, &a));
  std::vector<double> out(a, a + n);
  CELLFSI_PETSC(VecRestoreArrayRead(all, &a));
  VecScatterDestroy(&to_all);
  VecDestroy(&all);
  return out;
}

}  // namespace

DcImmersedFluid::DcImmersedFluid(MPI_Comm comm, const geometry::Patch& patch, const FluidOptions& options)
    : comm_(comm), patch_(patch), options_(options) {
  options_.validate();
  const std::optional<geometry::AffineMap> map = geometry::affine_map(patch);
  try {
    if (map) {
      offset_ = map->offset;
      scale_ = map->scale;
      space_ = std::make_unique<dc::DivConformingSpace>(
          dc::DivConformingSpace::from_patch(patch, options_.dc_degree));
    } else {  // (the patch outlives the fluid: the app owns both)
      const std::shared_ptr<const geometry::Patch> view(&patch, [](const geometry::Patch*) {});
      space_ =
          std::make_unique<dc::DivConformingSpace>(dc::DivConformingSpace::mapped(view, options_.dc_degree));
      inverter_ = std::make_unique<geometry::PointInverter>(patch);
    }
  } catch (const std::invalid_argument& e) {
    bad_option("fluid_space", "div_conforming", std::string("equal_order on this domain (") + e.what() + ")");
  }
  options_.pressure_null_space = false;  // one pressure unknown pinned per step, then zero mean
  fluid_ = std::make_unique<dc::DivConformingFluid>(comm, *space_, dc_options(options_));
  U_ = fluid_->create_vector();
  sync_solution();
}

DcImmersedFluid::~DcImmersedFluid() {
  VecDestroy(&U_);
  MatDestroy(&bulk_matrix_);
  MatDestroy(&stencil_op_);
  immersed_.destroy();
  VecDestroy(&applied_rhs_);
  VecScatterDestroy(&colloc_scatter_);
  VecDestroy(&colloc_x_);
}

void DcImmersedFluid::gather_iterate(Vec X) const {
  // An iterate unchanged since the last gather (the same vector, its state not raised) is not gathered again:
  // the coupling loop samples, forms the residual and refreshes the Jacobian at one iterate, and each gather
  // copies and reorders every unknown on every rank.
  PetscObjectId id = 0;
  PetscObjectState state = 0;
  CELLFSI_PETSC(PetscObjectGetId(reinterpret_cast<PetscObject>(X), &id));
  CELLFSI_PETSC(PetscObjectStateGet(reinterpret_cast<PetscObject>(X), &state));
  if (id == gathered_id_ && state == gathered_state_ && gathered_whole_) return;
  fluid_->gather(X, work_);
  gathered_id_ = id, gathered_state_ = state;
  gathered_whole_ = true;
}

void DcImmersedFluid::gather_iterate_part(Vec X, int part, const std::vector<int>& elements) const {
  PetscObjectId id = 0;
  PetscObjectState state = 0;
  CELLFSI_PETSC(PetscObjectGetId(reinterpret_cast<PetscObject>(X), &id));
  CELLFSI_PETSC(PetscObjectStateGet(reinterpret_cast<PetscObject>(X), &state));
  const bool same = id == gathered_id_ && state == gathered_state_;
  const auto p = static_cast<std::size_t>(part);
  // (held when these elements are among those gathered for this iterate: the bodies' samples come one body at
  // a time)
  int held =
      same && (gathered_whole_ ||
               (gathered_part_[p] && std::includes(gathered_elements_[p].begin(), gathered_elements_[p].end(),
                                                   elements.begin(), elements.end())));
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &held, 1, MPI_INT, MPI_MIN, comm_));
  // (held: the part is still set to these elements, for the levels DivConformingFluid computes on it)
  fluid_->gather_part(X, work_, part, elements, !held);
  if (held) return;
  if (!same) {  // (work_'s other entries hold an older iterate now)
    gathered_id_ = id, gathered_state_ = state;
    gathered_whole_ = false;
    gathered_part_ = {false, false};
  }
  if (gathered_part_[p]) {  // (this iterate's earlier elements and these)
    std::vector<int> both;
    std::set_union(gathered_elements_[p].begin(), gathered_elements_[p].end(), elements.begin(),
                   elements.end(), std::back_inserter(both));
    gathered_elements_[p] = std::move(both);
  } else {
    gathered_elements_[p] = elements;
  }
  gathered_part_[p] = true;
}

void DcImmersedFluid::sync_solution() { fluid_->scatter(fluid_->state(), U_); }

Vec3 DcImmersedFluid::space_point(const geometry::Param& xi) const {
  if (space_->is_mapped()) return space_->from_patch_parameters(xi);
  return offset_ + scale_.cwiseProduct(Vec3(xi[0], xi[1], xi[2]));
}

bool DcImmersedFluid::locate(const Vec3& x, Vec3& s, geometry::InversionResult* warm) const {
  if (inverter_) {
    // (from the previous point's element first: sample()'s points often come in order)
    geometry::InversionResult r =
        warm && warm->inside ? inverter_->invert(x, warm->element, warm->xi) : inverter_->invert(x);
    if (!r.inside && warm && warm->inside) r = inverter_->invert(x);
    if (r.inside) s = space_->from_patch_parameters(r.xi);
    if (warm) *warm = r;
    return r.inside;
  }
  for (int d = 0; d < dim(); ++d)
    if (!space_->periodic(d)) {
      const double tol = 1e-12 * (space_->hi(d) - space_->lo(d));
      if (x[d] < space_->lo(d) - tol || x[d] > space_->hi(d) + tol) return false;
    }
  s = x;
  return true;
}

std::vector<int> DcImmersedFluid::unknown_kinds() const {
  PetscInt lo = 0, hi = 0;
  CELLFSI_PETSC(VecGetOwnershipRange(U_, &lo, &hi));
  std::vector<int> kinds(static_cast<std::size_t>(hi - lo), 0);
  const std::vector<PetscInt>& idx = fluid_->petsc_numbering();
  const int D = dim();
  for (int g = 0; g < space_->n_dofs(); ++g) {
    if (idx[g] < lo || idx[g] >= hi) continue;
    int c = D;
    for (int k = 0; k < D; ++k)
      if (g >= space_->offset(k) && g < space_->offset(k + 1)) c = k;
    kinds[static_cast<std::size_t>(idx[g] - lo)] = c;
  }
  return kinds;
}

void DcImmersedFluid::set_initial_velocity(const std::function<Vec3(const Vec3&)>& v0) {
  fluid_->project_initial_state(v0, [](const Vec3&) { return Vec3(Vec3::Zero()); });
  sync_solution();
}

StepStats DcImmersedFluid::step() {
  const dc::DcSolveStats s = fluid_->step();
  StepStats st;
  st.newton_iterations = s.newton_iterations;
  st.linear_iterations = s.newton_iterations;  // one direct solve per Newton iteration
  st.converged = s.converged;
  st.reason = s.converged ? "CONVERGED" : "DIVERGED (Newton on the divergence-conforming fluid)";
  if (s.converged) sync_solution();
  return st;
}

std::vector<PointSample> DcImmersedFluid::evaluate(const std::vector<double>& c,
                                                   const std::vector<double>* rate,
                                                   const std::vector<Vec3>& points) const {
  std::vector<PointSample> out(points.size());
  dc::ElementBasis eb;
  Vec3 at;
  geometry::InversionResult warm;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (locate(points[i], at, &warm)) out[i] = at_space_point(c, rate, at, eb);
  return out;
}

PointSample DcImmersedFluid::at_space_point(const std::vector<double>& c, const std::vector<double>* rate,
                                            const Vec3& at, dc::ElementBasis& eb,
                                            const geometry::Index3* element) const {
  const int D = dim();
  if (element) {  // at as it is, in the given element (a periodic end is not wrapped to the start)
    dc::TensorRule rule;
    for (int d = 0; d < 3; ++d) {
      rule.points[d] = {d < D ? at[d] : 0.0};
      rule.weights[d] = {1.0};
    }
    space_->evaluate(*element, rule, eb);
  } else {
    space_->evaluate(space_->find_element(at), space_->point_rule(at), eb);
  }
  const auto pv = dc::DivConformingSpace::interpolate(eb, 0, D, c.data());
  PointSample s;
  s.found = true;
  for (int a = 0; a < D; ++a) {
    s.v[a] = pv.v[a];
    for (int b = 0; b < D; ++b) s.grad_v(a, b) = pv.grad[a][b];
  }
  s.p = pv.p;
  if (rate) {
    const auto pr = dc::DivConformingSpace::interpolate(eb, 0, D, rate->data());
    for (int a = 0; a < D; ++a) s.vdot[a] = pr.v[a];
  }
  return s;
}

std::vector<PointSample> DcImmersedFluid::sample(const std::vector<Vec3>& points) const {
  return evaluate(fluid_->state(), &fluid_->state_rate(), points);
}

std::vector<PointSample> DcImmersedFluid::sample_alpha(Vec X, const std::vector<geometry::Index3>& elements,
                                                       const std::vector<geometry::Param>& xi) const {
  std::vector<int> el(elements.size());
  std::vector<Vec3> x(xi.size());
  for (std::size_t i = 0; i < xi.size(); ++i) {
    el[i] = patch_.element_index(elements[i]);
    x[i] = space_point(xi[i]);
  }
  // (this rank's samples read the unknowns of their elements alone)
  std::vector<int> sampled = el;
  std::sort(sampled.begin(), sampled.end());
  sampled.erase(std::unique(sampled.begin(), sampled.end()), sampled.end());
  constexpr int part = dc::DivConformingFluid::kSamplePart;
  gather_iterate_part(X, part, sampled);
  const std::vector<dc::DivConformingFluid::StepSample> s = fluid_->sample_step(work_, el, x, part);
  std::vector<PointSample> out(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    out[i].found = true;
    out[i].v = s[i].v;
    out[i].grad_v = s[i].grad_v;
    out[i].vdot = s[i].a;
  }
  return out;
}

SectionData DcImmersedFluid::section(double u, int n_profile) const {
  if (space_->is_mapped()) return section_mapped(u, n_profile);
  // The section x_0 = const of the box; its normal is e_0. Gauss points of the velocity's degree + 1 on the
  // space's elements along the other directions (local: the state is on every rank).
  const int D = dim(), k = space_->degree();
  const double x0 = space_point({u, 0, 0})[0];
  const geometry::GaussRule& g = geometry::gauss_legendre(k + 3);
  SectionData out;
  const int n1 = space_->n_elements(1), n2 = D == 3 ? space_->n_elements(2) : 1;
  std::vector<Vec3> pts;
  std::vector<double> w;
  for (int e1 = 0; e1 < n1; ++e1)
    for (int e2 = 0; e2 < n2; ++e2)
      for (std::size_t q1 = 0; q1 < g.points.size(); ++q1)
        for (std::size_t q2 = 0; q2 < (D == 3 ? g.points.size() : 1); ++q2) {
          const double h1 = space_->element_size(1);
          Vec3 x(x0, space_->lo(1) + h1 * (e1 + 0.5 * (g.points[q1] + 1)), 0);
          double wq = 0.5 * h1 * g.weights[q1];
          if (D == 3) {
            const double h2 = space_->element_size(2);
            x[2] = space_->lo(2) + h2 * (e2 + 0.5 * (g.points[q2] + 1));
            wq *= 0.5 * h2 * g.weights[q2];
          }
          pts.push_back(x);
          w.push_back(wq);
        }
  const std::vector<PointSample> s = evaluate(fluid_->state(), nullptr, pts);
  for (std::size_t i = 0; i < s.size(); ++i) {
    out.flow_rate += w[i] * s[i].v[0];
    out.area += w[i];
  }
  std::vector<Vec3> prof(static_cast<std::size_t>(n_profile));
  for (int i = 0; i < n_profile; ++i) {
    Vec3 x(x0, space_->lo(1) + (space_->hi(1) - space_->lo(1)) * i / std::max(1, n_profile - 1), 0);
    if (D == 3) x[2] = 0.5 * (space_->lo(2) + space_->hi(2));
    prof[static_cast<std::size_t>(i)] = x;
  }
  const std::vector<PointSample> p = evaluate(fluid_->state(), nullptr, prof);
  for (int i = 0; i < n_profile; ++i) {
    out.points.push_back(prof[static_cast<std::size_t>(i)]);
    out.velocity.push_back(p[static_cast<std::size_t>(i)].v);
  }
  return out;
}

SectionData DcImmersedFluid::section_mapped(double u, int n_profile) const {
  // The section xi_0 = u of the patch: v . n dA from the map's derivatives there, (dy/dxi_1, -dx/dxi_1)
  // dxi_1 in 2D and dx/dxi_1 x dx/dxi_2 dxi_1 dxi_2 in 3D (as FluidSolver::section), on Gauss points of
  // the velocity's degree + 1 per element.
  const int D = dim();
  const geometry::GaussRule& g = geometry::gauss_legendre(space_->degree() + 3);
  const geometry::KnotVector& k1 = patch_.knots(1);
  const int n2 = D == 3 ? patch_.knots(2).n_elements() : 1;
  SectionData out;
  dc::ElementBasis eb;
  for (int e1 = 0; e1 < k1.n_elements(); ++e1)
    for (int e2 = 0; e2 < n2; ++e2)
      for (std::size_t q1 = 0; q1 < g.points.size(); ++q1)
        for (std::size_t q2 = 0; q2 < (D == 3 ? g.points.size() : 1); ++q2) {
          const double a1 = k1.element_begin(e1), b1 = k1.element_end(e1);
          geometry::Param xi{u, a1 + 0.5 * (b1 - a1) * (g.points[q1] + 1), 0};
          double w = 0.5 * (b1 - a1) * g.weights[q1];
          if (D == 3) {
            const geometry::KnotVector& k2 = patch_.knots(2);
            const double a2 = k2.element_begin(e2), b2 = k2.element_end(e2);
            xi[2] = a2 + 0.5 * (b2 - a2) * (g.points[q2] + 1);
            w *= 0.5 * (b2 - a2) * g.weights[q2];
          }
          const geometry::MapValues mv = patch_.evaluate(xi, 1);
          const Vec3 nA =
              D == 2 ? Vec3(mv.dx(1, 1), -mv.dx(0, 1), 0) : Vec3(mv.dx.col(1).cross(mv.dx.col(2)));
          const PointSample s = at_space_point(fluid_->state(), nullptr, space_point(xi), eb);
          out.flow_rate += w * s.v.dot(nA);
          out.area += w * nA.norm();
        }
  for (int i = 0; i < n_profile; ++i) {
    geometry::Param xi{u, k1.a() + (k1.b() - k1.a()) * i / std::max(1, n_profile - 1), 0};
    if (D == 3) xi[2] = 0.5 * (patch_.knots(2).a() + patch_.knots(2).b());
    const PointSample s = at_space_point(fluid_->state(), nullptr, space_point(xi), eb);
    out.points.push_back(eb.x[0]);
    out.velocity.push_back(s.v);
  }
  return out;
}

bool DcImmersedFluid::owns_element(const geometry::Index3& e) const {
  const int i = patch_.element_index(e);
  const std::array<int, 2> r = fluid_->owned_elements();
  return i >= r[0] && i < r[1];
}

void DcImmersedFluid::set_immersed_points(const std::vector<geometry::Index3>& elements,
                                          const std::vector<geometry::Param>& xi,
                                          const std::vector<ImmersedPoint>& data) {
  if (elements.size() != xi.size() || xi.size() != data.size())
    throw std::invalid_argument("set_immersed_points: elements, xi and data differ in size");
  std::vector<dc::DivConformingFluid::ImmersedAt>& pts = points_;  // (kept storage: see the fluid's)
  pts.clear();
  // Every point given is assembled here: the caller (the coupler) gives each rank its own share
  // (assembles_points_anywhere); the same points on every rank would count each once per rank.
  for (std::size_t i = 0; i < data.size(); ++i) {
    pts.push_back({patch_.element_index(elements[i]), space_point(xi[i]), data[i]});
  }
  fluid_->set_immersed_points(pts);
}

void DcImmersedFluid::set_viscosity(const std::function<double(int node)>& mu) {
  // The pressure space is the patch's own spline space when the degrees and function counts agree.
  const int D = dim(), P = D;
  for (int d = 0; d < D; ++d)
    if (patch_.degree(d) != space_->degree() || patch_.n_control(d) != space_->n_basis(P, d))
      bad_option("fluid_degree", std::to_string(patch_.degree(d)),
                 "-fluid_dc_degree (" + std::to_string(space_->degree()) +
                     ") with -fluid_space div_conforming and a viscosity contrast: the viscosity field is "
                     "given on the patch's splines, which must then be the pressure space");
  std::vector<double> values(static_cast<std::size_t>(space_->n_pressure()));
  for (int a = 0; a < space_->n_pressure(); ++a) values[static_cast<std::size_t>(a)] = mu(a);
  fluid_->set_viscosity(values);
}

void DcImmersedFluid::begin_step(Vec X) {
  fluid_->begin_step();
  fluid_->scatter(fluid_->state(), X);
}

void DcImmersedFluid::residual(Vec X, Vec F) {
  // (this rank's elements and its points' read their unknowns alone)
  constexpr int part = dc::DivConformingFluid::kAssemblyPart;
  gather_iterate_part(X, part, fluid_->immersed_elements());
  // (a mapped space has no bulk inverse to take the constant pressure: the pin holds it, as in a step)
  fluid_->step_residual(work_, F, space_->is_mapped(), part);
}

void DcImmersedFluid::jacobian(Vec X, Mat J) {
  if (J && J == stencil_op_) {
    refresh_stencil_operator(X);
    return;
  }
  gather_iterate(X);
  fluid_->set_solid_stiffness_apart(false);  // (an assembled Jacobian carries the points' own stiffness)
  if (space_->is_mapped()) {  // no mean flow to keep (not translation-invariant); the pressure pinned
    fluid_->step_tangent(work_, J, true, true);
    return;
  }
  if (fluid_->has_viscosity_field()) {  // the field moves with the cells: everything re-assembled
    fluid_->step_tangent(work_, J, true, false);
    return;
  }
  if (!bulk_matrix_) {  // the bulk part at the first iterate's mean flow (as bulk_inverse's), kept
    CELLFSI_PETSC(MatDuplicate(J, MAT_DO_NOT_COPY_VALUES, &bulk_matrix_));
    fluid_->bulk_tangent_of_mean(work_, bulk_matrix_);
  }
  fluid_->step_tangent_from(bulk_matrix_, work_, J, false);
}

void DcImmersedFluid::bulk_jacobian(Vec X, Mat J) {
  gather_iterate(X);
  fluid_->step_tangent(work_, J, false, false);
}

void DcImmersedFluid::end_step(Vec X) {
  gather_iterate(X);
  fluid_->end_step(work_);
  sync_solution();
}

void DcImmersedFluid::jacobian_part(Vec, Mat, const std::vector<char>&, bool) {
  throw std::logic_error("jacobian_part: the divergence-conforming fluid has no region split (-fluid_space)");
}
void DcImmersedFluid::jacobian_add_part(Vec, Mat, const std::vector<char>&) {
  throw std::logic_error(
      "jacobian_add_part: the divergence-conforming fluid has no region split (-fluid_space)");
}
std::vector<PetscInt> DcImmersedFluid::region_unknowns(const std::vector<char>&) const {
  throw std::logic_error(
      "region_unknowns: the divergence-conforming fluid has no region split (-fluid_space)");
}

std::optional<ImmersedFluid::OwnBulkInverse> DcImmersedFluid::bulk_inverse(Vec X) {
  if (!has_bulk_inverse()) return std::nullopt;
  // The operator without the cells and without the pressure pin (not translation-invariant); the solver pins
  // wave 0's constant pressure itself.
  // Of the flow averaged along the periodic directions: the initial state, uniform along them, stays as it
  // is; a later one (a rebuild after a failed solve, coupling/bulk_solve.cpp) gives the operator of its mean
  // flow, not of the cells' disturbance where the stencil's rows are taken (x index 0).
  // Only the rows the build reads and checks are assembled (DivConformingFluid::bulk_stencil_tangent): the
  // whole matrix is made only where a solve needs it (jacobian_matrix()).
  gather_iterate(X);
  Mat S = fluid_->bulk_stencil_tangent(work_);
  // The Jacobian's kept bulk part (-coupling_bulk_stencil false) follows: the next jacobian() makes it again.
  MatDestroy(&bulk_matrix_);
  applied_id_ = 0;  // (a product of an older inverse's output is not this one's)
  bulk_ = std::make_unique<dc::DcFourierSolver>(*space_, comm_, fluid_->petsc_numbering());
  try {
    bulk_->build(S, true);
  } catch (...) {
    MatDestroy(&S);
    throw;
  }
  MatDestroy(&S);
  OwnBulkInverse inv;
  inv.deviation = bulk_->deviation();
  char line[160];
  if (dim() == 2)
    std::snprintf(
        line, sizeof line,
        "divergence-conforming bulk inverse: DFT along x, one LU per wave number (%d in x), operator "
        "circulant to %.2e",
        space_->n_elements(0), inv.deviation);
  else
    std::snprintf(line, sizeof line,
                  "divergence-conforming bulk inverse: DFT along x and z, one LU per wave vector (%d x %d), "
                  "operator circulant to %.2e",
                  space_->n_elements(0), space_->n_elements(2), inv.deviation);
  inv.description = line;
  inv.apply = [this](Vec r, Vec out) {
    // r kept for the stencil operator's product with `out` (stencil_mult): S out = r (copied first, in case
    // a caller passes r as out).
    if (!applied_rhs_) CELLFSI_PETSC(VecDuplicate(r, &applied_rhs_));
    CELLFSI_PETSC(VecCopy(r, applied_rhs_));
    bulk_->solve(r, out);  // (each rank its lines: nothing gathered whole)
    CELLFSI_PETSC(PetscObjectGetId(reinterpret_cast<PetscObject>(out), &applied_id_));
    CELLFSI_PETSC(PetscObjectStateGet(reinterpret_cast<PetscObject>(out), &applied_state_));
  };
  if (!stencil_op_) {
    PetscInt m = 0, n = 0;
    CELLFSI_PETSC(VecGetLocalSize(U_, &m));
    CELLFSI_PETSC(VecGetSize(U_, &n));
    CELLFSI_PETSC(MatCreateShell(comm_, m, m, n, n, this, &stencil_op_));
    CELLFSI_PETSC(
        MatShellSetOperation(stencil_op_, MATOP_MULT, reinterpret_cast<void (*)(void)>(stencil_mult)));
    CELLFSI_PETSC(PetscObjectSetName(reinterpret_cast<PetscObject>(stencil_op_), "cellfsi_dc_stencil"));
  }
  inv.stencil_operator = stencil_op_;
  return inv;
}

bool DcImmersedFluid::set_solid_linearization(SolidLinearization& lin) {
  if (!has_bulk_inverse()) return false;  // (only the stencil operator applies it)
  std::swap(solid_, lin);                 // (lin: the old buffers, for the caller's next one)
  solid_given_ = true;
  return true;
}

void DcImmersedFluid::build_solid_operator() {
  const int D = dim();
  const double alpha_f = fluid_->velocity_alpha();
  const std::size_t n = solid_.elements.size();
  // This rank's run of the collocation points (3 rows each), the others' gathered at each product: every rank
  // evaluated the space at every point, about 0.2 s of a 64^3 step on one rank (perf), which did not divide.
  int rank = 0, size = 1;
  CELLFSI_PETSC(MPI_Comm_rank(comm_, &rank));
  CELLFSI_PETSC(MPI_Comm_size(comm_, &size));
  colloc_counts_.assign(static_cast<std::size_t>(size), 0);
  colloc_displs_.assign(static_cast<std::size_t>(size), 0);
  for (int r = 0; r < size; ++r) {
    const auto first = [&](int q) { return static_cast<int>(3 * (n * static_cast<std::size_t>(q) / size)); };
    colloc_displs_[r] = first(r);
    colloc_counts_[r] = first(r + 1) - first(r);
  }
  colloc_rows_ = 3 * n;
  colloc_begin_.assign(1, 0);
  colloc_index_.clear();
  colloc_value_.clear();
  dc::ElementBasis eb;
  dc::TensorRule rule;  // (at x as it is: the point's element holds it unwrapped, as in assemble_immersed)
  for (std::size_t i = n * rank / size; i < n * (rank + 1) / size; ++i) {
    const Vec3 x = space_point(solid_.xi[i]);
    const int e = patch_.element_index(solid_.elements[i]);
    for (int d = 0; d < 3; ++d) {
      rule.points[d].assign(1, d < D ? x[d] : 0.0);
      rule.weights[d].assign(1, 1.0);
    }
    space_->evaluate(space_->element_multi_index(e), rule, eb);
    for (int c = 0; c < 3; ++c) {
      if (c < D) {
        const dc::ComponentBasis& cb = eb.comp[c];
        for (int a = 0; a < cb.n; ++a) {
          colloc_index_.push_back(cb.index[a]);
          colloc_value_.push_back(alpha_f * cb.value[a]);
        }
      }
      colloc_begin_.push_back(static_cast<int>(colloc_index_.size()));
    }
  }
  // The unknowns these rows read, and a scatter of their values from the fluid's vectors: each product reads
  // them alone (gathering the whole iterate to every rank at each product did not divide).
  std::vector<int> read(colloc_index_.begin(), colloc_index_.end());
  std::sort(read.begin(), read.end());
  read.erase(std::unique(read.begin(), read.end()), read.end());
  for (int& k : colloc_index_)
    k = static_cast<int>(std::lower_bound(read.begin(), read.end(), k) - read.begin());
  std::vector<PetscInt> rows(read.size());
  for (std::size_t k = 0; k < read.size(); ++k) rows[k] = fluid_->petsc_numbering()[read[k]];
  VecScatterDestroy(&colloc_scatter_);
  VecDestroy(&colloc_x_);
  colloc_scatter_ = make_row_scatter(U_, rows, colloc_x_);
  solid_blocks_ = fluid_->solid_blocks(solid_.column, solid_.grad);
  // (The points' tables are in the blocks now; the product needs the collocation points and control alone.
  // Emptied but kept: set_solid_linearization hands them back to the coupler, which fills them again at the
  // next refresh without new pages.)
  solid_.column.clear();
  solid_.grad.clear();
}

void DcImmersedFluid::add_solid_product(Vec x, Vec y) {
  const std::size_t rows = colloc_begin_.size() - 1;  // (this rank's run)
  int rank = 0;
  CELLFSI_PETSC(MPI_Comm_rank(comm_, &rank));
  dv_.assign(colloc_rows_, 0.0);
  double* mine = dv_.data() + colloc_displs_[rank];
  CELLFSI_PETSC(VecScatterBegin(colloc_scatter_, x, colloc_x_, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(colloc_scatter_, x, colloc_x_, INSERT_VALUES, SCATTER_FORWARD));
  const PetscScalar* xr = nullptr;
  CELLFSI_PETSC(VecGetArrayRead(colloc_x_, &xr));
  for (std::size_t r = 0; r < rows; ++r) {
    double v = 0;
    for (int k = colloc_begin_[r]; k < colloc_begin_[r + 1]; ++k)
      v += colloc_value_[k] * xr[colloc_index_[k]];
    mine[r] = v;
  }
  CELLFSI_PETSC(VecRestoreArrayRead(colloc_x_, &xr));
  if (colloc_counts_.size() > 1)
    CELLFSI_PETSC(MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, dv_.data(), colloc_counts_.data(),
                                 colloc_displs_.data(), MPI_DOUBLE, comm_));
  // (-log_view's counts: these sums and each block's product; the bodies' collocation solves in control()
  // are the coupler's to count, FsiSolidControl)
  CELLFSI_PETSC(PetscLogFlops(2.0 * colloc_index_.size()));
  dc_.assign(solid_.n_columns, 0.0);
  solid_.control(dv_, dc_);
  for (const dc::DivConformingFluid::SolidBlock& b : solid_blocks_) {
    // y_rows += values dc[cols]: values is row-major, i.e. its transpose column-major for BLAS.
    const PetscBLASInt m = static_cast<PetscBLASInt>(b.rows.size()),
                       n = static_cast<PetscBLASInt>(b.cols.size());
    block_x_.resize(n);
    for (PetscBLASInt c = 0; c < n; ++c) block_x_[c] = dc_[b.cols[c]];
    block_y_.resize(m);
    const double one = 1.0, zero = 0.0;
    const PetscBLASInt inc = 1;
    BLASgemv_("T", &n, &m, &one, b.values.data(), &n, block_x_.data(), &inc, &zero, block_y_.data(), &inc);
    CELLFSI_PETSC(PetscLogFlops(2.0 * m * n));
    CELLFSI_PETSC(VecSetValues(y, m, b.rows.data(), block_y_.data(), ADD_VALUES));
  }
  CELLFSI_PETSC(VecAssemblyBegin(y));
  CELLFSI_PETSC(VecAssemblyEnd(y));
}

void DcImmersedFluid::refresh_stencil_operator(Vec X) {
  op_assembled_ = fluid_->has_viscosity_field();
  // The solids' stiffness through their collocation, if the coupler gave it for these points (and the
  // operator is the stencil's: an assembled one carries the points' own tangent).
  const bool apart = solid_given_ && !op_assembled_;
  fluid_->set_solid_stiffness_apart(apart);
  solid_given_ = false;
  if (!apart) solid_blocks_.clear(), colloc_begin_.clear();
  if (op_assembled_) {  // the field moves with the cells: the bulk is not the stencil's
    gather_iterate(X);
    fluid_->step_tangent(work_, fluid_->matrix(), true, false);
  } else {
    // The pattern of the elements that hold points, made again when they changed on any rank (the points
    // move, mostly within their elements between refreshes), then the points' tangent on it (its unknowns
    // alone gathered: the residual's part).
    std::vector<int> elements = fluid_->immersed_elements();
    constexpr int part = dc::DivConformingFluid::kAssemblyPart;
    gather_iterate_part(X, part, elements);
    int changed = !immersed_.C || elements != pattern_elements_;
    CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &changed, 1, MPI_INT, MPI_MAX, comm_));
    if (changed) {
      // (-log_view: DcImmersedPattern)
      static const PetscLogEvent pattern_event = register_log_event("cellfsi fluid", "DcImmersedPattern");
      EventScope ev(pattern_event);
      immersed_.destroy();
      immersed_ = fluid_->create_immersed_matrix();
      pattern_elements_ = std::move(elements);
    } else {
      CELLFSI_PETSC(MatZeroEntries(immersed_.C));
    }
    fluid_->immersed_tangent(work_, immersed_, part);
    if (apart) build_solid_operator();
  }
  // (An assembly raises the operator's state: KSP sets its preconditioner up again.)
  CELLFSI_PETSC(MatAssemblyBegin(stencil_op_, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(stencil_op_, MAT_FINAL_ASSEMBLY));
}

PetscErrorCode DcImmersedFluid::stencil_mult(Mat A, Vec x, Vec y) {
  PetscFunctionBeginUser;
  DcImmersedFluid* self = nullptr;
  PetscCall(MatShellGetContext(A, &self));
  if (self->op_assembled_) {
    PetscCall(MatMult(self->fluid_->matrix(), x, y));
    PetscFunctionReturn(0);
  }
  // x the bulk inverse's last output, unchanged since (a Krylov method with right preconditioning multiplies
  // each z = S^{-1} v it made): S x is that v, which was kept, so the stencil's product is skipped. S x = v holds
  // to the banded solves' round-off for every v compatible with S, w.v = 0 for S's left null vector w (ones on
  // the continuity rows, the wall-flux coefficients on the fixed wall-normal rows): the equation the inverse
  // pins. Every residual of the coupling loop is (its pin row kept, its fixed rows zero), and so is every
  // Krylov vector made from it and from this operator's products (the points' and the solids' parts have no
  // continuity rows and zero fixed rows). For any other v the product differs from S x by a constant on the
  // pinned pressure line.
  PetscObjectState state = 0;
  PetscObjectId id = 0;
  PetscCall(PetscObjectStateGet(reinterpret_cast<PetscObject>(x), &state));
  PetscCall(PetscObjectGetId(reinterpret_cast<PetscObject>(x), &id));  // (unique: not an address reused)
  if (self->applied_rhs_ && id == self->applied_id_ && state == self->applied_state_) {
    PetscCall(VecCopy(self->applied_rhs_, y));
    ++self->products_skipped_;
  } else {
    try {
      self->fluid_->gather(x, self->x_nat_);
      self->bulk_->multiply(self->x_nat_, self->y_nat_, true);  // (scatter() takes this rank's rows)
      self->fluid_->scatter(self->y_nat_, y);
    } catch (const std::exception& e) {
      SETERRQ(PetscObjectComm(reinterpret_cast<PetscObject>(A)), PETSC_ERR_LIB, "%s", e.what());
    }
  }
  if (self->immersed_.C) {
    try {
      self->immersed_.multiply_add(x, y);
    } catch (const std::exception& e) {
      SETERRQ(PetscObjectComm(reinterpret_cast<PetscObject>(A)), PETSC_ERR_LIB, "%s", e.what());
    }
  }
  if (!self->colloc_begin_.empty()) {
    try {
      self->add_solid_product(x, y);
    } catch (const std::exception& e) {
      SETERRQ(PetscObjectComm(reinterpret_cast<PetscObject>(A)), PETSC_ERR_LIB, "%s", e.what());
    }
  }
  PetscFunctionReturn(0);
}

std::string DcImmersedFluid::write_fields(const std::string& dir, const std::string& stem,
                                          int samples_per_element,
                                          const std::function<Vec3(const Vec3&)>& undisturbed) const {
  if (samples_per_element < 1)
    throw std::invalid_argument("write_fields: samples_per_element must be >= 1, got " +
                                std::to_string(samples_per_element));
  int rank = 0;
  CELLFSI_PETSC(MPI_Comm_rank(comm_, &rank));
  const int D = dim(), s = samples_per_element;
  const std::string name = stem + ".vts";
  int failed = 0;
  std::string message;
  if (rank == 0) {  // the state is on every rank: rank 0 writes the whole grid
    try {
      int n[3] = {1, 1, 1};
      for (int d = 0; d < D; ++d) n[d] = space_->n_elements(d) * s + 1;
      std::vector<Vec3> pts;
      pts.reserve(static_cast<std::size_t>(n[0]) * n[1] * n[2]);
      for (int m2 = 0; m2 < n[2]; ++m2)
        for (int m1 = 0; m1 < n[1]; ++m1)
          for (int m0 = 0; m0 < n[0]; ++m0) {
            const int m[3] = {m0, m1, m2};
            Vec3 x = Vec3::Zero();
            for (int d = 0; d < D; ++d)
              x[d] = space_->lo(d) + (space_->hi(d) - space_->lo(d)) * m[d] / (n[d] - 1);
            pts.push_back(x);
          }
      std::vector<PointSample> smp;
      if (space_->is_mapped()) {
        // The grid is in the space's coordinates: each sample evaluated in its element as it is (the last
        // along x in the last element, not wrapped to the period's start: mapped there it is x = L), then
        // mapped.
        dc::ElementBasis eb;
        for (std::size_t p = 0; p < pts.size(); ++p) {
          const int m[3] = {static_cast<int>(p % n[0]), static_cast<int>((p / n[0]) % n[1]),
                            static_cast<int>(p / (static_cast<std::size_t>(n[0]) * n[1]))};
          geometry::Index3 e{0, 0, 0};
          for (int d = 0; d < D; ++d) e[d] = std::min(m[d] / s, space_->n_elements(d) - 1);
          smp.push_back(at_space_point(fluid_->state(), nullptr, pts[p], eb, &e));
          pts[p] = eb.x[0];
        }
      } else {
        smp = evaluate(fluid_->state(), nullptr, pts);
      }
      vtkNew<vtkStructuredGrid> grid;
      grid->SetDimensions(n[0], n[1], n[2]);
      vtkNew<vtkPoints> points;
      points->SetDataTypeToDouble();
      vtkNew<vtkDoubleArray> vel, pre, vor, dvg, dis;
      vel->SetName("velocity");
      vel->SetNumberOfComponents(3);
      pre->SetName("pressure");
      vor->SetName("vorticity");
      vor->SetNumberOfComponents(3);
      dvg->SetName("divergence");
      dis->SetName("velocity_disturbance");
      dis->SetNumberOfComponents(3);
      for (std::size_t i = 0; i < pts.size(); ++i) {
        const PointSample& q = smp[i];
        const geometry::Mat3& g = q.grad_v;
        points->InsertNextPoint(pts[i][0], pts[i][1], pts[i][2]);
        vel->InsertNextTuple3(q.v[0], q.v[1], q.v[2]);
        pre->InsertNextValue(options_.density * q.p);
        vor->InsertNextTuple3(g(2, 1) - g(1, 2), g(0, 2) - g(2, 0), g(1, 0) - g(0, 1));
        dvg->InsertNextValue(g.trace());
        if (undisturbed) {
          const Vec3 d = q.v - undisturbed(pts[i]);
          dis->InsertNextTuple3(d[0], d[1], d[2]);
        }
      }
      grid->SetPoints(points);
      grid->GetPointData()->AddArray(vel);
      grid->GetPointData()->AddArray(pre);
      grid->GetPointData()->AddArray(vor);
      grid->GetPointData()->AddArray(dvg);
      if (undisturbed) grid->GetPointData()->AddArray(dis);
      vtkNew<vtkXMLStructuredGridWriter> writer;
      writer->SetInputData(grid);
      geometry::write_vtk_atomically(writer, (std::filesystem::path(dir) / name).string());
    } catch (const std::exception& e) {
      failed = 1;
      message = e.what();
    }
  }
  CELLFSI_PETSC(MPI_Bcast(&failed, 1, MPI_INT, 0, comm_));
  if (failed)
    throw std::runtime_error("write_fields: " + (rank == 0 ? message : std::string("rank 0 failed")));
  return name;
}

std::optional<double> DcImmersedFluid::max_divergence_ratio() const {
  const std::vector<double>& h = fluid_->divergence_history();
  return h.empty() ? 0.0 : *std::max_element(h.begin(), h.end());
}

std::string DcImmersedFluid::state_bytes() const {
  Vec u = natural_vector(comm_, fluid_->state()), udot = natural_vector(comm_, fluid_->state_rate());
  std::string bytes = vec_binary_on_rank_zero(u) + vec_binary_on_rank_zero(udot);
  VecDestroy(&u);
  VecDestroy(&udot);
  return bytes;
}

ImmersedFluid::LoadedState DcImmersedFluid::load_state(PetscViewer viewer, int steps) {
  const std::vector<double> zeros(static_cast<std::size_t>(space_->n_dofs()), 0.0);
  Vec u = natural_vector(comm_, zeros), udot = natural_vector(comm_, zeros);
  const StateRead read = read_state_pair(viewer, u, udot);
  const LoadedState r = read == StateRead::ok             ? LoadedState::ok
                        : read == StateRead::does_not_fit ? LoadedState::does_not_fit
                                                          : LoadedState::not_finite;
  if (r == LoadedState::ok) {
    fluid_->restore(all_entries(u), all_entries(udot), steps);
    sync_solution();
  }
  VecDestroy(&u);
  VecDestroy(&udot);
  return r;
}

}  // namespace cellfsi::fluid
