// The element tangent of the VMS formulation (vms_tangent_element, vms_tangent_element_blocks in
// vms_kernel.hpp): the pointwise tangent of vms_kernel.cpp summed over an element's quadrature points as
// small matrix products, with hand-vectorised register tiles (SSE2, and AVX2 + FMA chosen at run time) and
// sum factorisation for tensor-product elements. Checked against the pointwise tangent in
// tests/unit/fluid/test_vms_kernel.cpp; timings in docs/performance.md, "Assembly per element".
//
// Why this file is longer than 600 lines: the products, their register tiles and the sum-factorised variant
// are one family of templates instantiated for two instruction sets and two layouts; they share the tile
// primitives, and splitting them would move those templates into a header included by each part.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <vector>

#include "fluid/vms_point_state.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define CELLFSI_VMS_AVX2 1  // vms_tangent_element has an AVX2 + FMA version, chosen at run time
#include <immintrin.h>
#endif

namespace cellfsi::fluid {

namespace {

using detail::point_state;
using detail::PointState;

// Element tangent (vms_tangent_element). tangent_kernel's X is linear in (wN_A, wdN_A), so each entry of the
// block of a pair (A, B) at a point is linear in the A-side factors phi_s(A) = (N_A, dN_A,1, ..., dN_A,dim)
// as well as in the B-side factors y_t(B) = (N_B, m_B, dN_B,1, ..., dN_B,dim):
//   K[(A, c)][(B, e)] = sum_q sum_s phi_s,q(A) beta_s,q(B),   beta_s,q(B) = sum_t C_q[c][s][e][t] y_t,q(B),
// with C_q (= dX / dphi, weight folded in; coefficient_terms) depending on the point only. So block (c, e) of
// the element matrix is a matrix product, (n x |S| nq) A-side factors times (|S| nq x n) beta, S the factors
// with a term in the block: all of them in Navier-Stokes but N_A in the continuity-pressure block, fewer in
// Stokes mode (ElementPattern, read off the same code). The blocks of one row component c with consecutive e
// and the same S are one product, their columns side by side. The products are register-tiled and add each
// finished tile straight into K's interleaved layout (no element-sized temporary); forming the beta costs
// O(nq n) per block against the products' O(nq n^2).
//
// Multiply-adds at p = 3 in 2D (n = nq = 16) in units of n^2 nq: products 26 (Navier-Stokes) and 18 (Stokes),
// beta about 4 and 2, where the pointwise kernel summed over the points does 36 and 30. The rest is per point
// (tau, C_q) and the scatter of the tiles into the interleaved layout.

// Point quantities the coefficients are made of.
template <int Dim>
struct PointScalars {
  double w = 0, vel = 0, rate = 0, pres = 0, nu = 0, tm = 0, tc = 0;
  double v_fine[Dim] = {}, a[Dim] = {}, dv[Dim][Dim] = {}, M[Dim][Dim] = {};
};

// The per-point part of PointScalars (ps.vel, rate, pres, nu are per element and set by the caller).
template <int Dim, bool kConvective>
void point_scalars(const VmsParameters& prm, const PointFields& f, const Stabilization& tau, double weight,
                   PointScalars<Dim>& ps) {
  assert(!f.has_dnu());  // a varying viscosity is assembled point by point (vms_kernel.hpp)
  ps.w = weight;
  ps.tm = tau.tau_m;
  ps.tc = tau.tau_c;
  if constexpr (kConvective) {
    const PointState st = point_state(prm, f, tau);
    for (int i = 0; i < Dim; ++i) {
      ps.v_fine[i] = st.v_fine[i];
      ps.a[i] = st.a[i];
      for (int j = 0; j < Dim; ++j) ps.dv[i][j] = f.dv[i][j];
    }
    for (int i = 0; i < Dim; ++i)
      for (int e = 0; e < Dim; ++e) {
        double dvdv = 0;
        for (int j = 0; j < Dim; ++j) dvdv += ps.dv[i][j] * ps.dv[j][e];
        ps.M[i][e] = ps.vel * (ps.dv[i][e] - ps.tm * dvdv);
      }
  }
}

// Calls add(c, s, e, t, value) for each term of C (several calls may hit one coefficient): tangent_kernel's
// X[c][t][e] with wN -> w [s == 0] and wdN_j -> w [s == 1 + j], term by term and in the same order. constexpr
// so that the pattern of nonzero coefficients (ElementPattern) is read off the same code.
template <int Dim, bool kConvective, class Add>
constexpr void coefficient_terms(const PointScalars<Dim>& p, Add&& add) {
  const double w = p.w, vel = p.vel, rate = p.rate, pres = p.pres, nu = p.nu, tm = p.tm, tc = p.tc;
  for (int i = 0; i < Dim; ++i) {
    add(i, 0, i, 0, w * rate);         // N_A vdot_i
    add(i, 1 + i, Dim, 0, -w * pres);  // -d_i N_A p
    for (int j = 0; j < Dim; ++j) {
      add(i, 1 + j, i, 2 + j, w * nu * vel);  // nu d_j N_A d_j v_i
      add(i, 1 + j, j, 2 + i, w * nu * vel);  // nu d_j N_A d_i v_j
      add(i, 1 + i, j, 2 + j, w * tc * vel);  // LSIC -d_i N_A p'
    }
  }
  for (int e = 0; e < Dim; ++e) {
    add(Dim, 0, e, 2 + e, w * vel);  // N_A div v
    // PSPG -grad N_A . v' through the non-convective part of v'.
    add(Dim, 1 + e, e, 1, w * tm);
    add(Dim, 1 + e, Dim, 2 + e, w * tm * pres);
  }
  if constexpr (kConvective) {
    // a . grad N_A = sum_j a_j dN_A,j and ((grad N_A)^T dv)_e = sum_j dN_A,j dv[j][e] spread over s = 1 + j.
    for (int i = 0; i < Dim; ++i) {
      // Galerkin + cross through grad v: N_A (a . grad N_B).
      for (int j = 0; j < Dim; ++j) add(i, 0, i, 2 + j, w * vel * p.a[j]);
      for (int e = 0; e < Dim; ++e) {
        // The same two terms through v and v'.
        add(i, 0, e, 0, w * p.M[i][e]);
        add(i, 0, e, 1, -w * tm * p.dv[i][e]);
        add(i, 0, Dim, 2 + e, -w * tm * pres * p.dv[i][e]);
        // SUPG/Reynolds -(a . grad N_A) v'_i, through a ...
        for (int j = 0; j < Dim; ++j) add(i, 1 + j, e, 0, w * p.v_fine[i] * vel * tm * p.dv[j][e]);
        add(i, 1 + e, e, 0, -w * p.v_fine[i] * vel);
        add(i, 1 + e, e, 1, w * p.v_fine[i] * tm);
        add(i, 1 + e, Dim, 2 + e, w * p.v_fine[i] * tm * pres);
        // ... and through v'_i.
        for (int j = 0; j < Dim; ++j) add(i, 1 + j, e, 0, w * tm * vel * p.a[j] * p.dv[i][e]);
      }
      for (int j = 0; j < Dim; ++j) {
        add(i, 1 + j, i, 1, w * tm * p.a[j]);
        add(i, 1 + j, Dim, 2 + i, w * tm * pres * p.a[j]);
      }
    }
    // PSPG through the convective part of v'.
    for (int e = 0; e < Dim; ++e)
      for (int j = 0; j < Dim; ++j) add(Dim, 1 + j, e, 0, w * tm * vel * p.dv[j][e]);
  }
}

// Which coefficients can be nonzero, as lists: terms[c][s][e] holds the t with a term, and factors[c][e] has
// bit s set if block (c, e) has a term with A-side factor s.
template <int Dim, bool kConvective>
struct ElementPattern {
  static constexpr int nc = Dim + 1, ns = Dim + 1, ny = Dim + 2;
  struct Terms {
    int count = 0;
    int t[ny] = {};
  };
  Terms terms[nc][ns][nc] = {};
  unsigned factors[nc][nc] = {};

