// The PD resolved-rates controller (Algorithm 1) with the quasi-static rod model as the plant, no
// ROS: convergence on static targets in closed and open loop, the value of feedback under model
// mismatch, every safety trigger, the force limiter, and the options (defaults = config/controller.yaml,
// ranges of cfg/Controller.cfg).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/actuation/allocation.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/rod/so3.h"
#include "test_helpers.h"

using namespace hydrojet;
using control::Controller;
using control::ControllerInputs;
using control::ControllerOutput;
using control::ControllerState;
using control::Vec3;

namespace {

constexpr double kDt = 0.01;             // 100 Hz
constexpr double kFlowPerDuty = 1.6e-5;  // plant valve: full duty gives 1.6e-5 m^3/s

actuation::FlowRegulatorOptions flow_gains() {
  actuation::FlowRegulatorOptions p;
  p.feedforward = 1.0 / kFlowPerDuty;
  p.kp = 0.3 / kFlowPerDuty;
  p.ki = 5.0 / kFlowPerDuty;
  return p;
}

/// Quasi-static plant: valves set flows instantly, flows set jet forces by eq. (26), the rod
/// settles at once. Its rod may differ from the controller's model.
struct StaticPlant {
  rod::RodSolver rod;
  actuation::JetMap jets;
  actuation::Nozzle nozzle;
  Vec3 flows = Vec3::Zero();
  control::Mat3 tip = control::Mat3::Identity();
  int stuck_jet = -1;       ///< fault injection: this jet's flow is stuck_flow whatever the valve
  double stuck_flow = 0.0;  ///< [m^3/s]

  StaticPlant(const config::Scene& sc, const rod::RodModel& truth)
      : rod(truth, sc.solver), jets(*sc.jets), nozzle(sc.nozzle) {
    apply(Vec3::Zero());
  }
  void apply(const Vec3& duty) {
    flows = duty.cwiseMax(0.0).cwiseMin(1.0) * kFlowPerDuty;
    if (stuck_jet >= 0) flows[stuck_jet] = stuck_flow;
    Vec3 q;
    for (int i = 0; i < 3; ++i) q[i] = actuation::force_from_flow(flows[i], nozzle);
    rod::TipWrench w;
    w.force = jets.wrench(q).head<3>();
    const rod::RodSolution s = rod.solve(w);
    ASSERT_TRUE(s.converged);
    tip = s.tip_rotation;
  }
  ControllerInputs inputs(double t) const {
    ControllerInputs in;
    in.t = t;
    in.tip_valid = in.flow_valid = true;
    in.tip_stamp = in.flow_stamp = t;
    in.tip_rotation = tip;
    in.flows = flows;
    return in;
  }
};

/// The gains these tests were tuned with (K_p 4/s, K_d 0.2; config/controller.yaml has 3/s, 0).
control::ControllerOptions tuned_gains() {
  control::ControllerOptions p;
  p.kp = 4.0;
  p.kd = 0.2;
  return p;
}

control::ControllerOptions static_target(double theta, double phi) {
  control::ControllerOptions p = tuned_gains();
  p.path.theta_start = p.path.theta_end = theta;
  p.path.phi_start = p.path.phi_end = phi;
  p.path.duration = 1000.0;
  return p;
}

/// Runs `seconds` of control; returns the last output.
ControllerOutput run(Controller& c, StaticPlant& plant, double t0, double seconds) {
  ControllerOutput out;
  const int n = static_cast<int>(std::lround(seconds / kDt));
  for (int k = 0; k < n; ++k) {
    out = c.update(plant.inputs(t0 + k * kDt));
    plant.apply(out.valve_command);
    if (out.state == ControllerState::kAborted) break;
  }
  return out;
}

}  // namespace

// With an exact model both loops reach static targets across the workspace.
TEST(Controller, ConvergesOnStaticTargetsClosedAndOpenLoop) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const config::Scene sc = test::scene(name);
    for (control::LoopMode mode : {control::LoopMode::kClosed, control::LoopMode::kOpen}) {
      for (const auto& target : {std::make_pair(0.4, 0.5), std::make_pair(0.9, 2.5), std::make_pair(0.2, -2.0)}) {
        control::ControllerOptions p = static_target(target.first, target.second);
        p.mode = mode;
        Controller c(config::make_controller_model(sc, flow_gains()), p);
        StaticPlant plant(sc, test::bare(sc));
        c.start(0.0);
        const ControllerOutput out = run(c, plant, 0.0, 8.0);
        ASSERT_EQ(out.state, ControllerState::kRunning) << out.reason;
        EXPECT_LT(out.error_geodesic, 1e-3)
            << name << " " << control::to_string(mode) << " target " << target.first << "," << target.second;
        EXPECT_NEAR(control::bend_angle(plant.tip.col(2)), target.first, 1e-3);
      }
    }
  }
}

// Model mismatch (plant 25 % stiffer, precurvature off): closed loop still converges, open loop
// keeps the model's error — the paper's case for pose feedback.
TEST(Controller, FeedbackRemovesModelMismatch) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  rod::RodModel truth = test::bare(sc);
  truth.segments[0].stiffness *= 1.25;
  truth.segments[0].precurvature *= 0.0;
  double err[2];
  for (int m = 0; m < 2; ++m) {
    control::ControllerOptions p = static_target(0.7, 1.0);
    p.mode = m == 0 ? control::LoopMode::kClosed : control::LoopMode::kOpen;
    Controller c(config::make_controller_model(sc, flow_gains()), p);
    StaticPlant plant(sc, truth);
    c.start(0.0);
    const ControllerOutput out = run(c, plant, 0.0, 8.0);
    ASSERT_EQ(out.state, ControllerState::kRunning) << out.reason;
    err[m] = out.error_geodesic;
  }
  EXPECT_LT(err[0], 1e-3);
  EXPECT_GT(err[1], 0.05);
}

// The spiral of eq. (28), shortened: the closed loop follows it with a small error.
TEST(Controller, FollowsShortenedSpiral) {
  const config::Scene sc = test::scene("hydrojet_30deg");
  control::ControllerOptions p = tuned_gains();
  p.path.duration = 60.0;
  p.path.theta_end = 1.04;
  p.path.phi_end = 14.0;
  Controller c(config::make_controller_model(sc, flow_gains()), p);
  StaticPlant plant(sc, test::bare(sc));
  c.start(0.0);
  double sum2 = 0.0;
  int n = 0;
  for (int k = 0; k <= 6000; ++k) {
    const ControllerOutput out = c.update(plant.inputs(k * kDt));
    ASSERT_NE(out.state, ControllerState::kAborted) << out.reason << " at " << k * kDt;
    plant.apply(out.valve_command);
    if (k * kDt > 5.0) {
      sum2 += out.error_geodesic * out.error_geodesic;
      ++n;
    }
  }
  EXPECT_LT(std::sqrt(sum2 / n), 0.02);
  EXPECT_EQ(c.state(), ControllerState::kFinished);
}

// --- Reference and operator sources -------------------------------------------------------------

