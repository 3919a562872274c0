// The PD resolved-rates controller (Algorithm 1) with the quasi-static rod model as the plant, no
// ROS: convergence on static targets in closed and open loop, the value of feedback under model
// mismatch, the operator's sources (targets, paths, the reachable set), the fast-path elements, and the
// options (defaults = config/controller.yaml, ranges of cfg/Controller.cfg).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/control/papers_law.h"
#include "controller_fixtures.h"
#include "test_helpers.h"

using namespace hydrojet;
using control::Controller;
using control::ControllerOutput;
using control::ControllerState;
using control::Vec3;
using test::ArcPath;
using test::flow_gains;
using test::kDt;
using test::run;
using test::static_target;
using test::StaticPlant;
using test::tuned_gains;

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

// --- Operator sources ----------------------------------------------------------------------------

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
            p.path.type = control::PathType::kNone;
            p.identification.probe = false;  // a static plant has no mode to probe
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
  EXPECT_NEAR(control::geodesic_error(start, out.desired_direction), rig.c.options().limits.max_angular_rate * 1.0,
              0.02);
  out = rig.run_for(control::geodesic_error(start, target) / rig.c.options().limits.max_angular_rate + 2.0);
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
  EXPECT_GE(out.stability_margin, rig.c.options().safety.min_stability_margin);
}

// The paper's §7 spiral (the configured default) runs as written: every point lies in the full-force
// set paths are clipped to, although its end leaves the reserve set operator targets are clipped to;
// the same direction given as a fixed target is clipped. (The 60 s spiral: the same points, faster.)
TEST(ControllerSources, TheConfiguredSpiralRunsUnclippedAnOperatorTargetThereIsClipped) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const config::Scene sc = test::scene(name);
    control::ControllerOptions options = tuned_gains();
    options.path = control::ControllerOptions().path;  // == config/controller.yaml (DefaultsMatchYaml)
    options.path.type = control::PathType::kSpiral;
    options.path.duration = 60.0;
    Controller c(config::make_controller_model(sc, flow_gains()), options);
    Vec3 outside = Vec3::Zero();  // a spiral point outside the reserve set
    for (double t = 0.0; t <= options.path.duration; t += 0.1)
      if (!c.reachable_set().contains(options.path.direction_at(t))) outside = options.path.direction_at(t);
    // At 0° the spiral's end (ϑ up to 1.04 rad) leaves the reserve set at some azimuths; at 30° it stays
    // inside both sets.
    if (std::string(name) == "hydrojet_0deg") {
      ASSERT_GT(outside.norm(), 0.0) << name << ": the sets do not differ";
    }
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

