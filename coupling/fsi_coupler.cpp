#include "coupling/fsi_coupler.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include "common/collective.hpp"
#include "common/petsc_error.hpp"
#include "coupling/coupling_events.hpp"
#include "coupling/inner_viscosity.hpp"
#include "coupling/interface_marking.hpp"
#include "geometry/element_region.hpp"
#include "geometry/measures.hpp"

namespace cellfsi::coupling {

FsiCoupler::FsiCoupler(fluid::ImmersedFluid& fluid, std::vector<solid::SolidSolver*> bodies,
                       CouplerOptions options)
    : fluid_(fluid), bodies_(std::move(bodies)), opt_(options), locator_(fluid.patch()) {
  tp_ = solid::TimeParameters::from_rho_inf(fluid.options().rho_inf, fluid.options().dt);
  if (!(opt_.tolerance > 0 && opt_.tolerance < 1))
    throw std::invalid_argument("coupler tolerance must be in (0, 1)");
  check_interface_scaling(opt_.s_interface);
  for (auto* b : bodies_)
    if (b->dim() != fluid.dim())
      throw std::invalid_argument("body '" + b->name() + "' has another dimension");
  if (opt_.inner_viscosity.size() > bodies_.size())
    throw std::invalid_argument("more inner viscosities than bodies");
  opt_.inner_viscosity.resize(bodies_.size(), 0.0);
  for (size_t b = 0; b < bodies_.size(); ++b) {
    if (opt_.inner_viscosity[b] == 0) continue;
    check_inner_viscosity(bodies_[b]->name(), bodies_[b]->is_membrane(), opt_.inner_viscosity[b]);
    contrast_ = contrast_ || opt_.inner_viscosity[b] != fluid.options().viscosity;
  }
  collocation_loc_.resize(bodies_.size());
  quadrature_loc_.resize(bodies_.size());
  quadrature_owned_.resize(bodies_.size());
  CELLFSI_PETSC(VecDuplicate(fluid.solution(), &X_));
  CELLFSI_PETSC(VecDuplicate(X_, &dX_));
  CELLFSI_PETSC(VecDuplicate(X_, &F_));
  coupling_events();
  if (opt_.acceleration == Acceleration::anderson)
    anderson_ = std::make_unique<AndersonAcceleration>(X_, fluid.unknown_kinds(), opt_.acceleration_columns,
                                                       opt_.acceleration_reuse);
  LinearSolverOptions lo = opt_.linear;
  lo.fluid_atol = opt_.fluid_atol;
  lo.s_interface_dominates = opt_.s_interface > 1;
  lo.monitor = opt_.monitor;
  linear_ = std::make_unique<CoupledLinearSolver>(fluid, lo, [this] { return active_elements(); });
}

FsiCoupler::~FsiCoupler() {
  VecDestroy(&X_);
  VecDestroy(&dX_);
  VecDestroy(&F_);
}

std::vector<char> FsiCoupler::active_elements() const {
  std::vector<char> active = elements_supporting(fluid_.patch(), marked_);
  const geometry::Patch& patch = fluid_.patch();
  if (!viscous_.empty()) {
    const std::vector<char> viscous = elements_supporting(patch, viscous_);
    for (size_t e = 0; e < active.size(); ++e) active[e] = active[e] || viscous[e];
  }
  const int n0 = patch.n_elements(0), n1 = patch.n_elements(1);
  for (const auto& body : quadrature_loc_)
    for (const Location& l : body) active[l.element[0] + n0 * (l.element[1] + n1 * l.element[2])] = 1;
  return active;
}

void FsiCoupler::update_immersed(bool first_iteration) {
  // (Buffers kept between calls: at 64^3 they are tens of MB, and new ones at every coupling iteration are
  // that many page faults.)
  std::vector<geometry::Index3>& elements = scratch_elements_;
  std::vector<geometry::Param>& xi = scratch_xi_;
  std::vector<fluid::ImmersedPoint>& data = scratch_data_;
  elements.clear(), xi.clear(), data.clear();
  std::vector<geometry::Vec3> interface;
  const double rho1 = fluid_.options().density;
  const bool with_tangent =
      opt_.solid_tangent != SolidTangent::isotropic && linear_->may_assemble(first_iteration);
  // The bodies' stiffness through their collocation (fluid::SolidLinearization): each body that gives its
  // functions' gradients gets 3 columns per control unknown, from `offset`.
  const bool collocation =
      with_tangent && opt_.solid_tangent == SolidTangent::collocation && !linearization_refused_;
  fluid::SolidLinearization& lin = scratch_lin_;  // (the buffers the fluid gave back)
  lin.n_columns = 0;
  lin.control = nullptr;
  lin.elements.clear(), lin.xi.clear(), lin.column.clear(), lin.grad.clear();
  struct Linearized {
    solid::SolidSolver* body;
    int offset, n_control, first_point, n_points;
  };
  std::vector<Linearized> linearized;
  // (the bodies' basis gradients: hundreds of MB at a 3D red cell, kept between calls like the buffers above)
  std::vector<int>& q_begin = scratch_q_begin_;
  std::vector<int>& q_unknown = scratch_q_unknown_;
  std::vector<double>& q_grad = scratch_q_grad_;
  // Every body's points first, located: the repulsion between them needs them all. The material (stress,
  // tangent) is evaluated only at this rank's points: those of its fluid elements, or, where the fluid
  // assembles a point in any element, the rank's equal run of the body's points in the order of their
  // elements at the previous call (at the first, by element). By element, at 32^3 the points' terms stopped
  // dividing beyond 2 ranks: the cells sat in two ranks' elements (-log_view's operation counts). Runs in the
  // body's own order divided them, but a rank's points then spread over the whole cell and half their rows
  // went to other ranks: 64^3 on 2 ranks took 9.3-9.6 s per step against 8.1. In element order a rank's run
  // lies in a contiguous range of elements, as the fluid's own ranges do. Dealt out so, after the first call
  // a rank evaluates and locates only its run (the solid skips the others' points), and the ranks then
  // exchange their points' locations (the next call's order, the repulsion's bins, a warm start) and, for the
  // repulsion, a membrane's positions: before, every rank formed and located every point, and that part of
  // the step did not divide by the ranks. So of another rank's point, all_q holds a current position only for
  // a membrane with the repulsion on (its weight, beta and area, which do not change, from the first call);
  // its stress, tangent and force are an earlier call's, and only this rank's points (own) are read for them.
  std::vector<std::vector<solid::QuadratureData>>& all_q = scratch_q_;
  all_q.resize(bodies_.size());
  const bool dealt = fluid_.assembles_points_anywhere();
  int rank = 0, ranks = 1;
  CELLFSI_PETSC(MPI_Comm_rank(fluid_.comm(), &rank));
  CELLFSI_PETSC(MPI_Comm_size(fluid_.comm(), &ranks));
  const geometry::Patch& patch = fluid_.patch();
  for (size_t b = 0; b < bodies_.size(); ++b) {
    EventScope ev(coupling_events().quadrature);
    auto& warm = quadrature_loc_[b];
    std::vector<char>& own = quadrature_owned_[b];
    const std::size_t n_known = dealt ? warm.size() : 0;  // (the body's points at the previous call)
    std::vector<char>& mine = scratch_mine_;              // (this rank's run among them)
    std::vector<int>& order = scratch_order_;
    mine.assign(n_known, 0);
    // The rank that takes the k-th point in element order: equal runs.
    const auto rank_of = [&](std::size_t k) {
      return static_cast<int>(
          std::min(k * static_cast<std::size_t>(ranks) / n_known, static_cast<std::size_t>(ranks - 1)));
    };
    if (n_known > 0) {
      // The points in element order by a counting sort over the body's range of elements (O(points + that
      // range) where a comparison sort is O(points log points): every rank does it, at every call). Points
      // not found (refused below) first.
      std::vector<int>& start = scratch_start_;
      int lowest = std::numeric_limits<int>::max(), highest = -1;
      for (std::size_t i = 0; i < n_known; ++i)
        if (warm[i].found) {
          const int e = patch.element_index(warm[i].element);
          lowest = std::min(lowest, e), highest = std::max(highest, e);
        }
      if (highest < 0) lowest = highest = 0;
      auto key = [&](std::size_t i) {  // 0: not found; 1 + (element - lowest)
        return warm[i].found ? patch.element_index(warm[i].element) - lowest + 1 : 0;
      };
      start.assign(static_cast<std::size_t>(highest - lowest) + 3, 0);
      for (std::size_t i = 0; i < n_known; ++i) ++start[static_cast<std::size_t>(key(i)) + 1];
      for (std::size_t e = 1; e < start.size(); ++e) start[e] += start[e - 1];
      order.resize(n_known);
      for (std::size_t i = 0; i < n_known; ++i)
        order[start[static_cast<std::size_t>(key(i))]++] = static_cast<int>(i);
      for (std::size_t k = 0; k < n_known; ++k)
        if (rank_of(k) == rank) mine[order[k]] = 1;
    }
    // Only this rank's run is evaluated (the points of the previous call, on more than one rank).
    const bool split = n_known > 0 && ranks > 1;
    const auto evaluate = [&] {
      std::size_t offered = 0,
                  outside = SIZE_MAX;  // (a point outside the domain is refused after the call, so
                                       // that the body's inverted-element report does not claim it)
      bodies_[b]->quadrature_data(
          rho1, with_tangent,
          [&](std::size_t i, const geometry::Vec3& x) {
            ++offered;
            if (i >= warm.size()) warm.resize(i + 1);
            if (i >= own.size()) own.resize(i + 1);
            warm[i] = locator_.locate(x, &warm[i]);
            if (!warm[i].found && outside == SIZE_MAX) outside = i;
            own[i] = warm[i].found && (i < n_known ? mine[i] != 0 : fluid_.owns_element(warm[i].element));
            return own[i] != 0;
          },
          all_q[b], split ? &mine : nullptr);
      const std::size_t expected =
          split ? static_cast<std::size_t>(std::count(mine.begin(), mine.end(), 1)) : all_q[b].size();
      if (offered != expected)
        throw std::logic_error("body '" + bodies_[b]->name() + "' offered " + std::to_string(offered) +
                               " of the " + std::to_string(expected) + " quadrature points asked of it");
      if (outside != SIZE_MAX) locator_.locate_or_throw(all_q[b][outside].x);  // throws, naming the point
      warm.resize(all_q[b].size());
      own.resize(all_q[b].size());
      if (split)
        for (std::size_t i = 0; i < n_known; ++i)
          if (!mine[i]) own[i] = 0;
    };
    // A point refused (inverted, outside) on its rank alone stops every rank (and one refused on every rank
    // is reported once). A run's first call (no points known: every rank forms and locates them all) is
    // its own event, FsiLocateSetUp, once per run.
    std::optional<EventScope> first;
    if (warm.empty()) first.emplace(coupling_events().locate_setup);
    if (ranks > 1)
      on_every_rank(fluid_.comm(), evaluate);
    else
      evaluate();
    first.reset();
    if (!split) continue;
    // The others' points: each rank's run in element order, its points' elements and xi and (a membrane's,
    // for the repulsion) positions.
    const bool positions = opt_.repulsion.enabled && bodies_[b]->is_membrane();
    const int width = positions ? 7 : 4;
    std::vector<int>& counts = scratch_counts_;
    std::vector<int>& displs = scratch_displs_;
    counts.assign(static_cast<std::size_t>(ranks), 0);
    for (std::size_t k = 0; k < n_known; ++k) counts[static_cast<std::size_t>(rank_of(k))] += width;
    displs.assign(static_cast<std::size_t>(ranks), 0);
    for (int r = 1; r < ranks; ++r) displs[r] = displs[r - 1] + counts[r - 1];
    std::vector<double>& send = scratch_send_;
    std::vector<double>& all = scratch_recv_;
    send.clear();
    const auto k_begin = static_cast<std::size_t>(displs[rank] / width),
               k_end = k_begin + static_cast<std::size_t>(counts[rank] / width);
    for (std::size_t k = k_begin; k < k_end; ++k) {
      const auto i = static_cast<std::size_t>(order[k]);
      send.push_back(patch.element_index(warm[i].element));  // (exact in a double)
      send.insert(send.end(), warm[i].xi.data(), warm[i].xi.data() + 3);
      if (positions) send.insert(send.end(), all_q[b][i].x.data(), all_q[b][i].x.data() + 3);
    }
    all.resize(static_cast<std::size_t>(width) * n_known);
    CELLFSI_PETSC(MPI_Allgatherv(send.data(), counts[rank], MPI_DOUBLE, all.data(), counts.data(),
                                 displs.data(), MPI_DOUBLE, fluid_.comm()));
    for (std::size_t k = 0; k < n_known; ++k) {
      const auto i = static_cast<std::size_t>(order[k]);
      if (mine[i]) continue;
      const double* v = all.data() + static_cast<std::size_t>(width) * k;
      warm[i].found = true;  // (its rank refused a point not found)
      warm[i].element = patch.element_multi_index(static_cast<int>(v[0]));
      warm[i].xi = geometry::Param{v[1], v[2], v[3]};
      if (positions) all_q[b][i].x = geometry::Vec3(v[4], v[5], v[6]);
    }
  }
  const std::vector<std::vector<geometry::Vec3>>* contact = nullptr;
  {
    EventScope ev(coupling_events().repulsion);
    contact = repulsion_forces(all_q);
  }
  for (size_t b = 0; b < bodies_.size(); ++b) {
    const std::vector<solid::QuadratureData>& q = all_q[b];
    const std::vector<char>& own = quadrature_owned_[b];
    const auto n_own = static_cast<size_t>(std::count(own.begin(), own.end(), 1));
    bool linear = collocation && bodies_[b]->n_control() > 0 &&
                  bodies_[b]->basis_gradients(q_begin, q_unknown, q_grad, &own) &&
                  q_begin.size() == n_own + 1;
    if (collocation && ranks > 1) {  // (the linearisation's products are collective: every rank alike)
      int all = linear ? 1 : 0;
      CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &all, 1, MPI_INT, MPI_MIN, fluid_.comm()));
      linear = all == 1;
    }
    const int offset = lin.n_columns;
    if (linear) {
      const std::vector<geometry::Vec3> pts = bodies_[b]->collocation_points();
      auto& loc = collocation_loc_[b];
      if (loc.size() != pts.size()) {  // (before the first iteration of a run)
        EventScope first(coupling_events().locate_setup);
        loc.resize(pts.size());
        for (size_t i = 0; i < pts.size(); ++i) loc[i] = locator_.locate_or_throw(pts[i], nullptr);
      }
      linearized.push_back({bodies_[b], offset, bodies_[b]->n_control(),
                            static_cast<int>(lin.elements.size()), static_cast<int>(pts.size())});
      for (const Location& l : loc) lin.elements.push_back(l.element), lin.xi.push_back(l.xi);
      lin.n_columns += 3 * bodies_[b]->n_control();
    }
    const auto& warm = quadrature_loc_[b];
    for (size_t i = 0, o = 0; i < q.size(); ++i) {
      if (!own[i]) continue;     // another rank's: it keeps its own points
      const size_t k_own = o++;  // the point's place among this rank's (basis_gradients' list)
      elements.push_back(warm[i].element);
      xi.push_back(warm[i].xi);
      fluid::ImmersedPoint ip;
      ip.weight = q[i].weight;
      ip.beta = q[i].beta;
      // The solid's stiffness in the fluid tangent (see fluid::ImmersedPoint::stiffness_viscosity).
      const double stiffness_time = tp_.gamma * tp_.dt * tp_.alpha_f / tp_.alpha_m;
      ip.stiffness_viscosity = q[i].shear_modulus * stiffness_time / rho1;
      if (opt_.solid_tangent != SolidTangent::isotropic && q[i].has_tangent) {
        ip.stiffness_time = stiffness_time;
        ip.stiffness = q[i].tangent;
      }
      if (linear) {
        ip.solid_begin = static_cast<int>(lin.column.size());
        for (int k = q_begin[k_own]; k < q_begin[k_own + 1]; ++k) {
          lin.column.push_back(offset + 3 * q_unknown[k]);
          lin.grad.insert(lin.grad.end(), q_grad.begin() + 3 * k, q_grad.begin() + 3 * k + 3);
        }
        ip.solid_end = static_cast<int>(lin.column.size());
      }
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) ip.stress[r][c] = q[i].stress(r, c);
      for (int c = 0; c < 3; ++c) ip.force[c] = q[i].force[c];
      // The contact repulsion's force [dyn] on the point, per unit reference volume, like the loads.
      if (contact && !(*contact)[b].empty())
        for (int c = 0; c < 3; ++c) ip.force[c] += (*contact)[b][i][c] / (q[i].weight * rho1);
      data.push_back(ip);
    }
    if (!first_iteration) continue;  // (the marking's points; a remote body's are a message)
    const std::vector<geometry::Vec3> pts = bodies_[b]->interface_points();
    interface.insert(interface.end(), pts.begin(), pts.end());
  }
  if (!linearized.empty()) {
    // Collective: each body's columns (one collocation solve each) dealt out to the ranks in turn, the
    // increments summed over the ranks (every rank solved every body, which did not divide).
    lin.control = [linearized, comm = fluid_.comm(), rank, ranks, dv3 = std::vector<solid::Vec3>(),
                   dc = Eigen::MatrixXd()](const std::vector<double>& dv, std::vector<double>& out) mutable {
      EventScope ev(coupling_events().solid_control);
      std::fill(out.begin(), out.end(), 0.0);
      for (std::size_t k = 0, job = 0; k < linearized.size(); ++k) {
        const Linearized& l = linearized[k];
        // (one job per column on more than one rank; one per body on one)
        const int columns = ranks > 1 ? l.body->dim() : 1;
        for (int c = 0; c < columns; ++c, ++job) {
          if (static_cast<int>(job % static_cast<std::size_t>(ranks)) != rank) continue;
          dv3.resize(l.n_points);
          for (int i = 0; i < l.n_points; ++i)
            for (int d = 0; d < 3; ++d) dv3[i][d] = dv[3 * static_cast<size_t>(l.first_point + i) + d];
          if (!l.body->control_increment(dv3, dc, ranks > 1 ? c : -1)) continue;
          CELLFSI_PETSC(
              PetscLogFlops(l.body->control_increment_operations() * (ranks > 1 ? 1 : l.body->dim())));
          for (Eigen::Index r = 0; r < dc.rows(); ++r)
            for (Eigen::Index d = 0; d < dc.cols(); ++d)
              if (ranks == 1 || d == c) out[l.offset + 3 * r + d] = dc(r, d);
        }
      }
      if (ranks > 1)
        CELLFSI_PETSC(
            MPI_Allreduce(MPI_IN_PLACE, out.data(), static_cast<int>(out.size()), MPI_DOUBLE, MPI_SUM, comm));
    };
    // (A fluid that does not take it says so once; its points keep their consistent tangent.)
    linearization_refused_ = !fluid_.set_solid_linearization(lin);
  }
  fluid_.set_immersed_points(elements, xi, data);
  // A fluid without s^h (the divergence-conforming space) has no marking: its Jacobian does not depend on
  // one, so the cells' moving through the mesh refreshes nothing before -coupling_refresh_steps.
  if (!first_iteration || !fluid_.uses_interface_scaling()) return;
  std::vector<int> marked = functions_near(locator_, interface, opt_.marking);
  // With s_I >> 1 the marked rows dominate the Jacobian: a new marking invalidates a reused preconditioner.
  if (marked != marked_) {
    marked_ = std::move(marked);
    linear_->marking_changed();
  }
  apply_scaling();
}

