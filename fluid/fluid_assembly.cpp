// FluidSolver::assemble: the element loop of the VMS residual and tangent (vms_kernel.hpp) and of the
// immersed-solid points, with the Dirichlet rows; the SNES callbacks.
#include <stdexcept>
#include <string>
#include <utility>

#include "common/generalized_alpha.hpp"
#include "common/petsc_error.hpp"
#include "fluid/fluid_solver.hpp"
#include "fluid/point_evaluation.hpp"
#include "fluid/seq_baij_inserter.hpp"

namespace cellfsi::fluid {

using geometry::BasisValues;
using geometry::MapValues;

namespace {

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define CELLFSI_POINT_AVX2 1
/// point_fields' 3D sums with a node's four unknowns (v_x, v_y, v_z, p) as one AVX vector: per function
/// six vector FMAs (values, rates, Laplacian, the x, y and z derivatives) instead of 23 scalar products.
/// Chosen at run time where the CPU has AVX2 and FMA; the same sums in the same order, rounded as fused
/// multiply-adds.
/// (Generic 4-wide vectors without AVX made the 3D residual 2.2x slower: measured, bench/fluid_assembly.)
[[gnu::target("avx2,fma")]] void point_sums_3d_avx2(const PointBasis& b, const double* Vf, const double* Vd,
                                                    const double* S, double& s, double v[3], double vdot[3],
                                                    double lap_v[3], double dv[3][3], double& p,
                                                    double dp[3]) {
  typedef double Quad __attribute__((vector_size(32)));
  typedef double QuadU __attribute__((vector_size(32), aligned(8), may_alias));
  Quad val{}, rate{}, lap{}, dx{}, dy{}, dz{};
  double sum_s = 0;
  for (int k = 0; k < b.n; ++k) {
    const double N = b.N[k], lapN = b.lapN[k];
    const double* dN = b.dN + 3 * k;
    const Quad f = *reinterpret_cast<const QuadU*>(Vf + 4 * k);
    sum_s += N * S[k];
    val += Quad{N, N, N, N} * f;
    rate += Quad{N, N, N, N} * *reinterpret_cast<const QuadU*>(Vd + 4 * k);
    lap += Quad{lapN, lapN, lapN, lapN} * f;
    dx += Quad{dN[0], dN[0], dN[0], dN[0]} * f;
    dy += Quad{dN[1], dN[1], dN[1], dN[1]} * f;
    dz += Quad{dN[2], dN[2], dN[2], dN[2]} * f;
  }
  s = sum_s;
  for (int i = 0; i < 3; ++i) {
    v[i] = val[i];
    vdot[i] = rate[i];
    lap_v[i] = lap[i];
    dv[i][0] = dx[i];
    dv[i][1] = dy[i];
    dv[i][2] = dz[i];
  }
  p = val[3];
  dp[0] = dx[3];
  dp[1] = dy[3];
  dp[2] = dz[3];
}
#endif

/// The fields at a point from the element's nodal values (Vf, Vd interleaved by node, dof D + 1; S), for
/// FluidSolver::assemble. D is a template parameter so that the small loops unroll and the sums stay in
/// registers.
template <int D>
void point_fields(const PointBasis& b, const double* Vf, const double* Vd, const double* S,
                  const std::array<std::array<double, 3>, 3>& G, PointFields& pf) {
  constexpr int nd = D + 1;
  double s = 0, v[D] = {}, vdot[D] = {}, lap_v[D] = {}, dv[D][D] = {}, p = 0, dp[D] = {};
  if constexpr (D == 2) {
    // The same sums two at a time: lanes (x, y) of v, vdot, lap_v, the columns of dv and dp, and (p, s).
    typedef double Pair __attribute__((vector_size(16)));
    typedef double PairU __attribute__((vector_size(16), aligned(8), may_alias));
    Pair v2{}, vdot2{}, lap2{}, dvx{}, dvy{}, dp2{}, ps{};
    for (int k = 0; k < b.n; ++k) {
      const double N = b.N[k], lapN = b.lapN[k], pk = Vf[k * nd + D];
      const Pair Nk{N, N}, vk = *reinterpret_cast<const PairU*>(Vf + k * nd);
      const Pair dNk = *reinterpret_cast<const PairU*>(b.dN + 3 * k);
      v2 += Nk * vk;
      vdot2 += Nk * *reinterpret_cast<const PairU*>(Vd + k * nd);
      lap2 += Pair{lapN, lapN} * vk;
      dvx += Pair{dNk[0], dNk[0]} * vk;
      dvy += Pair{dNk[1], dNk[1]} * vk;
      dp2 += dNk * Pair{pk, pk};
      ps += Nk * Pair{pk, S[k]};
    }
    for (int i = 0; i < 2; ++i) {
      v[i] = v2[i];
      vdot[i] = vdot2[i];
      lap_v[i] = lap2[i];
      dv[i][0] = dvx[i];
      dv[i][1] = dvy[i];
      dp[i] = dp2[i];
    }
    p = ps[0];
    s = ps[1];
  } else {
#ifdef CELLFSI_POINT_AVX2
    if (cpu_has_avx2_fma())
      point_sums_3d_avx2(b, Vf, Vd, S, s, v, vdot, lap_v, dv, p, dp);
    else
#endif
    for (int k = 0; k < b.n; ++k) {
      const double N = b.N[k], lapN = b.lapN[k];
      const double* dN = b.dN + 3 * k;
      s += N * S[k];
      for (int i = 0; i < D; ++i) {
        const double vk = Vf[k * nd + i];
        v[i] += N * vk;
        vdot[i] += N * Vd[k * nd + i];
        lap_v[i] += lapN * vk;
        for (int j = 0; j < D; ++j) dv[i][j] += dN[j] * vk;
      }
      const double pk = Vf[k * nd + D];
      p += N * pk;
      for (int j = 0; j < D; ++j) dp[j] += dN[j] * pk;
    }
  }
  // Every member assigned (no zero-fill of the whole struct first).
  pf.s = s;
  pf.p = p;
  for (int i = 0; i < 3; ++i) {
    pf.v[i] = i < D ? v[i] : 0.0;
    pf.vdot[i] = i < D ? vdot[i] : 0.0;
    pf.lap_v[i] = i < D ? lap_v[i] : 0.0;
    pf.dp[i] = i < D ? dp[i] : 0.0;
    for (int j = 0; j < 3; ++j) pf.dv[i][j] = i < D && j < D ? dv[i][j] : 0.0;
  }
  pf.G = G;
  pf.dnu = {};  // set by the caller where a viscosity field varies
}

/// The element matrix of vms_tangent_element_blocks (n x n column-major blocks of bs x bs) in the row-major
/// layout of vms_tangent_element and MatSetValuesBlocked: K[(A bs + c) n bs + B bs + e] = Kb[(A n + B) bs^2 +
/// e bs + c].
void rows_from_blocks(int n, int bs, const double* Kb, double* K) {
  const std::size_t ld = static_cast<std::size_t>(n) * bs, bs2 = static_cast<std::size_t>(bs) * bs;
  for (int A = 0; A < n; ++A)
    for (int B = 0; B < n; ++B) {
      const double* kb = Kb + (static_cast<std::size_t>(A) * n + B) * bs2;
      double* k = K + static_cast<std::size_t>(A) * bs * ld + static_cast<std::size_t>(B) * bs;
      for (int c = 0; c < bs; ++c)
        for (int e = 0; e < bs; ++e) k[c * ld + e] = kb[e * bs + c];
    }
}

}  // namespace

void FluidSolver::assemble(Vec U, Vec F, Mat J, const std::vector<char>* in_region, bool region_side,
                           bool accumulate) {
  const int D = dim_, nd = dof_;
  const double dt = opt_.dt;
  VmsParameters prm;
  prm.dim = D;
  prm.nu = opt_.viscosity / opt_.density;
  for (int c = 0; c < 3; ++c) prm.g[c] = opt_.body_force[c] / opt_.density;
  prm.dt = dt;
  prm.c_i = opt_.c_i;
  prm.stokes = opt_.stokes;
  const TangentScales ts{alpha_.alpha_f, alpha_.rate_alpha_m_scale(), 1.0};

  Vec U_loc, F_loc = nullptr;
  CELLFSI_PETSC(DMGetLocalVector(da_, &U_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_, U, INSERT_VALUES, U_loc));
  CELLFSI_PETSC(DMGlobalToLocal(da_scalar_, S_, INSERT_VALUES, S_loc_));
  const PetscScalar *u, *un, *udn, *sh, *nuh = nullptr;
  PetscScalar* f = nullptr;
  CELLFSI_PETSC(VecGetArrayRead(U_loc, &u));
  CELLFSI_PETSC(VecGetArrayRead(Un_loc_, &un));
  CELLFSI_PETSC(VecGetArrayRead(Udotn_loc_, &udn));
  CELLFSI_PETSC(VecGetArrayRead(S_loc_, &sh));
  if (Nu_) {
    CELLFSI_PETSC(DMGlobalToLocal(da_scalar_, Nu_, INSERT_VALUES, Nu_loc_));
    CELLFSI_PETSC(VecGetArrayRead(Nu_loc_, &nuh));
  }
  if (F) {
    CELLFSI_PETSC(DMGetLocalVector(da_, &F_loc));
    CELLFSI_PETSC(VecSet(F_loc, 0.0));
    CELLFSI_PETSC(VecGetArray(F_loc, &f));
  }
  if (J) {
    // Dirichlet rows are zeroed after assembly; keeping their pattern lets the matrix be assembled again.
    CELLFSI_PETSC(MatSetOption(J, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));
    if (!accumulate) CELLFSI_PETSC(MatZeroEntries(J));
  }

  SeqBaijInserter direct(J, nd);  // usable only for a one-rank BAIJ Jacobian

  BasisValues bv;
  MapValues mv;
  PhysicalPoint pp;
  ElementValues scratch;
  std::vector<double> Re, Ke, Kb, Vf, Vd, S, Nu;
  std::vector<PetscInt> lidx, lnode;

  // Gathers the element's nodal fields at the alpha levels: Vf = velocity at n+alpha_f and pressure at n+1,
  // Vd = velocity rate at n+alpha_m, S = s^h, Nu = nu_A (with a viscosity field); lnode = local node
  // indices, lidx = local dof indices.
  auto gather = [&](const int first[3]) {
    int np[3] = {1, 1, 1};
    for (int d = 0; d < D; ++d) np[d] = patch_.degree(d) + 1;
    const int n = np[0] * np[1] * np[2];
    Vf.assign(n * nd, 0.0);
    Vd.assign(n * nd, 0.0);
    S.assign(n, 1.0);
    if (nuh) Nu.resize(n);
    lidx.resize(n * nd);
    lnode.resize(n);
    for_each_element_node(patch_, first, gxs_, gxm_, [&](int k, PetscInt node) {
      lnode[k] = node;
      S[k] = sh[node];
      if (nuh) Nu[k] = nuh[node];
      for (int c = 0; c < nd; ++c) {
        const PetscInt li = node * nd + c;
        lidx[k * nd + c] = li;
        if (c < D) {
          Vf[k * nd + c] = alpha_.value_alpha_f(u[li], un[li]);
          Vd[k * nd + c] = alpha_.rate_alpha_m(u[li], un[li], udn[li]);
        } else {
          Vf[k * nd + c] = u[li];
        }
      }
    });
    return n;
  };

  auto fields = [&](const PointBasis& b, const std::array<std::array<double, 3>, 3>& G, PointFields& pf) {
    if (D == 2)
      point_fields<2>(b, Vf.data(), Vd.data(), S.data(), G, pf);
    else
      point_fields<3>(b, Vf.data(), Vd.data(), S.data(), G, pf);
  };

  // The viscosity over an element: uniform (false; prm_e.nu its value, prm's without a field, so that the
  // element kernels' fast paths run unchanged) or varying (true: each point gets its own nu^h and grad nu^h,
  // point_viscosity).
  VmsParameters prm_e = prm;
  auto element_viscosity = [&](int n) {
    if (!nuh) return false;
    prm_e.nu = Nu[0];
    for (int k = 1; k < n; ++k)
      if (Nu[k] != Nu[0]) return true;
    return false;
  };
  auto point_viscosity = [&](const PointBasis& b, VmsParameters& pq, PointFields& pf) {
    pq = prm;
    pq.nu = 0;
    for (int k = 0; k < b.n; ++k) {
      pq.nu += b.N[k] * Nu[k];
      for (int j = 0; j < D; ++j) pf.dnu[j] += b.dN[k * 3 + j] * Nu[k];
    }
  };

  auto scatter = [&](int n, bool matrix_done) {
    if (F)
      for (int r = 0; r < n * nd; ++r) f[lidx[r]] += Re[r];
    if (!J || matrix_done) return;
    // Straight into the value array of a one-rank BAIJ matrix; a block outside its pattern (never on the
    // DMDA's box stencil) hands the matrix back and switches to PETSc's insertion for the rest of the
    // assembly.
    if (direct.usable()) {
      if (direct.add(n, Ke.data())) return;
      direct.finish();
    }
    // Node blocks (the DMDA matrix has block size dof): one index per node instead of per unknown.
    CELLFSI_PETSC(MatSetValuesBlockedLocal(J, n, lnode.data(), n, lnode.data(), Ke.data(), ADD_VALUES));
  };

  PointFields pf;
  VmsParameters prm_q;
  std::vector<PointFields> point_fields;
  std::vector<VmsParameters> point_prm;
  if (in_region && static_cast<int>(in_region->size()) != patch_.n_elements())
    throw std::invalid_argument("FluidSolver: the element mask has " + std::to_string(in_region->size()) +
                                " entries for " + std::to_string(patch_.n_elements()) + " elements");
  const int ne0 = patch_.n_elements(0), ne1 = patch_.n_elements(1);
  for (const Index3& e : owned_elements()) {
    if (in_region && ((*in_region)[e[0] + ne0 * (e[1] + ne1 * e[2])] != 0) != region_side) continue;
    int first[3];
    const ElementValues& ev = element_basis_.evaluate(e, scratch, first);
    const int n = gather(first);
    const bool varying = element_viscosity(n);
    // On a one-rank BAIJ matrix the tangent is formed in its block layout and added straight into it.
    const bool prepared = J && direct.usable() && direct.prepare(n, lnode.data());
    const bool blocks = prepared && !varying;
    // Axis-affine patches (2D): the tangent's products are sum-factorised over the basis' univariate factors.
    const bool tensor = ev.tensor && D == 2 && !varying;
    Re.assign(n * nd, 0.0);
    if (J) {
      if (blocks || tensor)
        Ke.resize(static_cast<size_t>(n * nd) * n * nd);  // overwritten
      else
        Ke.assign(static_cast<size_t>(n * nd) * n * nd, 0.0);
    }
    point_fields.resize(ev.nq);
    if (varying) point_prm.resize(ev.nq);
    for (int q = 0; q < ev.nq; ++q) {
      const PointBasis pb{n, &ev.N[static_cast<size_t>(q) * n], &ev.dN[static_cast<size_t>(q) * n * 3],
                          &ev.lapN[static_cast<size_t>(q) * n]};
      fields(pb, ev.G[q], point_fields[q]);
      if (varying) point_viscosity(pb, point_prm[q], point_fields[q]);
      if (F) vms_residual(varying ? point_prm[q] : prm_e, pb, point_fields[q], ev.weight[q], Re.data());
    }
    // The element tangent at once: small matrix products over the quadrature points (same result as summing
    // vms_tangent over them, to round-off; tested).
    if (J && varying) {  // the element kernels need one nu per element: point by point
      for (int q = 0; q < ev.nq; ++q) {
        const PointBasis pb{n, &ev.N[static_cast<size_t>(q) * n], &ev.dN[static_cast<size_t>(q) * n * 3],
                            &ev.lapN[static_cast<size_t>(q) * n]};
        vms_tangent(point_prm[q], pb, point_fields[q], ts, ev.weight[q], Ke.data());
      }
    } else if (J) {
      const ElementPoints points{
          n, ev.nq, ev.N.data(), ev.dN.data(), ev.lapN.data(), ev.weight.data(), point_fields.data()};
      if (blocks || tensor) {
        TensorFactors tf;
        for (int d = 0; d < 3; ++d) {
          tf.np[d] = ev.np[d];
          tf.nq[d] = ev.nq1[d];
          tf.value[d] = ev.factor_value[d].data();
          tf.deriv[d] = ev.factor_deriv[d].data();
        }
        if (blocks) {
          vms_tangent_element_blocks(prm_e, points, ts, Ke.data(), tensor ? &tf : nullptr);
          direct.add_blocks(n, Ke.data());
        } else {  // for MatSetValuesBlockedLocal: the blocks' rows side by side
          Kb.resize(Ke.size());
          vms_tangent_element_blocks(prm_e, points, ts, Kb.data(), &tf);
          rows_from_blocks(n, nd, Kb.data(), Ke.data());
        }
      } else {
        vms_tangent_element(prm_e, points, ts, Ke.data());
      }
    }
    scatter(n, blocks);
  }

  // Immersed-solid points (paper Eq. (10)) in this rank's elements.
  static const PetscLogEvent immersed_event = register_log_event("cellfsi fluid", "FluidImmersed");
  CELLFSI_PETSC(PetscLogEventBegin(immersed_event, 0, 0, 0, 0));
  // The points of one element (immersed_ is sorted by element) are summed and added to F and J once: on
  // several ranks each addition to rows of another rank is stashed until the assembly (measured: the 3D
  // compound capsule at 16^3 on 2 ranks, 9.8 GB and 20 s per Jacobian when added point by point).
  // The fluid viscosity the immersed terms remove is the local one (nu^h at the point, where a field varies).
  for (std::size_t i = 0; i < immersed_.size() && !(in_region && !region_side);) {
    const Index3 element = immersed_[i].element;
    int n = 0;
    bool varying = false;
    for (bool first_point = true; i < immersed_.size() && immersed_[i].element == element; ++i) {
      const LocatedPoint& ip = immersed_[i];
      physical_point(patch_, ip.element, ip.xi, 2, bv, mv, pp, affine());
      if (first_point) {
        n = gather(pp.first);
        varying = element_viscosity(n);
        if (direct.usable()) direct.prepare(n, lnode.data());
        Re.assign(n * nd, 0.0);
        if (J) Ke.assign(static_cast<size_t>(n * nd) * n * nd, 0.0);
        first_point = false;
      }
      const PointBasis pb{pp.n, pp.N.data(), pp.dN.data(), pp.lapN.data()};
      fields(pb, pp.G, pf);
      if (varying) point_viscosity(pb, prm_q, pf);
      const VmsParameters& pi = varying ? prm_q : prm_e;
      if (F) immersed_residual(pi, pb, pf, ip.data, Re.data());
      if (J) immersed_tangent(pi, pb, pf, ts, ip.data, Ke.data());
    }
    scatter(n, false);
  }
  CELLFSI_PETSC(PetscLogEventEnd(immersed_event, 0, 0, 0, 0));

  CELLFSI_PETSC(VecRestoreArrayRead(U_loc, &u));
  CELLFSI_PETSC(VecRestoreArrayRead(Un_loc_, &un));
  CELLFSI_PETSC(VecRestoreArrayRead(Udotn_loc_, &udn));
  CELLFSI_PETSC(VecRestoreArrayRead(S_loc_, &sh));
  if (nuh) CELLFSI_PETSC(VecRestoreArrayRead(Nu_loc_, &nuh));
  CELLFSI_PETSC(DMRestoreLocalVector(da_, &U_loc));

  const std::vector<PetscInt> rows = dirichlet_rows();
  if (F) {
    CELLFSI_PETSC(VecRestoreArray(F_loc, &f));
    CELLFSI_PETSC(VecSet(F, 0.0));
    CELLFSI_PETSC(DMLocalToGlobal(da_, F_loc, ADD_VALUES, F));
    CELLFSI_PETSC(DMRestoreLocalVector(da_, &F_loc));
    // Dirichlet rows: F = U - U_D, with U_D the values apply_dirichlet_values sets.
    Vec UD;
    CELLFSI_PETSC(VecDuplicate(U, &UD));
    CELLFSI_PETSC(VecCopy(U, UD));
    apply_dirichlet_values(UD, time_ + opt_.dt);
    PetscInt lo = 0;
    CELLFSI_PETSC(VecGetOwnershipRange(F, &lo, nullptr));
    PetscScalar* fa;
    const PetscScalar *ua, *uda;
    CELLFSI_PETSC(VecGetArray(F, &fa));
    CELLFSI_PETSC(VecGetArrayRead(U, &ua));
    CELLFSI_PETSC(VecGetArrayRead(UD, &uda));
    for (PetscInt r : rows) fa[r - lo] = ua[r - lo] - uda[r - lo];
    CELLFSI_PETSC(VecRestoreArray(F, &fa));
    CELLFSI_PETSC(VecRestoreArrayRead(U, &ua));
    CELLFSI_PETSC(VecRestoreArrayRead(UD, &uda));
    CELLFSI_PETSC(VecDestroy(&UD));
  }
  if (J) {
    direct.finish();
    CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
    const double diagonal = in_region && region_side && !accumulate ? 0.0 : 1.0;
    CELLFSI_PETSC(
        MatZeroRows(J, static_cast<PetscInt>(rows.size()), rows.data(), diagonal, nullptr, nullptr));
  }
}

void FluidSolver::bulk_jacobian(Vec X, Mat J) {
  // s^h, the immersed points and a viscosity field are set aside and restored whatever happens (an exception
  // included).
  Vec S = nullptr;
  CELLFSI_PETSC(VecDuplicate(S_, &S));
  struct Restore {
    FluidSolver& f;
    Vec& S;
    std::vector<LocatedPoint> immersed;
    Vec nu = nullptr, nu_loc = nullptr;
    bool scaling_saved = false, immersed_saved = false, viscosity_saved = false;
    ~Restore() {
      if (viscosity_saved) {
        std::swap(nu, f.Nu_);
        std::swap(nu_loc, f.Nu_loc_);
      }
      if (immersed_saved) immersed.swap(f.immersed_);
      if (scaling_saved) VecCopy(S, f.S_);
      VecDestroy(&S);
    }
  } restore{*this, S, {}};
  CELLFSI_PETSC(VecCopy(S_, S));
  restore.scaling_saved = true;
  restore.immersed.swap(immersed_);
  restore.immersed_saved = true;
  std::swap(restore.nu, Nu_);
  std::swap(restore.nu_loc, Nu_loc_);
  restore.viscosity_saved = true;
  CELLFSI_PETSC(VecSet(S_, 1.0));
  assemble(X, nullptr, J);
}

PetscErrorCode fluid_residual(SNES, Vec U, Vec F, void* ctx) {
  PetscFunctionBeginUser;
  try {
    static_cast<FluidSolver*>(ctx)->assemble(U, F, nullptr);
  } catch (const std::exception& e) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "%s", e.what());
  }
  PetscFunctionReturn(0);
}

PetscErrorCode fluid_jacobian(SNES, Vec U, Mat J, Mat, void* ctx) {
  PetscFunctionBeginUser;
  try {
    static_cast<FluidSolver*>(ctx)->assemble(U, nullptr, J);
  } catch (const std::exception& e) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "%s", e.what());
  }
  PetscFunctionReturn(0);
}

void FluidSolver::evaluate_residual(Vec U, Vec F) {
  CELLFSI_PETSC(DMGlobalToLocal(da_, U_, INSERT_VALUES, Un_loc_));
  CELLFSI_PETSC(DMGlobalToLocal(da_, Udot_, INSERT_VALUES, Udotn_loc_));
  assemble(U, F, nullptr);
}

void FluidSolver::evaluate_jacobian(Vec U, Mat J) {
  CELLFSI_PETSC(DMGlobalToLocal(da_, U_, INSERT_VALUES, Un_loc_));
  CELLFSI_PETSC(DMGlobalToLocal(da_, Udot_, INSERT_VALUES, Udotn_loc_));
  assemble(U, nullptr, J);
}

}  // namespace cellfsi::fluid
