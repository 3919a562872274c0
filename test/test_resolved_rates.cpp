// The resolved-rates steps (resolved_rates.h): DirectionPd's correction (eqs. 17-18, the integral, the
// feedforward), input_step on the actuation Jacobian (eqs. 19-20), and round_allocation's common mode.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "hydrojet_control/actuation/allocation.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/control/modal_law.h"
#include "hydrojet_control/control/resolved_rates.h"
#include "hydrojet_control/rod/so3.h"
#include "controller_fixtures.h"
#include "test_helpers.h"

using namespace hydrojet;
using control::Vec3;
using test::dir;
using test::flow_gains;

// --- DirectionPd (eqs. 17-18) --------------------------------------------------------------------

namespace {

/// DirectionPd's terms alone: K_p, K_i, the feedforward's weight; no derivative.
control::PdOptions pd_terms(double kp, double ki, double feedforward) {
  control::PdOptions g;
  g.kp = kp;
  g.kd = 0.0;
  g.ki = ki;
  g.feedforward = feedforward;
  return g;
}

}  // namespace

// The feedforward is x_des's own motion per step (none on the priming step); K_i integrates.
TEST(DirectionPd, TheFeedforwardIsTheReferencesMotionAndTheIntegralAccumulates) {
  const control::PdOptions g = pd_terms(0.0, control::PdOptions().ki, 1.0);
  control::DirectionPd pd;
  Vec3 x = pd.correction(dir(0.0), dir(0.0), 0.01, g);  // primes: no motion known yet
  EXPECT_EQ(x.norm(), 0.0);
  x = pd.correction(dir(0.01), dir(0.01), 0.01, g);  // 0.01 rad about +y
  EXPECT_NEAR((x - Vec3(0.0, 0.01, 0.0)).norm(), 0.0, 1e-12);
  // K_i: the integral of a constant error e over n steps of dt adds K_i dt (n dt) e, bounded.
  control::PdOptions gi = pd_terms(0.0, 2.0, 0.0);
  gi.max_integral = 1.0;
  gi.fast_path_rate = 0.0;  // unscheduled: the still reference below gets the integral too
  control::DirectionPd pi;
  const Vec3 e(0.0, 0.02, 0.0);
  for (int n = 1; n <= 5; ++n) {
    x = pi.correction(dir(0.0), dir(0.02), 0.01, gi);
    EXPECT_NEAR((x - gi.ki * 0.01 * (n * 0.01) * e).norm(), 0.0, 1e-12) << n;
  }
}

// The integral's weight on the reference's speed v: w = v²/(v² + v₀²), 1 without v₀. A still
// reference gets none of it (the paper's law); a moving one gets w of the error per step; when the
// reference stops, the integral leaks at K_p.
TEST(DirectionPd, TheIntegralIsWeightedByTheReferenceSpeedAndLeaksWhenItStops) {
  EXPECT_EQ(control::fast_path_weight(0.0, 0.1), 0.0);
  EXPECT_DOUBLE_EQ(control::fast_path_weight(0.1, 0.1), 0.5);
  EXPECT_DOUBLE_EQ(control::fast_path_weight(0.3, 0.1), 0.9);
  EXPECT_EQ(control::fast_path_weight(0.0, 0.0), 1.0);
  control::PdOptions g = pd_terms(0.0, 2.0, 0.0);
  g.max_integral = 1.0;
  g.fast_path_rate = 0.1;
  const double dt = 0.01, e = 0.02;
  // Still: no integral at all.
  control::DirectionPd still;
  for (int n = 0; n < 5; ++n) EXPECT_EQ(still.correction(dir(0.0), dir(e), dt, g).norm(), 0.0) << n;
  // Moving at 0.3 rad/s (w = 0.9), the tip e behind: after the priming step, K_i dt Σ w e dt.
  control::DirectionPd moving;
  moving.correction(dir(-e), dir(0.0), dt, g);  // primes (v unknown: 0)
  Vec3 x;
  for (int n = 1; n <= 5; ++n) {
    const double a = 0.3 * dt * n;
    x = moving.correction(dir(a - e), dir(a), dt, g);
    EXPECT_NEAR(x.y(), g.ki * dt * (n * dt * 0.9 * e), 1e-9) << n;
  }
  // It stops: with K_p the integral leaks by (1 − K_p dt) per step (and K_p's own term adds K_p dt e).
  g.kp = 3.0;
  const double before = x.y() / (g.ki * dt);
  const double a = 0.3 * dt * 5;
  x = moving.correction(dir(a - e), dir(a), dt, g);
  EXPECT_NEAR(x.y(), g.kp * dt * e + g.ki * dt * before * (1.0 - g.kp * dt), 1e-9);
}

