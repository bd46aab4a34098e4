// Pointwise VMS kernels; the formulas are those of vms_kernel.hpp. The tangent is derived by hand from them
// and checked against finite differences in tests/unit/fluid/test_vms_kernel.cpp.
//
// The element tangent formed as small matrix products (vms_tangent_element*) is in vms_element_tangent.cpp.
//
// Cost matters: these run at every quadrature point of every element, once per Newton iteration. So whatever
// does not depend on the basis functions is formed once per point (r_M, v', a = v + v', ...) and the weight
// is folded into per-function factors; the tangent's per-pair work is a small fixed sum of products (see
// tangent_kernel); there is no heap allocation; dim is a template parameter so the small loops unroll.
#include "fluid/vms_kernel.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <vector>

#include "fluid/vms_point_state.hpp"

namespace cellfsi::fluid {

namespace {

using detail::Mat3;
using detail::point_state;
using detail::PointState;
using detail::Vec3;

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define CELLFSI_RESIDUAL_AVX2 1
/// residual_kernel's per-function sums in 3D with a function's four rows (momentum x, y, z, continuity) as
/// one AVX vector: four vector FMAs per function. Chosen at run time where the CPU has AVX2 and FMA.
[[gnu::target("avx2,fma")]] void function_sums_3d_avx2(const PointBasis& basis, const double alpha[4],
                                                       const double beta[3][4], double* R) {
  typedef double Quad __attribute__((vector_size(32)));
  typedef double QuadU __attribute__((vector_size(32), aligned(8), may_alias));
  const Quad al = *reinterpret_cast<const QuadU*>(alpha), bx = *reinterpret_cast<const QuadU*>(beta[0]),
             by = *reinterpret_cast<const QuadU*>(beta[1]), bz = *reinterpret_cast<const QuadU*>(beta[2]);
  for (int A = 0; A < basis.n; ++A) {
    const double N = basis.N[A];
    const double* dN = basis.dN + A * 3;
    QuadU* RA = reinterpret_cast<QuadU*>(R + A * 4);
    *RA += Quad{N, N, N, N} * al + Quad{dN[0], dN[0], dN[0], dN[0]} * bx +
           Quad{dN[1], dN[1], dN[1], dN[1]} * by + Quad{dN[2], dN[2], dN[2], dN[2]} * bz;
  }
}
#endif

template <int Dim>
void residual_kernel(const VmsParameters& prm, const PointBasis& basis, const PointFields& f,
                     const Stabilization& tau, double weight, double* R) {
  constexpr int nc = Dim + 1;
  const bool convective = !prm.stokes;
  const PointState st = point_state(prm, f, tau);

  // The Galerkin convection and the cross term both multiply N_A: together N_A ((v + v').grad) v_i.
  double mass[Dim];       // weight (vdot + (a.grad) v - g)
  double fine[Dim];       // weight v'
  double a[Dim];          // v + v' (zero in Stokes mode: no SUPG/Reynolds line)
  double visc[Dim][Dim];  // weight nu (dv + dv^T)
  for (int i = 0; i < Dim; ++i) {
    mass[i] = f.vdot[i] - prm.g[i];
    if (convective)
      for (int j = 0; j < Dim; ++j) mass[i] += st.a[j] * f.dv[i][j];
    mass[i] *= weight;
    fine[i] = weight * st.v_fine[i];
    a[i] = convective ? st.a[i] : 0.0;
    for (int j = 0; j < Dim; ++j) visc[i][j] = weight * prm.nu * (f.dv[i][j] + f.dv[j][i]);
  }
  const double pressure = weight * (f.p - st.tau_c * st.r_c);  // p + p'
  const double div = weight * st.r_c;

  // Row c of function A is N_A alpha_c + sum_j dN_A,j beta_j,c (the momentum rows: N_A mass_i - dN_A,i
  // (p + p') - (a.dN_A) v'_i + visc_ij dN_A,j; the continuity row: N_A div - dN_A.v'), so the per-point
  // factors are formed once and every function costs nc (Dim + 1) products.
  double alpha[nc], beta[Dim][nc];
  for (int i = 0; i < Dim; ++i) alpha[i] = mass[i];
  alpha[Dim] = div;
  for (int j = 0; j < Dim; ++j) {
    for (int i = 0; i < Dim; ++i) beta[j][i] = visc[i][j] - a[j] * fine[i] - (i == j ? pressure : 0.0);
    beta[j][Dim] = -fine[j];
  }
  if constexpr (Dim == 3) {
#ifdef CELLFSI_RESIDUAL_AVX2
    if (cpu_has_avx2_fma()) return function_sums_3d_avx2(basis, alpha, beta, R);
#endif
  }
  for (int A = 0; A < basis.n; ++A) {
    const double N = basis.N[A];
    const double* dN = basis.dN + A * 3;
    double* RA = R + A * nc;
    for (int c = 0; c < nc; ++c) {
      double r = N * alpha[c];
      for (int j = 0; j < Dim; ++j) r += dN[j] * beta[j][c];
      RA[c] += r;
    }
  }
}

// Every entry of the tangent is linear in the derivatives of the fields with respect to U_B, which are N_B,
// dN_B and lapN_B times the TangentScales; lapN_B enters only through d r_M / dV_B, so each entry of the
// (Dim+1) x (Dim+1) block of a pair (A, B) is
//   K[c][e] = N_B X[c][0][e] + m_B X[c][1][e] + sum_j dN_B,j X[c][2+j][e]
// with m_B the delta_ie part of d r_M,i / d V_{B,e} and coefficients X depending on A only. So the work per
// pair is (Dim+1)^2 (Dim+2) products, and the formulas live in the per-A coefficients, one term at a time.
template <int Dim>
struct ColumnFactors {
  double y[Dim + 2];  // N_B, m_B, dN_B
};

// Enough for p = 3 in 3D (64 functions) in one pass; more functions are handled in several passes.
constexpr int kColumnChunk = 64;

template <int Dim, bool kConvective>
void tangent_kernel(const VmsParameters& prm, const PointBasis& basis, const PointFields& f,
                    const TangentScales& ts, double weight, double* K) {
  constexpr int nc = Dim + 1, ny = Dim + 2;
  const int n = basis.n;
  const std::size_t ld = static_cast<std::size_t>(n) * nc;
  const double vel = ts.velocity, rate = ts.velocity_rate, pres = ts.pressure, nu = prm.nu;

  const Stabilization tau = vms_stabilization(prm, f);
  const PointState st = point_state(prm, f, tau);
  const double tm = tau.tau_m, tc = tau.tau_c;

  double v[Dim], v_fine[Dim], a[Dim], dv[Dim][Dim];
  for (int i = 0; i < Dim; ++i) {
    v[i] = f.v[i];
    v_fine[i] = st.v_fine[i];
    a[i] = st.a[i];
    for (int j = 0; j < Dim; ++j) dv[i][j] = f.dv[i][j];
  }
  // A viscosity field (vms_kernel.hpp): r_M,j has -grad nu . (grad v_j + d_j v), whose second part gives
  // d r_M,j / d V_{B,e} = -velocity dnu_e dN_B,j, so d v'_j / d V_{B,e} gains tau_M velocity dnu_e dN_B,j.
  const bool has_dnu = f.has_dnu();
  double dnu[Dim];
  for (int j = 0; j < Dim; ++j) dnu[j] = f.dnu[j];
  // N_A ((v + v').grad) v_i differentiated through v and v' (convective part) gives N_A N_B M[i][e].
  [[maybe_unused]] double M[Dim][Dim];
  if constexpr (kConvective) {
    for (int i = 0; i < Dim; ++i)
      for (int e = 0; e < Dim; ++e) {
        double dvdv = 0;
        for (int j = 0; j < Dim; ++j) dvdv += dv[i][j] * dv[j][e];
        M[i][e] = vel * (dv[i][e] - tm * dvdv);
      }
  }

  ColumnFactors<Dim> cols[kColumnChunk];
  for (int b0 = 0; b0 < n; b0 += kColumnChunk) {
    const int b1 = std::min(n, b0 + kColumnChunk);
    for (int B = b0; B < b1; ++B) {
      double* y = cols[B - b0].y;
      y[0] = basis.N[B];
      y[1] = rate * y[0] - nu * vel * basis.lapN[B];
      for (int j = 0; j < Dim; ++j) {
        y[2 + j] = basis.dN[B * 3 + j];
        if constexpr (kConvective) y[1] += vel * v[j] * y[2 + j];
      }
      // -grad nu . grad v_i in r_M,i (the delta_ie part of the viscosity field's term).
      if (has_dnu)
        for (int j = 0; j < Dim; ++j) y[1] -= vel * dnu[j] * y[2 + j];
    }

    for (int A = 0; A < n; ++A) {
      const double wN = weight * basis.N[A];
      double wdN[Dim];
      for (int j = 0; j < Dim; ++j) wdN[j] = weight * basis.dN[A * 3 + j];

      // X[c][t][e]: coefficient of y_t in K[(A, c)][(B, e)], times the weight. Term by term, with
      //   d v'_j / d V_{B,e} = -tau_M (m_B delta_je + [convective] velocity N_B dv[j][e]),
      //   d v'_j / d P_B = -tau_M pressure dN_B,j,   d p' / d V_{B,e} = -tau_C velocity dN_B,e.
      double X[nc][ny][nc] = {};
      for (int i = 0; i < Dim; ++i) {
        X[i][0][i] += rate * wN;        // N_A vdot_i
        X[i][0][Dim] -= pres * wdN[i];  // -d_i N_A p
        for (int j = 0; j < Dim; ++j) {
          X[i][2 + j][i] += nu * vel * wdN[j];  // nu d_j N_A d_j v_i
          X[i][2 + i][j] += nu * vel * wdN[j];  // nu d_j N_A d_i v_j
          X[i][2 + j][j] += tc * vel * wdN[i];  // LSIC -d_i N_A p'
        }
      }
      for (int e = 0; e < Dim; ++e) {
        X[Dim][2 + e][e] += vel * wN;  // N_A div v
        // PSPG -grad N_A . v' through the non-convective part of v'.
        X[Dim][1][e] += tm * wdN[e];
        X[Dim][2 + e][Dim] += tm * pres * wdN[e];
      }
      if constexpr (kConvective) {
        double a_dN = 0, dNt_dv[Dim] = {};  // a . grad N_A, (grad N_A)^T dv
        for (int j = 0; j < Dim; ++j) {
          a_dN += a[j] * wdN[j];
          for (int e = 0; e < Dim; ++e) dNt_dv[e] += wdN[j] * dv[j][e];
        }
        for (int i = 0; i < Dim; ++i) {
          // N_A (v.grad) v_i + N_A (v'.grad) v_i (Galerkin + cross), through grad v: N_A (a . grad N_B).
          for (int j = 0; j < Dim; ++j) X[i][2 + j][i] += vel * wN * a[j];
          for (int e = 0; e < Dim; ++e) {
            // The same two terms through v and v': N_A dv[i][j] (velocity N_B delta_je + d v'_j).
            X[i][0][e] += wN * M[i][e];
            X[i][1][e] -= tm * wN * dv[i][e];
            X[i][2 + e][Dim] -= tm * pres * wN * dv[i][e];
            // SUPG/Reynolds -(a . grad N_A) v'_i, through a = v + v' ...
            X[i][0][e] += v_fine[i] * vel * (tm * dNt_dv[e] - wdN[e]);
            X[i][1][e] += v_fine[i] * tm * wdN[e];
            X[i][2 + e][Dim] += v_fine[i] * tm * pres * wdN[e];
            // ... and through v'_i.
            X[i][0][e] += tm * vel * a_dN * dv[i][e];
          }
          X[i][1][i] += tm * a_dN;
          X[i][2 + i][Dim] += tm * pres * a_dN;
        }
        // PSPG through the convective part of v'.
        for (int e = 0; e < Dim; ++e) X[Dim][0][e] += tm * vel * dNt_dv[e];
        if (has_dnu)  // the three convective terms through the dnu_e dN_B,j part of v'_j
          for (int e = 0; e < Dim; ++e) {
            const double g = tm * vel * dnu[e];
            for (int i = 0; i < Dim; ++i) {
              for (int j = 0; j < Dim; ++j) X[i][2 + j][e] += g * (wN * dv[i][j] - v_fine[i] * wdN[j]);
              X[i][2 + i][e] -= g * a_dN;
            }
          }
      }
      if (has_dnu)  // PSPG -grad N_A . v' through the same part
        for (int e = 0; e < Dim; ++e)
          for (int j = 0; j < Dim; ++j) X[Dim][2 + j][e] -= tm * vel * dnu[e] * wdN[j];

      double* const block_row = K + static_cast<std::size_t>(A) * nc * ld;
      for (int B = b0; B < b1; ++B) {
        const double* y = cols[B - b0].y;
        double* const block = block_row + B * nc;
#pragma GCC unroll 4
        for (int c = 0; c < nc; ++c) {
          double k[nc];
#pragma GCC unroll 4
          for (int e = 0; e < nc; ++e) k[e] = y[0] * X[c][0][e];
#pragma GCC unroll 5
          for (int t = 1; t < ny; ++t) {
            if (!kConvective && c < Dim && t == 1) continue;  // no m_B in the Stokes momentum rows
#pragma GCC unroll 4
            for (int e = 0; e < nc; ++e) k[e] += y[t] * X[c][t][e];
          }
          double* Kc = block + c * ld;
#pragma GCC unroll 4
          for (int e = 0; e < nc; ++e) Kc[e] += k[e];
        }
      }
    }
  }
}

/// Voigt index of the index pair (i, j): 11, 22, 33, 23, 13, 12.
constexpr int kVoigt[3][3] = {{0, 5, 4}, {5, 1, 3}, {4, 3, 2}};

#ifdef CELLFSI_RESIDUAL_AVX2
/// immersed_tangent_kernel's rows of one function A in 3D: for every B and row i, the block row (columns e =
/// 0..2, and the pressure's, which gets zeros) sum_l dN_B,l W[i][l] + N_B M[i], as one AVX vector.
[[gnu::target("avx2,fma")]] void immersed_rows_3d_avx2(const PointBasis& basis, const double (*W)[3][4],
                                                       const double (*M)[4], double* KA, std::size_t ld) {
  typedef double Quad __attribute__((vector_size(32)));
  typedef double QuadU __attribute__((vector_size(32), aligned(8), may_alias));
  Quad w[3][3], m[3];
  for (int i = 0; i < 3; ++i) {
    m[i] = *reinterpret_cast<const QuadU*>(M[i]);
    for (int l = 0; l < 3; ++l) w[i][l] = *reinterpret_cast<const QuadU*>(W[i][l]);
  }
  for (int B = 0; B < basis.n; ++B) {
    const double N = basis.N[B];
    const double* g = basis.dN + B * 3;
    const Quad n4{N, N, N, N}, g0{g[0], g[0], g[0], g[0]}, g1{g[1], g[1], g[1], g[1]},
        g2{g[2], g[2], g[2], g[2]};
    for (int i = 0; i < 3; ++i) {
      QuadU* Ki = reinterpret_cast<QuadU*>(KA + i * ld + B * 4);
      *Ki += n4 * m[i] + g0 * w[i][0] + g1 * w[i][1] + g2 * w[i][2];
    }
  }
}
#endif

template <int Dim>
void immersed_tangent_kernel(const VmsParameters& prm, const PointBasis& basis, const PointFields& f,
                             const TangentScales& ts, const ImmersedPoint& ip, double* K) {
  constexpr int nc = Dim + 1;
  const int n = basis.n;
  const std::size_t ld = static_cast<std::size_t>(n) * nc;
  const bool convective = !prm.stokes;
  const double w = ip.weight, vel = ts.velocity;
  double v[Dim], dv[Dim][Dim];  // local copies: K may alias f
  for (int i = 0; i < Dim; ++i) {
    v[i] = f.v[i];
    for (int j = 0; j < Dim; ++j) dv[i][j] = f.dv[i][j];
  }
  // The solid's stiffness: isotropic (a viscosity nu_s beside the fluid's), or consistent (ImmersedPoint).
  const bool consistent = ip.stiffness_time > 0;
  const double nu_s = consistent ? 0.0 : ip.stiffness_viscosity, s_w = w * vel * ip.stiffness_time;
  double c[6][6] = {};
  if (consistent)
    for (int r = 0, t = 0; r < 6; ++r)
      for (int q = r; q < 6; ++q, ++t) c[r][q] = c[q][r] = ip.stiffness[t];
  // Every term is, in the block (A, B), row i and column e, sum_l dN_B,l W[i][l][e] + N_B M[i][e] with W
  // and M of A alone:
  //   -w (nu - nu_s) vel (d_e N_A dN_B,i + delta_ie dN_A . dN_B)      (viscosity and isotropic stiffness)
  //   mass_A (rate N_B + vel v . dN_B) delta_ie + mass_A vel N_B dv_ie  (the solid's inertia)
  //   a_j c_ijel dN_B,l + stress_il dN_B,l a_e + delta_ie a . stress dN_B (consistent stiffness: c : sym(L),
  //   stress L^T and L stress, a = s_w dN_A)
  double W[Dim][Dim][4] = {}, M[Dim][4] = {};
  for (int A = 0; A < n; ++A) {
    const double mass_A = -w * ip.beta * basis.N[A];
    double visc[Dim], a[Dim], sa[Dim] = {};
    for (int j = 0; j < Dim; ++j) {
      visc[j] = -w * (prm.nu - nu_s) * vel * basis.dN[A * 3 + j];
      a[j] = s_w * basis.dN[A * 3 + j];
    }
    for (int i = 0; i < Dim; ++i) {
      for (int e = 0; e < Dim; ++e) {
        M[i][e] = (i == e ? mass_A * ts.velocity_rate : 0.0) + (convective ? mass_A * vel * dv[i][e] : 0.0);
        for (int l = 0; l < Dim; ++l) {
          double x = (i == l ? visc[e] : 0.0) + (i == e ? visc[l] : 0.0);
          if (convective && i == e) x += mass_A * vel * v[l];
          W[i][l][e] = x;
        }
      }
    }
    if (consistent) {
      for (int i = 0; i < Dim; ++i)
        for (int j = 0; j < Dim; ++j) sa[i] += ip.stress[i][j] * a[j];
      for (int i = 0; i < Dim; ++i)
        for (int l = 0; l < Dim; ++l)
          for (int e = 0; e < Dim; ++e) {
            double x = ip.stress[i][l] * a[e] + (i == e ? sa[l] : 0.0);
            for (int j = 0; j < Dim; ++j) x += a[j] * c[kVoigt[i][j]][kVoigt[e][l]];
            W[i][l][e] += x;
          }
    }
    double* KA = K + static_cast<std::size_t>(A) * nc * ld;
    if constexpr (Dim == 3) {
#ifdef CELLFSI_RESIDUAL_AVX2
      if (cpu_has_avx2_fma()) {
        immersed_rows_3d_avx2(basis, W, M, KA, ld);
        continue;
      }
#endif
    }
    for (int B = 0; B < n; ++B) {
      const double N_B = basis.N[B];
      const double* g = basis.dN + B * 3;
      for (int i = 0; i < Dim; ++i) {
        double* Ki = KA + i * ld + B * nc;
        for (int e = 0; e < Dim; ++e) {
          double k = N_B * M[i][e];
          for (int l = 0; l < Dim; ++l) k += g[l] * W[i][l][e];
          Ki[e] += k;
        }
      }
    }
  }
}

}  // namespace

Stabilization vms_stabilization(const VmsParameters& prm, const PointFields& f) {
  assert(prm.dim == 2 || prm.dim == 3);
  const int d = prm.dim;
  double v_G_v = 0, G_G = 0, trace = 0;
  for (int i = 0; i < d; ++i) {
    trace += f.G[i][i];
    for (int j = 0; j < d; ++j) {
      G_G += f.G[i][j] * f.G[i][j];
      v_G_v += f.v[i] * f.G[i][j] * f.v[j];
    }
  }
  double inv_tau2 = 4.0 / (prm.dt * prm.dt) + prm.c_i * prm.nu * prm.nu * G_G;
  if (!prm.stokes) inv_tau2 += v_G_v;
  Stabilization tau;
  tau.tau_m = 1.0 / std::sqrt(f.s * inv_tau2);
  tau.tau_c = 1.0 / (tau.tau_m * trace);
  return tau;
}

void vms_residual(const VmsParameters& prm, const PointBasis& basis, const PointFields& f, double weight,
                  double* R, const Stabilization* frozen) {
  assert(prm.dim == 2 || prm.dim == 3);
  const Stabilization tau = frozen ? *frozen : vms_stabilization(prm, f);
  if (prm.dim == 2)
    residual_kernel<2>(prm, basis, f, tau, weight, R);
  else
    residual_kernel<3>(prm, basis, f, tau, weight, R);
}

void vms_tangent(const VmsParameters& prm, const PointBasis& basis, const PointFields& f,
                 const TangentScales& ts, double weight, double* K) {
  assert(prm.dim == 2 || prm.dim == 3);
  if (prm.dim == 2) {
    if (prm.stokes)
      tangent_kernel<2, false>(prm, basis, f, ts, weight, K);
    else
      tangent_kernel<2, true>(prm, basis, f, ts, weight, K);
  } else {
    if (prm.stokes)
      tangent_kernel<3, false>(prm, basis, f, ts, weight, K);
    else
      tangent_kernel<3, true>(prm, basis, f, ts, weight, K);
  }
}

void immersed_residual(const VmsParameters& prm, const PointBasis& basis, const PointFields& f,
                       const ImmersedPoint& ip, double* R) {
  assert(prm.dim == 2 || prm.dim == 3);
  const int d = prm.dim, nc = d + 1;
  Vec3 mass{};  // -weight (beta (vdot + (v.grad) v - g) + force)
  Mat3 flux{};  // weight (stress - nu (dv + dv^T))
  for (int i = 0; i < d; ++i) {
    double m = f.vdot[i] - prm.g[i];
    if (!prm.stokes)
      for (int j = 0; j < d; ++j) m += f.v[j] * f.dv[i][j];
    mass[i] = -ip.weight * ip.beta * m - ip.weight * ip.force[i];
    for (int j = 0; j < d; ++j)
      flux[i][j] = ip.weight * (ip.stress[i][j] - prm.nu * (f.dv[i][j] + f.dv[j][i]));
  }
  for (int A = 0; A < basis.n; ++A) {
    const double* dN = basis.dN + A * 3;
    for (int i = 0; i < d; ++i) {
      double r = basis.N[A] * mass[i];
      for (int j = 0; j < d; ++j) r += flux[i][j] * dN[j];
      R[A * nc + i] += r;
    }
  }
}

void immersed_tangent(const VmsParameters& prm, const PointBasis& basis, const PointFields& f,
                      const TangentScales& ts, const ImmersedPoint& ip, double* K) {
  assert(prm.dim == 2 || prm.dim == 3);
  if (prm.dim == 2)
    immersed_tangent_kernel<2>(prm, basis, f, ts, ip, K);
  else
    immersed_tangent_kernel<3>(prm, basis, f, ts, ip, K);
}

}  // namespace cellfsi::fluid