const std::vector<std::vector<geometry::Vec3>>* FsiCoupler::repulsion_forces(
    const std::vector<std::vector<solid::QuadratureData>>& q) {
  if (!opt_.repulsion.enabled) return nullptr;
  const int dim = fluid_.dim();
  std::vector<RepulsionBody> bodies(q.size());
  contact_x_.resize(q.size());
  contact_area_.resize(q.size());
  int membranes = 0;
  double scale = 0;
  for (size_t b = 0; b < q.size(); ++b) {
    if (q[b].empty() || !(q[b][0].area > 0)) continue;  // a bulky body
    ++membranes;
    auto& x = contact_x_[b];
    auto& a = contact_area_[b];
    x.resize(q[b].size());
    a.resize(q[b].size());
    double area = 0, volume = 0;
    for (size_t i = 0; i < q[b].size(); ++i) {
      x[i] = q[b][i].x;
      a[i] = q[b][i].area;
      area += a[i], volume += q[b][i].weight;
    }
    bodies[b] = {&x, &a, &quadrature_loc_[b]};
    if (repulsion_checked_) continue;
    // The default scale: the membrane's surface modulus G h over the radius of a circle (sphere) of its
    // reference perimeter (area), the pressure that strains it by about one.
    const double radius = dim == 2 ? area / (2 * M_PI) : std::sqrt(area / (4 * M_PI));
    scale = std::max(scale, q[b][0].shear_modulus * (volume / area) / radius);
  }
  if (!repulsion_checked_) {
    // (Once per run: -log_view's FsiRepulsionSetUp, which the count model leaves out, as the bulk's factors.)
    EventScope ev(coupling_events().repulsion_setup);
    repulsion_checked_ = true;
    if (membranes == 0) return nullptr;
    const double cutoff =
        opt_.repulsion.cutoff > 0 ? opt_.repulsion.cutoff : geometry::smallest_element_extent(fluid_.patch());
    repulsion_ = std::make_unique<Repulsion>(fluid_.patch(), cutoff,
                                             opt_.repulsion.scale > 0 ? opt_.repulsion.scale : scale,
                                             opt_.repulsion.walls);
  }
  if (!repulsion_) return nullptr;
  repulsion_stats_ = repulsion_->forces(bodies, contact_force_);
  return repulsion_stats_.cell_pairs + repulsion_stats_.wall_points > 0 ? &contact_force_ : nullptr;
}

