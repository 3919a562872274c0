// The simulated plant's parts against their own definitions: valve statics and lag, sensor noise
// statistics, plant configuration errors and defaults, the static limit against the quasi-static model, and
// determinism of a closed-loop run for a seed.
#include <gtest/gtest.h>

#include <cmath>

#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/sim/closed_loop_run.h"
#include "test_helpers.h"

using namespace hydrojet;

TEST(Valve, DeadZoneLagHysteresisAndSaturation) {
  plant::ValveModel p;
  p.max_flow = 1.6e-5, p.dead_zone = 0.1, p.exponent = 0.8, p.hysteresis = 0.0, p.time_constant = 0.05;
  p.saturation = 1.0;
  plant::Valve v(p);
  EXPECT_EQ(v.steady_flow(0.05), 0.0);  // inside the dead zone
  const double u = (0.6 - 0.1) / 0.9;
  EXPECT_NEAR(v.steady_flow(0.6), 1.6e-5 * std::pow(u, 0.8), 1e-18);
  // First-order lag: after one time constant 1 − e⁻¹ of the step.
  double q = 0.0;
  for (int i = 0; i < 50; ++i) q = v.step(0.6, 0.001);
  EXPECT_NEAR(q / v.steady_flow(0.6), 1.0 - std::exp(-1.0), 1e-12);
  // Saturation.
  p.saturation = 1e-5;
  plant::Valve s(p);
  for (int i = 0; i < 2000; ++i) s.step(1.0, 0.001);
  EXPECT_NEAR(s.flow(), 1e-5, 1e-12);
  // Hysteresis (play of width h): coming down, the effective duty lags by h.
  p.saturation = 1.0, p.hysteresis = 0.1, p.time_constant = 1e-4;
  plant::Valve h(p);
  for (int i = 0; i < 100; ++i) h.step(0.8, 0.001);
  for (int i = 0; i < 100; ++i) h.step(0.7, 0.001);
  EXPECT_NEAR(h.flow(), 1.6e-5 * std::pow((0.75 - 0.1) / 0.9, 0.8), 1e-12);  // 0.7 + h/2
  // Stuck: ignores the command.
  h.set_stuck(1.0);
  for (int i = 0; i < 100; ++i) h.step(0.0, 0.001);
  EXPECT_GT(h.flow(), 1.5e-5);
  EXPECT_EQ(p.validate(), "");
  p.dead_zone = 1.0;
  EXPECT_EQ(p.validate().rfind("dead_zone", 0), 0u);
}

TEST(Sensors, NoiseHasTheConfiguredSpreadAndLatencyDelays) {
  plant::TrackerNoise n;
  n.position_quantum = 0.0;
  plant::TrackerModel tracker(n, 42);
  plant::SensorPose tip, base;
  double s2 = 0.0, a2 = 0.0;
  const int N = 4000;
  for (int i = 0; i < N; ++i) {
    const plant::TrackerSample s = tracker.sample(i * 0.01, tip, base);
    ASSERT_TRUE(s.valid);
    s2 += s.tip.position.squaredNorm();
    a2 += Eigen::AngleAxisd(s.tip.orientation).angle() * Eigen::AngleAxisd(s.tip.orientation).angle();
  }
  // 3 axes: E|x|² = 3σ²; the standard error of the estimate at N = 4000 is ~2 %.
  EXPECT_NEAR(std::sqrt(s2 / (3 * N)), n.position_sigma, 0.05 * n.position_sigma);
  EXPECT_NEAR(std::sqrt(a2 / (3 * N)), n.angle_sigma, 0.05 * n.angle_sigma);

  plant::TrackerNoise exact{0, 0, 0, 0.03, 0, 0.05};
  plant::TrackerModel delayed(exact, 1);
  for (int i = 0; i <= 10; ++i) {
    plant::SensorPose p;
    p.position.x() = i;  // the true pose moves by 1 per sample
    const plant::TrackerSample s = delayed.sample(i * 0.01, p, base);
    ASSERT_TRUE(s.valid);
    EXPECT_NEAR(s.tip.position.x(), std::max(0, i - 3), 1e-12);  // 30 ms = 3 samples late
    EXPECT_NEAR(s.stamp, std::max(0, i - 3) * 0.01, 1e-12);
  }
  delayed.force_dropout(0.2, 0.05);
  EXPECT_FALSE(delayed.sample(0.21, base, base).valid);
  EXPECT_TRUE(delayed.sample(0.26, base, base).valid);
}

