#include "fluid/div_conforming/dc_sum_factorization.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "common/petsc_error.hpp"
#include "geometry/basis.hpp"

namespace cellfsi::fluid::dc {

ComponentFactors component_factors(const DivConformingSpace& space, int c, const Index3& e,
                                   const TensorRule& rule) {
  ComponentFactors f;
  for (int d = 0; d < space.dim(); ++d)
    if (rule.points[d].empty() || rule.points[d].size() > static_cast<size_t>(kMaxRulePoints))
      throw std::invalid_argument("component_factors: a rule of 1 to " + std::to_string(kMaxRulePoints) +
                                  " points per direction is needed, got " +
                                  std::to_string(rule.points[d].size()));
  for (int d = 0; d < space.dim(); ++d) {
    const KnotVector& kv = space.knots(c, d);
    const int p = kv.degree(), span = kv.element_span(e[d]);
    f.n[d] = p + 1;
    f.nq[d] = static_cast<int>(rule.points[d].size());
    f.value[d].resize(static_cast<size_t>(f.nq[d]) * f.n[d]);
    f.deriv[d].resize(f.value[d].size());
    double ders[2 * (geometry::kMaxDegree + 1)];
    for (int q = 0; q < f.nq[d]; ++q) {
      geometry::bspline_basis(kv, span, rule.points[d][q], 1, ders);
      for (int j = 0; j <= p; ++j) {
        f.value[d][static_cast<size_t>(q) * f.n[d] + j] = ders[j];
        f.deriv[d][static_cast<size_t>(q) * f.n[d] + j] = ders[(p + 1) + j];
      }
    }
  }
  for (int d = space.dim(); d < 3; ++d) f.value[d] = {1.0}, f.deriv[d] = {0.0};
  return f;
}

namespace {

/// o[e] = sum_t c[t] x[t][e] for e < m, T terms. The loop over the block's elements is the one that
/// vectorises. On x86-64 with GCC the kernel is compiled for AVX-512F, AVX2 and the baseline and the CPU's
/// instruction sets choose one at load time (target_clones; the build's own flags target the baseline, and
/// "arch=" clones would be chosen by CPU model: this EPYC ran the baseline one under them). Elsewhere (other
/// CPUs, Clang, which takes no target_clones on templates) it is compiled once. The AVX-512 clone fuses
/// multiply-adds, so a result's last bits depend on the CPU. Measured on the 3D compound capsule at 32^3, one
/// rank: the elements' terms of 20 residuals 1.62-1.64 s with the AVX-512 clone, 1.87 s with the baseline
/// one; several terms a pass (not one product per pass over o) made the larger difference
/// (docs/notes/2026-11-29-dc-step-sum-factorisation.md).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define CELLFSI_SUM_FACTORIZATION_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define CELLFSI_SUM_FACTORIZATION_CLONES
#endif
template <int T>
CELLFSI_SUM_FACTORIZATION_CLONES void weighted_sum(const double* c, const double* const* x, double* o,
                                                   int m) {
  for (int e = 0; e < m; ++e) {
    double acc = 0;
    for (int t = 0; t < T; ++t) acc += c[t] * x[t][e];
    o[e] = acc;
  }
}

void weighted_sum(int T, const double* c, const double* const* x, double* o, int m) {
  switch (T) {
    case 1:
      return weighted_sum<1>(c, x, o, m);
    case 2:
      return weighted_sum<2>(c, x, o, m);
    case 3:
      return weighted_sum<3>(c, x, o, m);
    case 4:
      return weighted_sum<4>(c, x, o, m);
    case 5:
      return weighted_sum<5>(c, x, o, m);
    case 6:
      return weighted_sum<6>(c, x, o, m);
    case 8:
      return weighted_sum<8>(c, x, o, m);
    case 10:
      return weighted_sum<10>(c, x, o, m);
    default:
      std::fill(o, o + m, 0.0);
      for (int t = 0; t < T; ++t)
        for (int e = 0; e < m; ++e) o[e] += c[t] * x[t][e];
  }
}

constexpr int kMaxTerms = 2 * kMaxRulePoints;  // (a transposed sum's terms: two per point)
static_assert(kMaxTerms >= geometry::kMaxDegree + 2, "a contraction's terms: one per function");

/// One direction's contraction on a block: in[(i + I (j + n r)) m + e] -> out[(i + I (q + Q r)) m + e] =
/// sum_j M[q n + j] in[...].
void contract(const std::vector<double>& M, int I, int n, int Q, int R, int m, const double* in,
              double* out) {
  CELLFSI_PETSC(PetscLogFlops(2.0 * R * Q * I * n * m));  // (-log_view's counts: a multiply-add per term)
  const double* x[kMaxTerms];
  for (int r = 0; r < R; ++r)
    for (int q = 0; q < Q; ++q)
      for (int i = 0; i < I; ++i) {
        for (int j = 0; j < n; ++j) x[j] = in + static_cast<size_t>(i + I * (j + n * r)) * m;
        weighted_sum(n, M.data() + static_cast<size_t>(q) * n, x,
                     out + static_cast<size_t>(i + I * (q + Q * r)) * m, m);
      }
}

/// The transpose: in[(i + I (q + Q r)) m + e] -> out[(i + I (j + n r)) m + e] = sum_q M[q n + j] in[...],
/// plus the same sum of M2 and in2 where they are given.
void contract_transposed(const std::vector<double>& M, int I, int n, int Q, int R, int m, const double* in,
                         double* out, const std::vector<double>* M2 = nullptr, const double* in2 = nullptr) {
  const double* x[kMaxTerms];
  double c[kMaxTerms];
  CELLFSI_PETSC(PetscLogFlops(2.0 * R * n * I * Q * (M2 ? 2 : 1) * m));
  for (int r = 0; r < R; ++r)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < I; ++i) {
        int T = 0;
        for (int q = 0; q < Q; ++q, ++T) {
          c[T] = M[static_cast<size_t>(q) * n + j];
          x[T] = in + static_cast<size_t>(i + I * (q + Q * r)) * m;
        }
        if (M2)
          for (int q = 0; q < Q; ++q, ++T) {
            c[T] = (*M2)[static_cast<size_t>(q) * n + j];
            x[T] = in2 + static_cast<size_t>(i + I * (q + Q * r)) * m;
          }
        weighted_sum(T, c, x, out + static_cast<size_t>(i + I * (j + n * r)) * m, m);
      }
}

}  // namespace

