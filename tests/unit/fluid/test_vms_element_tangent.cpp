// The element tangent (vms_tangent_element, vms_tangent_element_blocks; fluid/vms_element_tangent.cpp): equal
// to the sum of the pointwise tangents over the element's points, with and without sum factorisation, in both
// instruction sets and layouts.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "fluid/vms_kernel.hpp"
#include "vms_test_cases.hpp"

using namespace cellfsi::fluid;
using namespace vms_test;

namespace {

struct ElementCase {
  VmsParameters prm;
  TangentScales ts;
  int n = 0, nq = 0;
  std::vector<double> N, dN, lapN, weight;
  std::vector<PointFields> fields;
  int nc() const { return prm.dim + 1; }
  int size() const { return n * nc(); }
  ElementPoints points() const {
    return {n, nq, N.data(), dN.data(), lapN.data(), weight.data(), fields.data()};
  }
};

ElementCase make_element(int dim, int n, int nq, bool stokes, const Scales& sc, unsigned seed) {
  ElementCase el;
  el.n = n;
  el.nq = nq;
  for (int q = 0; q < nq; ++q) {
    const Case c = make_case(dim, n, stokes, sc, seed + 1000 * q);
    if (q == 0) {
      el.prm = c.prm;
      el.ts = c.ts;
    }
    el.N.insert(el.N.end(), c.N.begin(), c.N.end());
    el.dN.insert(el.dN.end(), c.dN.begin(), c.dN.end());
    el.lapN.insert(el.lapN.end(), c.lapN.begin(), c.lapN.end());
    el.weight.push_back(c.weight);
    el.fields.push_back(c.fields());
  }
  return el;
}

std::vector<double> summed_point_tangents(const ElementCase& el) {
  std::vector<double> K(static_cast<size_t>(el.size()) * el.size(), 0.0);
  for (int q = 0; q < el.nq; ++q) {
    const PointBasis pb{el.n, &el.N[static_cast<size_t>(q) * el.n], &el.dN[static_cast<size_t>(q) * el.n * 3],
                        &el.lapN[static_cast<size_t>(q) * el.n]};
    vms_tangent(el.prm, pb, el.fields[q], el.ts, el.weight[q], K.data());
  }
  return K;
}

// max over blocks (c, e) of max |K - ref| / max |ref| in the block; a block that is zero in ref must be zero
// in K.
double worst_block_error(const ElementCase& el, const std::vector<double>& K,
                         const std::vector<double>& ref) {
  const int nc = el.nc(), m = el.size();
  double worst = 0;
  for (int c = 0; c < nc; ++c)
    for (int e = 0; e < nc; ++e) {
      double scale = 0, diff = 0;
      for (int A = 0; A < el.n; ++A)
        for (int B = 0; B < el.n; ++B) {
          const size_t k = static_cast<size_t>(A * nc + c) * m + B * nc + e;
          scale = std::max(scale, std::abs(ref[k]));
          diff = std::max(diff, std::abs(K[k] - ref[k]));
        }
      worst = std::max(worst, scale > 0 ? diff / scale : (diff > 0 ? 1e300 : 0.0));
    }
  return worst;
}

const char* isa_name(ElementKernelIsa isa) { return isa == ElementKernelIsa::best ? "best" : "baseline"; }

}  // namespace

TEST(VmsKernel, ElementTangentEqualsTheSumOfThePointTangents) {
  struct Shape {
    int dim, n, nq;
  };
  unsigned seed = 900;
  for (const Scales* sc : {&kPhysical, &kBalanced})
    for (bool stokes : {false, true})
      for (const Shape& sh : {Shape{2, 9, 9}, Shape{2, 16, 16}, Shape{3, 27, 27}}) {
        const ElementCase el = make_element(sh.dim, sh.n, sh.nq, stokes, *sc, seed++);
        const std::vector<double> ref = summed_point_tangents(el);
        for (ElementKernelIsa isa : {ElementKernelIsa::best, ElementKernelIsa::baseline}) {
          std::vector<double> K(ref.size(), 0.0);
          vms_tangent_element(el.prm, el.points(), el.ts, K.data(), isa);
          const double worst = worst_block_error(el, K, ref);
          std::printf(
              "  element vs summed point tangents, %-8s %dD %-6s n=%2d nq=%2d %-8s: %.2e (tol %.0e)\n",
              sc->name, sh.dim, stokes ? "Stokes" : "NS", sh.n, sh.nq, isa_name(isa), worst, kRefTol);
          EXPECT_LT(worst, kRefTol) << sc->name << " " << sh.dim << "D n=" << sh.n << " " << isa_name(isa);
        }
      }
}