// A path starts where it begins: the reference moves to its first direction at the rate limit, the
// tip settles there, and only then does the path's clock start (path_time 0 until then); the path
// then runs its whole duration. An approach that cannot settle fails, and the reference holds.
TEST(ControllerSources, APathIsApproachedAndItsClockStartsOnceTheTipHasSettled) {
  OperatorRig rig;
  rig.c.start(0.0);
  rig.run_for(0.5);
  std::vector<control::Waypoint> w(2);
  w[0].t = 0.0, w[0].direction = control::direction(0.4, 0.5);
  w[1].t = 2.0, w[1].direction = control::direction(0.6, 0.5);
  const double away = control::geodesic_error(rig.c.reference().direction(), w[0].direction);
  const double rate = rig.c.options().limits.max_angular_rate, window = rig.c.options().approach.settle_time;
  rig.c.follow(control::make_waypoints(w), rig.t);
  ControllerOutput out;
  int approach_cycles = 0;
  for (; approach_cycles < 2000; ++approach_cycles) {
    out = rig.run_for(kDt);
    ASSERT_EQ(out.state, ControllerState::kRunning) << out.reason;
    ASSERT_TRUE(out.path_failure.empty()) << out.path_failure;
    if (!out.approaching) break;
    EXPECT_EQ(out.path_time, 0.0);
  }
  // The clock starts at this cycle: the way there at the rate limit, then at least one window.
  EXPECT_EQ(out.path_time, 0.0);
  EXPECT_GE(out.approach_time, away / rate + window - 2 * kDt);
  EXPECT_LE(out.approach_time, away / rate + window + 1.5);
  EXPECT_NEAR(out.approach_time, approach_cycles * kDt, 1.5 * kDt);
  EXPECT_LT(out.error_geodesic, rig.c.options().approach.tolerance);
  EXPECT_LT(control::geodesic_error(out.desired_direction, w[0].direction), 1e-9);
  out = rig.run_for(1.0);
  EXPECT_NEAR(out.path_time, 1.0, 1e-9);  // the cycles after the clock started: T + kDt .. T + 1
  EXPECT_EQ(out.state, ControllerState::kRunning);
  out = rig.run_for(1.05);
  EXPECT_EQ(out.state, ControllerState::kFinished);

  // A tolerance no real tip meets: after the way there and the timeout, a failure; the reference holds.
  control::ControllerOptions strict = rig.c.options();
  strict.approach.tolerance = 1e-9;
  strict.approach.timeout = 0.5;
  rig.c.set_options(strict);
  w[0].direction = control::direction(0.2, -1.0), w[1].direction = control::direction(0.3, -1.0);
  const double away2 = control::geodesic_error(rig.c.reference().direction(), w[0].direction);
  rig.c.follow(control::make_waypoints(w), rig.t);
  int cycles = 0;
  for (; cycles < 2000 && out.path_failure.empty(); ++cycles) out = rig.run_for(kDt);
  EXPECT_EQ(out.path_failure.rfind("approach: the tip did not settle", 0), 0u) << out.path_failure;
  EXPECT_NEAR(cycles * kDt, away2 / rate + 0.5, 0.05);
  EXPECT_EQ(out.state, ControllerState::kRunning);
  EXPECT_EQ(out.source, control::Source::kHold);
  out = rig.run_for(0.1);
  EXPECT_TRUE(out.path_failure.empty());
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

// --- Options -------------------------------------------------------------------------------------

TEST(ControllerOptions, ValidationNamesTheField) {
  control::ControllerOptions p;
  EXPECT_EQ(p.validate(), "");
  p.pd.kp = -1;
  EXPECT_EQ(p.validate().rfind("pd/kp:", 0), 0u) << p.validate();
  p = control::ControllerOptions();
  p.safety.sample_period = std::nan("");
  EXPECT_EQ(p.validate().rfind("safety/sample_period:", 0), 0u);
  p = control::ControllerOptions();
  p.path.duration = 0;
  EXPECT_EQ(p.validate().rfind("path/duration:", 0), 0u);
  p = control::ControllerOptions();
  p.allocation.max_common_force_rate = 0;
  EXPECT_EQ(p.validate().rfind("allocation/max_common_force_rate:", 0), 0u) << p.validate();
  p = control::ControllerOptions();
  p.approach.timeout = -1;
  EXPECT_EQ(p.validate().rfind("approach/timeout:", 0), 0u) << p.validate();
  p = control::ControllerOptions();
  p.modal.tracker_sigma = 0;
  EXPECT_EQ(p.validate().rfind("modal/tracker_sigma:", 0), 0u) << p.validate();
}

// A key that moved to its owner's group is still read from its old place, with a warning naming the
// new key; given at both places it is refused; an invalid value at the old place names the old key.
TEST(ControllerOptions, MovedKeysAreReadFromTheirOldPlaceWithAWarning) {
  const config::ControllerNodeOptions o = config::parse_controller_options(
      YAML::Load("{gains: {kp: 2.5, damping: 0.05}, fast_path_rate: 0.2, allocation_smoothing: 0.1, "
                 "allocation_weight: 1.0e-5, limits: {max_common_force_rate: 0.07}, integrate_from_measured: false}"));
  EXPECT_EQ(o.controller.pd.kp, 2.5);
  EXPECT_EQ(o.controller.allocation.damping, 0.05);
  EXPECT_EQ(o.controller.pd.fast_path_rate, 0.2);
  EXPECT_EQ(o.controller.allocation.smoothing, 0.1);
  EXPECT_EQ(o.controller.allocation.weight, 1.0e-5);
  EXPECT_EQ(o.controller.allocation.max_common_force_rate, 0.07);
  ASSERT_EQ(o.warnings.size(), 7u);
  for (const char* moved :
       {"gains/kp: deprecated, read as pd/kp", "gains/damping: deprecated, read as allocation/damping",
        "fast_path_rate: deprecated, read as pd/fast_path_rate",
        "allocation_smoothing: deprecated, read as allocation/smoothing",
        "allocation_weight: deprecated, read as allocation/weight",
        "limits/max_common_force_rate: deprecated, read as allocation/max_common_force_rate",
        "integrate_from_measured: removed"})
    EXPECT_EQ(std::count_if(o.warnings.begin(), o.warnings.end(),
                            [&](const std::string& w) { return w.rfind(moved, 0) == 0; }),
              1)
        << moved;
  EXPECT_TRUE(config::parse_controller_options(YAML::Load("{pd: {kp: 2.5}}")).warnings.empty());
  const test::RefusedOptions refused[] = {{"{gains: {kp: 2.5}, pd: {kp: 3}}", "gains/kp", "moved to pd/kp"},
                                          {"{gains: {kp: -1}}", "gains/kp", "must lie in [0, 50]"},
                                          {"{allocation_smoothing: 11}", "allocation_smoothing", "must lie in [0, 10]"},
                                          {"{integrate_from_measured: true}", "integrate_from_measured", "removed"},
                                          {"{gains: {kq: 1}}", "gains/kq", "unknown key"}};
  for (const auto& c : refused) test::expect_refused(c);
}

// The controller validates what it is given, and acts with the law the options name or the one given.
TEST(ControllerOptions, TheControllerValidatesItsOptionsAndHoldsOneLaw) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  const control::RobotModel model = config::make_controller_model(sc, flow_gains());
  control::ControllerOptions bad;
  bad.limits.reachable_force_fraction = 0.0;
  try {
    Controller c(model, bad);
    ADD_FAILURE() << "invalid options accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("limits/reachable_force_fraction:", 0), 0u) << e.what();
  }
  control::ControllerOptions p;
  Controller c(model, p);
  EXPECT_EQ(c.law().kind(), control::ControlLaw::kModal);
  p.control_law = control::ControlLaw::kPapers;
  p.pd.kp = 2.0;
  c.set_options(p);
  EXPECT_EQ(c.law().kind(), control::ControlLaw::kPapers);
  EXPECT_EQ(c.law().pd().kp, 2.0);
  control::ControllerOptions wrong = p;
  wrong.safety.max_oscillation = -1.0;
  EXPECT_THROW(c.set_options(wrong), std::invalid_argument);
  EXPECT_EQ(c.options().safety.max_oscillation, p.safety.max_oscillation);  // nothing changed
  Controller given(model, control::ControllerOptions(), std::make_unique<control::PapersLaw>(p.pd));
  EXPECT_EQ(given.law().kind(), control::ControlLaw::kPapers);
  EXPECT_EQ(given.law().pd().kp, control::PdOptions().kp);  // the options' gains
}

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
      {"pd/kp", f.pd.kp, d.pd.kp},
      {"pd/kd", f.pd.kd, d.pd.kd},
      {"pd/ki", f.pd.ki, d.pd.ki},
      {"pd/max_integral", f.pd.max_integral, d.pd.max_integral},
      {"pd/feedforward", f.pd.feedforward, d.pd.feedforward},
      {"pd/fast_path_rate", f.pd.fast_path_rate, d.pd.fast_path_rate},
      {"limits/max_force", f.limits.max_force, d.limits.max_force},
      {"limits/max_force_rate", f.limits.max_force_rate, d.limits.max_force_rate},
      {"limits/max_angular_rate", f.limits.max_angular_rate, d.limits.max_angular_rate},
      {"limits/reachable_force_fraction", f.limits.reachable_force_fraction, d.limits.reachable_force_fraction},
      {"limits/max_path_rate", f.limits.max_path_rate, d.limits.max_path_rate},
      {"allocation/damping", f.allocation.damping, d.allocation.damping},
      {"allocation/weight", f.allocation.weight, d.allocation.weight},
      {"allocation/smoothing", f.allocation.smoothing, d.allocation.smoothing},
      {"allocation/max_common_force_rate", f.allocation.max_common_force_rate, d.allocation.max_common_force_rate},
      {"safety/max_oscillation", f.safety.max_oscillation, d.safety.max_oscillation},
      {"safety/sample_period", f.safety.sample_period, d.safety.sample_period},
      {"safety/stale_periods", double(f.safety.stale_periods), double(d.safety.stale_periods)},
      {"safety/max_solver_failures", double(f.safety.max_solver_failures), double(d.safety.max_solver_failures)},
      {"safety/min_stability_margin", f.safety.min_stability_margin, d.safety.min_stability_margin},
      {"safety/unreachable_tolerance", f.safety.unreachable_tolerance, d.safety.unreachable_tolerance},
      {"safety/flow_fault_tolerance", f.safety.flow_fault_tolerance, d.safety.flow_fault_tolerance},
      {"safety/flow_fault_time", f.safety.flow_fault_time, d.safety.flow_fault_time},
      {"modal/kp", f.modal.kp, d.modal.kp},
      {"modal/ki", f.modal.ki, d.modal.ki},
      {"modal/gain_speed", f.modal.gain_speed, d.modal.gain_speed},
      {"modal/damping_gain", f.modal.damping_gain, d.modal.damping_gain},
      {"modal/actuator_lag", f.modal.actuator_lag, d.modal.actuator_lag},
      {"modal/rounding_force", f.modal.rounding_force, d.modal.rounding_force},
      {"modal/tip_mass_scale", f.modal.tip_mass_scale, d.modal.tip_mass_scale},
      {"modal/damping_time", f.modal.damping_time, d.modal.damping_time},
      {"modal/tracker_sigma", f.modal.tracker_sigma, d.modal.tracker_sigma},
      {"modal/velocity_noise", f.modal.velocity_noise, d.modal.velocity_noise},
      {"modal/disturbance_noise", f.modal.disturbance_noise, d.modal.disturbance_noise},
      {"modal/ring_amplitude", f.modal.ring_amplitude, d.modal.ring_amplitude},
      {"modal/recover_time", f.modal.recover_time, d.modal.recover_time},
      {"identification/probe", double(f.identification.probe), double(d.identification.probe)},
      {"identification/probe_amplitude", f.identification.probe_amplitude, d.identification.probe_amplitude},
      {"approach/tolerance", f.approach.tolerance, d.approach.tolerance},
      {"approach/settle_time", f.approach.settle_time, d.approach.settle_time},
      {"approach/timeout", f.approach.timeout, d.approach.timeout},
      {"path/theta_start", f.path.theta_start, d.path.theta_start},
      {"path/theta_end", f.path.theta_end, d.path.theta_end},
      {"path/phi_start", f.path.phi_start, d.path.phi_start},
      {"path/phi_end", f.path.phi_end, d.path.phi_end},
      {"path/duration", f.path.duration, d.path.duration},
      {"contact/force_threshold", f.contact.force_threshold, d.contact.force_threshold},
      {"contact/max_force", f.contact.max_force, d.contact.max_force},
      {"flow_regulator/feedforward", ff.feedforward, fd.feedforward},
      {"flow_regulator/lead_time", ff.lead_time, fd.lead_time},
      {"flow_regulator/valve_exponent", ff.valve_exponent, fd.valve_exponent},
      {"flow_regulator/kp", ff.kp, fd.kp},
      {"flow_regulator/ki", ff.ki, fd.ki},
      {"flow_regulator/output_min", ff.output_min, fd.output_min},
      {"flow_regulator/output_max", ff.output_max, fd.output_max},
  };
  for (const auto& n : numbers) {
    EXPECT_TRUE(in_file(n.key)) << n.key << " is not in " << path;
    EXPECT_EQ(n.file, n.def) << n.key;
  }
  for (const char* key :
       {"mode", "control_law", "autostart", "base_frame", "path/type", "contact/reaction", "keep_out"})
    EXPECT_TRUE(in_file(key)) << key;
  EXPECT_TRUE(f.keep_out.empty() && d.keep_out.empty());
  EXPECT_EQ(f.contact.reaction, d.contact.reaction);
  EXPECT_EQ(f.mode, d.mode);
  EXPECT_EQ(f.control_law, d.control_law);
  EXPECT_EQ(f.path.type, d.path.type);
  EXPECT_EQ(file.autostart, def.autostart);
  EXPECT_EQ(file.base_frame, def.base_frame);
  // And the file names nothing else (the parser rejects unknown keys, so this is the full list).
  size_t keys = 0;
  for (const auto& top : yaml) keys += top.second.IsMap() ? top.second.size() : 1;
  EXPECT_EQ(keys, sizeof(numbers) / sizeof(numbers[0]) + 7);
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

