// Partition of unity and derivatives (against central finite differences) of B-spline and NURBS bases.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "geometry/basis.hpp"
#include "geometry/builders.hpp"
#include "geometry/knot_vector.hpp"
#include "geometry/patch.hpp"

using namespace cellfsi::geometry;

namespace {

// A non-uniform open knot vector with one repeated interior knot.
KnotVector nonuniform_open(int p) {
  std::vector<double> U(p + 1, 0.0);
  for (double u : {0.1, 0.25, 0.4, 0.7, 0.75, 0.9}) U.push_back(u);
  if (p >= 2) U.push_back(0.25);  // a repeated interior knot (C^{p-2} there)
  std::sort(U.begin(), U.end());
  for (int i = 0; i <= p; ++i) U.push_back(1.0);
  return KnotVector::open(p, U);
}

std::vector<double> values_at(const KnotVector& kv, double u, int nd) {
  std::vector<double> d((nd + 1) * (kv.degree() + 1));
  bspline_basis(kv, kv.find_span(u), kv.normalize(u), nd, d.data());
  return d;
}

}  // namespace

TEST(BsplineBasis, PartitionOfUnityOpenAndPeriodic) {
  for (int p = 1; p <= 5; ++p) {
    for (const KnotVector& kv : {nonuniform_open(p), KnotVector::periodic_uniform(p, 7, -1.0, 2.0)}) {
      for (int s = 0; s <= 200; ++s) {
        const double u = kv.a() + (kv.b() - kv.a()) * s / 200.0;
        const auto d = values_at(kv, u, 2);
        double sum = 0, dsum = 0, d2sum = 0;
        for (int j = 0; j <= p; ++j) sum += d[j], dsum += d[p + 1 + j], d2sum += d[2 * (p + 1) + j];
        EXPECT_NEAR(sum, 1.0, 1e-14) << "p=" << p << " u=" << u;
        EXPECT_NEAR(dsum, 0.0, 1e-11) << "p=" << p;
        EXPECT_NEAR(d2sum, 0.0, 1e-9) << "p=" << p;
        for (int j = 0; j <= p; ++j) EXPECT_GE(d[j], -1e-15);
      }
    }
  }
}

TEST(BsplineBasis, DerivativesMatchFiniteDifferences) {
  const double h = 1e-6;
  for (int p = 1; p <= 5; ++p) {
    const KnotVector kv = nonuniform_open(p);
    for (int e = 0; e < kv.n_elements(); ++e) {
      // Points well inside each element so u +- h stays in the same span.
      for (double t : {0.2, 0.5, 0.8}) {
        const double u = kv.element_begin(e) + t * (kv.element_end(e) - kv.element_begin(e));
        const int span = kv.element_span(e);
        std::vector<double> d0(3 * (p + 1)), dp(3 * (p + 1)), dm(3 * (p + 1));
        bspline_basis(kv, span, u, 2, d0.data());
        bspline_basis(kv, span, u + h, 2, dp.data());
        bspline_basis(kv, span, u - h, 2, dm.data());
        for (int j = 0; j <= p; ++j) {
          const double fd1 = (dp[j] - dm[j]) / (2 * h);
          EXPECT_NEAR(d0[p + 1 + j], fd1, 1e-6 * (1 + std::abs(fd1))) << "p=" << p;
          if (p >= 2) {
            const double fd2 = (dp[p + 1 + j] - dm[p + 1 + j]) / (2 * h);
            EXPECT_NEAR(d0[2 * (p + 1) + j], fd2, 1e-5 * (1 + std::abs(fd2))) << "p=" << p;
          }
        }
      }
    }
  }
}

TEST(BsplineBasis, PeriodicFunctionsArePeriodic) {
  const KnotVector kv = KnotVector::periodic_uniform(3, 6, 0.0, 1.0);
  EXPECT_EQ(kv.n_basis(), 6);
  for (double u : {0.03, 0.31, 0.77}) {
    // Value of folded function j at u and at u + period (evaluated with the wrapped coordinate) agree.
    const auto a = values_at(kv, u, 0);
    const auto b = values_at(kv, u + 1.0, 0);
    const int sa = kv.find_span(u), sb = kv.find_span(u + 1.0);
    for (int j = 0; j <= 3; ++j) {
      EXPECT_EQ(kv.fold(sa - 3 + j), kv.fold(sb - 3 + j));
      EXPECT_NEAR(a[j], b[j], 1e-15);
    }
  }
}