// Sizes the register tiles do not divide (rows are tiled by 3 or 4, columns by 2 or 4 doubles), points fewer
// or more than functions, one point, and p = 4 in 3D; K is added to, not overwritten.
TEST(VmsKernel, ElementTangentHandlesOddSizesAndAccumulates) {
  struct Shape {
    int dim, n, nq;
  };
  unsigned seed = 950;
  double worst = 0;
  for (bool stokes : {false, true})
    for (const Shape& sh : {Shape{2, 5, 7}, Shape{2, 10, 1}, Shape{2, 16, 9}, Shape{2, 9, 16}, Shape{3, 8, 3},
                            Shape{3, 125, 2}, Shape{2, 1, 2}})
      for (ElementKernelIsa isa : {ElementKernelIsa::best, ElementKernelIsa::baseline}) {
        const ElementCase el = make_element(sh.dim, sh.n, sh.nq, stokes, kBalanced, seed++);
        std::vector<double> ref = summed_point_tangents(el);
        // Start from a filled matrix: the result must be the fill plus the tangent.
        std::vector<double> K(ref.size());
        for (size_t k = 0; k < K.size(); ++k) K[k] = 0.25 * std::sin(1.0 + k);
        for (size_t k = 0; k < K.size(); ++k) ref[k] += K[k];
        vms_tangent_element(el.prm, el.points(), el.ts, K.data(), isa);
        const double w = worst_block_error(el, K, ref);
        EXPECT_LT(w, kRefTol) << sh.dim << "D n=" << sh.n << " nq=" << sh.nq << (stokes ? " Stokes " : " NS ")
                              << isa_name(isa);
        worst = std::max(worst, w);
      }
  std::printf("  element vs summed point tangents, odd sizes, into a filled K: worst %.2e (tol %.0e)\n",
              worst, kRefTol);
}

// vms_tangent_element_blocks: the BAIJ block layout of the same sums, without and with the sum-factorised
// (tensor-product) path. The tensor case builds N and dN from univariate factors, so both paths see the same
// element.
namespace {

/// K (vms_tangent_element layout) from Kb (node blocks, each column-major).
std::vector<double> unblock(const ElementCase& el, const std::vector<double>& Kb) {
  const int nc = el.nc(), m = el.size();
  std::vector<double> K(static_cast<size_t>(m) * m);
  for (int A = 0; A < el.n; ++A)
    for (int B = 0; B < el.n; ++B)
      for (int c = 0; c < nc; ++c)
        for (int e = 0; e < nc; ++e)
          K[static_cast<size_t>(A * nc + c) * m + B * nc + e] =
              Kb[static_cast<size_t>(A * el.n + B) * nc * nc + e * nc + c];
  return K;
}

}  // namespace

TEST(VmsKernel, BlockElementTangentMatchesThePointSumsWithAndWithoutSumFactorisation) {
  double worst_plain = 0, worst_tensor = 0;
  unsigned seed = 1200;
  for (const Scales* sc : {&kPhysical, &kBalanced})
    for (bool stokes : {false, true})
      for (int p : {2, 3}) {
        const int n1 = p + 1, nq1 = p + 1;
        ElementCase el = make_element(2, n1 * n1, nq1 * nq1, stokes, *sc, seed++);
        // Univariate factors (values and x-derivatives in each direction) and the tensor-product basis.
        std::mt19937 rng(seed++);
        std::uniform_real_distribution<double> u(-1.0, 1.0);
        std::vector<double> val[2], der[2];
        for (int d = 0; d < 2; ++d)
          for (int k = 0; k < nq1 * n1; ++k)
            val[d].push_back(0.5 + 0.5 * u(rng)), der[d].push_back(u(rng) / sc->length);
        for (int q1 = 0; q1 < nq1; ++q1)
          for (int q0 = 0; q0 < nq1; ++q0)
            for (int a1 = 0; a1 < n1; ++a1)
              for (int a0 = 0; a0 < n1; ++a0) {
                const int q = q0 + nq1 * q1, A = a0 + n1 * a1;
                const double v0 = val[0][q0 * n1 + a0], v1 = val[1][q1 * n1 + a1];
                el.N[q * el.n + A] = v0 * v1;
                el.dN[(q * el.n + A) * 3 + 0] = der[0][q0 * n1 + a0] * v1;
                el.dN[(q * el.n + A) * 3 + 1] = v0 * der[1][q1 * n1 + a1];
                el.dN[(q * el.n + A) * 3 + 2] = 0.0;
              }
        const std::vector<double> ref = summed_point_tangents(el);
        TensorFactors tf;
        for (int d = 0; d < 2; ++d)
          tf.np[d] = n1, tf.nq[d] = nq1, tf.value[d] = val[d].data(), tf.deriv[d] = der[d].data();
        std::vector<double> Kb(static_cast<size_t>(el.n) * el.n * el.nc() * el.nc(),
                               1e300);  // written, not added
        vms_tangent_element_blocks(el.prm, el.points(), el.ts, Kb.data());
        const double w_plain = worst_block_error(el, unblock(el, Kb), ref);
        std::fill(Kb.begin(), Kb.end(), 1e300);
        vms_tangent_element_blocks(el.prm, el.points(), el.ts, Kb.data(), &tf);
        const double w_tensor = worst_block_error(el, unblock(el, Kb), ref);
        EXPECT_LT(w_plain, kRefTol) << sc->name << " p=" << p << (stokes ? " Stokes" : " NS");
        EXPECT_LT(w_tensor, kRefTol) << sc->name << " p=" << p << (stokes ? " Stokes" : " NS") << " (tensor)";
        worst_plain = std::max(worst_plain, w_plain);
        worst_tensor = std::max(worst_tensor, w_tensor);
      }
  std::printf(
      "  block element tangent vs summed point tangents: plain %.2e, sum-factorised %.2e (tol %.0e)\n",
      worst_plain, worst_tensor, kRefTol);
}