// A new target is not a step: the reference moves along the great circle at most max_angular_rate.
TEST(Reference, MovesTowardANewTargetAlongTheGreatCircleAtTheRateLimit) {
  control::Reference ref(0.2, nullptr, nullptr);
  ref.hold();
  ref.start(Vec3::UnitZ(), 0.0);
  const Vec3 target = control::direction(0.4, 0.0);
  ref.aim(2.0 * target, control::Source::kDirection);  // not unit: normalised
  Vec3 prev = ref.direction();
  for (int k = 1; k <= 250; ++k) {
    const Vec3 d = ref.advance(k * kDt, kDt, control::Mat3::Identity());
    EXPECT_LE(control::geodesic_error(prev, d), 0.2 * kDt + 1e-12) << k;
    EXPECT_NEAR(d.y(), 0.0, 1e-12);  // on the great circle through z and the target
    EXPECT_NEAR(d.norm(), 1.0, 1e-12);
    if (k == 100) EXPECT_NEAR(control::bend_angle(d), 0.2, 1e-9);
    prev = d;
  }
  EXPECT_LT(control::geodesic_error(ref.direction(), target), 1e-12);  // there after 0.4 / 0.2 = 2 s
  EXPECT_EQ(ref.source(), control::Source::kDirection);
}

// Rate sources turn about the tip frame's axes (up = +x, right = +y) and hold once they expire.
TEST(Reference, RatesTurnAboutTheTipAxesAndHoldWhenTheyExpire) {
  const control::Mat3 tip = Eigen::AngleAxisd(0.3, Vec3::UnitZ()).toRotationMatrix();  // camera rolled 0.3 rad
  for (int axis = 0; axis < 2; ++axis) {
    control::Reference ref(0.2, nullptr, nullptr);
    ref.start(Vec3::UnitZ(), 0.0);
    const Eigen::Vector2d rates = axis == 0 ? Eigen::Vector2d(0.1, 0.0) : Eigen::Vector2d(0.0, 0.1);
    ref.turn(rates, control::Source::kJoy, 1.0);
    for (int k = 1; k <= 100; ++k) ref.advance(k * kDt, kDt, tip);
    // Up turns z toward the tip's −y, right toward the tip's +x, by 0.1 rad/s × 1 s.
    const Vec3 expected = axis == 0 ? Vec3(-tip.col(1) * std::sin(0.1) + Vec3::UnitZ() * std::cos(0.1))
                                    : Vec3(tip.col(0) * std::sin(0.1) + Vec3::UnitZ() * std::cos(0.1));
    EXPECT_LT(control::geodesic_error(ref.direction(), expected), 1e-9) << axis;
    const Vec3 held = ref.direction();
    for (int k = 101; k <= 400; ++k) ref.advance(k * kDt, kDt, tip);  // no new message: expired at 1 s
    EXPECT_EQ(ref.source(), control::Source::kHold);
    EXPECT_LT(control::geodesic_error(ref.direction(), held), 0.1 * 2 * kDt);
  }
}

// Overflowing commands are directions and rates like any other, not infinities: a target of
// (1e308, 1e308, 1e308) aims along (1, 1, 1), a rate of 1e308 turns at the cap; NaN is refused.
TEST(Reference, HugeTargetsAndRatesAreNotTakenForSomethingElse) {
  control::Reference ref(0.2, nullptr, nullptr);
  ref.hold();
  ref.start(Vec3::UnitZ(), 0.0);
  ASSERT_TRUE(ref.aim(Vec3(1e308, 1e308, 1e308), control::Source::kDirection));
  for (int k = 1; k <= 1000; ++k) ref.advance(k * kDt, kDt, control::Mat3::Identity());
  EXPECT_LT(control::geodesic_error(ref.direction(), Vec3(1, 1, 1).normalized()), 1e-12);
  EXPECT_FALSE(ref.aim(Vec3(NAN, 0, 1), control::Source::kDirection));
  EXPECT_FALSE(ref.aim(Vec3::Zero(), control::Source::kDirection));
  EXPECT_EQ(ref.source(), control::Source::kDirection);  // the refused commands changed nothing

  control::Reference turning(0.2, nullptr, nullptr);
  turning.start(Vec3::UnitZ(), 0.0);
  turning.turn(Eigen::Vector2d(1e308, 0.0), control::Source::kKeyboard, 1.0);
  for (int k = 1; k <= 50; ++k) turning.advance(k * kDt, kDt, control::Mat3::Identity());
  // Up at the cap, 0.2 rad/s for 0.5 s: z turned toward −y by 0.1 rad.
  EXPECT_LT(control::geodesic_error(turning.direction(), Vec3(0, -std::sin(0.1), std::cos(0.1))), 1e-9);
}

namespace {
/// A controller holding on the exact-model static plant (path/type none).
struct OperatorRig {
  config::Scene sc = test::scene("hydrojet_0deg");
  Controller c;
  StaticPlant plant;
  double t = 0.0;
  OperatorRig()
      : c(config::make_controller_model(sc, flow_gains()),
          [] {
            control::ControllerOptions p = tuned_gains();
            p.path_type = control::PathType::kNone;
            return p;
          }()),
        plant(sc, test::bare(sc)) {}
  ControllerOutput run_for(double seconds) {
    const ControllerOutput out = run(c, plant, t, seconds);
    t += seconds;
    return out;
  }
};
}  // namespace

// path/type none holds where it starts; a target 0.4 rad away is reached after 0.4 / rate + settling.
TEST(ControllerSources, HoldsAtStartThenReachesATargetAtTheRateLimit) {
  OperatorRig rig;
  rig.c.start(0.0);
  ControllerOutput out = rig.run_for(1.0);
  ASSERT_EQ(out.state, ControllerState::kRunning) << out.reason;
  EXPECT_EQ(out.source, control::Source::kHold);
  EXPECT_LT(out.error_geodesic, 1e-3);
  const Vec3 start = out.measured_direction;
  const Vec3 target = control::direction(0.4, 1.0);
  rig.c.aim(target, control::Source::kDirection);
  out = rig.run_for(1.0);
  EXPECT_EQ(out.source, control::Source::kDirection);
  EXPECT_NEAR(control::geodesic_error(start, out.desired_direction), rig.c.params().max_angular_rate * 1.0, 0.02);
  out = rig.run_for(control::geodesic_error(start, target) / rig.c.params().max_angular_rate + 2.0);
  ASSERT_EQ(out.state, ControllerState::kRunning) << out.reason;
  EXPECT_LT(control::geodesic_error(out.measured_direction, target), 1e-3);
  EXPECT_FALSE(out.clipped);
}

// A command while idle is kept and drives from the start.
TEST(ControllerSources, CommandsWhileIdleAreUsedAtStart) {
  OperatorRig rig;
  rig.c.aim(control::direction(0.3, 0.0), control::Source::kDirection);
  EXPECT_TRUE(rig.c.commands_pending());
  rig.c.start(0.0);
  EXPECT_FALSE(rig.c.commands_pending());
  const ControllerOutput out = rig.run_for(5.0);
  EXPECT_EQ(out.source, control::Source::kDirection);
  EXPECT_LT(control::geodesic_error(out.measured_direction, control::direction(0.3, 0.0)), 1e-3);
}