// Conditional integration (the integral's anti-windup at the inputs' bounds): along a held axis the
// error is not integrated where it would grow the integral that way, and is where it would shrink
// it; across the axis the integral accumulates as before. Holding nothing (zero) holds nothing.
TEST(DirectionPd, AHeldAxisIsNotIntegratedOutward) {
  control::PdOptions g = pd_terms(0.0, 2.0, 0.0);
  g.max_integral = 1.0;
  g.fast_path_rate = 0.0;  // unscheduled: every step integrates the whole error
  const double dt = 0.01;
  const Vec3 x_axis = Vec3::UnitX(), y_axis = Vec3::UnitY();
  // An error of 0.02 rad about +y (dir(a) turns about +y) and 0.01 about +x.
  auto err_dir = [](double about_x, double about_y) {
    return Vec3((Eigen::AngleAxisd(about_x, Vec3::UnitX()) * Eigen::AngleAxisd(about_y, Vec3::UnitY())) *
                Vec3::UnitZ());
  };
  const Vec3 desired = err_dir(0.01, 0.02);
  control::DirectionPd free_pd, held;
  Vec3 free_x, held_x;
  for (int n = 1; n <= 5; ++n) {
    free_x = free_pd.correction(Vec3::UnitZ(), desired, dt, g);
    held.hold_integral(3.0 * y_axis);  // any length: its direction counts
    held_x = held.correction(Vec3::UnitZ(), desired, dt, g);
  }
  const Vec3 e = control::rotation_between(Vec3::UnitZ(), desired);
  EXPECT_NEAR(free_x.y(), g.ki * dt * 5 * dt * e.y(), 1e-12);
  EXPECT_NEAR(held_x.y(), 0.0, 1e-15) << "not integrated along the held axis";
  EXPECT_NEAR(held_x.x(), free_x.x(), 1e-15) << "across it as before";
  // Held against the error's sign (the bounds took motion the other way): the error is integrated.
  control::DirectionPd against;
  for (int n = 1; n <= 5; ++n) {
    against.hold_integral(-y_axis);
    held_x = against.correction(Vec3::UnitZ(), desired, dt, g);
  }
  EXPECT_NEAR((held_x - free_x).norm(), 0.0, 1e-15);
  // Holding zero is holding nothing; reset() forgets a held axis.
  control::DirectionPd none;
  none.hold_integral(Vec3::Zero());
  EXPECT_NEAR((none.correction(Vec3::UnitZ(), desired, dt, g) - g.ki * dt * dt * e).norm(), 0.0, 1e-15);
  none.hold_integral(x_axis);
  none.reset();
  EXPECT_NEAR((none.correction(Vec3::UnitZ(), desired, dt, g) - g.ki * dt * dt * e).norm(), 0.0, 1e-15);
}

// A cycle without a correction (the controller held while the model did not converge, the reference on
// a path, which moves with time; Controller::hold skips only then): the reference's speed is its
// motion over both cycles, not over the last one (which would double it), and the
// feedforward carries the motion of both.
TEST(DirectionPd, AHeldCycleCountsInTheReferenceSpeed) {
  const control::PdOptions g = pd_terms(0.0, 0.0, 1.0);
  const double dt = 0.01, v = 0.2;
  control::DirectionPd pd;
  pd.skip(dt);  // before the first correction: nothing to carry
  pd.correction(dir(0.0), dir(0.0), dt, g);
  pd.correction(dir(v * dt), dir(v * dt), dt, g);
  EXPECT_NEAR(pd.speed(), v, 1e-9);
  pd.skip(dt);  // the held cycle; x_des moved on by v dt
  const Vec3 x = pd.correction(dir(3 * v * dt), dir(3 * v * dt), dt, g);
  EXPECT_NEAR(pd.speed(), v, 1e-9);
  EXPECT_NEAR(x.y(), 2 * v * dt, 1e-12);
  pd.correction(dir(4 * v * dt), dir(4 * v * dt), dt, g);  // the skip is spent
  EXPECT_NEAR(pd.speed(), v, 1e-9);
  pd.reset();
  pd.skip(dt);
  pd.correction(dir(0.0), dir(0.0), dt, g);
  pd.correction(dir(v * dt), dir(v * dt), dt, g);
  EXPECT_NEAR(pd.speed(), v, 1e-9);
}