void sum_factorized_values(const ComponentFactors& f, int m, const double* u, double* value,
                           const std::array<double*, 3>* grad, std::vector<double>& scratch) {
  const auto& [n0, n1, n2] = f.n;
  const auto& [Q0, Q1, Q2] = f.nq;
  const size_t st = static_cast<size_t>(Q0) * n1 * n2 * m, ss = static_cast<size_t>(Q0) * Q1 * n2 * m;
  scratch.resize(2 * st + 3 * ss);
  double* t = scratch.data();  // after direction 0: the value's factor, then its derivative's
  double* td = t + st;
  double* s00 = td + st;  // after direction 1: value x value, derivative x value, value x derivative
  double* s10 = s00 + ss;
  double* s01 = s10 + ss;
  contract(f.value[0], 1, n0, Q0, n1 * n2, m, u, t);
  contract(f.value[1], Q0, n1, Q1, n2, m, t, s00);
  if (value) contract(f.value[2], Q0 * Q1, n2, Q2, 1, m, s00, value);
  if (!grad) return;
  contract(f.deriv[0], 1, n0, Q0, n1 * n2, m, u, td);
  contract(f.value[1], Q0, n1, Q1, n2, m, td, s10);
  contract(f.deriv[1], Q0, n1, Q1, n2, m, t, s01);
  contract(f.value[2], Q0 * Q1, n2, Q2, 1, m, s10, (*grad)[0]);
  contract(f.value[2], Q0 * Q1, n2, Q2, 1, m, s01, (*grad)[1]);
  contract(f.deriv[2], Q0 * Q1, n2, Q2, 1, m, s00, (*grad)[2]);
}

void sum_factorized_test(const ComponentFactors& f, int m, const double* r_value,
                         const std::array<const double*, 3>* r_grad, double* out,
                         std::vector<double>& scratch) {
  const auto& [n0, n1, n2] = f.n;
  const auto& [Q0, Q1, Q2] = f.nq;
  const size_t st = static_cast<size_t>(Q0) * n1 * n2 * m, ss = static_cast<size_t>(Q0) * Q1 * n2 * m;
  scratch.resize(2 * st + 3 * ss);
  double* t = scratch.data();
  double* td = t + st;
  double* s00 = td + st;
  double* s10 = s00 + ss;
  double* s01 = s10 + ss;
  if (!r_grad) {
    contract_transposed(f.value[2], Q0 * Q1, n2, Q2, 1, m, r_value, s00);
    contract_transposed(f.value[1], Q0, n1, Q1, n2, m, s00, t);
    contract_transposed(f.value[0], 1, n0, Q0, n1 * n2, m, t, out);
    return;
  }
  contract_transposed(f.value[2], Q0 * Q1, n2, Q2, 1, m, r_value, s00, &f.deriv[2], (*r_grad)[2]);
  contract_transposed(f.value[2], Q0 * Q1, n2, Q2, 1, m, (*r_grad)[0], s10);
  contract_transposed(f.value[2], Q0 * Q1, n2, Q2, 1, m, (*r_grad)[1], s01);
  contract_transposed(f.value[1], Q0, n1, Q1, n2, m, s00, t, &f.deriv[1], s01);
  contract_transposed(f.value[1], Q0, n1, Q1, n2, m, s10, td);
  contract_transposed(f.value[0], 1, n0, Q0, n1 * n2, m, t, out, &f.deriv[0], td);
}