namespace {
// A 2D-parametric rational patch in 3D (a curved surface) with non-trivial weights, degrees 2 and 3.
Patch rational_surface() {
  const KnotVector k0 = KnotVector::open(2, {0, 0, 0, 0.3, 0.6, 1, 1, 1});
  const KnotVector k1 = KnotVector::open(3, {0, 0, 0, 0, 0.5, 1, 1, 1, 1});
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> w(0.5, 2.0), z(-0.3, 0.3);
  std::vector<Vec3> cps;
  std::vector<double> ws;
  for (int j = 0; j < k1.n_basis(); ++j)
    for (int i = 0; i < k0.n_basis(); ++i) {
      cps.emplace_back(i + 0.2 * z(rng), j + 0.2 * z(rng), z(rng));
      ws.push_back(w(rng));
    }
  return Patch({k0, k1}, 3, cps, ws);
}
}  // namespace

TEST(NurbsBasis, PartitionOfUnityAndDerivativesMatchFiniteDifferences) {
  const Patch patch = rational_surface();
  ASSERT_TRUE(patch.rational());
  const double h = 1e-6;
  BasisValues b0, bp, bm;
  for (double u : {0.1, 0.45, 0.8})
    for (double v : {0.2, 0.7}) {
      const Param xi{u, v, 0};
      const Index3 e = patch.find_element(xi);
      patch.basis(xi, 2, b0, &e);
      double sum = 0, dsum[2] = {0, 0};
      for (int k = 0; k < b0.n; ++k) sum += b0.value[k], dsum[0] += b0.d1[3 * k], dsum[1] += b0.d1[3 * k + 1];
      EXPECT_NEAR(sum, 1.0, 1e-14);
      EXPECT_NEAR(dsum[0], 0.0, 1e-12);
      EXPECT_NEAR(dsum[1], 0.0, 1e-12);
      for (int a = 0; a < 2; ++a) {
        Param xp = xi, xm = xi;
        xp[a] += h;
        xm[a] -= h;
        patch.basis(xp, 2, bp, &e);
        patch.basis(xm, 2, bm, &e);
        for (int k = 0; k < b0.n; ++k) {
          const double fd1 = (bp.value[k] - bm.value[k]) / (2 * h);
          EXPECT_NEAR(b0.d1[3 * k + a], fd1, 1e-7 * (1 + std::abs(fd1)));
          for (int c = 0; c < 2; ++c) {
            const double fd2 = (bp.d1[3 * k + c] - bm.d1[3 * k + c]) / (2 * h);
            EXPECT_NEAR(b0.d2[9 * k + 3 * a + c], fd2, 1e-6 * (1 + std::abs(fd2)));
          }
        }
      }
    }
}

TEST(NurbsMap, JacobianAndSecondDerivativesMatchFiniteDifferences) {
  const Patch patch = rational_surface();
  const double h = 1e-6;
  for (double u : {0.15, 0.5, 0.9})
    for (double v : {0.25, 0.6}) {
      const Param xi{u, v, 0};
      const Index3 e = patch.find_element(xi);
      BasisValues bv;
      MapValues m0, mp, mm;
      patch.basis(xi, 2, bv, &e);
      patch.map(bv, m0);
      for (int a = 0; a < 2; ++a) {
        Param xp = xi, xm = xi;
        xp[a] += h;
        xm[a] -= h;
        patch.basis(xp, 2, bv, &e);
        patch.map(bv, mp);
        patch.basis(xm, 2, bv, &e);
        patch.map(bv, mm);
        const Vec3 fd1 = (mp.x - mm.x) / (2 * h);
        EXPECT_LT((m0.dx.col(a) - fd1).norm(), 1e-7 * (1 + fd1.norm()));
        for (int i = 0; i < 3; ++i)
          for (int c = 0; c < 2; ++c) {
            const double fd2 = (mp.dx(i, c) - mm.dx(i, c)) / (2 * h);
            EXPECT_NEAR(m0.d2x[i](a, c), fd2, 1e-6 * (1 + std::abs(fd2)));
          }
      }
    }
}