TEST(PlantConfig, ErrorsNameTheKey) {
  const config::Scene sc = test::scene("hydrojet_30deg");
  auto key = [&](const std::string& yaml) -> std::string {
    try {
      config::make_plant(sc, yaml);
    } catch (const config::SceneError& e) {
      return e.key();
    }
    return "(none)";
  };
  EXPECT_EQ(key("plant: {mismatch: {tip_mass_scale: -1}}"), "plant.mismatch.tip_mass_scale");
  EXPECT_EQ(key("plant: {mismatch: {colour: 1}}"), "plant.mismatch.colour");
  EXPECT_EQ(key("plant: {valves: [{dead_zone: 2}, {}, {}]}"), "plant.valves[0].dead_zone");
  EXPECT_EQ(key("plant: {valves: [{}, {}]}"), "plant.valves");
  EXPECT_EQ(key("plant: {dynamics: {nodes: 2.5}}"), "plant.dynamics.nodes");
  EXPECT_EQ(key("plant: {sensor_noise: maybe}"), "plant.sensor_noise");
  EXPECT_EQ(key("plant: {dynamics: {internal_dt: 0.5}}"), "plant.internal_dt");
  EXPECT_EQ(key("plant: [1"), "plant");
  EXPECT_EQ(key("plant: {tracker: {latnecy: 0.01}}"), "plant.tracker.latnecy");
  EXPECT_EQ(key("plant: {flow_sensors: {sigma: low}}"), "plant.flow_sensors.sigma");
  EXPECT_EQ(key("plant: {dynamics: {tip_inertia: [1, 2]}}"), "plant.dynamics.tip_inertia");
  EXPECT_EQ(key("plant: {command_timeout: .nan}"), "plant.command_timeout");
  // The base tilt is read off the scene's gravity: 30° (plus the mismatch's offset, here none).
  EXPECT_NEAR(config::make_plant(sc, "plant: {mismatch: {base_tilt_offset: 0}}").base_tilt, M_PI / 6, 1e-9);
}

