#pragma once
// How the tests compare floating-point numbers: the policy, and the one helper every test uses for it.
//
// 1. Exact equality (EXPECT_EQ on doubles) only where both numbers come out of the same operations in the
//    same order, in one build on one machine: a restart that replays the same steps, a run started again from
//    its own options.yaml, a value read back from a file written with full precision, a cached result against
//    its recomputation by the same function. Those agree to the bit whatever BLAS kernels run, because both
//    sides run the same kernels.
// 2. Two different code paths (two formulas of one law, single- against double-precision LU, 1 against 2
//    ranks, a fast path against the general one) never compare with ==: the order of the floating-point
//    operations differs, and so does the result's last bits, and by more where the BLAS kernels differ
//    (OpenBLAS picks its kernels per CPU: Haswell's and AVX-512's sum in other orders). They compare with
//    `agree(a, b, rel, floor)`, |a - b| <= rel * max(|a|, |b|, floor), and the tolerance is stated beside the
//    assertion from the operations between the two:
//      - a closed formula of n operations: a few n * eps (eps = 2.2e-16), e.g. 1e-14 for a material's stress;
//      - a quantity behind a linear solve: eps times the condition number of the operator (a fluid Jacobian
//        on the test meshes: 1e6-1e8, so 1e-9 to 1e-8 relative);
//      - a quantity behind an iteration stopped at a tolerance tol (the coupling loop, an FGMRES to rtol): a
//        few tol, unless both paths iterate alike from identical data, when the solve's round-off above
//        applies.
//    Iteration counts of two paths may differ by one where a residual ends near its tolerance; tests that
//    assert equal counts say why the margin is wide.
// 3. Against exact or published values: the method's error (a rate's margin, the paper's digits), stated.
// The whole suite passes with OpenBLAS's own kernel choice and with forced Haswell kernels:
// `env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE ctest ...` against the plain environment (tests/README.md).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>

namespace cellfsi_test {

/// Round-off unit of double precision.
inline constexpr double kEps = 2.220446049250313e-16;

/// |a - b| <= rel * max(|a|, |b|, floor): two code paths' results agree to a relative tolerance (floor: the
/// scale below which the tolerance is absolute, rel * floor, for quantities that can vanish).
inline ::testing::AssertionResult agree(double a, double b, double rel, double floor = 0.0) {
  const double scale = std::max({std::abs(a), std::abs(b), floor});
  if (std::isfinite(a) && std::isfinite(b) && std::abs(a - b) <= rel * scale)
    return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << a << " and " << b << " differ by " << std::abs(a - b)
                                       << ", more than " << rel << " relative (scale " << scale << ")";
}

/// The same for optional values (a metric read from summary.json): both present, and agreeing.
inline ::testing::AssertionResult agree(const std::optional<double>& a, const std::optional<double>& b,
                                        double rel, double floor = 0.0) {
  if (!a || !b) return ::testing::AssertionFailure() << "a value is missing";
  return agree(*a, *b, rel, floor);
}

}  // namespace cellfsi_test
