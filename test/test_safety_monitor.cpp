// The safety monitor (safety_monitor.h) through the controller: jets at zero when idle and stopped, and
// every trigger (stale or non-finite data, solver failures, stability margin, oscillation, flow faults).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/control/safety_monitor.h"
#include "hydrojet_control/rod/so3.h"
#include "controller_fixtures.h"
#include "test_helpers.h"

using namespace hydrojet;
using control::Controller;
using control::ControllerInputs;
using control::ControllerOutput;
using control::ControllerState;
using control::Vec3;
using test::flow_gains;
using test::kDt;
using test::run;
using test::static_target;
using test::StaticPlant;

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

TEST(SafetyMonitor, StartsAndStopsWithJetsAtZero) {
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

TEST(SafetyMonitor, StaleTrackerAbortsWithinThreeSamplePeriods) {
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

TEST(SafetyMonitor, NonFiniteTrackerPoseAborts) {
  SafetyRig r;
  ControllerInputs in = r.plant.inputs(1.0);
  in.tip_rotation(0, 0) = std::nan("");
  expect_aborted(r.step(in), "tracker");
}

TEST(SafetyMonitor, StaleNanOrNegativeFlowAborts) {
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

TEST(SafetyMonitor, SolverFailingTwiceInARowAborts) {
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

TEST(SafetyMonitor, LowStabilityMarginAborts) {
  control::ControllerOptions p = static_target(0.5, 0.0);
  const config::Scene sc = test::scene("hydrojet_0deg");
  Controller c(config::make_controller_model(sc, flow_gains()), p);
  StaticPlant plant(sc, test::bare(sc));
  p.safety.min_stability_margin = 100.0;  // N/m, far above the HydroJet's ~3 N/m
  c.set_options(p);
  c.start(0.0);
  expect_aborted(c.update(plant.inputs(0.0)), "sigma_c");
}

TEST(SafetyMonitor, OscillationBeyondHalfRadianAborts) {
  SafetyRig r;
  ControllerInputs in = r.plant.inputs(1.0);
  in.tip_rotation = so3::exp(Vec3(0.0, 0.5 + 0.6, 0.0));  // 0.6 rad past the 0.5 rad target
  expect_aborted(r.step(in), "oscillation");
}

// A valve stuck open: the measured flow of that jet stays far above its command; the controller
// notices from flow feedback within flow_fault_time and stops.
TEST(SafetyMonitor, StuckOpenJetIsDetectedFromFlowFeedback) {
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
  const double params_time = control::SafetyOptions().flow_fault_time;
  // The excess over the tolerance (3e-6) is at most 3e-6 here, so it cannot trip sooner than
  // flow_fault_time; it trips soon after the loop has pushed jet 2's command away from the stuck flow.
  EXPECT_GE(k * kDt, params_time - 1e-9);
  EXPECT_LE(k * kDt, 2.0);
}

// The flows must come one per jet (three for the HydroJet's jet map).
TEST(SafetyMonitor, WrongNumberOfFlowReadingsAborts) {
  SafetyRig r;
  EXPECT_EQ(r.c.input_count(), 3);
  ControllerInputs in = r.plant.inputs(1.0);
  in.flows = Eigen::Vector2d(1e-6, 1e-6);
  expect_aborted(r.step(in), "flow: 2 readings for 3 jets");
}