void point_factors(const DivConformingSpace& space, const Index3& e, const Vec3& x, PointFactors& out) {
  for (int s = 0; s < 2; ++s)
    for (int d = 0; d < 3; ++d) {
      if (d >= space.dim()) {
        out.n[s][d] = 1, out.value[s][d][0] = 1.0, out.deriv[s][d][0] = 0.0;
        continue;
      }
      out.n[s][d] = space.degree() + s + 1;
      space.univariate(s, d, e[d], x[d], out.value[s][d], out.deriv[s][d]);  // (x in element e)
    }
}

namespace {
/// The space (0: low, 1: high) of component c along direction d.
inline int space_of(int c, int d) { return c == d ? 1 : 0; }
}  // namespace

double point_value(const PointFactors& f, int c, const double* u, double* grad) {
  const int s0 = space_of(c, 0), s1 = space_of(c, 1), s2 = space_of(c, 2);
  const int n0 = f.n[s0][0], n1 = f.n[s1][1], n2 = f.n[s2][2];
  const double *B0 = f.value[s0][0], *D0 = f.deriv[s0][0], *B1 = f.value[s1][1], *D1 = f.deriv[s1][1],
               *B2 = f.value[s2][2], *D2 = f.deriv[s2][2];
  double val = 0, g[3] = {0, 0, 0};
  CELLFSI_PETSC(PetscLogFlops(4.0 * n0 * n1 * n2 + 6.0 * n1 * n2 + 8.0 * n2));
  for (int j2 = 0; j2 < n2; ++j2) {
    double s00 = 0, s10 = 0, s01 = 0;
    for (int j1 = 0; j1 < n1; ++j1) {
      const double* x = u + n0 * (j1 + n1 * j2);
      double t = 0, td = 0;
      for (int j0 = 0; j0 < n0; ++j0) t += B0[j0] * x[j0], td += D0[j0] * x[j0];
      s00 += B1[j1] * t;
      s10 += B1[j1] * td;
      s01 += D1[j1] * t;
    }
    val += B2[j2] * s00;
    g[0] += B2[j2] * s10;
    g[1] += B2[j2] * s01;
    g[2] += D2[j2] * s00;
  }
  if (grad)
    for (int j = 0; j < 3; ++j) grad[j] = g[j];
  return val;
}

void point_test(const PointFactors& f, int c, double r_value, const double* r_grad, double* out) {
  const int s0 = space_of(c, 0), s1 = space_of(c, 1), s2 = space_of(c, 2);
  const int n0 = f.n[s0][0], n1 = f.n[s1][1], n2 = f.n[s2][2];
  const double *B0 = f.value[s0][0], *D0 = f.deriv[s0][0], *B1 = f.value[s1][1], *D1 = f.deriv[s1][1],
               *B2 = f.value[s2][2], *D2 = f.deriv[s2][2];
  CELLFSI_PETSC(PetscLogFlops(4.0 * n0 * n1 * n2 + 4.0 * n1 * n2 + 5.0 * n2));
  for (int j2 = 0; j2 < n2; ++j2) {
    const double s00 = B2[j2] * r_value + D2[j2] * r_grad[2], s10 = B2[j2] * r_grad[0],
                 s01 = B2[j2] * r_grad[1];
    for (int j1 = 0; j1 < n1; ++j1) {
      const double t = B1[j1] * s00 + D1[j1] * s01, td = B1[j1] * s10;
      double* o = out + n0 * (j1 + n1 * j2);
      for (int j0 = 0; j0 < n0; ++j0) o[j0] += B0[j0] * t + D0[j0] * td;
    }
  }
}

}  // namespace cellfsi::fluid::dc