// Asking for the impossible never aborts: the target is clipped to the reachable set, the status says so.
TEST(ControllerSources, TargetOutsideTheReachableSetIsClippedNotAborted) {
  OperatorRig rig;
  ASSERT_FALSE(rig.c.reachable_set().empty());
  rig.c.start(0.0);
  rig.run_for(0.5);
  const Vec3 impossible = control::direction(2.0, 0.5);
  ASSERT_FALSE(rig.c.reachable_set().contains(impossible));
  rig.c.aim(impossible, control::Source::kDirection);
  const ControllerOutput out = rig.run_for(15.0);
  ASSERT_EQ(out.state, ControllerState::kRunning) << out.reason;
  EXPECT_TRUE(out.clipped);
  EXPECT_GT(out.clip_angle, 0.3);
  double moved = 0.0;
  const Vec3 clipped = rig.c.reachable_set().clip(impossible, &moved);
  EXPECT_NEAR(out.clip_angle, moved, 1e-12);
  EXPECT_LT(control::geodesic_error(out.desired_direction, clipped), 1e-12);
  EXPECT_LT(control::geodesic_error(out.measured_direction, clipped), 2e-3);
  EXPECT_GE(out.stability_margin, rig.c.params().min_stability_margin);
}

// The paper's §7 spiral (the configured default) runs as written: every point lies in the full-force
// set paths are clipped to, although its end leaves the reserve set operator targets are clipped to;
// the same direction given as a fixed target is clipped. (The 60 s spiral: the same points, faster.)
TEST(ControllerSources, TheConfiguredSpiralRunsUnclippedAnOperatorTargetThereIsClipped) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const config::Scene sc = test::scene(name);
    control::ControllerOptions options = tuned_gains();
    options.path = control::ControllerOptions().path;  // == config/controller.yaml (DefaultsMatchYaml)
    options.path_type = control::PathType::kSpiral;
    options.path.duration = 60.0;
    Controller c(config::make_controller_model(sc, flow_gains()), options);
    Vec3 outside = Vec3::Zero();  // a spiral point outside the reserve set
    for (double t = 0.0; t <= options.path.duration; t += 0.1)
      if (!c.reachable_set().contains(options.path.direction_at(t))) outside = options.path.direction_at(t);
    // At 0° the spiral's end (ϑ up to 1.04 rad) leaves the reserve set at some azimuths; at 30° it stays
    // inside both sets.
    if (std::string(name) == "hydrojet_0deg") ASSERT_GT(outside.norm(), 0.0) << name << ": the sets do not differ";
    StaticPlant plant(sc, test::bare(sc));
    c.start(0.0);
    ControllerOutput out;
    for (int k = 0; k * kDt < options.path.duration; ++k) {
      out = c.update(plant.inputs(k * kDt));
      plant.apply(out.valve_command);
      ASSERT_EQ(out.state, ControllerState::kRunning) << name << " t = " << k * kDt << ": " << out.reason;
      ASSERT_FALSE(out.clipped) << name << " t = " << k * kDt;
      EXPECT_LT(control::geodesic_error(out.desired_direction, options.path.direction_at(k * kDt)), 1e-12);
    }
    if (outside.norm() == 0.0) continue;
    c.aim(outside, control::Source::kDirection);
    out = c.update(plant.inputs(options.path.duration + 2 * kDt));
    EXPECT_TRUE(out.clipped) << name;
    EXPECT_GT(out.clip_angle, 0.0) << name;
  }
}

// A follow()ed path drives; at its end the controller is finished, holding; a new command runs again.
TEST(ControllerSources, FollowedPathFinishesAndANewCommandRunsAgain) {
  OperatorRig rig;
  rig.c.start(0.0);
  rig.run_for(0.5);
  std::vector<control::Waypoint> w(2);
  w[0].t = 0.0, w[0].direction = rig.c.reference().direction();
  w[1].t = 2.0, w[1].direction = control::direction(0.2, 0.0);
  rig.c.follow(control::make_waypoints(w), rig.t);
  ControllerOutput out = rig.run_for(3.0);
  EXPECT_EQ(out.state, ControllerState::kFinished);
  EXPECT_EQ(out.source, control::Source::kPath);
  rig.c.hold();
  EXPECT_EQ(rig.c.state(), ControllerState::kRunning);
  out = rig.run_for(0.1);
  EXPECT_EQ(out.state, ControllerState::kRunning);
  EXPECT_EQ(out.source, control::Source::kHold);
}

// An operator's path (follow()) is clipped as operator targets are, to the set with the force reserve:
// a raster of theta_max 3.0 (accepted: within [0, pi]) used to run to the edge of what the jets reach
// at all, and abort on oscillation there. The configured spiral keeps the full set (the test above).
TEST(ControllerSources, AnOperatorsPathIsClippedToTheOperatorSet) {
  OperatorRig rig;
  rig.c.start(0.0);
  rig.run_for(0.5);
  control::RasterOptions r;
  r.theta_min = 0.1, r.theta_max = 3.0, r.rows = 3, r.phi_start = -0.5, r.phi_end = 0.5, r.speed = 0.2;
  rig.c.follow(control::make_raster(r), rig.t);
  double most = 0.0;
  for (int k = 0; k < 1000; ++k) {
    const ControllerOutput out = rig.run_for(kDt);
    ASSERT_EQ(out.state, ControllerState::kRunning) << k << ": " << out.reason;
    most = std::max(most, out.clip_angle);
    // On the operator set's boundary at most (its polyline is inscribed: inside up to 1e-9).
    const Vec3 d = out.desired_direction;
    EXPECT_TRUE(rig.c.reachable_set().contains(d) || control::geodesic_error(rig.c.reachable_set().clip(d), d) < 1e-9)
        << k;
  }
  EXPECT_GT(most, 0.1);  // within these 10 s the raster climbs well past the set's edge
}

// --- Safety -------------------------------------------------------------------------------------

namespace {
struct SafetyRig {
  config::Scene sc = test::scene("hydrojet_0deg");
  Controller c;
  StaticPlant plant;
  explicit SafetyRig(control::ControllerOptions p = static_target(0.5, 0.0),
                     rod::ShootingOptions solver = test::scene("hydrojet_0deg").solver)
      : c(
            [&] {
              auto m = config::make_controller_model(sc, flow_gains());
              m.solver = solver;
              return m;
            }(),
            p),
        plant(sc, test::bare(sc)) {
    c.start(0.0);
    const ControllerOutput out = run(c, plant, 0.0, 1.0);  // running, jets on
    EXPECT_EQ(out.state, ControllerState::kRunning) << out.reason;
    EXPECT_GT(out.valve_command.sum(), 0.0);
  }
  ControllerOutput step(const ControllerInputs& in) {
    const ControllerOutput out = c.update(in);
    plant.apply(out.valve_command);
    return out;
  }
};

void expect_aborted(const ControllerOutput& out, const std::string& reason_part) {
  EXPECT_EQ(out.state, ControllerState::kAborted);
  EXPECT_EQ(out.valve_command, Vec3::Zero());
  EXPECT_NE(out.reason.find(reason_part), std::string::npos) << out.reason;
}
}  // namespace