// config/plant.yaml is the source of the plant's defaults: every key it sets equals the field of
// the default-constructed struct, it sets no key this test does not compare, and a plant built
// without a plant file is the plant built from it.
TEST(PlantConfig, DefaultsMatchYaml) {
  const std::string path = std::string(HYDROJET_SOURCE_DIR) + "/config/plant.yaml";
  const YAML::Node root = YAML::LoadFile(path);
  config::YamlTree<config::SceneError> t(root, '.');
  const plant::ModelMismatch m;
  const plant::PlantModel p;
  const std::string M = "plant.mismatch.", D = "plant.dynamics.", T = "plant.tracker.", F = "plant.flow_sensors.";
  EXPECT_EQ(t.vec3<Eigen::Vector3d>(M + "precurvature_offset"), m.precurvature_offset);
  EXPECT_EQ(t.number(M + "bending_stiffness_scale"), m.bending_stiffness_scale);
  EXPECT_EQ(t.number(M + "torsional_stiffness_scale"), m.torsional_stiffness_scale);
  EXPECT_EQ(t.vec3<Eigen::Vector3d>(M + "misalignment_offset"), m.misalignment_offset);
  EXPECT_EQ(t.number(M + "tip_mass_scale"), m.tip_mass_scale);
  EXPECT_EQ(t.number(M + "base_tilt_offset"), m.base_tilt_offset);

  EXPECT_EQ(t.number(D + "shear_stiffness"), p.rod.shear_stiffness);
  EXPECT_EQ(t.number(D + "axial_stiffness"), p.rod.axial_stiffness);
  EXPECT_EQ(t.number(D + "kelvin_voigt_time"), p.rod.kelvin_voigt_time);
  EXPECT_EQ(t.number(D + "linear_drag"), p.rod.linear_drag);
  EXPECT_EQ(t.number(D + "tip_drag"), p.rod.tip_drag);
  EXPECT_EQ(t.number(D + "tip_angular_drag"), p.rod.tip_angular_drag);
  EXPECT_EQ(t.vec3<Eigen::Vector3d>(D + "tip_inertia"), p.rod.tip_inertia);
  EXPECT_EQ(t.integer(D + "nodes", -1), p.rod.nodes);
  EXPECT_EQ(t.number(D + "alpha"), p.rod.alpha);
  EXPECT_EQ(t.number(D + "internal_dt"), p.internal_dt);

  const YAML::Node valves = t.find("plant.valves");
  t.allow("plant.valves");
  ASSERT_TRUE(valves.IsSequence());
  ASSERT_EQ(valves.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    SCOPED_TRACE("valve " + std::to_string(i + 1));
    config::YamlTree<config::SceneError> v(valves[i], '.');
    const plant::ValveModel& d = p.valves[i];
    EXPECT_EQ(v.number("max_flow"), d.max_flow);
    EXPECT_EQ(v.number("dead_zone"), d.dead_zone);
    EXPECT_EQ(v.number("exponent"), d.exponent);
    EXPECT_EQ(v.number("hysteresis"), d.hysteresis);
    EXPECT_EQ(v.number("time_constant"), d.time_constant);
    EXPECT_EQ(v.number("saturation"), d.saturation);
    EXPECT_NO_THROW(v.reject_unknown());
  }

  EXPECT_EQ(t.number(T + "position_sigma"), p.tracker.position_sigma);
  EXPECT_EQ(t.number(T + "angle_sigma"), p.tracker.angle_sigma);
  EXPECT_EQ(t.number(T + "position_quantum"), p.tracker.position_quantum);
  EXPECT_EQ(t.number(T + "latency"), p.tracker.latency);
  EXPECT_EQ(t.number(T + "dropout_rate"), p.tracker.dropout_rate);
  EXPECT_EQ(t.number(T + "dropout_duration"), p.tracker.dropout_duration);
  EXPECT_EQ(t.number(F + "sigma"), p.flow.sigma);
  EXPECT_EQ(t.number(F + "quantum"), p.flow.quantum);
  EXPECT_EQ(t.boolean("plant.sensor_noise", !p.sensor_noise), p.sensor_noise);
  EXPECT_EQ(t.number("plant.command_timeout"), p.command_timeout);
  EXPECT_EQ(t.number("plant.thruster_time_constant"), p.thruster_time_constant);
  EXPECT_EQ(t.vec3<Eigen::Vector3d>("plant.base_position"), p.base_position);
  EXPECT_EQ(t.vec3<Eigen::Vector3d>("plant.external_tip_force"), p.external_tip_force);
  EXPECT_EQ(t.vec3<Eigen::Vector3d>("plant.external_tip_moment"), p.external_tip_moment);
  EXPECT_NO_THROW(t.reject_unknown());  // nothing in the file left uncompared

  // No plant file = config/plant.yaml.
  const config::Scene sc = test::scene("hydrojet_30deg");
  const plant::PlantModel a = config::make_plant(sc, ""), b = config::load_plant(sc, path);
  EXPECT_EQ(a.base_tilt, b.base_tilt);
  EXPECT_EQ(a.rod.rod.segments[0].precurvature, b.rod.rod.segments[0].precurvature);
  EXPECT_EQ(a.rod.rod.segments[0].stiffness, b.rod.rod.segments[0].stiffness);
  EXPECT_EQ(a.rod.rod.tip_mass, b.rod.rod.tip_mass);
  ASSERT_EQ(a.rod.rod.actuators.size(), b.rod.rod.actuators.size());
  for (size_t i = 0; i < a.rod.rod.actuators.size(); ++i)
    EXPECT_EQ(a.rod.rod.actuators[i].unit_wrench(), b.rod.rod.actuators[i].unit_wrench());
  EXPECT_EQ(a.rod.kelvin_voigt_time, b.rod.kelvin_voigt_time);
  EXPECT_EQ(a.valves[1].dead_zone, b.valves[1].dead_zone);
}

namespace {

/// The plant of scene `sc` exactly as the scene says: no mismatch, no sensor noise.
plant::PlantModel exact_plant(const config::Scene& sc) {
  return config::make_plant(
      sc,
      "plant: {sensor_noise: false, dynamics: {kelvin_voigt_time: 0.03}, mismatch: {precurvature_offset: [0, 0, 0], "
      "bending_stiffness_scale: 1, misalignment_offset: [0, 0, 0], tip_mass_scale: 1, base_tilt_offset: 0}}");
}

}  // namespace