void FsiCoupler::apply_scaling() {
  const std::vector<double> s = scaling_values(fluid_.patch().n_control(), marked_, opt_.s_interface);
  fluid_.set_scaling([&](int node) { return s[node]; });
}

void FsiCoupler::set_interface_scaling(double s_interface) {
  check_interface_scaling(s_interface);
  if (s_interface == opt_.s_interface) return;
  opt_.s_interface = s_interface;
  apply_scaling();
  linear_->marking_changed();
}

void FsiCoupler::update_viscosity() {
  if (!contrast_) return;
  EventScope ev(coupling_events().viscosity);
  const double mu_out = fluid_.options().viscosity;
  std::vector<std::vector<geometry::Patch>> patches;
  std::vector<size_t> which;
  for (size_t b = 0; b < bodies_.size(); ++b)
    if (opt_.inner_viscosity[b] > 0 && opt_.inner_viscosity[b] != mu_out) {
      patches.push_back(bodies_[b]->current_patches());
      which.push_back(b);
    }
  std::vector<InnerViscosity> inner;
  for (size_t i = 0; i < patches.size(); ++i)
    inner.push_back(
        {&patches[i][0], opt_.inner_viscosity[which[i]], patches[i].size() > 1 ? &patches[i] : nullptr});
  const std::vector<double> mu = viscosity_values(fluid_.patch(), inner, mu_out);
  fluid_.set_viscosity([&](int node) { return mu[node]; });
  std::vector<int> viscous;
  for (size_t k = 0; k < mu.size(); ++k)
    if (mu[k] != mu_out) viscous.push_back(static_cast<int>(k));
  // The field changes the Jacobian's rows there: like a new s^h marking, it invalidates a kept
  // preconditioner.
  if (viscous != viscous_) {
    viscous_ = std::move(viscous);
    linear_->marking_changed();
  }
}

