// The modal law's pieces (control/modal_law.h) against independent truths: the transition against
// the damped oscillator's closed-form response, the estimator against a general Kalman filter (the
// textbook equations below, in full matrices) run component by component, its rate estimate's errors against its own
// covariance on a simulated rod mode, and the shaping's inversion of the mode on a sinusoid.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <complex>
#include <random>

#include "hydrojet_control/control/controller_options.h"
#include "hydrojet_control/control/modal_law.h"

namespace {

using hydrojet::control::modal_shaping;
using hydrojet::control::modal_transition;
using hydrojet::control::ModalEstimator;
using hydrojet::control::ModalLawOptions;
using hydrojet::control::ReferenceMotion;
using Vec3 = Eigen::Vector3d;

/// The textbook Kalman filter in full matrices (predict; update in Joseph form with S solved by LDLT):
/// a second method for the estimator, which shares one covariance between the components.
class KalmanFilter {
 public:
  void reset(const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0) {
    x_ = x0;
    P_ = P0;
  }
  void predict(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::VectorXd& u, const Eigen::MatrixXd& Q) {
    x_ = A * x_ + B * u;
    P_ = A * P_ * A.transpose() + Q;
    P_ = 0.5 * (P_ + P_.transpose());
  }
  /// False (and no change) when z is not finite.
  bool update(const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, const Eigen::VectorXd& z) {
    if (!z.allFinite()) return false;
    const Eigen::MatrixXd S = H * P_ * H.transpose() + R;
    const Eigen::MatrixXd K = S.ldlt().solve(H * P_).transpose();  // P Hᵀ S⁻¹ (S, P symmetric)
    const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(P_.rows(), P_.cols()) - K * H;
    x_ += K * (z - H * x_);
    P_ = IKH * P_ * IKH.transpose() + K * R * K.transpose();
    return true;
  }
  const Eigen::VectorXd& state() const { return x_; }
  const Eigen::MatrixXd& covariance() const { return P_; }