TEST(ControllerOptions, BadTeleopPathTypeAndLawAreRefusedNamingTheKey) {
  const struct {
    const char* yaml;
    const char* key;
  } cases[] = {{"{teleop: {axis_up: -1}}", "teleop/axis_up"},
               {"{teleop: {timeout: 0}}", "teleop/timeout"},
               {"{teleop: {scale_right: .nan}}", "teleop/scale_right"},
               {"{path: {type: circle}}", "path/type"},
               {"{limits: {max_angular_rate: 0}}", "limits/max_angular_rate"},
               {"{limits: {reachable_force_fraction: 1.5}}", "limits/reachable_force_fraction"},
               {"{control_law: lqr}", "control_law"},
               {"{modal: {damping_gain: -1}}", "modal/damping_gain"},
               {"{modal: {tip_mass_scale: .nan}}", "modal/tip_mass_scale"},
               {"{observer: {enabled: true}}", "observer/enabled"},
               {"{limits: {min_jet_force: 0.005}}", "limits/min_jet_force"}};
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
      {"pd/kp", 0.0, 50.0},
      {"pd/kd", 0.0, 5.0},
      {"pd/feedforward", 0.0, 2.0},
      {"allocation/damping", 1e-4, 10.0},
      {"limits/max_force", 0.01, 1.0},
      {"limits/max_force_rate", 0.01, 20.0},
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

// --- Fast paths ----------------------------------------------------------------------------------

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
    p.control_law = control::ControlLaw::kPapers;
    p.pd.ki = law == 0 ? 0.0 : 6.0;
    p.pd.fast_path_rate = law == 2 ? 0.0 : 0.1;
    p.path.type = control::PathType::kNone;
    p.identification.probe = false;  // a static plant has no mode to probe
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

// Held still, the fast-path elements (K_i, rounded allocation) do nothing: config/controller.yaml's law
// commands what the paper's law does, bit for bit, on a still target with a mismatched plant.
TEST(Controller, OnAStillTargetTheFastPathElementsAreThePapersLaw) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  rod::RodModel truth = test::bare(sc);
  truth.segments[0].stiffness *= 0.8;
  control::ControllerOptions bare = static_target(0.6, 1.0);
  bare.pd.ki = 0.0;
  bare.allocation.smoothing = 0.0;
  const control::ControllerOptions fast = static_target(0.6, 1.0);  // the defaults: K_i 6, rounding
  ASSERT_GT(fast.pd.ki, 0.0);
  ASSERT_GT(fast.allocation.smoothing, 0.0);
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
    p.identification.probe = false;  // a static plant has no mode to probe
    p.path.type = control::PathType::kNone;
    p.control_law = control::ControlLaw::kPapers;  // the allocation alone
    p.pd.ki = 0.0;
    p.allocation.smoothing = round ? 0.3 : 0.0;
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