// --- The step on the actuation Jacobian (eqs. 19-20) ----------------------------------------------

namespace {

/// The HydroJet model at rest-ish: its tip frame, C^b and the jets' J_q = C^b W at a tip force.
struct HydroJetLinearisation {
  control::Mat3 R;
  control::ActuatedModel::Linearisation lin;
  rod::InputVector lower, upper;
};

HydroJetLinearisation hydrojet_linearisation(const Eigen::Vector3d& q) {
  control::ActuatedModel m(config::make_controller_model(test::scene("hydrojet_0deg"), flow_gains()));
  EXPECT_TRUE(m.rod().tip_actuated_uniform());
  const rod::RodSolution sol = m.solve(q);
  EXPECT_TRUE(sol.converged);
  return {sol.tip_rotation, m.linearise(), m.lower(), m.upper()};
}

}  // namespace

// Away from the bounds, the tip force W q takes exactly eq. (19)'s step on the force block of C^b,
// δf = (MᵀM + μ²)⁻¹Mᵀ(x_cntr × d) with M = −d̂ R C^b_ω[:, f_x f_y], and q is eq. (20)'s allocation of
// the new force (the 27-set enumeration of allocation.h, an independent solver).
TEST(InputStep, OnTheHydroJetIsEquationNineteenThenTwenty) {
  const Eigen::Vector3d q0(0.05, 0.03, 0.02);
  const HydroJetLinearisation h = hydrojet_linearisation(q0);
  const actuation::JetMap jets(actuation::hydrojet_geometry());
  const Vec3 d = h.R.col(2);
  const Vec3 x_cntr(0.004, -0.003, 0.0005);
  control::InputStepOptions o;
  o.max_force_step = 1.0;  // no rate limit here
  const control::InputStep step = control::input_step(h.R, h.lin, x_cntr, q0, h.lower, h.upper, o);
  ASSERT_TRUE(step.ok) << step.message;
  const Eigen::Matrix<double, 3, 2> M = -so3::hat(d) * h.R * h.lin.body_compliance.block<3, 2>(3, 0);
  const Eigen::Vector2d df = (M.transpose() * M + o.damping * o.damping * Eigen::Matrix2d::Identity())
                                 .ldlt()
                                 .solve(M.transpose() * x_cntr.cross(d));
  const Eigen::Vector2d f = jets.planar() * q0 + df;
  const Eigen::Vector3d q = step.q;
  EXPECT_NEAR((jets.planar() * q - f).norm(), 0.0, 1e-7 * f.norm()) << "W q = f + δf (λ = 1e-6 moves it by ~λ)";
  const actuation::AllocationResult ref = actuation::allocate(jets.planar(), f, h.lower, h.upper, 0.0);
  ASSERT_TRUE(ref.ok);
  EXPECT_NEAR((q - ref.q).norm(), 0.0, 1e-6) << "the smallest jet forces for that force";
  EXPECT_LE(step.bound_cost, 1e-6);
  // No jet at its top: what the step loses is λ's pull on the jets' common mode through their lower
  // bounds (a few 1e-9 rad here), far under what the modal law holds.
  EXPECT_LT(step.lost.norm(), 0.01 * control::ModalLaw::kHeldLoss);
}

TEST(InputStep, StepAndMagnitudeAreLimitedInTipForce) {
  const Eigen::Vector3d q0(0.05, 0.03, 0.02);
  const HydroJetLinearisation h = hydrojet_linearisation(q0);
  const actuation::JetMap jets(actuation::hydrojet_geometry());
  const Vec3 x_cntr = 0.3 * h.R.col(0);  // a large turn about the tip x-axis (δf ≈ 0.045 N)
  control::InputStepOptions o;
  o.max_force_step = 0.01;  // 1 N/s · 10 ms
  const control::InputStep a = control::input_step(h.R, h.lin, x_cntr, q0, h.lower, h.upper, o);
  o.max_force_step = 10.0;
  const control::InputStep b = control::input_step(h.R, h.lin, x_cntr, q0, h.lower, h.upper, o);
  ASSERT_TRUE(a.ok && b.ok);
  const Eigen::Vector3d qa = a.q, qb = b.q;
  const Eigen::Vector2d fa = jets.planar() * (qa - q0), fb = jets.planar() * (qb - q0);
  EXPECT_NEAR(fa.norm(), 0.01, 1e-12) << "the step's tip-force change is cut to the limit";
  EXPECT_GT(fb.norm(), 0.02);
  EXPECT_NEAR(fa.normalized().dot(fb.normalized()), 1.0, 1e-9) << "along the unlimited step";
  // The magnitude: the force itself is scaled onto max_force, and every input stays in its bounds.
  o.max_force = 0.05;
  const control::InputStep c = control::input_step(h.R, h.lin, x_cntr, q0, h.lower, h.upper, o);
  ASSERT_TRUE(c.ok);
  const Eigen::Vector3d qc = c.q;
  EXPECT_NEAR((jets.planar() * qc).norm(), 0.05, 1e-12);
  EXPECT_TRUE((qc.array() >= -1e-15).all() && (qc.array() <= h.upper.array()).all());
}