TEST(ControllerSafety, StartsAndStopsWithJetsAtZero) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  Controller c(config::make_controller_model(sc, flow_gains()), static_target(0.5, 0.0));
  StaticPlant plant(sc, test::bare(sc));
  EXPECT_EQ(c.update(plant.inputs(0.0)).valve_command, Vec3::Zero());  // idle before start
  c.start(0.0);
  ControllerOutput out = run(c, plant, 0.0, 1.0);
  EXPECT_GT(out.valve_command.sum(), 0.0);
  c.stop();
  out = c.update(plant.inputs(1.0));
  EXPECT_EQ(out.state, ControllerState::kIdle);
  EXPECT_EQ(out.valve_command, Vec3::Zero());
}

TEST(ControllerSafety, StaleTrackerAbortsWithinThreeSamplePeriods) {
  SafetyRig r;
  const double t_last = 0.99;  // last tracker sample
  ControllerOutput out;
  int k = 0;
  for (; k < 10; ++k) {
    ControllerInputs in = r.plant.inputs(1.0 + k * kDt);
    in.tip_stamp = t_last;
    out = r.step(in);
    if (out.state == ControllerState::kAborted) break;
  }
  EXPECT_LE(1.0 + k * kDt - t_last, 3 * kDt + 1e-9 + kDt);
  expect_aborted(out, "tracker");
  // Latched: healthy data again does not restart the jets.
  out = r.step(r.plant.inputs(1.2));
  expect_aborted(out, "tracker");
  r.c.start(1.3);  // until commanded
  EXPECT_EQ(r.step(r.plant.inputs(1.3)).state, ControllerState::kRunning);
}

TEST(ControllerSafety, NonFiniteTrackerPoseAborts) {
  SafetyRig r;
  ControllerInputs in = r.plant.inputs(1.0);
  in.tip_rotation(0, 0) = std::nan("");
  expect_aborted(r.step(in), "tracker");
}

TEST(ControllerSafety, StaleNanOrNegativeFlowAborts) {
  {
    SafetyRig r;
    ControllerInputs in = r.plant.inputs(1.05);
    in.flow_stamp = 1.0;
    expect_aborted(r.step(in), "flow");
  }
  {
    SafetyRig r;
    ControllerInputs in = r.plant.inputs(1.0);
    in.flows[1] = std::nan("");
    expect_aborted(r.step(in), "jet 2");
  }
  {
    SafetyRig r;
    ControllerInputs in = r.plant.inputs(1.0);
    in.flows[2] = -1e-6;
    expect_aborted(r.step(in), "jet 3");
  }
}

TEST(ControllerSafety, SolverFailingTwiceInARowAborts) {
  rod::ShootingOptions weak = test::scene("hydrojet_0deg").solver;
  SafetyRig r(static_target(0.5, 0.0), weak);
  // Now cripple the controller's solver: one Newton step, no continuation, and a large jump of
  // the measured flows that it cannot follow in one step.
  control::RobotModel m = config::make_controller_model(r.sc, flow_gains());
  m.solver.max_iterations = 1;
  m.solver.max_continuation_steps = 0;
  Controller c(m, static_target(0.5, 0.0));
  c.start(0.0);
  ControllerInputs in = r.plant.inputs(0.0);
  in.flows = Vec3(1.2e-5, 0.0, 0.0);
  ControllerOutput out = c.update(in);
  EXPECT_EQ(out.state, ControllerState::kRunning);  // one failure is tolerated
  EXPECT_FALSE(out.solver_converged);
  in.t = in.tip_stamp = in.flow_stamp = kDt;
  in.flows = Vec3(0.0, 1.2e-5, 0.0);
  out = c.update(in);
  expect_aborted(out, "did not converge");
}

TEST(ControllerSafety, LowStabilityMarginAborts) {
  control::ControllerOptions p = static_target(0.5, 0.0);
  const config::Scene sc = test::scene("hydrojet_0deg");
  Controller c(config::make_controller_model(sc, flow_gains()), p);
  StaticPlant plant(sc, test::bare(sc));
  p.min_stability_margin = 100.0;  // N/m, far above the HydroJet's ~3 N/m
  c.set_params(p);
  c.start(0.0);
  expect_aborted(c.update(plant.inputs(0.0)), "sigma_c");
}

TEST(ControllerSafety, OscillationBeyondHalfRadianAborts) {
  SafetyRig r;
  ControllerInputs in = r.plant.inputs(1.0);
  in.tip_rotation = so3::exp(Vec3(0.0, 0.5 + 0.6, 0.0));  // 0.6 rad past the 0.5 rad target
  expect_aborted(r.step(in), "oscillation");
}

TEST(ControllerOptions, ValidationNamesTheField) {
  control::ControllerOptions p;
  EXPECT_EQ(p.validate(), "");
  p.kp = -1;
  EXPECT_EQ(p.validate().rfind("kp:", 0), 0u) << p.validate();
  p = control::ControllerOptions();
  p.sample_period = std::nan("");
  EXPECT_EQ(p.validate().rfind("sample_period:", 0), 0u);
  p = control::ControllerOptions();
  p.path.duration = 0;
  EXPECT_EQ(p.validate().rfind("path.duration:", 0), 0u);
}

TEST(TaskSpace, AnglesDirectionsAndMetrics) {
  for (double th : {0.0, 0.3, 1.04, 1.5})
    for (double ph : {-3.0, -0.5, 0.0, 2.0}) {
      const Vec3 d = control::direction(th, ph);
      EXPECT_NEAR(d.norm(), 1.0, 1e-15);
      EXPECT_NEAR(control::bend_angle(d), th, 1e-12);
      if (th > 0) {
        EXPECT_NEAR(std::remainder(control::azimuth(d) - ph, 2 * M_PI), 0.0, 1e-12);
      }
    }
  const Vec3 a = control::direction(0.4, 0.2), b = control::direction(0.9, 1.7);
  const Vec3 r = control::rotation_between(a, b);
  EXPECT_LT((so3::exp(r) * a - b).norm(), 1e-12);
  EXPECT_NEAR(r.norm(), control::geodesic_error(a, b), 1e-12);
  // Pure pitch: the paper's metric equals the geodesic angle.
  EXPECT_NEAR(control::pitch_yaw_error(control::direction(0.2, 0.0), control::direction(0.5, 0.0)), 0.3, 1e-12);
  // Spiral end point (eq. 28 defaults).
  control::SpiralPath s;
  EXPECT_NEAR(s.angles(600.0)[0], 1.04, 1e-12);
  EXPECT_NEAR(s.angles(600.0)[1], 14.0, 1e-12);
  EXPECT_NEAR(s.angles(300.0)[0], 0.52, 1e-12);
}