// With constant valve duties the plant settles to the quasi-static model at its true parameters.
TEST(Plant, SettlesToTheQuasiStaticModel) {
  const config::Scene sc = test::scene("hydrojet_30deg");
  // No mismatch: the plant is the nominal scene.
  const plant::PlantModel p = exact_plant(sc);
  plant::Plant pl(p, 1);
  const Eigen::Vector3d duty(0.4, 0.2, 0.3);
  for (int k = 1; k <= 600; ++k) {
    pl.command(duty, (k - 1) * 0.01);
    ASSERT_TRUE(pl.advance_to(k * 0.01)) << pl.error();
  }
  rod::RodSolver qs(p.rod.rod, sc.solver);
  const rod::RodSolution s = qs.solve(pl.jet_forces());
  ASSERT_TRUE(s.converged);
  // Shear/extension compliance of the dynamic rod (GA = EA = 1e5 N) and its grid: ~1e-6.
  EXPECT_LT((pl.tip_position() - s.tip_position).norm(), 2e-6);
  EXPECT_LT(so3::log(pl.tip_rotation().transpose() * s.tip_rotation).norm(), 2e-5);
}

namespace {

/// The controller model, the plant and the controller options of a shipped scene with the shipped
/// config/controller.yaml and config/plant.yaml (what scripts/experiment runs).
struct ShippedSetup {
  control::RobotModel model;
  plant::PlantModel plant;
  control::ControllerOptions controller;
};

ShippedSetup shipped(const std::string& scene) {
  const config::Scene sc = test::scene(scene);
  const config::ControllerNodeOptions o =
      config::load_controller_options(std::string(HYDROJET_SOURCE_DIR) + "/config/controller.yaml");
  return {config::make_controller_model(sc, o.flow_regulator),
          config::load_plant(sc, std::string(HYDROJET_SOURCE_DIR) + "/config/plant.yaml"), o.controller};
}

}  // namespace

TEST(ClosedLoopRun, DeterministicForASeed) {
  const ShippedSetup setup = shipped("hydrojet_0deg");
  const control::RobotModel& m = setup.model;
  const plant::PlantModel& p = setup.plant;
  control::ControllerOptions c = setup.controller;
  c.path.duration = 5.0;
  const sim::RunResult a = sim::run_path(m, c, p, 7), b = sim::run_path(m, c, p, 7), d = sim::run_path(m, c, p, 8);
  ASSERT_TRUE(a.completed) << a.reason;
  EXPECT_EQ(a.rms, b.rms);
  EXPECT_EQ(a.samples.size(), b.samples.size());
  EXPECT_NE(a.rms, d.rms);  // another seed, other sensor noise
}

// A general robot: with constant drives the second robot's plant settles where the
// static general solver puts it at the forces its thrusters reach (drive × max_force after their
// lag), mid-body thrusters, point mass and segments included.
TEST(PlantGeneral, SettlesToTheGeneralStaticModel) {
  const config::Scene sc = test::scene("two_segment_thrusters");
  const plant::PlantModel p = exact_plant(sc);
  plant::Plant pl(p, 1);
  ASSERT_EQ(pl.input_count(), 6);
  rod::InputVector duty(6);
  duty << 0.4, 0.0, 0.3, 0.1, 0.5, 0.2;
  for (int k = 1; k <= 600; ++k) {
    pl.command(duty, (k - 1) * 0.01);
    ASSERT_TRUE(pl.advance_to(k * 0.01)) << pl.error();
  }
  rod::InputVector q(6);
  for (int i = 0; i < 6; ++i) q[i] = duty[i] * sc.rod.actuators[i].max_force;
  EXPECT_LT((pl.jet_forces() - q).norm(), 1e-9) << "the drives' forces after their lag";
  EXPECT_EQ(pl.flow_sample(), rod::InputVector::Zero(6)) << "thrusters have no flow";
  rod::RodSolver qs(sc.rod, sc.solver);
  const rod::RodSolution s = qs.solve(q);
  ASSERT_TRUE(s.converged) << s.message;
  std::printf("second robot: plant vs static model: %.2e m, %.2e rad\n", (pl.tip_position() - s.tip_position).norm(),
              so3::log(pl.tip_rotation().transpose() * s.tip_rotation).norm());
  EXPECT_LT((pl.tip_position() - s.tip_position).norm(), 2e-6);
  EXPECT_LT(so3::log(pl.tip_rotation().transpose() * s.tip_rotation).norm(), 2e-5);
  // A command of the wrong size closes the valves (drives at zero).
  pl.command(rod::InputVector::Constant(3, 0.5), 6.0);
  EXPECT_EQ(pl.valve_command(), rod::InputVector::Zero(6));
}