TEST(InputStep, AtTheBoundsTheBestAllowedStepAndItsCost) {
  // Every jet at q_max but jet 1 at 0: a turn that needs more of jets 2 and 3 is out of reach.
  const Eigen::Vector3d q0(0.0, 0.224, 0.244);
  const HydroJetLinearisation h = hydrojet_linearisation(q0);
  const actuation::JetMap jets(actuation::hydrojet_geometry());
  const Vec3 d = h.R.col(2);
  const Eigen::Matrix<double, 3, 2> M = -so3::hat(d) * h.R * h.lin.body_compliance.block<3, 2>(3, 0);
  // The direction change that the force (jets 2 + 3 more) would cause.
  const Eigen::Vector2d push = jets.planar() * Eigen::Vector3d(0.0, 0.05, 0.05);
  const Vec3 dd = M * push;
  const Vec3 x_cntr = d.cross(dd);  // x_cntr × d = dd
  control::InputStepOptions o;
  o.max_force_step = 1.0;
  const control::InputStep s = control::input_step(h.R, h.lin, x_cntr, q0, h.lower, h.upper, o);
  ASSERT_TRUE(s.ok);
  const Eigen::Vector3d q = s.q;
  EXPECT_TRUE((q.array() >= -1e-15).all() && (q.array() <= h.upper.array() + 1e-15).all());
  EXPECT_GT(s.bound_cost, 1e-3) << "the bounds cost tip force";
  // No input vector in the box does better on the task (the objective is convex; compare with a grid).
  auto task = [&](const Eigen::Vector3d& qq) { return (M * (jets.planar() * (qq - q0)) - dd).norm(); };
  double best = 1e9;
  for (int i = 0; i <= 40; ++i)
    for (int j = 0; j <= 40; ++j)
      for (int k = 0; k <= 40; ++k) best = std::min(best, task(Eigen::Vector3d(i, j, k).cwiseProduct(h.upper) / 40.0));
  EXPECT_LE(task(q), best + 1e-4);
  // What the bounds took: the unbounded damped step of eq. (19) in closed form, δf = (MᵀM + μ²)⁻¹Mᵀ dd,
  // less what the bounded step's force change makes of the tip direction.
  const Eigen::Vector2d df =
      (M.transpose() * M + o.damping * o.damping * Eigen::Matrix2d::Identity()).ldlt().solve(M.transpose() * dd);
  const Vec3 lost = M * (df - jets.planar() * (q - q0));
  EXPECT_GT(lost.norm(), 0.1 * dd.norm());
  EXPECT_NEAR((s.lost - lost).norm(), 0.0, 1e-6 * lost.norm()) << s.lost.transpose() << " / " << lost.transpose();
}

// --- The rounded allocation ----------------------------------------------------------------------

// The HydroJet's common mode (allocation_smoothing) against eq. (24): the jets' planar forces P (2 × 3)
// and their moments d e_z × f cancel together along P's null vector, the cross product of its rows.
// J_q = C^b W has that null space and no other; two jets have none; a jet left out gets 0.
TEST(RoundedAllocation, TheJetsCommonModeMovesTheTipByNothing) {
  const HydroJetLinearisation h = hydrojet_linearisation(Eigen::Vector3d(0.05, 0.02, 0.0));
  const rod::InputVector jets = rod::InputVector::Ones(3);
  const rod::InputVector n = control::jet_common_mode(h.lin.actuation, jets);
  ASSERT_EQ(n.size(), 3);
  const actuation::JetMap map(*test::scene("hydrojet_0deg").jets);
  Eigen::Vector3d closed = map.planar().row(0).transpose().cross(map.planar().row(1).transpose());
  if (closed.sum() < 0.0) closed = -closed;
  closed /= closed.maxCoeff();
  EXPECT_LT((n - closed).norm(), 1e-9) << n.transpose() << " vs " << closed.transpose();
  EXPECT_GT(n.minCoeff(), 0.5);  // misaligned by 0.06–0.12 rad: near, not at, all equal
  EXPECT_LT((h.lin.actuation * n).norm(), 1e-9 * h.lin.actuation.norm());
  rod::InputVector two = jets;
  two[2] = 0.0;
  EXPECT_TRUE(control::jet_common_mode(h.lin.actuation, two).isZero());
}