// A valve stuck open: the measured flow of that jet stays far above its command; the controller
// notices from flow feedback within flow_fault_time and stops.
TEST(ControllerSafety, StuckOpenJetIsDetectedFromFlowFeedback) {
  SafetyRig r;
  r.plant.stuck_jet = 1;  // jet 2 partly open whatever it is told
  r.plant.stuck_flow = 6e-6;
  const double t0 = 1.0;
  ControllerOutput out;
  int k = 0;
  for (; k < 200; ++k) {
    out = r.c.update(r.plant.inputs(t0 + k * kDt));
    r.plant.apply(out.valve_command);
    if (out.state == ControllerState::kAborted) break;
  }
  expect_aborted(out, "jet 2 does not follow");
  const double params_time = control::ControllerOptions().flow_fault_time;
  // The excess over the tolerance (3e-6) is at most 3e-6 here, so it cannot trip sooner than
  // flow_fault_time; it trips soon after the loop has pushed jet 2's command away from the stuck flow.
  EXPECT_GE(k * kDt, params_time - 1e-9);
  EXPECT_LE(k * kDt, 2.0);
}

// The flows must come one per jet (three for the HydroJet's jet map).
TEST(ControllerSafety, WrongNumberOfFlowReadingsAborts) {
  SafetyRig r;
  EXPECT_EQ(r.c.input_count(), 3);
  ControllerInputs in = r.plant.inputs(1.0);
  in.flows = Eigen::Vector2d(1e-6, 1e-6);
  expect_aborted(r.step(in), "flow: 2 readings for 3 jets");
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
}

// --- Options ----------------------------------------------------------------------------------

// config/controller.yaml is the source of every default: it names every key, and the
// default-constructed options hold the same values, field by field (the scene aside).
TEST(ControllerOptions, DefaultsEqualConfigControllerYaml) {
  const std::string path = std::string(HYDROJET_SOURCE_DIR) + "/config/controller.yaml";
  const YAML::Node yaml = YAML::LoadFile(path);
  const config::ControllerNodeOptions file = config::load_controller_options(path);
  const config::ControllerNodeOptions def;
  auto in_file = [&](const std::string& key) {
    const size_t slash = key.find('/');
    return slash == std::string::npos ? bool(yaml[key]) : bool(yaml[key.substr(0, slash)][key.substr(slash + 1)]);
  };
  const control::ControllerOptions &f = file.controller, &d = def.controller;
  const actuation::FlowRegulatorOptions &ff = file.flow_regulator, &fd = def.flow_regulator;
  const struct {
    const char* key;
    double file, def;
  } numbers[] = {
      {"rate", file.rate, def.rate},
      {"gains/kp", f.kp, d.kp},
      {"gains/kd", f.kd, d.kd},
      {"gains/ki", f.ki, d.ki},
      {"gains/max_integral", f.max_integral, d.max_integral},
      {"fast_path_rate", f.fast_path_rate, d.fast_path_rate},
      {"gains/feedforward", f.feedforward, d.feedforward},
      {"gains/damping", f.damping, d.damping},
      {"gains/lead_time", f.lead_time, d.lead_time},
      {"observer/enabled", double(f.observer), double(d.observer)},
      {"observer/time_constant", f.observer_time_constant, d.observer_time_constant},
      {"observer/prediction", double(f.observer_prediction), double(d.observer_prediction)},
      {"limits/max_force", f.max_force, d.max_force},
      {"limits/max_force_rate", f.max_force_rate, d.max_force_rate},
      {"limits/min_jet_force", f.min_jet_force, d.min_jet_force},
      {"limits/max_common_force_rate", f.max_common_force_rate, d.max_common_force_rate},
      {"limits/max_angular_rate", f.max_angular_rate, d.max_angular_rate},
      {"limits/reachable_force_fraction", f.reachable_force_fraction, d.reachable_force_fraction},
      {"allocation_weight", f.allocation_weight, d.allocation_weight},
      {"allocation_smoothing", f.allocation_smoothing, d.allocation_smoothing},
      {"integrate_from_measured", double(f.integrate_from_measured), double(d.integrate_from_measured)},
      {"safety/max_oscillation", f.max_oscillation, d.max_oscillation},
      {"safety/sample_period", f.sample_period, d.sample_period},
      {"safety/stale_periods", double(f.stale_periods), double(d.stale_periods)},
      {"safety/max_solver_failures", double(f.max_solver_failures), double(d.max_solver_failures)},
      {"safety/min_stability_margin", f.min_stability_margin, d.min_stability_margin},
      {"safety/unreachable_tolerance", f.unreachable_tolerance, d.unreachable_tolerance},
      {"safety/flow_fault_tolerance", f.flow_fault_tolerance, d.flow_fault_tolerance},
      {"safety/flow_fault_time", f.flow_fault_time, d.flow_fault_time},
      {"path/theta_start", f.path.theta_start, d.path.theta_start},
      {"path/theta_end", f.path.theta_end, d.path.theta_end},
      {"path/phi_start", f.path.phi_start, d.path.phi_start},
      {"path/phi_end", f.path.phi_end, d.path.phi_end},
      {"path/duration", f.path.duration, d.path.duration},
      {"flow_regulator/feedforward", ff.feedforward, fd.feedforward},
      {"flow_regulator/lead_time", ff.lead_time, fd.lead_time},
      {"flow_regulator/kp", ff.kp, fd.kp},
      {"flow_regulator/ki", ff.ki, fd.ki},
      {"flow_regulator/output_min", ff.output_min, fd.output_min},
      {"flow_regulator/output_max", ff.output_max, fd.output_max},
  };
  for (const auto& n : numbers) {
    EXPECT_TRUE(in_file(n.key)) << n.key << " is not in " << path;
    EXPECT_EQ(n.file, n.def) << n.key;
  }
  for (const char* key : {"mode", "autostart", "base_frame", "path/type"}) EXPECT_TRUE(in_file(key)) << key;
  EXPECT_EQ(f.mode, d.mode);
  EXPECT_EQ(f.path_type, d.path_type);
  EXPECT_EQ(file.autostart, def.autostart);
  EXPECT_EQ(file.base_frame, def.base_frame);
  EXPECT_EQ(ff.anti_windup, fd.anti_windup);  // not a key: the regulator's own default
  // And the file names nothing else (the parser rejects unknown keys, so this is the full list).
  size_t keys = 0;
  for (const auto& top : yaml) keys += top.second.IsMap() ? top.second.size() : 1;
  EXPECT_EQ(keys, sizeof(numbers) / sizeof(numbers[0]) + 4);
}