// The controller steers the second robot on its plant (model mismatch, sensor noise): closed loop
// follows a spiral with less than half the open-loop error (the experiment's comparison).
TEST(ClosedLoopRun, TheSecondRobotClosedLoopBeatsOpenLoop) {
  const ShippedSetup setup = shipped("two_segment_thrusters");
  const control::RobotModel& m = setup.model;
  const plant::PlantModel& p = setup.plant;
  control::ControllerOptions c = setup.controller;
  c.path.duration = 60.0;
  c.path.theta_end = 0.5;
  c.path.phi_end = 4.0;
  c.mode = control::LoopMode::kClosed;
  const sim::RunResult closed = sim::run_path(m, c, p, 3);
  c.mode = control::LoopMode::kOpen;
  const sim::RunResult open = sim::run_path(m, c, p, 3);
  ASSERT_TRUE(closed.completed) << closed.reason;
  ASSERT_TRUE(open.completed) << open.reason;
  std::printf("second robot, 60 s spiral to 0.5 rad: closed %.4f rad, open %.4f rad RMS\n", closed.rms, open.rms);
  EXPECT_LT(closed.rms, 0.5 * open.rms);
}

// The disturbance observer converges to a constant force injected at the simulated tip
// within 2 s, to 10 %. The plant is the model exactly (no mismatch) but for that force, with sensor
// noise; the controller holds its start direction in closed loop, so the inputs move meanwhile.
TEST(DisturbanceObserver, ConvergesToAForceInjectedAtTheTip) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  plant::PlantModel p = exact_plant(sc);
  p.sensor_noise = true;
  p.external_tip_force = Eigen::Vector3d(0.03, -0.02, 0.0);  // [N], tip frame
  const config::ControllerNodeOptions o =
      config::load_controller_options(std::string(HYDROJET_SOURCE_DIR) + "/config/controller.yaml");
  control::ControllerOptions c = o.controller;
  c.path_type = control::PathType::kNone;
  c.mode = control::LoopMode::kClosed;
  c.observer = true;
  c.observer_time_constant = 0.25;
  control::Controller ctl(config::make_controller_model(sc, o.flow_regulator), c);
  plant::Plant pl(p, 5);
  const double dt = 0.01;
  ctl.start(0.0);
  double at_2s = -1.0;
  for (int k = 0; k <= 300; ++k) {
    const double t = k * dt;
    ASSERT_TRUE(pl.advance_to(t)) << pl.error();
    control::ControllerInputs in;
    const plant::TrackerSample ts = pl.tracker_sample();
    in.t = t;
    in.tip_valid = ts.valid;
    in.tip_stamp = ts.stamp;
    in.tip_rotation = ts.base.orientation.toRotationMatrix().transpose() * ts.tip.orientation.toRotationMatrix();
    in.flows = pl.flow_sample();
    in.flow_valid = true;
    in.flow_stamp = t;
    const control::ControllerOutput out = ctl.update(in);
    ASSERT_NE(out.state, control::ControllerState::kAborted) << out.reason;
    pl.command(out.valve_command, t);
    if (k == 200) at_2s = (ctl.observer().force() - p.external_tip_force).norm() / p.external_tip_force.norm();
  }
  const Eigen::Vector3d f = ctl.observer().force();
  std::printf("observer: estimate (%.4f, %.4f, %.4f) N at 3 s, relative error %.3f at 2 s\n", f.x(), f.y(), f.z(),
              at_2s);
  EXPECT_LT(at_2s, 0.10);
}

// The plant variations (config/plants/*.yaml) load on both HydroJet scenes and differ
// from the default plant where their comments say.
TEST(PlantConfig, TheVariationsLoad) {
  const std::string dir = std::string(HYDROJET_SOURCE_DIR) + "/config/plants/";
  const config::Scene sc = test::scene("hydrojet_0deg");
  const plant::PlantModel def = config::load_plant(sc, std::string(HYDROJET_SOURCE_DIR) + "/config/plant.yaml");
  int n = 0;
  for (const char* name : {"heavy_slow", "other_draw", "mid_latency"}) {
    SCOPED_TRACE(name);
    for (const char* scene : {"hydrojet_0deg", "hydrojet_30deg"})
      EXPECT_NO_THROW(config::load_plant(test::scene(scene), dir + name + ".yaml"));
    const plant::PlantModel v = config::load_plant(sc, dir + name + ".yaml");
    EXPECT_NE(v.rod.kelvin_voigt_time, def.rod.kelvin_voigt_time);
    EXPECT_NE(v.rod.rod.tip_mass, def.rod.rod.tip_mass);
    ++n;
  }
  EXPECT_EQ(n, 3);
}