void FsiCoupler::initialize() {
  for (size_t b = 0; b < bodies_.size(); ++b) {
    const std::vector<geometry::Vec3> pts = bodies_[b]->collocation_points();
    const std::vector<fluid::PointSample> v = fluid_.sample(pts);
    std::vector<solid::Vec3> rate(pts.size());
    for (size_t i = 0; i < pts.size(); ++i) {
      if (!v[i].found)
        throw std::runtime_error("body '" + bodies_[b]->name() + "' lies outside the fluid domain");
      rate[i] = v[i].v;
    }
    bodies_[b]->set_rate(rate);
  }
  update_viscosity();
  EventScope ev(coupling_events().locate);  // (as in a step: the model finds the repulsion inside it)
  update_immersed(true);
}

void FsiCoupler::restart() {
  if (anderson_) anderson_->reset();
  update_viscosity();
  EventScope ev(coupling_events().locate);
  update_immersed(true);
}

CouplerStats FsiCoupler::step() {
  CouplerStats st;
  const fluid::FluidOptions& fo = fluid_.options();
  const solid::TimeParameters tp = solid::TimeParameters::from_rho_inf(fo.rho_inf, fo.dt, fluid_.time());
  tp_ = tp;
  // The cells' insides from the configuration at t_n (once per step, like s^h; the bodies' current_patch()
  // is valid between steps only).
  update_viscosity();
  {
    EventScope ev(coupling_events().step_ends);
    fluid_.begin_step(X_);
    for (auto* b : bodies_) b->begin_step(tp);
  }
  if (anderson_) anderson_->begin_step();
  st.solid_residual0.assign(bodies_.size(), 0.0);
  st.solid_residual.assign(bodies_.size(), 0.0);
  double fluid_peak = 0;
  std::vector<double> solid_peak(bodies_.size(), 0.0);
  int rank = 0, ranks = 1;
  CELLFSI_PETSC(MPI_Comm_rank(fluid_.comm(), &rank));
  CELLFSI_PETSC(MPI_Comm_size(fluid_.comm(), &ranks));
  for (int it = 0; it < opt_.max_iterations; ++it) {
    // Steps 1-3 for every body, from the current fluid iterate. Where the fluid samples anywhere (its state
    // whole on every rank), each rank locates and samples an equal run of the body's collocation points and
    // the ranks gather their runs (their locations too: the solids' linearisation reads them); before, every
    // rank sampled every point, which did not divide by the ranks.
    int first_column = 0;  // (the kinematic update's collocation columns dealt out over the bodies in turn)
    for (size_t b = 0; b < bodies_.size(); ++b) {
      const std::vector<geometry::Vec3> pts = bodies_[b]->collocation_points();
      const std::size_t n = pts.size();
      auto& warm = collocation_loc_[b];
      warm.resize(n);
      const bool split = ranks > 1 && fluid_.samples_anywhere();
      const std::size_t i0 = split ? n * static_cast<std::size_t>(rank) / static_cast<std::size_t>(ranks) : 0,
                        i1 = split ? n * static_cast<std::size_t>(rank + 1) / static_cast<std::size_t>(ranks)
                                   : n;
      std::vector<geometry::Index3> el(i1 - i0);
      std::vector<geometry::Param> xi(i1 - i0);
      {
        EventScope ev(coupling_events().locate);
        const auto locate = [&] {
          for (size_t i = i0; i < i1; ++i) {
            warm[i] = locator_.locate_or_throw(pts[i], &warm[i]);
            el[i - i0] = warm[i].element;
            xi[i - i0] = warm[i].xi;
          }
        };
        if (split)
          on_every_rank(fluid_.comm(), locate);  // (a point outside on one rank stops every rank)
        else
          locate();
      }
      std::vector<solid::VelocitySample> vs(n);
      {
        EventScope ev(coupling_events().solid);
        const std::vector<fluid::PointSample> v = fluid_.sample_alpha(X_, el, xi);
        for (size_t i = i0; i < i1; ++i) vs[i].v = v[i - i0].v, vs[i].grad_v = v[i - i0].grad_v;
        if (split) {
          // Per point: its element, xi, v and grad v (16 values); rank r's run from n r / ranks on.
          constexpr int kWidth = 16;
          std::vector<int> counts(static_cast<std::size_t>(ranks)), displs(static_cast<std::size_t>(ranks));
          for (int r = 0; r < ranks; ++r) {
            displs[r] =
                kWidth * static_cast<int>(n * static_cast<std::size_t>(r) / static_cast<std::size_t>(ranks));
            counts[r] = kWidth * static_cast<int>(n * static_cast<std::size_t>(r + 1) /
                                                  static_cast<std::size_t>(ranks)) -
                        displs[r];
          }
          std::vector<double>& all = scratch_recv_;
          all.resize(kWidth * n);
          for (size_t i = i0; i < i1; ++i) {
            double* p = all.data() + kWidth * i;
            p[0] = fluid_.patch().element_index(warm[i].element);  // (exact in a double)
            for (int c = 0; c < 3; ++c) p[1 + c] = warm[i].xi[c], p[4 + c] = vs[i].v[c];
            for (int r = 0; r < 3; ++r)
              for (int c = 0; c < 3; ++c) p[7 + 3 * r + c] = vs[i].grad_v(r, c);
          }
          CELLFSI_PETSC(MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, all.data(), counts.data(),
                                       displs.data(), MPI_DOUBLE, fluid_.comm()));
          for (size_t i = 0; i < n; ++i) {
            if (i >= i0 && i < i1) continue;
            const double* p = all.data() + kWidth * i;
            warm[i].found = true;  // (its rank refused a point not found)
            warm[i].element = fluid_.patch().element_multi_index(static_cast<int>(p[0]));
            for (int c = 0; c < 3; ++c) warm[i].xi[c] = p[1 + c], vs[i].v[c] = p[4 + c];
            for (int r = 0; r < 3; ++r)
              for (int c = 0; c < 3; ++c) vs[i].grad_v(r, c) = p[7 + 3 * r + c];
          }
        }
      }
      EventScope ev(coupling_events().kinematic);
      // Where every rank has every sample, the ranks share the update: each its run of the points and its
      // collocation columns (every rank updated every body, which did not divide).
      solid::KinematicShare share;
      double operations = 0;
      share.operations = &operations;
      if (split) {
        share.part = rank, share.parts = ranks;
        share.first_column = first_column;  // (the bodies' columns dealt out in turn)
        const MPI_Comm comm = fluid_.comm();
        share.gather = [comm, ranks, n, &counts = scratch_counts_, &displs = scratch_displs_](double* v,
                                                                                              int width) {
          if (static_cast<long long>(width) * static_cast<long long>(n) > std::numeric_limits<int>::max())
            throw std::runtime_error("the kinematic update's exchange: " + std::to_string(n) + " points of " +
                                     std::to_string(width) + " values exceed MPI's int counts");
          counts.assign(static_cast<std::size_t>(ranks), 0);
          displs.assign(static_cast<std::size_t>(ranks), 0);
          for (int r = 0; r < ranks; ++r) {
            const auto at = [&](int q) {
              return width *
                     static_cast<int>(n * static_cast<std::size_t>(q) / static_cast<std::size_t>(ranks));
            };
            displs[r] = at(r);
            counts[r] = at(r + 1) - at(r);
          }
          CELLFSI_PETSC(MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, v, counts.data(), displs.data(),
                                       MPI_DOUBLE, comm));
        };
        // (reduced on rank 0 and broadcast: the residual's norm steers every rank's loop alike)
        share.sum = [comm, rank](double* v, int m) {
          CELLFSI_PETSC(MPI_Reduce(rank == 0 ? MPI_IN_PLACE : v, v, m, MPI_DOUBLE, MPI_SUM, 0, comm));
          CELLFSI_PETSC(MPI_Bcast(v, m, MPI_DOUBLE, 0, comm));
        };
      }
      st.solid_residual[b] = bodies_[b]->kinematic_update(vs, share);
      first_column += bodies_[b]->dim();
      CELLFSI_PETSC(PetscLogFlops(operations));
      if (it == 0) st.solid_residual0[b] = st.solid_residual[b];
    }
    // Step 4: immersed contributions of the updated bodies, then the fluid residual. s^h is marked once per
    // step, at the first iteration: re-marking inside the iteration makes the residual jump whenever an
    // interface point crosses a support boundary, and the iteration can cycle between two markings (seen with
    // the capsule at 64 x 32: |R_MC| alternating 9.1e-4 / 1.4e-4 for 30 iterations).
    {
      EventScope ev(coupling_events().locate);
      update_immersed(it == 0);
    }
    {
      EventScope ev(coupling_events().residual);
      fluid_.residual(X_, F_);
    }
    CELLFSI_PETSC(VecNorm(F_, NORM_2, &st.fluid_residual));
    if (it == 0) st.fluid_residual0 = st.fluid_residual;
    if (opt_.monitor) {
      CELLFSI_PETSC(PetscPrintf(fluid_.comm(), "  fsi iteration %d: |R_MC| %.3e", it, st.fluid_residual));
      for (size_t b = 0; b < bodies_.size(); ++b)
        CELLFSI_PETSC(
            PetscPrintf(fluid_.comm(), "  |R_K(%s)| %.3e", bodies_[b]->name().c_str(), st.solid_residual[b]));
      CELLFSI_PETSC(PetscPrintf(fluid_.comm(), "\n"));
    }
    // Each residual must drop by the tolerance below the largest value it has had in this step: the kinematic
    // residual is ~0 at the first iteration when the predictor matches the fluid, and grows once the fluid
    // moves.
    fluid_peak = std::max(fluid_peak, st.fluid_residual);
    bool done = st.fluid_residual <= opt_.tolerance * fluid_peak || st.fluid_residual <= opt_.fluid_atol;
    for (size_t b = 0; b < bodies_.size(); ++b) {
      solid_peak[b] = std::max(solid_peak[b], st.solid_residual[b]);
      done = done && (st.solid_residual[b] <= opt_.tolerance * solid_peak[b] ||
                      st.solid_residual[b] <= opt_.solid_atol);
    }
    if (done && it > 0) {
      st.converged = true;
      st.reason = "all residuals dropped by the tolerance";
      break;
    }
    st.iterations = it + 1;
    // Steps 5-7: K_MC, a linear solve, the update.
    try {
      SolveCounts counts;
      st.linear_iterations += linear_->solve(X_, F_, dX_, it == 0, counts);
      st.factorizations += counts.factorizations;
      st.bulk_factorizations += counts.bulk_factorizations;
      st.refreshes += counts.refreshes;
    } catch (const std::invalid_argument&) {
      throw;  // bad input found by the solver (a misspelt type read at the first solve)
    } catch (const std::exception& e) {
      st.reason = e.what();
      if (anderson_) anderson_->reset();
      return st;
    }
    if (anderson_)
      anderson_->update(X_, dX_);
    else
      CELLFSI_PETSC(VecAXPY(X_, -1.0, dX_));
  }
  if (!st.converged) {
    if (anderson_) anderson_->reset();
    if (st.reason.empty()) {
      // Where the last residuals stood against their targets: a stall just above them (a point changing
      // element at every iteration, say) reads differently from residuals that grew.
      char text[160];
      std::snprintf(text, sizeof text, "no convergence in %d iterations: |R_MC| %.2e against %.2e",
                    opt_.max_iterations, st.fluid_residual,
                    std::max(opt_.tolerance * fluid_peak, opt_.fluid_atol));
      st.reason = text;
      std::size_t worst = bodies_.size();
      double worst_ratio = 1;
      for (size_t b = 0; b < bodies_.size(); ++b) {
        const double target = std::max(opt_.tolerance * solid_peak[b], opt_.solid_atol);
        if (st.solid_residual[b] > worst_ratio * target)
          worst = b, worst_ratio = st.solid_residual[b] / target;
      }
      if (worst < bodies_.size()) {
        std::snprintf(text, sizeof text, ", |R_K(%s)| %.2e against %.2e", bodies_[worst]->name().c_str(),
                      st.solid_residual[worst],
                      std::max(opt_.tolerance * solid_peak[worst], opt_.solid_atol));
        st.reason += text;
      }
    }
    return st;
  }
  {
    EventScope ev(coupling_events().step_ends);
    fluid_.end_step(X_);
    for (auto* b : bodies_) b->end_step();
  }
  st.repulsion = repulsion_stats_;
  return st;
}

}  // namespace cellfsi::coupling