// config/teleop.yaml is the source of the joystick defaults (TeleopOptions), key by key.
TEST(ControllerOptions, TeleopDefaultsEqualConfigTeleopYaml) {
  const std::string path = std::string(HYDROJET_SOURCE_DIR) + "/config/teleop.yaml";
  const YAML::Node yaml = YAML::LoadFile(path);
  const config::TeleopOptions file = config::parse_controller_options(yaml).teleop, def;
  const struct {
    const char* key;
    double file, def;
  } numbers[] = {
      {"axis_up", double(file.axis_up), double(def.axis_up)},
      {"scale_up", file.scale_up, def.scale_up},
      {"axis_right", double(file.axis_right), double(def.axis_right)},
      {"scale_right", file.scale_right, def.scale_right},
      {"deadman_button", double(file.deadman_button), double(def.deadman_button)},
      {"timeout", file.timeout, def.timeout},
  };
  for (const auto& n : numbers) {
    EXPECT_TRUE(bool(yaml["teleop"][n.key])) << n.key << " is not in " << path;
    EXPECT_EQ(n.file, n.def) << n.key;
  }
  EXPECT_EQ(yaml["teleop"].size(), sizeof(numbers) / sizeof(numbers[0]));
  // ROS joy: stick up reads +1 and tilts the view up; stick right reads −1 and turns it right.
  EXPECT_GT(def.scale_up, 0.0);
  EXPECT_LT(def.scale_right, 0.0);
}

TEST(ControllerOptions, BadTeleopAndPathTypeAreRefusedNamingTheKey) {
  const struct {
    const char* yaml;
    const char* key;
  } cases[] = {{"{teleop: {axis_up: -1}}", "teleop/axis_up"},
               {"{teleop: {timeout: 0}}", "teleop/timeout"},
               {"{teleop: {scale_right: .nan}}", "teleop/scale_right"},
               {"{path: {type: circle}}", "path/type"},
               {"{limits: {max_angular_rate: 0}}", "limits/max_angular_rate"},
               {"{limits: {reachable_force_fraction: 1.5}}", "limits/reachable_force_fraction"}};
  for (const auto& c : cases) {
    try {
      config::parse_controller_options(YAML::Load(c.yaml));
      ADD_FAILURE() << c.yaml << " accepted";
    } catch (const config::ParamError& e) {
      EXPECT_EQ(e.key(), c.key) << e.what();
    }
  }
}

// validate() enforces the ranges of cfg/Controller.cfg: the bounds pass, a value just outside
// either bound is refused naming the key.
TEST(ControllerOptions, RangesOfControllerCfgAreEnforced) {
  const struct {
    const char* key;
    double lo, hi;
  } ranges[] = {
      {"gains/kp", 0.0, 50.0},       {"gains/kd", 0.0, 5.0},          {"gains/feedforward", 0.0, 2.0},
      {"gains/damping", 1e-4, 10.0}, {"limits/max_force", 0.01, 1.0}, {"limits/max_force_rate", 0.01, 20.0},
  };
  auto parse = [](const std::string& key, double v) {
    const size_t slash = key.find('/');
    YAML::Node root;
    root[key.substr(0, slash)][key.substr(slash + 1)] = v;
    return config::parse_controller_options(root);
  };
  for (const auto& r : ranges) {
    EXPECT_NO_THROW(parse(r.key, r.lo)) << r.key;
    EXPECT_NO_THROW(parse(r.key, r.hi)) << r.key;
    for (double v : {r.lo - std::max(1e-6, 1e-3 * r.lo), r.hi * (1 + 1e-6)}) {
      try {
        parse(r.key, v);
        ADD_FAILURE() << r.key << " = " << v << " accepted";
      } catch (const config::ParamError& e) {
        EXPECT_EQ(e.key(), r.key) << e.what();
        EXPECT_NE(std::string(e.what()).find("must lie in"), std::string::npos) << e.what();
      }
    }
  }
}

// --- Fast paths -----------------------------------------------------------------------------------

namespace {

/// The direction a [rad] from +z toward +x.
Vec3 dir(double a) { return Vec3(std::sin(a), 0.0, std::cos(a)); }

/// DirectionPd's terms alone: K_p, K_i, the feedforward's weight; no derivative.
control::ControllerOptions pd_terms(double kp, double ki, double feedforward) {
  control::ControllerOptions g;
  g.kp = kp;
  g.kd = 0.0;
  g.ki = ki;
  g.feedforward = feedforward;
  return g;
}

/// A great circle from +z toward +x at `rate` [rad/s] for `duration` [s].
class ArcPath : public control::Path {
 public:
  ArcPath(double rate, double duration) : rate_(rate), duration_(duration) {}
  Vec3 direction_at(double t) const override { return dir(rate_ * std::clamp(t, 0.0, duration_)); }
  double duration() const override { return duration_; }
  const char* type() const override { return "arc"; }

 private:
  double rate_, duration_;
};

}  // namespace

// A path is followed as written once the reference is on it, even faster than max_angular_rate
// (which still limits the way onto it); preview() looks ahead along it and is the reference itself
// otherwise.
TEST(Reference, APathIsFollowedAtItsOwnSpeedOnceJoined) {
  control::Reference ref(0.25, nullptr, nullptr);
  const auto path = std::make_shared<ArcPath>(0.6, 2.0);  // 0.6 rad/s > 0.25
  ref.follow(path, 0.0, /*starts_at_path=*/true);
  ref.start(Vec3::UnitZ(), 0.0);
  for (int k = 1; k <= 100; ++k) {
    const double t = 0.01 * k;
    const Vec3 d = ref.advance(t, 0.01, control::Mat3::Identity());
    EXPECT_NEAR(control::geodesic_error(d, path->direction_at(t)), 0.0, 1e-12) << t;
  }
  EXPECT_NEAR(control::geodesic_error(ref.preview(1.0, 0.1), path->direction_at(1.1)), 0.0, 1e-12);
  EXPECT_EQ(ref.preview(1.0, 0.0), ref.direction());
  // Joining from elsewhere: at most max_angular_rate until on the path, then the path's speed.
  control::Reference join(0.25, nullptr, nullptr);
  join.start(Vec3(std::sin(0.3), 0.0, std::cos(0.3)), 0.0);
  join.follow(std::make_shared<ArcPath>(0.6, 10.0), 0.0);
  Vec3 prev = join.direction();
  bool joined = false;
  for (int k = 1; k <= 300 && !joined; ++k) {
    const Vec3 d = join.advance(0.01 * k, 0.01, control::Mat3::Identity());
    joined = control::geodesic_error(d, ArcPath(0.6, 10.0).direction_at(0.01 * k)) < 1e-12;
    // Rate-limited on the way; the step that joins adds at most the path's own step (0.006 rad).
    EXPECT_LE(control::geodesic_error(prev, d), 0.25 * 0.01 + (joined ? 0.006 : 0.0) + 1e-12) << k;
    prev = d;
  }
  EXPECT_TRUE(joined);
  EXPECT_EQ(join.preview(0.0, 0.0), join.direction());
}

