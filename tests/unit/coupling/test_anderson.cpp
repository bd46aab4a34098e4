// Anderson acceleration of a fixed-point iteration (coupling/anderson.hpp): on a linear map x = M x + b of
// dimension n it is a Krylov method, exact after at most n + 1 updates with n columns, where the plain
// iteration x <- x - dx only contracts by rho(M) per update; columns kept from earlier "steps" (the same map)
// make the first iterate of the next one already exact.
#include <gtest/gtest.h>
#include <petscvec.h>

#include <Eigen/Dense>
#include <random>

#include "coupling/anderson.hpp"

using cellfsi::coupling::AndersonAcceleration;

namespace {

struct LinearMap {
  Eigen::MatrixXd M;
  Eigen::VectorXd b;
  // The correction dx with G(x) = M x + b = x - dx.
  Eigen::VectorXd correction(const Eigen::VectorXd& x) const { return x - (M * x + b); }
  Eigen::VectorXd fixed_point() const {
    return (Eigen::MatrixXd::Identity(M.rows(), M.cols()) - M).partialPivLu().solve(b);
  }
};

LinearMap make_map(int n, double rho, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(-1, 1);
  LinearMap m{Eigen::MatrixXd(n, n), Eigen::VectorXd(n)};
  for (int i = 0; i < n; ++i) {
    m.b[i] = uni(rng);
    for (int j = 0; j < n; ++j) m.M(i, j) = uni(rng);
  }
  // Non-normal, with spectral radius rho: the plain iteration needs ~log(1e-10) / log(rho) updates.
  const double r = m.M.eigenvalues().cwiseAbs().maxCoeff();
  m.M *= rho / r;
  return m;
}

void to_vec(const Eigen::VectorXd& e, Vec v) {
  PetscScalar* a = nullptr;
  VecGetArray(v, &a);
  for (int i = 0; i < e.size(); ++i) a[i] = e[i];
  VecRestoreArray(v, &a);
}
Eigen::VectorXd from_vec(Vec v) {
  PetscInt n = 0;
  VecGetSize(v, &n);
  const PetscScalar* a = nullptr;
  VecGetArrayRead(v, &a);
  Eigen::VectorXd e(n);
  for (int i = 0; i < n; ++i) e[i] = a[i];
  VecRestoreArrayRead(v, &a);
  return e;
}

// Runs `updates` iterations from x0; returns the error |x - x*| / |x*| after each.
std::vector<double> iterate(const LinearMap& m, AndersonAcceleration* acc, Vec x, Vec dx, int updates) {
  const Eigen::VectorXd xs = m.fixed_point();
  std::vector<double> err;
  for (int k = 0; k < updates; ++k) {
    const Eigen::VectorXd xe = from_vec(x);
    to_vec(m.correction(xe), dx);
    if (acc) {
      acc->update(x, dx);
    } else {
      VecAXPY(x, -1.0, dx);
    }
    err.push_back((from_vec(x) - xs).norm() / xs.norm());
  }
  return err;
}

}  // namespace

TEST(AndersonAcceleration, SolvesALinearFixedPointProblemInDimensionPlusOneUpdates) {
  const int n = 12;  // 4 nodes of 3 unknowns (u, v, p), with the pressure scaled 1000x like cgs units
  for (int block : {1, 3}) {
    LinearMap m = make_map(n, 0.9, 5 + block);
    if (block == 3)
      for (int i = 2; i < n; i += 3) m.b[i] *= 1000.0;
    Vec x, dx;
    VecCreateSeq(PETSC_COMM_SELF, n, &x);
    VecDuplicate(x, &dx);
    VecSet(x, 0.0);
    const std::vector<double> plain = iterate(m, nullptr, x, dx, n + 2);
    VecSet(x, 0.0);
    AndersonAcceleration acc(x, block, n, 0);
    acc.begin_step();
    const std::vector<double> fast = iterate(m, &acc, x, dx, n + 2);
    std::printf("  block %d: error after %d updates: plain %.2e, Anderson %.2e (%d columns)\n", block, n + 2,
                plain.back(), fast.back(), acc.columns_used());
    EXPECT_GT(plain.back(), 1e-2);
    EXPECT_LT(fast.back(), 1e-9);
    EXPECT_EQ(acc.columns_used(), n);
    VecDestroy(&x);
    VecDestroy(&dx);
  }
}

TEST(AndersonAcceleration, ColumnsKeptFromEarlierStepsDescribeTheMapFromTheFirstUpdate) {
  const int n = 6;
  const LinearMap m = make_map(n, 0.8, 11);
  Vec x, dx;
  VecCreateSeq(PETSC_COMM_SELF, n, &x);
  VecDuplicate(x, &dx);
  for (int reuse : {0, 1}) {
    AndersonAcceleration acc(x, 1, n + 2, reuse);
    VecSet(x, 0.0);
    acc.begin_step();
    iterate(m, &acc, x, dx, n + 2);  // step 1: n + 1 columns describe M completely
    VecSet(x, 1.0);                  // step 2 from elsewhere
    acc.begin_step();
    const std::vector<double> second = iterate(m, &acc, x, dx, 2);
    std::printf("  reuse %d: second step's error after 2 updates %.2e\n", reuse, second.back());
    if (reuse == 0)
      EXPECT_GT(second.back(), 1e-3);  // a fresh start: one column only
    else
      EXPECT_LT(second.back(), 1e-9);  // the kept columns: exact at the second update (the first forms none)
  }
  // reset() forgets them.
  AndersonAcceleration acc(x, 1, n + 2, 5);
  VecSet(x, 0.0);
  acc.begin_step();
  iterate(m, &acc, x, dx, n + 2);
  acc.reset();
  EXPECT_EQ(acc.columns_used(), 0);
  VecDestroy(&x);
  VecDestroy(&dx);
}

TEST(AndersonAcceleration, RejectsInvalidSettings) {
  Vec x;
  VecCreateSeq(PETSC_COMM_SELF, 4, &x);
  EXPECT_THROW(AndersonAcceleration(x, 0, 3, 0), std::invalid_argument);
  EXPECT_THROW(AndersonAcceleration(x, 1, 0, 0), std::invalid_argument);
  EXPECT_THROW(AndersonAcceleration(x, 1, 3, -1), std::invalid_argument);
  VecDestroy(&x);
}