// round_allocation: the log-sum-exp amount in closed form, blind to a common mode already in q (its
// excess), s log m with every jet on its bound; and on the HydroJet's jets (eq. 24), a tip force
// of 0.1 N turned once round the tip: the least-water allocation (one jet on its bound, what the
// box QP gives) has a corner each time the force passes a jet, a second difference of O(h) at step
// h; rounded, none (O(h²)), and the tip force is the same.
TEST(RoundedAllocation, TheLogSumExpAmountAndNoCornerWhereTheForcePassesAJet) {
  const double s = 0.035, a = 0.02, b = 0.07, d = 0.01;
  const rod::InputVector ones = rod::InputVector::Ones(3), zero = rod::InputVector::Zero(3);
  const rod::InputVector q = (rod::InputVector(3) << 0.0, a, b).finished();
  const control::AllocationRounding r = control::round_allocation(q, zero, ones, s);
  EXPECT_EQ(r.excess, 0.0);
  EXPECT_NEAR(r.amount, s * std::log(1.0 + std::exp(-a / s) + std::exp(-b / s)), 1e-15);
  const control::AllocationRounding shifted = control::round_allocation(q + d * ones, zero, ones, s);
  EXPECT_NEAR(shifted.excess, d, 1e-15);
  EXPECT_NEAR(shifted.amount, r.amount, 1e-15);
  EXPECT_NEAR(control::round_allocation(zero, zero, ones, s).amount, s * std::log(3.0), 1e-15);
  const control::AllocationRounding none = control::round_allocation(q + d * ones, zero, ones, 0.0);
  EXPECT_NEAR(none.excess, d, 1e-15);  // scale 0: no rounding, the least common mode
  EXPECT_EQ(none.amount, 0.0);

  const actuation::JetMap map(*test::scene("hydrojet_0deg").jets);
  const Eigen::Matrix<double, 2, 3> P = map.planar();
  Eigen::Vector3d n = P.row(0).transpose().cross(P.row(1).transpose());
  if (n.sum() < 0.0) n = -n;
  n /= n.maxCoeff();
  const Eigen::Matrix<double, 3, 2> pinv = P.transpose() * (P * P.transpose()).inverse();
  auto allocate = [&](double phi, bool round) {
    const Eigen::Vector2d F = 0.1 * Eigen::Vector2d(std::cos(phi), std::sin(phi));
    Eigen::Vector3d x = pinv * F;
    x -= (x.array() / n.array()).minCoeff() * n;  // least water: one jet at 0
    rod::InputVector q = x;
    if (round) q += control::round_allocation(q, zero, n, s).amount * n;
    EXPECT_LT((P * q - F).norm(), 1e-12);
    EXPECT_GE(q.minCoeff(), -1e-15);
    return q;
  };
  const double h = 1e-3;
  double hard = 0.0, rounded = 0.0;
  for (double phi = 0.0; phi < 2.0 * M_PI; phi += h) {
    hard = std::max(
        hard, (allocate(phi + h, false) - 2.0 * allocate(phi, false) + allocate(phi - h, false)).cwiseAbs().maxCoeff());
    rounded = std::max(
        rounded, (allocate(phi + h, true) - 2.0 * allocate(phi, true) + allocate(phi - h, true)).cwiseAbs().maxCoeff());
  }
  // A corner: h times the jump of slope, here (0.1 N) · O(1) per rad; smooth: h² max|q''|, q'' at
  // most (0.1 N)² / s + 0.1 N, a few 0.1 N/rad².
  EXPECT_GT(hard, 0.1 * h * 0.1);
  EXPECT_LT(rounded, h * h * 1.0);
  EXPECT_LT(rounded, 0.02 * hard);
}