// The lead enters the feedforward once, when it starts; after that the feedforward is the motion
// ahead; when the lead ends it is not taken back in one step.
TEST(DirectionPd, TheLeadEntersOnceAndIsNotTakenBackAtOnce) {
  const control::ControllerOptions g = pd_terms(0.0, control::ControllerOptions().ki, 1.0);
  control::DirectionPd pd;
  // Cycle 1 primes on x_des = dir(0) with x_ff = dir(0.05): the lead (0.05 rad about +y) enters.
  Vec3 x = pd.correction(dir(0.0), dir(0.0), dir(0.05), 0.01, g);
  EXPECT_NEAR((x - Vec3(0.0, 0.05, 0.0)).norm(), 0.0, 1e-12);
  // Then the motion ahead: 0.01 rad per step.
  x = pd.correction(dir(0.01), dir(0.01), dir(0.06), 0.01, g);
  EXPECT_NEAR((x - Vec3(0.0, 0.01, 0.0)).norm(), 0.0, 1e-12);
  // The lead ends (x_ff = x_des): x_des's own motion, no step back by 0.05.
  x = pd.correction(dir(0.02), dir(0.02), dir(0.02), 0.01, g);
  EXPECT_NEAR((x - Vec3(0.0, 0.01, 0.0)).norm(), 0.0, 1e-12);
  // K_i: the integral of a constant error e over n steps of dt adds K_i dt (n dt) e, bounded.
  control::ControllerOptions gi = pd_terms(0.0, 2.0, 0.0);
  gi.max_integral = 1.0;
  gi.fast_path_rate = 0.0;  // unscheduled: the still reference below gets the integral too
  control::DirectionPd pi;
  const Vec3 e(0.0, 0.02, 0.0);
  for (int n = 1; n <= 5; ++n) {
    x = pi.correction(dir(0.0), dir(0.02), dir(0.02), 0.01, gi);
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
  control::ControllerOptions g = pd_terms(0.0, 2.0, 0.0);
  g.max_integral = 1.0;
  g.fast_path_rate = 0.1;
  const double dt = 0.01, e = 0.02;
  // Still: no integral at all.
  control::DirectionPd still;
  for (int n = 0; n < 5; ++n) EXPECT_EQ(still.correction(dir(0.0), dir(e), dir(e), dt, g).norm(), 0.0) << n;
  // Moving at 0.3 rad/s (w = 0.9), the tip e behind: after the priming step, K_i dt Σ w e dt.
  control::DirectionPd moving;
  moving.correction(dir(-e), dir(0.0), dir(0.0), dt, g);  // primes (v unknown: 0)
  Vec3 x;
  for (int n = 1; n <= 5; ++n) {
    const double a = 0.3 * dt * n;
    x = moving.correction(dir(a - e), dir(a), dir(a), dt, g);
    EXPECT_NEAR(x.y(), g.ki * dt * (n * dt * 0.9 * e), 1e-9) << n;
  }
  // It stops: with K_p the integral leaks by (1 − K_p dt) per step (and K_p's own term adds K_p dt e).
  g.kp = 3.0;
  const double before = x.y() / (g.ki * dt);
  const double a = 0.3 * dt * 5;
  x = moving.correction(dir(a - e), dir(a), dir(a), dt, g);
  EXPECT_NEAR(x.y(), g.kp * dt * e + g.ki * dt * before * (1.0 - g.kp * dt), 1e-9);
}

// A cycle without a correction (the controller held while the model did not converge, the reference on
// a path, which moves with time; Controller::hold skips only then): the reference's speed is its
// motion over both cycles, not over the last one (which would double it), and the
// feedforward carries the motion of both.
TEST(DirectionPd, AHeldCycleCountsInTheReferenceSpeed) {
  const control::ControllerOptions g = pd_terms(0.0, 0.0, 1.0);
  const double dt = 0.01, v = 0.2;
  control::DirectionPd pd;
  pd.skip(dt);  // before the first correction: nothing to carry
  pd.correction(dir(0.0), dir(0.0), dir(0.0), dt, g);
  pd.correction(dir(v * dt), dir(v * dt), dir(v * dt), dt, g);
  EXPECT_NEAR(pd.speed(), v, 1e-9);
  pd.skip(dt);  // the held cycle; x_des moved on by v dt
  const Vec3 x = pd.correction(dir(3 * v * dt), dir(3 * v * dt), dir(3 * v * dt), dt, g);
  EXPECT_NEAR(pd.speed(), v, 1e-9);
  EXPECT_NEAR(x.y(), 2 * v * dt, 1e-12);
  pd.correction(dir(4 * v * dt), dir(4 * v * dt), dir(4 * v * dt), dt, g);  // the skip is spent
  EXPECT_NEAR(pd.speed(), v, 1e-9);
  pd.reset();
  pd.skip(dt);
  pd.correction(dir(0.0), dir(0.0), dir(0.0), dt, g);
  pd.correction(dir(v * dt), dir(v * dt), dir(v * dt), dt, g);
  EXPECT_NEAR(pd.speed(), v, 1e-9);
}

// A plant 25 % softer than the model (its direction gain g = 1.25): on an arc at v = 0.3 rad/s the
// paper's law settles at the type-1 ramp error (1 − 1/g) v / K_p = 0.02 rad; with the speed-weighted,
// leaking integral (K_i 6, w = 0.9 at v₀ = 0.1 rad/s) the closed form is
// (1 − 1/g) v / (K_p + K_i w / ((1 − w) K_p)) = 0.06 / 21 = 0.0029 rad, and without the weight (type 2) 0.
TEST(Controller, TheSpeedWeightedIntegralRemovesTheRampErrorOfAGainMismatch) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  rod::RodModel truth = test::bare(sc);
  truth.segments[0].stiffness *= 0.8;
  double ramp_error[3];  // the paper's law; K_i weighted (the default); K_i unweighted
  for (int law = 0; law < 3; ++law) {
    control::ControllerOptions p;  // K_p 3/s
    p.ki = law == 0 ? 0.0 : 6.0;
    p.fast_path_rate = law == 2 ? 0.0 : 0.1;
    p.min_jet_force = 0.0;
    p.path_type = control::PathType::kNone;
    Controller c(config::make_controller_model(sc, flow_gains()), p);
    StaticPlant plant(sc, truth);
    c.follow(std::make_shared<ArcPath>(0.3, 3.0), 0.0);  // joined from the rest direction at ≤ 0.25 rad/s
    c.start(0.0);
    double sum2 = 0.0;
    int n = 0;
    for (int k = 0; k <= 300; ++k) {
      const ControllerOutput out = c.update(plant.inputs(k * kDt));
      ASSERT_NE(out.state, ControllerState::kAborted) << out.reason;
      plant.apply(out.valve_command);
      if (k * kDt >= 2.0) sum2 += out.error_geodesic * out.error_geodesic, ++n;
    }
    ramp_error[law] = std::sqrt(sum2 / n);
  }
  // The closed forms, within the gain's spread along the arc (the plant is not exactly 1.25× the
  // model everywhere: the paper's law measures 0.017); the weighted law's ratio to it is K_p / 21.
  EXPECT_NEAR(ramp_error[0], 0.2 * 0.3 / 3.0, 0.005);
  EXPECT_NEAR(ramp_error[1] / ramp_error[0], 3.0 / 21.0, 0.04);
  EXPECT_LT(ramp_error[2], 0.1 * ramp_error[0]);
}

