// The DARE and the Kalman filter (control/linear_quadratic.h) against independent truths: the scalar
// Riccati equation's closed form, the finite-horizon Riccati recursion run to its limit, and the
// normalised estimation error squared (NEES) of the filter on a simulated linear system, which for a
// consistent filter is χ²-distributed with n degrees of freedom.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>

#include "hydrojet_control/control/linear_quadratic.h"

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using hydrojet::control::KalmanFilter;
using hydrojet::control::lqr_gain;
using hydrojet::control::solve_dare;

MatrixXd scalar(double v) { return MatrixXd::Constant(1, 1, v); }

TEST(LinearQuadratic, ScalarDareMatchesTheClosedForm) {
  // b²P² + (r(1 − a²) − q b²) P − q r = 0, the positive root.
  const double cases[][4] = {{0.9, 0.5, 1.0, 0.1}, {1.2, 0.1, 2.0, 0.01}, {-0.5, 2.0, 0.3, 5.0}, {1.0, 1.0, 1.0, 1.0}};
  for (const auto& c : cases) {
    const double a = c[0], b = c[1], q = c[2], r = c[3];
    const double beta = r * (1 - a * a) - q * b * b;
    const double truth = (-beta + std::sqrt(beta * beta + 4 * b * b * q * r)) / (2 * b * b);
    MatrixXd P;
    ASSERT_TRUE(solve_dare(scalar(a), scalar(b), scalar(q), scalar(r), &P)) << a;
    EXPECT_NEAR(P(0, 0), truth, 1e-10 * truth) << a;
    const double k = lqr_gain(scalar(a), scalar(b), scalar(r), P)(0, 0);
    EXPECT_NEAR(k, a * b * truth / (r + b * b * truth), 1e-10) << a;
    EXPECT_LT(std::abs(a - b * k), 1.0) << a;  // the closed loop is stable
  }
  MatrixXd P;
  EXPECT_FALSE(solve_dare(scalar(2.0), scalar(0.0), scalar(1.0), scalar(1.0), &P));  // not stabilisable
  EXPECT_FALSE(solve_dare(scalar(0.5), scalar(1.0), scalar(1.0), scalar(0.0), &P));  // R not definite
}

TEST(LinearQuadratic, DareIsTheLimitOfTheRiccatiRecursion) {
  // A lightly damped oscillator in two axes (4 states), force inputs, 10 ms steps.
  const double w = 2 * M_PI * 3.3, z = 0.05, dt = 0.01;
  MatrixXd Ac = MatrixXd::Zero(4, 4), Bc = MatrixXd::Zero(4, 2);
  Ac.block(0, 2, 2, 2).setIdentity();
  Ac.block(2, 0, 2, 2) = -w * w * MatrixXd::Identity(2, 2);
  Ac.block(2, 2, 2, 2) = -2 * z * w * MatrixXd::Identity(2, 2);
  Bc.block(2, 0, 2, 2) = 100.0 * MatrixXd::Identity(2, 2);
  // Explicit Euler: mildly unstable open loop (|1 + iωΔt| > 1), which the LQR must stabilise.
  const MatrixXd A = MatrixXd::Identity(4, 4) + Ac * dt, B = dt * Bc;
  MatrixXd Q = MatrixXd::Identity(4, 4);
  Q(0, 0) = Q(1, 1) = 1e4;
  const MatrixXd R = 0.1 * MatrixXd::Identity(2, 2);
  MatrixXd P;
  ASSERT_TRUE(solve_dare(A, B, Q, R, &P));
  MatrixXd Pk = Q;
  for (int k = 0; k < 20000; ++k) {
    const MatrixXd BtP = B.transpose() * Pk;
    Pk = Q + A.transpose() * Pk * A - A.transpose() * Pk * B * (R + BtP * B).ldlt().solve(BtP * A);
  }
  EXPECT_LT((P - Pk).norm(), 1e-9 * Pk.norm());
  const MatrixXd K = lqr_gain(A, B, R, P);
  const Eigen::VectorXcd ev = (A - B * K).eigenvalues();
  EXPECT_LT(ev.cwiseAbs().maxCoeff(), 1.0);
}

TEST(LinearQuadratic, KalmanFilterIsConsistentNeesWithinChiSquareBounds) {
  // x = [position, velocity] of a damped oscillator driven by white acceleration noise; the
  // position is measured. N runs: at each step the mean NEES over the runs, times N, is χ²(2N).
  const double w = 2 * M_PI * 3.0, z = 0.2, dt = 0.01, qa = 4.0, sigma = 0.005;
  MatrixXd A(2, 2), G(2, 1), H(1, 2);
  A << 1.0, dt, -w * w * dt, 1.0 - 2 * z * w * dt;
  G << 0.5 * dt * dt, dt;
  H << 1.0, 0.0;
  const MatrixXd Q = G * qa * G.transpose(), R = scalar(sigma * sigma), B = MatrixXd::Zero(2, 0);
  const int runs = 200, steps = 150;
  std::mt19937 rng(11);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<double> nees(steps, 0.0);
  const MatrixXd P0 = Eigen::Vector2d(1e-4, 1e-2).asDiagonal();
  for (int r = 0; r < runs; ++r) {
    VectorXd x(2);
    x << 1e-2 * n01(rng), 1e-1 * n01(rng);  // drawn from the filter's prior
    KalmanFilter kf;
    kf.reset(VectorXd::Zero(2), P0);
    for (int k = 0; k < steps; ++k) {
      x = A * x + G * (std::sqrt(qa) * n01(rng));
      kf.predict(A, B, VectorXd(0), Q);
      ASSERT_TRUE(kf.update(H, R, H * x + VectorXd::Constant(1, sigma * n01(rng))));
      const VectorXd e = x - kf.state();
      nees[k] += e.dot(kf.covariance().ldlt().solve(e)) / runs;
    }
  }
  // Wilson–Hilferty: the χ²(k) quantile for the normal quantile u.
  auto chi2 = [](double k, double u) { return k * std::pow(1 - 2 / (9 * k) + u * std::sqrt(2 / (9 * k)), 3); };
  const double k = 2.0 * runs, lo = chi2(k, -2.807) / runs, hi = chi2(k, 2.807) / runs;  // 99.5 % two-sided
  int outside = 0;
  double mean = 0.0;
  for (int s = 0; s < steps; ++s) outside += nees[s] < lo || nees[s] > hi, mean += nees[s] / steps;
  std::printf("mean NEES %.3f (2 for a consistent filter); %d of %d steps outside [%.3f, %.3f]\n", mean, outside, steps,
              lo, hi);
  EXPECT_LE(outside, 4);  // 0.5 % of 150 expected outside: about 1
  EXPECT_NEAR(mean, 2.0, 0.1);
  // A filter that believes the tracker 10× better than it is: inconsistent, and the test sees it.
  KalmanFilter over;
  over.reset(VectorXd::Zero(2), P0);
  VectorXd x = VectorXd::Zero(2);
  double nees_over = 0.0;
  for (int s = 0; s < steps; ++s) {
    x = A * x + G * (std::sqrt(qa) * n01(rng));
    over.predict(A, B, VectorXd(0), Q * 0.01);
    over.update(H, R * 0.01, H * x + VectorXd::Constant(1, sigma * n01(rng)));
    const VectorXd e = x - over.state();
    nees_over += e.dot(over.covariance().ldlt().solve(e)) / steps;
  }
  EXPECT_GT(nees_over, hi);
  EXPECT_FALSE(over.update(H, R, VectorXd::Constant(1, std::nan(""))));
}

}  // namespace