  constexpr ElementPattern() {
    bool nz[nc][ns][nc][ny] = {};
    coefficient_terms<Dim, kConvective>(PointScalars<Dim>{},
                                        [&](int c, int s, int e, int t, double) { nz[c][s][e][t] = true; });
    for (int c = 0; c < nc; ++c)
      for (int s = 0; s < ns; ++s)
        for (int e = 0; e < nc; ++e)
          for (int t = 0; t < ny; ++t)
            if (nz[c][s][e][t]) {
              Terms& l = terms[c][s][e];
              l.t[l.count++] = t;
              factors[c][e] |= 1u << s;
            }
  }
};

// The products and the beta are written once for a vector of W doubles and built twice: W = 2 (SSE2, the
// x86-64 baseline the Release build targets) and, on x86-64, W = 4 with AVX2 and FMA, chosen at run time if
// the CPU has them (the products then run about twice as fast). Helpers are always_inline so that each is
// compiled for the instruction set of the entry point it ends up in.
template <int W>
struct VectorOf;
template <>
struct VectorOf<2> {
  typedef double type __attribute__((vector_size(16)));
};
#ifdef CELLFSI_VMS_AVX2
template <>
struct VectorOf<4> {
  // Declared by the intrinsics headers for AVX: one declared here, without AVX, would not be a native vector
  // type even in AVX code, and would live in memory.
  using type = __m256d;
};
#endif

// Rows per register tile of the products: 4, or 3 if n is a multiple of 3 but not of 4 (9 and 27 functions).
inline int tile_rows(int n) { return n % 4 != 0 && n % 3 == 0 ? 3 : 4; }

// One product of the element tangent: for rows A < n and columns j < ncols,
//   Kc[A rs + col[j]] += sum_{si < nS} sum_q phi_{S[si], q}(A) beta[(si nq + q) ldb + j]
// (= instead of += if store).
// phi is packed by tiles of MR = tile_rows(n) rows (zero-padded), each value twice (a broadcast is one load
// for W = 2): phi[(((A / MR) ns + s) nq + q) 2 MR + 2 (A % MR) + {0, 1}], so that a tile reads it
// contiguously. beta rows are readable up to a multiple of W past ncols.
struct Product {
  int nS = 0;
  const int* S = nullptr;
  int nq = 0, n = 0, ns = 0;
  const double* phi = nullptr;
  const double* beta = nullptr;
  int ldb = 0, ncols = 0;
  const int* col = nullptr;
  double* Kc = nullptr;
  std::size_t rs = 0;
  bool store = false;
};

// One register tile: rows MR tile .. MR tile + MR - 1 (those below n), columns j0 .. j0 + W NP - 1 (those
// below ncols).
template <int W, int MR, int NP, bool kStore>
[[gnu::always_inline]] inline void product_tile(const Product& g, int tile, int j0) {
  using V = typename VectorOf<W>::type;
  V acc[MR][NP] = {};
  const double* b = g.beta + j0;
  for (int si = 0; si < g.nS; ++si) {
    const double* a = g.phi + (static_cast<std::size_t>(tile) * g.ns + g.S[si]) * g.nq * 2 * MR;
    for (int q = 0; q < g.nq; ++q, a += 2 * MR, b += g.ldb) {
      V bv[NP];
      for (int p = 0; p < NP; ++p) std::memcpy(&bv[p], b + W * p, sizeof(V));
      for (int r = 0; r < MR; ++r) {
        V av;
        if constexpr (W == 2) {
          std::memcpy(&av, a + 2 * r, sizeof(V));
        } else {
          const double x = a[2 * r];
          av = V{x, x, x, x};
        }
        for (int p = 0; p < NP; ++p) acc[r][p] += av * bv[p];
      }
    }
  }
  // Fully unrolled (acc indexed by constants only, or it would live on the stack).
#pragma GCC unroll 4
  for (int r = 0; r < MR; ++r) {
    double* row = g.Kc + static_cast<std::size_t>(MR * tile + r) * g.rs;
    const bool row_in = MR * tile + r < g.n;
#pragma GCC unroll 3
    for (int p = 0; p < NP; ++p)
#pragma GCC unroll 4
      for (int l = 0; l < W; ++l)
        if (row_in && j0 + W * p + l < g.ncols) {
          if constexpr (kStore)
            row[g.col[j0 + W * p + l]] = acc[r][p][l];
          else
            row[g.col[j0 + W * p + l]] += acc[r][p][l];
        }
  }
}

// Row tiles outermost (a tile's phi stays in L1 while the beta is swept; faster than the other order here,
// even at n = 64), then panels of NP vectors of columns, then a narrower one.
template <int W, int MR, int NP, bool kStore>
[[gnu::always_inline]] inline void product_tiles(const Product& g) {
  static_assert(NP <= 3);
  for (int tile = 0; tile * MR < g.n; ++tile) {
    int j0 = 0;
    for (; j0 + W * NP <= g.ncols; j0 += W * NP) product_tile<W, MR, NP, kStore>(g, tile, j0);
    const int rest = (g.ncols - j0 + W - 1) / W;  // <= NP vectors, the last one maybe partly used
    if (rest == NP) product_tile<W, MR, NP, kStore>(g, tile, j0);
    if (rest == 1 && NP > 1) product_tile<W, MR, 1, kStore>(g, tile, j0);
    if constexpr (NP > 2)
      if (rest == 2) product_tile<W, MR, 2, kStore>(g, tile, j0);
  }
}

// Tiles of MR rows by NP vectors of columns: at most 12 accumulators, which with the operands fit in the 16
// vector registers (SSE2's two-operand instructions need one more for a temporary: 8 or 9 accumulators
// there).
template <int W, bool kStore>
[[gnu::always_inline]] inline void product_as(const Product& g) {
  if (tile_rows(g.n) == 3)
    product_tiles<W, 3, 3, kStore>(g);
  else
    product_tiles<W, 4, W == 2 ? 2 : 3, kStore>(g);
}
template <int W>
[[gnu::always_inline]] inline void product(const Product& g) {
  if (g.store)
    product_as<W, true>(g);
  else
    product_as<W, false>(g);
}

[[gnu::noinline]] void product_baseline(const Product& g) { product<2>(g); }
#ifdef CELLFSI_VMS_AVX2
[[gnu::noinline, gnu::target("avx2,fma")]] void product_avx2(const Product& g) { product<4>(g); }
#endif

// One column component e of the beta rows of one factor s, at every point: for q < nq and B < n,
//   dst[q ldd + B] = sum_{i < Count} coef[q ldc + t[i]] y[q ldq + t[i] ldy + B],
// W at a time: up to a multiple of W past n is written (the y rows are zero-padded to ldy, at least that
// long).
template <int W, int Count>
[[gnu::always_inline]] inline void combine(int nq, const int* t, const double* coef, std::size_t ldc,
                                           const double* y, std::size_t ldq, int ldy, int n, double* dst,
                                           std::size_t ldd) {
  using V = typename VectorOf<W>::type;
  const int nv = (n + W - 1) / W;
  for (int q = 0; q < nq; ++q, coef += ldc, y += ldq, dst += ldd) {
    double k[Count > 0 ? Count : 1] = {};
    const double* yk[Count > 0 ? Count : 1] = {};
    for (int i = 0; i < Count; ++i) {
      k[i] = coef[t[i]];
      yk[i] = y + t[i] * ldy;
    }
    for (int v = 0; v < nv; ++v) {
      V sum{};
      for (int i = 0; i < Count; ++i) {
        V x;
        std::memcpy(&x, yk[i] + W * v, sizeof(V));
        if constexpr (W == 2)
          sum += V{k[i], k[i]} * x;
        else
          sum += V{k[i], k[i], k[i], k[i]} * x;
      }
      std::memcpy(dst + W * v, &sum, sizeof(V));
    }
  }
}

struct ElementScratch {
  int ldy = 0;  // length of the y rows: n rounded up to a multiple of 4 (the widest vector), zero-padded
  std::vector<double> phi, y, C, beta, T;
  std::vector<int> col;
  std::vector<const double*> ka, kr;  // operands of the sum-factorised products
  std::vector<Stabilization> tau;     // per point (sum-factorised tangent)
  std::vector<double> Ct;             // its coefficients; zero off its pattern, for Ct_pattern
  int Ct_pattern = -1;                // kConvective of the pattern Ct is zero off, -1: none
};

// Per thread, kept between calls: no heap allocation once it has grown to the largest element.
ElementScratch& element_scratch() {
  thread_local ElementScratch scratch;
  return scratch;
}

// The per-point work: A-side factors phi (packed for the products), B-side factors y_t(B) and coefficients
// C_q. Scalar code, compiled for the baseline instruction set only (called from AVX code it ran slower).
template <int Dim, bool kConvective>
void element_points(const VmsParameters& prm, const ElementPoints& ep, const TangentScales& ts,
                    ElementScratch& sc) {
  constexpr int nc = Dim + 1, ns = Dim + 1, ny = Dim + 2, nC = nc * ns * nc * ny;
  const int n = ep.n, nq = ep.nq;
  const int ldy = sc.ldy = (n + 3) / 4 * 4;
  const int mr = tile_rows(n), tiles = (n + mr - 1) / mr;
  sc.phi.resize(static_cast<std::size_t>(tiles) * ns * nq * 2 * mr);
  if (n % mr != 0)  // padding rows of the last tile
    for (int s = 0; s < ns; ++s)
      for (int q = 0; q < nq; ++q)
        for (int r = n % mr; r < mr; ++r) {
          double* a =
              sc.phi.data() + ((static_cast<std::size_t>(tiles - 1) * ns + s) * nq + q) * 2 * mr + 2 * r;
          a[0] = a[1] = 0.0;
        }
  sc.y.resize(static_cast<std::size_t>(nq) * ny * ldy);
  sc.C.assign(static_cast<std::size_t>(nq) * nC, 0.0);

  PointScalars<Dim> ps;
  ps.vel = ts.velocity;
  ps.rate = ts.velocity_rate;
  ps.pres = ts.pressure;
  ps.nu = prm.nu;
  for (int q = 0; q < nq; ++q) {
    const double* N = ep.N + static_cast<std::size_t>(q) * n;
    const double* dN = ep.dN + static_cast<std::size_t>(q) * n * 3;
    const double* lapN = ep.lapN + static_cast<std::size_t>(q) * n;
    const PointFields& f = ep.fields[q];
    double* y = sc.y.data() + static_cast<std::size_t>(q) * ny * ldy;
    for (int B = 0; B < n; ++B) {
      double m = ps.rate * N[B] - ps.nu * ps.vel * lapN[B];  // m_B as in tangent_kernel
      for (int j = 0; j < Dim; ++j) {
        if constexpr (kConvective) m += ps.vel * f.v[j] * dN[B * 3 + j];
        y[(2 + j) * ldy + B] = dN[B * 3 + j];
      }
      y[B] = N[B];
      y[ldy + B] = m;
    }
    for (int t = 0; t < ny; ++t) std::fill(y + t * ldy + n, y + (t + 1) * ldy, 0.0);
    const std::size_t lds = static_cast<std::size_t>(nq) * 2 * mr;  // from one factor s to the next
    for (int A = 0; A < n; ++A) {
      double* a = sc.phi.data() + (static_cast<std::size_t>(A / mr) * ns * nq + q) * 2 * mr + 2 * (A % mr);
      a[0] = a[1] = N[A];
      for (int j = 0; j < Dim; ++j) a[(1 + j) * lds] = a[(1 + j) * lds + 1] = dN[A * 3 + j];
    }

    const Stabilization tau = vms_stabilization(prm, f);
    point_scalars<Dim, kConvective>(prm, f, tau, ep.weight[q], ps);
    double* C = sc.C.data() + static_cast<std::size_t>(q) * nC;
    coefficient_terms<Dim, kConvective>(
        ps, [C](int c, int s, int e, int t, double v) { C[((c * ns + s) * nc + e) * ny + t] += v; });
  }
}

// Where the element tangent goes: added to K in vms_tangent's layout (rows), or stored in node blocks
// (vms_tangent_element_blocks' layout). Every entry is produced by exactly one product, so storing overwrites
// all of K.
enum class Layout { rows, blocks };

// The beta and the products, one per row component c and run of column components with the same factors.
template <int Dim, bool kConvective, int W>
[[gnu::always_inline]] inline void element_products(const ElementPoints& ep, ElementScratch& sc, double* K,
                                                    Layout layout) {
  static constexpr ElementPattern<Dim, kConvective> pattern{};
  constexpr int nc = Dim + 1, ns = Dim + 1, ny = Dim + 2, nC = nc * ns * nc * ny;
  const int n = ep.n, nq = ep.nq, ldy = sc.ldy;
  const std::size_t ld = static_cast<std::size_t>(n) * nc;
  auto round_up = [](int i) { return (i + W - 1) / W * W; };
  // Row length of the beta of E column components: room for combine's writes past the end of the last.
  auto beta_ld = [&](int E) { return round_up((E - 1) * n + round_up(n)); };
  sc.beta.resize(static_cast<std::size_t>(ns) * nq * beta_ld(nc));
  sc.col.resize(static_cast<std::size_t>(nc) * n);

  for (int c = 0; c < nc; ++c)
    for (int e0 = 0; e0 < nc;) {
      const unsigned mask = pattern.factors[c][e0];
      int e1 = e0 + 1;
      while (e1 < nc && pattern.factors[c][e1] == mask) ++e1;
      int S[ns], nS = 0;
      for (int s = 0; s < ns; ++s)
        if (mask >> s & 1u) S[nS++] = s;
      const int ncols = (e1 - e0) * n, ldb = beta_ld(e1 - e0), written = (e1 - e0 - 1) * n + round_up(n);

      // beta[(si nq + q) ldb + (e - e0) n + B] = beta_{S[si], q}^{ce}(B), e increasing so that combine's
      // writes past the end of a column component are overwritten by the next one.
      for (int si = 0; si < nS; ++si) {
        double* rows = sc.beta.data() + static_cast<std::size_t>(si) * nq * ldb;
        for (int e = e0; e < e1; ++e) {
          const auto& terms = pattern.terms[c][S[si]][e];
          const double* coef = sc.C.data() + ((c * ns + S[si]) * nc + e) * ny;
          const std::size_t ldq = static_cast<std::size_t>(ny) * ldy;
          double* dst = rows + (e - e0) * n;
          switch (terms.count) {
            case 0:
              combine<W, 0>(nq, terms.t, coef, nC, sc.y.data(), ldq, ldy, n, dst, ldb);
              break;
            case 1:
              combine<W, 1>(nq, terms.t, coef, nC, sc.y.data(), ldq, ldy, n, dst, ldb);
              break;
            case 2:
              combine<W, 2>(nq, terms.t, coef, nC, sc.y.data(), ldq, ldy, n, dst, ldb);
              break;
            case 3:
              combine<W, 3>(nq, terms.t, coef, nC, sc.y.data(), ldq, ldy, n, dst, ldb);
              break;
            case 4:
              combine<W, 4>(nq, terms.t, coef, nC, sc.y.data(), ldq, ldy, n, dst, ldb);
              break;
            default:
              static_assert(Dim + 2 <= 5);
              combine<W, 5>(nq, terms.t, coef, nC, sc.y.data(), ldq, ldy, n, dst, ldb);
              break;
          }
        }
        if (written < ldb)
          for (int q = 0; q < nq; ++q) std::fill(rows + q * ldb + written, rows + (q + 1) * ldb, 0.0);
      }
      const bool blocks = layout == Layout::blocks;
      for (int e = e0; e < e1; ++e)
        for (int B = 0; B < n; ++B) sc.col[(e - e0) * n + B] = blocks ? (B * nc + e) * nc : B * nc + e;

      Product g;
      g.nS = nS;
      g.S = S;
      g.nq = nq;
      g.n = n;
      g.ns = ns;
      g.phi = sc.phi.data();
      g.beta = sc.beta.data();
      g.ldb = ldb;
      g.ncols = ncols;
      g.col = sc.col.data();
      g.Kc = blocks ? K + c : K + c * ld;
      g.rs = nc * ld;  // rows: A nc rows of ld; blocks: n blocks of nc^2
      g.store = blocks;
#ifdef CELLFSI_VMS_AVX2
      if constexpr (W == 4) product_avx2(g);
#endif
      if constexpr (W == 2) product_baseline(g);
      e0 = e1;
    }
}

template <int Dim, bool kConvective>
void element_products_baseline(const ElementPoints& ep, ElementScratch& sc, double* K, Layout layout) {
  element_products<Dim, kConvective, 2>(ep, sc, K, layout);
}

#ifdef CELLFSI_VMS_AVX2
template <int Dim, bool kConvective>
[[gnu::target("avx2,fma")]] void element_products_avx2(const ElementPoints& ep, ElementScratch& sc, double* K,
                                                       Layout layout) {
  element_products<Dim, kConvective, 4>(ep, sc, K, layout);
}

#endif

// Sum-factorised element tangent (2D, TensorFactors given; vms_tangent_element_blocks). All row components at
// once, in the node-block layout: the B-side rows have one column per (B, e, c), col = (B nc + e) nc + c,
//   beta_s(q)[col] = sum_t C_q[c][s][e][t] y_t,q(B)   (s = 0, 1, 2: the A-side factor N_A, dN_A/dx, dN_A/dy),
// so that row A of the product is row A of the element's block matrix, stored contiguously. With A = a + na
// b, q = qx + nqx qy and the univariate factors X = value[0], Xd = deriv[0], Y = value[1], Yd = deriv[1]:
//   Kb[A][col] = sum_qx X(qx, a) TX(qx, b)[col] + Xd(qx, a) TXd(qx, b)[col],
//   TX(qx, b) = sum_qy Y(qy, b) beta_0(q) + Yd(qy, b) beta_2(q),   TXd(qx, b) = sum_qy Y(qy, b) beta_1(q).
// Multiply-adds per column: nqx nb 3 nqy + na nb 2 nqx against element_products' n nq 3 (p = 3: 320 against
// 768; p = 2: 135 against 243). Both contractions are one kind of small product,
//   out_r[j] = sum_{k < K} a_k[r] rows_k[j],   r < R, j < ncols,
// register-tiled by up to 4 rows and NP vectors of columns. beta costs (nc^2 rounded up to 4) ny
// multiply-adds per point, function and factor, its coefficients for one (point, s, t) being a few contiguous
// vectors.
constexpr int kLanes2d = 12;  // nc^2 = 9 coefficients of one (point, s, t), rounded up to a multiple of 4

struct TensorGemm {
  int R = 0, K = 0, ncols = 0;
  const double* const* a = nullptr;     // a[k][r]
  const double* const* rows = nullptr;  // rows[k][j], readable up to a multiple of W past ncols
  double* out = nullptr;                // row r at out + r ld; stored, not added
  std::size_t ld = 0;
};

// Unaligned vector loads and stores (a memcpy per vector was compiled as a copy through the stack here).
template <int W>
struct UnalignedOf {
  typedef double type __attribute__((vector_size(8 * W), aligned(8), may_alias));
};

// x in every lane (an out-parameter: returning an AVX vector from a function not compiled for AVX is an ABI
// question, even inlined).
template <int W>
[[gnu::always_inline]] inline void splat(double x, typename VectorOf<W>::type& v) {
  double lanes[W];
  for (int l = 0; l < W; ++l) lanes[l] = x;
  std::memcpy(&v, lanes, sizeof v);
}

// kExact: columns past ncols are not written (the element matrix's rows); otherwise whole vectors are (room
// up to a multiple of W past ncols).
template <int W, int MR, int NP, bool kExact>
[[gnu::always_inline]] inline void tensor_tile(const TensorGemm& g, int r0, int j0) {
  using V = typename VectorOf<W>::type;
  using U = typename UnalignedOf<W>::type;
  V acc[MR][NP] = {};
  for (int k = 0; k < g.K; ++k) {
    const double* b = g.rows[k] + j0;
    const double* a = g.a[k] + r0;
    V bv[NP];
#pragma GCC unroll 3
    for (int p = 0; p < NP; ++p) bv[p] = *reinterpret_cast<const U*>(b + W * p);
#pragma GCC unroll 4
    for (int r = 0; r < MR; ++r) {
      const double x = a[r];
      V av;
      if constexpr (W == 2)
        av = V{x, x};
      else
        av = V{x, x, x, x};
#pragma GCC unroll 3
      for (int p = 0; p < NP; ++p) acc[r][p] += av * bv[p];
    }
  }
#pragma GCC unroll 4
  for (int r = 0; r < MR; ++r) {
    double* row = g.out + static_cast<std::size_t>(r0 + r) * g.ld + j0;
#pragma GCC unroll 3
    for (int p = 0; p < NP; ++p) {
      if (!kExact || j0 + W * (p + 1) <= g.ncols) {
        *reinterpret_cast<U*>(row + W * p) = acc[r][p];
      } else {
#pragma GCC unroll 4
        for (int l = 0; l < W; ++l)
          if (j0 + W * p + l < g.ncols) row[W * p + l] = acc[r][p][l];
      }
    }
  }
}

template <int W, int MR, bool kExact>
[[gnu::always_inline]] inline void tensor_panels(const TensorGemm& g, int r0) {
  constexpr int NP = W == 2 ? 2 : 3;  // MR NP accumulators: up to 8 (SSE2) or 12 (AVX2)
  int j0 = 0;
  for (; j0 + W * NP <= g.ncols; j0 += W * NP) tensor_tile<W, MR, NP, kExact>(g, r0, j0);
  const int rest = (g.ncols - j0 + W - 1) / W;  // <= NP vectors, the last one maybe partly used
  if (rest == NP) tensor_tile<W, MR, NP, kExact>(g, r0, j0);
  if (rest == 1 && NP > 1) tensor_tile<W, MR, 1, kExact>(g, r0, j0);
  if constexpr (NP > 2)
    if (rest == 2) tensor_tile<W, MR, 2, kExact>(g, r0, j0);
}

template <int W, bool kExact>
[[gnu::always_inline]] inline void tensor_gemm(const TensorGemm& g) {
  for (int r0 = 0; r0 < g.R;) {
    switch (std::min(4, g.R - r0)) {
      case 4:
        tensor_panels<W, 4, kExact>(g, r0);
        r0 += 4;
        break;
      case 3:
        tensor_panels<W, 3, kExact>(g, r0);
        r0 += 3;
        break;
      case 2:
        tensor_panels<W, 2, kExact>(g, r0);
        r0 += 2;
        break;
      default:
        tensor_panels<W, 1, kExact>(g, r0);
        r0 += 1;
        break;
    }
  }
}

// Which coefficients of the sum-factorised tangent can be nonzero: lane[s][t][e nc + c], and whether factor s
// has any (s[s]).
template <bool kConvective>
struct FactorPattern {
  bool lane[3][4][kLanes2d] = {};
  bool s[3] = {};
  constexpr FactorPattern() {
    const ElementPattern<2, kConvective> pattern{};
    for (int c = 0; c < 3; ++c)
      for (int s_ = 0; s_ < 3; ++s_)
        for (int e = 0; e < 3; ++e)
          for (int i = 0; i < pattern.terms[c][s_][e].count; ++i) {
            lane[s_][pattern.terms[c][s_][e].t[i]][e * 3 + c] = true;
            s[s_] = true;
          }
  }
  // Whether the vector of lanes [l0, l0 + W) of (s, t) has a nonzero.
  constexpr bool any(int s_, int t, int l0, int W) const {
    bool a = false;
    for (int l = l0; l < l0 + W; ++l) a = a || lane[s_][t][l];
    return a;
  }
};

// For each term of coefficient_terms<2, kConvective>, in its order: whether it is the first to reach its
// coefficient.
template <bool kConvective>
struct FirstTerms {
  static constexpr int kMax = 128;
  bool first[kMax] = {};
  int count = 0;
  constexpr FirstTerms() {
    bool seen[3][3][3][4] = {};
    coefficient_terms<2, kConvective>(PointScalars<2>{}, [&](int c, int s, int e, int t, double) {
      first[count++] = !seen[c][s][e][t];
      seen[c][s][e][t] = true;
    });
  }
};
static_assert(FirstTerms<true>{}.count <= FirstTerms<true>::kMax);

// The per-point work of the sum-factorised tangent: tau, m_B (y_1 of element_points) and the coefficients,
// here Ct[((q ns + s) ny + t) kLanes2d + e nc + c] (zero off the pattern and in the padding). Scalar code,
// baseline instruction set.
template <bool kConvective>
void tensor_points(const VmsParameters& prm, const ElementPoints& ep, const TangentScales& ts,
                   ElementScratch& sc) {
  constexpr int Dim = 2, nc = 3, ns = 3, ny = 4, nL = kLanes2d;
  const int n = ep.n, nq = ep.nq;
  sc.y.resize(static_cast<std::size_t>(nq) * n);  // y_1 = m_B only: the others are N, dN
  // Entries off the pattern are never written: zeroed when the array grows or the pattern changes. Entries
  // on it are assigned by their first term (coefficient_terms' order, FirstTerms).
  const std::size_t size = static_cast<std::size_t>(nq) * ns * ny * nL;
  if (sc.Ct.size() < size || sc.Ct_pattern != int{kConvective}) {
    sc.Ct.assign(std::max(size, sc.Ct.size()), 0.0);
    sc.Ct_pattern = kConvective;
  }
  // tau first, for all points: its square root and divisions then overlap from point to point.
  sc.tau.resize(nq);
  for (int q = 0; q < nq; ++q) sc.tau[q] = vms_stabilization(prm, ep.fields[q]);

  PointScalars<Dim> ps;
  ps.vel = ts.velocity;
  ps.rate = ts.velocity_rate;
  ps.pres = ts.pressure;
  ps.nu = prm.nu;
  for (int q = 0; q < nq; ++q) {
    const double* N = ep.N + static_cast<std::size_t>(q) * n;
    const double* dN = ep.dN + static_cast<std::size_t>(q) * n * 3;
    const double* lapN = ep.lapN + static_cast<std::size_t>(q) * n;
    const PointFields& f = ep.fields[q];
    double* m = sc.y.data() + static_cast<std::size_t>(q) * n;
    for (int B = 0; B < n; ++B) {
      double mB = ps.rate * N[B] - ps.nu * ps.vel * lapN[B];  // m_B as in tangent_kernel
      if constexpr (kConvective)
        for (int j = 0; j < Dim; ++j) mB += ps.vel * f.v[j] * dN[B * 3 + j];
      m[B] = mB;
    }

    const Stabilization tau = sc.tau[q];
    point_scalars<Dim, kConvective>(prm, f, tau, ep.weight[q], ps);
    static constexpr FirstTerms<kConvective> first{};
    double* C = sc.Ct.data() + static_cast<std::size_t>(q) * ns * ny * nL;
    int term = 0;
    coefficient_terms<Dim, kConvective>(ps, [C, &term](int c, int s, int e, int t, double v) {
      double& x = C[(s * ny + t) * nL + e * nc + c];
      x = first.first[term++] ? v : x + v;
    });
  }
}

// beta_s, every s, at the points q = qx + nqx qy, qy < nqy, one row of ldb per point: per function B, the
// nc^2 values sum_t C[q][s][t][.] y_t,q(B) as kLanes2d / W vectors (structurally zero ones skipped), B
// increasing so that each vector's lanes past nc^2 are overwritten by the next function's.
template <bool kConvective, int W>
[[gnu::always_inline]] inline void tensor_beta(const ElementPoints& ep, const ElementScratch& sc, int qx,
                                               int nqx, int nqy, double* const* beta, std::size_t ldb) {
  static constexpr FactorPattern<kConvective> fp{};
  using V = typename VectorOf<W>::type;
  using U = typename UnalignedOf<W>::type;
  constexpr int nc = 3, ns = 3, ny = 4, nL = kLanes2d, nv = nL / W;
  const int n = ep.n;
  for (int qy = 0; qy < nqy; ++qy) {
    const std::size_t q = static_cast<std::size_t>(qx) + static_cast<std::size_t>(nqx) * qy;
    const double* C = sc.Ct.data() + q * ns * ny * nL;
    const double *N = ep.N + q * n, *m = sc.y.data() + q * n, *dN = ep.dN + q * n * 3;
    const std::size_t row = static_cast<std::size_t>(qy) * ldb;
    for (int B = 0; B < n; ++B) {
      V yv[ny];  // y_t(B): N_B, m_B, dN_B
      splat<W>(N[B], yv[0]);
      splat<W>(m[B], yv[1]);
      splat<W>(dN[B * 3], yv[2]);
      splat<W>(dN[B * 3 + 1], yv[3]);
#pragma GCC unroll 3
      for (int s = 0; s < ns; ++s) {
        if (!fp.s[s]) continue;
        double* dst = beta[s] + row + B * nc * nc;
#pragma GCC unroll 6
        for (int v = 0; v < nv; ++v) {
          V sum{};
#pragma GCC unroll 4
          for (int t = 0; t < ny; ++t)
            if (fp.any(s, t, W * v, W))
              sum += *reinterpret_cast<const U*>(C + (s * ny + t) * nL + W * v) * yv[t];
          *reinterpret_cast<U*>(dst + W * v) = sum;
        }
      }
    }
  }
}

template <bool kConvective, int W>
[[gnu::always_inline]] inline void tensor_products(const ElementPoints& ep, const TensorFactors& tf,
                                                   ElementScratch& sc, double* Kb) {
  static constexpr FactorPattern<kConvective> fp{};
  constexpr int nc = 3, ns = 3;
  const int na = tf.np[0], nb = tf.np[1], nqx = tf.nq[0], nqy = tf.nq[1];
  const int n = ep.n;
  auto round_up = [](int i) { return (i + W - 1) / W * W; };
  // Rows of beta and T: room for tensor_beta's writes past the last function (kLanes2d - nc^2).
  const int ncols = n * nc * nc, ldb = round_up(ncols + kLanes2d - nc * nc);
  // beta of one line of points (qx fixed), for each factor s; TX and TXd for every (qx, b).
  sc.beta.resize(static_cast<std::size_t>(ns) * nqy * ldb);
  sc.T.resize(static_cast<std::size_t>(2) * nqx * nb * ldb);
  sc.ka.resize(2 * std::max(nqx, nqy));
  sc.kr.resize(sc.ka.size());
  const double *X = tf.value[0], *Xd = tf.deriv[0], *Y = tf.value[1], *Yd = tf.deriv[1];
  double* const TX = sc.T.data();
  double* const TXd = TX + static_cast<std::size_t>(nqx) * nb * ldb;
  double* beta[ns];
  for (int s = 0; s < ns; ++s) beta[s] = sc.beta.data() + static_cast<std::size_t>(s) * nqy * ldb;
  constexpr bool has_x = fp.s[0] || fp.s[2];

  TensorGemm g;
  g.R = nb;
  g.ncols = ncols;
  g.a = sc.ka.data();
  g.rows = sc.kr.data();
  g.ld = ldb;
  for (int qx = 0; qx < nqx; ++qx) {
    tensor_beta<kConvective, W>(ep, sc, qx, nqx, nqy, beta, ldb);
    if constexpr (has_x) {
      g.K = 0;
      for (int qy = 0; qy < nqy; ++qy) {
        if constexpr (fp.s[0]) {
          sc.ka[g.K] = Y + static_cast<std::size_t>(qy) * nb;
          sc.kr[g.K++] = beta[0] + static_cast<std::size_t>(qy) * ldb;
        }
        if constexpr (fp.s[2]) {
          sc.ka[g.K] = Yd + static_cast<std::size_t>(qy) * nb;
          sc.kr[g.K++] = beta[2] + static_cast<std::size_t>(qy) * ldb;
        }
      }
      g.out = TX + static_cast<std::size_t>(qx) * nb * ldb;
      tensor_gemm<W, false>(g);
    }
    if constexpr (fp.s[1]) {
      g.K = 0;
      for (int qy = 0; qy < nqy; ++qy) {
        sc.ka[g.K] = Y + static_cast<std::size_t>(qy) * nb;
        sc.kr[g.K++] = beta[1] + static_cast<std::size_t>(qy) * ldb;
      }
      g.out = TXd + static_cast<std::size_t>(qx) * nb * ldb;
      tensor_gemm<W, false>(g);
    }
  }

  // The rows of Kb, one product per b (functions a + na b).
  g.R = na;
  g.ld = ncols;
  for (int b = 0; b < nb; ++b) {
    g.K = 0;
    for (int qx = 0; qx < nqx; ++qx) {
      const std::size_t row = (static_cast<std::size_t>(qx) * nb + b) * ldb;
      if constexpr (has_x) {
        sc.ka[g.K] = X + static_cast<std::size_t>(qx) * na;
        sc.kr[g.K++] = TX + row;
      }
      if constexpr (fp.s[1]) {
        sc.ka[g.K] = Xd + static_cast<std::size_t>(qx) * na;
        sc.kr[g.K++] = TXd + row;
      }
    }
    g.out = Kb + static_cast<std::size_t>(na) * b * ncols;
    tensor_gemm<W, true>(g);
  }
}

template <bool kConvective>
void tensor_products_baseline(const ElementPoints& ep, const TensorFactors& tf, ElementScratch& sc,
                              double* Kb) {
  tensor_products<kConvective, 2>(ep, tf, sc, Kb);
}

#ifdef CELLFSI_VMS_AVX2
template <bool kConvective>
[[gnu::target("avx2,fma")]] void tensor_products_avx2(const ElementPoints& ep, const TensorFactors& tf,
                                                      ElementScratch& sc, double* Kb) {
  tensor_products<kConvective, 4>(ep, tf, sc, Kb);
}
#endif

template <int Dim, bool kConvective>
void tangent_element_kernel(const VmsParameters& prm, const ElementPoints& ep, const TangentScales& ts,
                            double* K, bool baseline, Layout layout, const TensorFactors* tensor) {
  ElementScratch& sc = element_scratch();
  if constexpr (Dim == 2) {
    if (layout == Layout::blocks && tensor != nullptr) {
      tensor_points<kConvective>(prm, ep, ts, sc);
#ifdef CELLFSI_VMS_AVX2
      if (!baseline && cpu_has_avx2_fma()) return tensor_products_avx2<kConvective>(ep, *tensor, sc, K);
#endif
      return tensor_products_baseline<kConvective>(ep, *tensor, sc, K);
    }
  }
  element_points<Dim, kConvective>(prm, ep, ts, sc);
#ifdef CELLFSI_VMS_AVX2
  if (!baseline && cpu_has_avx2_fma()) return element_products_avx2<Dim, kConvective>(ep, sc, K, layout);
#endif
  (void)baseline;
  (void)tensor;
  element_products_baseline<Dim, kConvective>(ep, sc, K, layout);
}

void tangent_element(const VmsParameters& prm, const ElementPoints& points, const TangentScales& ts,
                     double* K, bool baseline, Layout layout, const TensorFactors* tensor) {
  assert(prm.dim == 2 || prm.dim == 3);
  if (prm.dim == 2) {
    if (prm.stokes)
      tangent_element_kernel<2, false>(prm, points, ts, K, baseline, layout, tensor);
    else
      tangent_element_kernel<2, true>(prm, points, ts, K, baseline, layout, tensor);
  } else {
    if (prm.stokes)
      tangent_element_kernel<3, false>(prm, points, ts, K, baseline, layout, tensor);
    else
      tangent_element_kernel<3, true>(prm, points, ts, K, baseline, layout, tensor);
  }
}

}  // namespace

bool cpu_has_avx2_fma() {
#ifdef CELLFSI_VMS_AVX2
  static const bool has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return has;
#else
  return false;
#endif
}

void vms_tangent_element(const VmsParameters& prm, const ElementPoints& points, const TangentScales& ts,
                         double* K, ElementKernelIsa isa) {
  if (points.n <= 0 || points.nq <= 0) return;
  tangent_element(prm, points, ts, K, isa == ElementKernelIsa::baseline, Layout::rows, nullptr);
}

void vms_tangent_element_blocks(const VmsParameters& prm, const ElementPoints& points,
                                const TangentScales& ts, double* Kb, const TensorFactors* tensor,
                                ElementKernelIsa isa) {
  if (points.n <= 0) return;
  if (points.nq <= 0) {
    const int nc = prm.dim + 1;
    std::fill(Kb, Kb + static_cast<std::size_t>(points.n) * points.n * nc * nc, 0.0);
    return;
  }
  // The factors must describe the element; otherwise the unfactorised products.
  if (tensor && (tensor->np[0] * tensor->np[1] * tensor->np[2] != points.n ||
                 tensor->nq[0] * tensor->nq[1] * tensor->nq[2] != points.nq || tensor->np[2] != 1 ||
                 tensor->nq[2] != 1))
    tensor = nullptr;
  tangent_element(prm, points, ts, Kb, isa == ElementKernelIsa::baseline, Layout::blocks, tensor);
}

}  // namespace cellfsi::fluid