// Held still, the fast-path elements (K_i, idling jets, rounded allocation) do nothing: config/controller.yaml's law
// commands what the paper's law does, bit for bit, on a still target with a mismatched plant.
TEST(Controller, OnAStillTargetTheFastPathElementsAreThePapersLaw) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  rod::RodModel truth = test::bare(sc);
  truth.segments[0].stiffness *= 0.8;
  control::ControllerOptions bare = static_target(0.6, 1.0);
  bare.ki = 0.0;
  bare.min_jet_force = 0.0;
  bare.allocation_smoothing = 0.0;
  const control::ControllerOptions fast = static_target(0.6, 1.0);  // the defaults: K_i 6, idle, rounding
  ASSERT_GT(fast.ki, 0.0);
  ASSERT_GT(fast.min_jet_force, 0.0);
  ASSERT_GT(fast.allocation_smoothing, 0.0);
  Controller paper(config::make_controller_model(sc, flow_gains()), bare);
  Controller scheduled(config::make_controller_model(sc, flow_gains()), fast);
  StaticPlant a(sc, truth), b(sc, truth);
  paper.start(0.0);
  scheduled.start(0.0);
  for (int k = 0; k < 300; ++k) {
    const ControllerOutput oa = paper.update(a.inputs(k * kDt)), ob = scheduled.update(b.inputs(k * kDt));
    ASSERT_EQ(oa.jet_force_command, ob.jet_force_command) << k;
    a.apply(oa.valve_command);
    b.apply(ob.valve_command);
  }
}

// Idling jets (min_jet_force, here at every speed: fast_path_rate 0): every jet stays at or above
// the idle force while the controller runs, and the targets are reached as before (the jets' common
// force adds no net tip force the law cannot correct). Without it the allocation closes a jet at
// these targets (so the check can fail). Stopped, the jets are at zero.
TEST(Controller, IdlingJetsStayOpenAndTheTargetIsStillReached) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  for (const auto& target : {std::make_pair(0.4, 0.5), std::make_pair(0.9, 2.5)}) {
    for (double idle : {0.0, 0.01}) {
      control::ControllerOptions p = static_target(target.first, target.second);
      p.min_jet_force = idle;
      p.fast_path_rate = 0.0;
      p.ki = 0.0;
      p.allocation_smoothing = 0.0;  // the idle alone
      Controller c(config::make_controller_model(sc, flow_gains()), p);
      StaticPlant plant(sc, test::bare(sc));
      c.start(0.0);
      double lowest = 1e9;
      ControllerOutput out;
      for (int k = 0; k < 800; ++k) {
        out = c.update(plant.inputs(k * kDt));
        ASSERT_EQ(out.state, ControllerState::kRunning) << out.reason;
        plant.apply(out.valve_command);
        lowest = std::min(lowest, out.jet_force_command.minCoeff());
      }
      EXPECT_LT(out.error_geodesic, 1e-3) << "idle " << idle;
      if (idle > 0.0)
        EXPECT_GE(lowest, idle - 1e-12);
      else
        EXPECT_LT(out.jet_force_command.minCoeff(), 1e-9);
    }
  }
}

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

// The controller on a cone round the tip (the tip force turns past each jet), quasi-static plant with
// the model's own rod and jets: rounded, the jets' commanded forces have far smaller second
// differences than the paper's allocation where the force passes a jet, and the tip follows no worse
// (the common mode moves it by nothing; where the paper's allocation closes a jet its flow regulator
// sits at zero duty, and the tip lags: measured 0.00045 against 0.00011 rad RMS).
TEST(Controller, TheRoundedAllocationSmoothsTheJetsAndLeavesTheTip) {
  class ConePath : public control::Path {
   public:
    Vec3 direction_at(double t) const override {
      const double theta = std::min(0.3 * t, 0.4), phi = 0.7 * t;
      return Vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
    }
    double duration() const override { return 12.0; }
    const char* type() const override { return "cone"; }
  };
  const config::Scene sc = test::scene("hydrojet_0deg");
  double second[2], rms[2];
  for (int round : {0, 1}) {
    control::ControllerOptions p;
    p.path_type = control::PathType::kNone;
    p.ki = 0.0;
    p.min_jet_force = 0.0;
    p.allocation_smoothing = round ? 0.3 : 0.0;
    Controller c(config::make_controller_model(sc, flow_gains()), p);
    StaticPlant plant(sc, test::bare(sc));
    c.start(0.0);
    c.follow(std::make_shared<ConePath>(), 0.0);
    std::vector<rod::InputVector> q;
    double e2 = 0.0;
    int n = 0;
    const rod::InputVector upper = control::ActuatedModel(config::make_controller_model(sc, flow_gains())).upper();
    for (int k = 0; k < 1200; ++k) {
      const double t = k * kDt;
      const ControllerOutput out = c.update(plant.inputs(t));
      ASSERT_EQ(out.state, ControllerState::kRunning) << out.reason;
      plant.apply(out.valve_command);
      ASSERT_GE(out.jet_force_command.minCoeff(), 0.0) << t;  // within the jets' bounds
      ASSERT_TRUE((out.jet_force_command.array() <= upper.array()).all()) << t;
      if (t >= 3.0) {
        q.push_back(out.jet_force_command);
        e2 += out.error_geodesic * out.error_geodesic;
        ++n;
      }
    }
    second[round] = 0.0;
    for (size_t k = 1; k + 1 < q.size(); ++k)
      second[round] = std::max(second[round], (q[k + 1] - 2.0 * q[k] + q[k - 1]).cwiseAbs().maxCoeff());
    rms[round] = std::sqrt(e2 / n);
  }
  std::printf(
      "max second difference of the jet forces: paper's allocation %.3g N, rounded %.3g N; "
      "tip error RMS %.4g / %.4g rad\n",
      second[0], second[1], rms[0], rms[1]);
  EXPECT_LT(second[1], 0.25 * second[0]);
  EXPECT_LE(rms[1], rms[0]);
}

// With the default weighting, on an arc at 0.3 rad/s (w = 0.9): once the reference moves at that
// speed and the idle force has risen (at most max_force_rate), every jet is at least 0.9 × the idle
// force; a still reference before the arc starts leaves the jets free to close.
TEST(Controller, JetsIdleInProportionToTheReferenceSpeed) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  control::ControllerOptions p;
  p.path_type = control::PathType::kNone;
  p.min_jet_force = 0.01;
  Controller c(config::make_controller_model(sc, flow_gains()), p);
  StaticPlant plant(sc, test::bare(sc));
  c.start(0.0);
  double lowest_still = 1e9, lowest_moving = 1e9;
  for (int k = 0; k < 400; ++k) {
    const double t = k * kDt;
    if (k == 100) c.follow(std::make_shared<ArcPath>(0.3, 10.0), t);  // from the rest direction
    const ControllerOutput out = c.update(plant.inputs(t));
    ASSERT_EQ(out.state, ControllerState::kRunning) << out.reason;
    plant.apply(out.valve_command);
    if (k < 100) lowest_still = std::min(lowest_still, out.jet_force_command.minCoeff());
    if (t >= 2.5) lowest_moving = std::min(lowest_moving, out.jet_force_command.minCoeff());
  }
  EXPECT_LT(lowest_still, 1e-9);
  EXPECT_GE(lowest_moving, 0.9 * p.min_jet_force - 1e-9);
}