TEST(KnotVector, GrevilleIdentityReproducesTheParameter) {
  for (const KnotVector& kv : {nonuniform_open(3), KnotVector::periodic_uniform(2, 5, 0.0, 2.0)}) {
    const auto tau = kv.greville_unwrapped();
    for (double s : {0.0, 0.13, 0.5, 0.999}) {
      const double u = kv.a() + s * (kv.b() - kv.a());
      const int span = kv.find_span(u), p = kv.degree();
      std::vector<double> d(p + 1);
      bspline_basis(kv, span, u, 0, d.data());
      double x = 0;
      for (int j = 0; j <= p; ++j) {
        const int jj = span - p + j;
        x += d[j] * (tau[kv.fold(jj)] + kv.wrap_count(jj) * kv.period());
      }
      EXPECT_NEAR(x, u, 1e-14);
    }
  }
}

TEST(KnotVector, FindElementIsTheLargestElementBeginningAtOrBeforeThePoint) {
  // find_element's guess for equal elements, checked against a scan, on equal and unequal elements, at the
  // breakpoints themselves, just either side of them, and beyond the ends (clamped; periodic: wrapped).
  const std::vector<KnotVector> vectors = {KnotVector::open_uniform(2, 64, -1.5e-3, 2.5e-3),
                                           KnotVector::open(2, {0, 0, 0, 0.1, 0.15, 0.7, 1, 1, 1}),
                                           KnotVector::periodic_uniform(3, 9, 0.0, 3.0)};
  for (const KnotVector& kv : vectors) {
    std::vector<double> us;
    for (int e = 0; e < kv.n_elements(); ++e)
      for (double u : {kv.element_begin(e), kv.element_end(e)})
        for (double f : {-1e-12, 0.0, 1e-12}) us.push_back(u + f * (kv.b() - kv.a()));
    for (int i = 0; i <= 1000; ++i) us.push_back(kv.a() + (kv.b() - kv.a()) * (1.2 * i / 1000.0 - 0.1));
    for (double u : us) {
      const double v = kv.normalize(u);
      int scan = 0;
      for (int e = 0; e < kv.n_elements(); ++e)
        if (kv.element_begin(e) <= v) scan = e;
      EXPECT_EQ(kv.find_element(u), scan) << "u " << u;
    }
  }
}

TEST(KnotVector, StructureAndInvalidInput) {
  const KnotVector kv = KnotVector::open_uniform(3, 4, 0.0, 1.0);
  EXPECT_EQ(kv.n_basis(), 7);
  EXPECT_EQ(kv.n_elements(), 4);
  EXPECT_EQ(kv.find_element(0.5), 2);
  EXPECT_EQ(kv.find_element(1.0), 3);
  EXPECT_EQ(kv.multiplicity(0.25), 1);
  const KnotVector c0 = KnotVector::open_uniform(3, 4, 0.0, 1.0, 0);
  EXPECT_EQ(c0.multiplicity(0.5), 3);
  EXPECT_EQ(c0.n_basis(), 13);
  const KnotVector per = KnotVector::periodic_uniform(2, 5);
  EXPECT_EQ(per.n_basis(), 5);
  EXPECT_EQ(per.n_elements(), 5);
  EXPECT_EQ(per.find_element(1.1), 0);  // wraps
  EXPECT_THROW(KnotVector::open_uniform(2, 0), std::invalid_argument);
  EXPECT_THROW(KnotVector::open_uniform(2, 3, 0.0, 1.0, 2), std::invalid_argument);  // continuity > p-1
  EXPECT_THROW(KnotVector::open(2, {0, 0, 1, 1, 1, 1}), std::invalid_argument);      // start multiplicity 2
  EXPECT_THROW(KnotVector::open(2, {0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1}),
               std::invalid_argument);  // discontinuous
  EXPECT_THROW(KnotVector::periodic_uniform(3, 2), std::invalid_argument);
}