 private:
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
};

TEST(ModalLaw, TheTransitionIsTheDampedOscillatorsClosedForm) {
  const double w = 19.0, zeta = 0.2, dt = 0.013;
  Eigen::Matrix3d A;
  Eigen::Vector3d B;
  modal_transition(w, zeta, dt, &A, &B);
  // Free response from y = 1, v = 0 over k steps; and the step response to s = 1 (from rest).
  const double wd = w * std::sqrt(1 - zeta * zeta);
  Eigen::Vector3d x(1, 0, 0), u = Eigen::Vector3d::Zero();
  for (int k = 1; k <= 40; ++k) {
    x = A * x;
    u = A * u + B;
    const double t = k * dt, e = std::exp(-zeta * w * t);
    const double free = e * (std::cos(wd * t) + zeta * w / wd * std::sin(wd * t));
    EXPECT_NEAR(x(0), free, 1e-12) << t;
    EXPECT_NEAR(x(1), -w * w / wd * e * std::sin(wd * t), 1e-10) << t;
    EXPECT_NEAR(u(0), 1.0 - free, 1e-12) << t;
  }
  EXPECT_EQ(x(2), 0.0);  // d is held
  EXPECT_NEAR(A(2, 2), 1.0, 1e-15);
}

TEST(ModalLaw, TheEstimatorIsTheKalmanFilterOnEachComponent) {
  ModalLawOptions o;
  const double w = 21.0, zeta = 0.25, dt = 0.01;
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  ModalEstimator e;
  const Vec3 z0(0.01, -0.02, 0.999), s0(0.0, 0.0, 1.0);
  e.start(z0, s0, w, o);
  Eigen::Matrix3d A;
  Eigen::Vector3d B;
  modal_transition(w, zeta, dt, &A, &B);
  const Eigen::MatrixXd Q =
      Eigen::Vector3d(0.0, o.velocity_noise * o.velocity_noise * dt, o.disturbance_noise * o.disturbance_noise * dt)
          .asDiagonal();
  const Eigen::MatrixXd H = Eigen::RowVector3d(1, 0, 0),
                        R = Eigen::MatrixXd::Constant(1, 1, o.tracker_sigma * o.tracker_sigma);
  KalmanFilter k[3];
  for (int c = 0; c < 3; ++c) k[c].reset(Eigen::Vector3d(z0(c), 0.0, z0(c) - s0(c)), e.covariance());
  for (int step = 0; step < 200; ++step) {
    const Vec3 s(0.1 * std::sin(0.05 * step), 0.05 * n(rng), 1.0), z = Vec3(n(rng), n(rng), n(rng)) * 0.01 + s;
    e.step(s, z, w, zeta, dt, o);
    for (int c = 0; c < 3; ++c) {
      k[c].predict(A, B, Eigen::VectorXd::Constant(1, s(c)), Q);
      ASSERT_TRUE(k[c].update(H, R, Eigen::VectorXd::Constant(1, z(c))));
      EXPECT_NEAR((k[c].state() - e.state().col(c)).norm(), 0.0, 1e-12) << step << " " << c;
    }
    EXPECT_NEAR((k[0].covariance() - e.covariance()).norm(), 0.0, 1e-12) << step;
  }
}

TEST(ModalLaw, TheRateEstimateIsConsistentOnASimulatedMode) {
  // The truth: the mode driven by a random s, with the process noise the filter assumes, a slowly
  // wandering d, and tracker noise σ. Normalised squared errors of (y, v, d) over many steps: mean 3
  // per component for a consistent filter (χ² with 3 degrees of freedom); the rate alone: mean 1.
  ModalLawOptions o;
  const double w = 20.0, zeta = 0.3, dt = 0.01;
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Matrix3d A;
  Eigen::Vector3d B;
  modal_transition(w, zeta, dt, &A, &B);
  // Process noise enters the discrete state as the filter models it (diagonal, per step).
  const double qv = o.velocity_noise * std::sqrt(dt), qd = o.disturbance_noise * std::sqrt(dt);
  Eigen::Vector3d x(0.0, 0.0, 0.02);
  ModalEstimator e;
  e.start(Vec3(x(0) + o.tracker_sigma * n(rng), 0, 0), Vec3(0, 0, 0), w, o);
  // Start the truth inside the filter's initial uncertainty.
  x(2) = e.model_error()(0) + 0.0;
  double nees = 0.0, rate = 0.0;
  int count = 0;
  for (int k = 0; k < 4000; ++k) {
    const double s = 0.1 * std::sin(0.7 * k * dt) + 0.02 * n(rng);
    x = A * x + B * s + Eigen::Vector3d(0.0, qv * n(rng), qd * n(rng));
    const double z = x(0) + o.tracker_sigma * n(rng);
    e.step(Vec3(s, 0, 0), Vec3(z, 0, 0), w, zeta, dt, o);
    if (k < 200) continue;  // the start's transient
    const Eigen::Vector3d err = x - e.state().col(0);
    nees += err.dot(e.covariance().ldlt().solve(err));
    rate += err(1) * err(1) / e.covariance()(1, 1);
    ++count;
  }
  nees /= count, rate /= count;
  // 3800 correlated samples: the means within ±15 % of 3 and 1.
  EXPECT_NEAR(nees, 3.0, 0.45);
  EXPECT_NEAR(rate, 1.0, 0.15);
}

TEST(ModalLaw, TheShapingInvertsTheModeAndTheActuatorLagOnASinusoid) {
  // s drives a first-order lag τ_a (the flow loop), whose output drives the mode. With
  // s = r + m_ff (the shaping without feedback) the steady state follows r but for the τ_a r⃛/ω² term
  // the shaping leaves out; with s = r it lags by the cascade's phase. Both against the closed form
  // on H(jW) = 1 / ((1 + jWτ_a)(1 − (W/ω)² + 2jζW/ω)).
  const double w = 20.0, zeta = 0.3, dt = 0.001, W = 4.0;
  for (const double tau : {0.0, 0.03, 0.06}) {
    ModalLawOptions o;
    o.damping_gain = 0.0;
    o.actuator_lag = tau;
    Eigen::Matrix3d A;
    Eigen::Vector3d B;
    modal_transition(w, zeta, dt, &A, &B);
    const double lag = tau > 0.0 ? std::exp(-dt / tau) : 0.0;  // exact over a step with s held
    Eigen::Vector3d shaped = Eigen::Vector3d::Zero(), plain = Eigen::Vector3d::Zero();
    double u_shaped = 0.0, u_plain = 0.0, err_shaped = 0.0, err_plain = 0.0;
    for (int k = 0; k < 6000; ++k) {
      const double t = k * dt, mid = t + dt / 2;  // s is held over [t, t + dt]
      ReferenceMotion r;
      r.rate = Vec3(W * std::cos(W * mid), 0, 0);
      r.accel = Vec3(-W * W * std::sin(W * mid), 0, 0);
      const double ref = std::sin(W * mid);
      const double s = ref + modal_shaping(r, Vec3::Zero(), w, zeta, o)(0);
      // The mode sees the lag's output held over the step (its mean over the step, to first order).
      const double u_shaped_next = lag * u_shaped + (1 - lag) * s, u_plain_next = lag * u_plain + (1 - lag) * ref;
      shaped = A * shaped + B * (tau > 0.0 ? 0.5 * (u_shaped + u_shaped_next) : s);
      plain = A * plain + B * (tau > 0.0 ? 0.5 * (u_plain + u_plain_next) : ref);
      u_shaped = u_shaped_next;
      u_plain = u_plain_next;
      if (t > 3.0) {
        const double truth = std::sin(W * (t + dt));
        err_shaped = std::max(err_shaped, std::abs(shaped(0) - truth));
        err_plain = std::max(err_plain, std::abs(plain(0) - truth));
      }
    }
    const std::complex<double> jW(0.0, W);
    const std::complex<double> H = 1.0 / ((1.0 + jW * tau) * (1.0 + 2.0 * zeta * jW / w + jW * jW / (w * w)));
    const double plain_truth = std::abs(1.0 - H);                            // 0.1307 at τ_a = 0
    const double shaped_truth = std::abs(H * tau * jW * jW * jW) / (w * w);  // the r⃛ term left out
    std::printf(
        "tau_a %.2f s: error unshaped %.6f (closed form %.6f, off %.1e), shaped %.6f (closed form %.6f, off %.1e)\n",
        tau, err_plain, plain_truth, std::abs(err_plain - plain_truth), err_shaped, shaped_truth,
        std::abs(err_shaped - shaped_truth));
    // Within 2e-5 (measured at most 1.1e-5: the lag's output averaged over a held step is exact to
    // first order only, an error of order (dt/τ_a)² of the lagged motion).
    EXPECT_NEAR(err_plain, plain_truth, 2e-5) << "tau " << tau;
    EXPECT_NEAR(err_shaped, shaped_truth, 2e-5) << "tau " << tau;
    if (tau == 0.0) {
      EXPECT_NEAR(plain_truth, 0.1307, 1e-4);
    } else {
      EXPECT_LT(err_shaped, 0.1 * err_plain) << "tau " << tau;
    }
  }
}

// A latency keeps the crossover's phase lag (k_p times the loop's delay) and the PI zero's place
// under the crossover (k_i / k_p²) of the latency-free tuning; none leaves the gains as they are.
TEST(ModalLaw, TheGainsKeepTheCrossoversPhaseLagUnderLatency) {
  ModalLawOptions o;
  const double T = 0.01, own = T + o.actuator_lag;
  const auto none = hydrojet::control::modal_gains(o, T, 0.0);
  EXPECT_DOUBLE_EQ(none.kp, o.kp);
  EXPECT_DOUBLE_EQ(none.ki, o.ki);
  for (double latency : {0.01, 0.02, 0.03, 0.1}) {
    const auto g = hydrojet::control::modal_gains(o, T, latency);
    EXPECT_NEAR(g.kp * (own + latency), o.kp * own, 1e-12) << latency;
    EXPECT_NEAR(g.ki / (g.kp * g.kp), o.ki / (o.kp * o.kp), 1e-12) << latency;
    EXPECT_LT(g.kp, none.kp);
  }
  EXPECT_DOUBLE_EQ(hydrojet::control::modal_gains(o, T, -1.0).kp, o.kp);  // no latency below zero
  // A flow loop slower than the tuning's actuator_lag adds its excess to the delay; a faster one, none.
  for (double flow_lag : {0.06, 0.09}) {
    const auto g = hydrojet::control::modal_gains(o, T, 0.02, flow_lag);
    EXPECT_NEAR(g.kp * (T + flow_lag + 0.02), o.kp * own, 1e-12) << flow_lag;
    EXPECT_NEAR(g.ki / (g.kp * g.kp), o.ki / (o.kp * o.kp), 1e-12) << flow_lag;
  }
  EXPECT_DOUBLE_EQ(hydrojet::control::modal_gains(o, T, 0.0, 0.5 * o.actuator_lag).kp, o.kp);
}

// The ratio that scales the PD's gains (and, squared, the damping gain): the tuning's delay over
// the loop's, 1 without latency or a slower flow loop.
TEST(ModalLaw, TheLagRatioIsTheTuningsDelayOverTheLoops) {
  ModalLawOptions o;
  const double T = 0.01, own = T + o.actuator_lag;
  EXPECT_DOUBLE_EQ(hydrojet::control::lag_ratio(o, T, 0.0, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(hydrojet::control::lag_ratio(o, T, 0.03, 0.08), own / (T + 0.08 + 0.03));
  for (double latency : {0.0, 0.02, 0.03})
    EXPECT_NEAR(hydrojet::control::lag_ratio(o, T, latency, 0.06) * o.kp,
                hydrojet::control::modal_gains(o, T, latency, 0.06).kp, 1e-12);
}

// The flow loop's lag: the valve's, shortened by the regulator's proportional loop gain and its lead.
TEST(ModalLaw, TheFlowLoopsLagIsTheValvesUnderItsRegulator) {
  hydrojet::actuation::FlowRegulatorOptions flow;
  flow.kp = 18750.0, flow.feedforward = 62500.0, flow.lead_time = 0.01;  // loop gain 0.3
  EXPECT_NEAR(hydrojet::control::flow_loop_lag(0.065, flow), 0.065 / 1.3 - 0.01, 1e-15);
  flow.feedforward = 0.0;  // no feedforward: no loop gain known
  EXPECT_NEAR(hydrojet::control::flow_loop_lag(0.065, flow), 0.055, 1e-15);
  EXPECT_EQ(hydrojet::control::flow_loop_lag(0.005, flow), 0.0);  // a lead longer than the lag
}

// The schedule moves from the paper's gains toward the modal law's, and never below the paper's.
TEST(ModalLaw, TheScheduledGainsNeverFallBelowThePapers) {
  hydrojet::control::PdOptions pd, top;
  pd.kp = 3.0, pd.ki = 6.0;
  top.kp = 5.0, top.ki = 12.0;
  auto g = hydrojet::control::scheduled_gains(pd, top, 0.5);
  EXPECT_DOUBLE_EQ(g.kp, 4.0);
  EXPECT_DOUBLE_EQ(g.ki, 9.0);
  top.kp = 2.5, top.ki = 3.9;  // the modal law's gains at 30 ms of latency: below the paper's
  g = hydrojet::control::scheduled_gains(pd, top, 1.0);
  EXPECT_DOUBLE_EQ(g.kp, pd.kp);
  EXPECT_DOUBLE_EQ(g.ki, pd.ki);
  top.kp = 4.0;  // one above, one below
  g = hydrojet::control::scheduled_gains(pd, top, 1.0);
  EXPECT_DOUBLE_EQ(g.kp, 4.0);
  EXPECT_DOUBLE_EQ(g.ki, pd.ki);
}

TEST(ModalLaw, TheDampingGainOpposesTheEstimatedRateRelativeToThePath) {
  ModalLawOptions o;
  o.damping_gain = 0.5;
  ReferenceMotion r;
  r.rate_now = Vec3(0.2, 0, 0);
  const Vec3 m = modal_shaping(r, Vec3(0.6, -0.1, 0), 20.0, 0.0, o);
  EXPECT_NEAR(m(0), -0.5 * 0.4 / 20.0, 1e-15);
  EXPECT_NEAR(m(1), 0.5 * 0.1 / 20.0, 1e-15);
  hydrojet::control::ControllerOptions c;
  EXPECT_TRUE(c.validate().empty());
  c.modal.damping_gain = -1;
  EXPECT_NE(c.validate().find("modal/damping_gain"), std::string::npos);
}

}  // namespace
