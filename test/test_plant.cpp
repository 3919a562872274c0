// The simulated plant's parts against their own definitions: sensor noise statistics, plant
// configuration errors and defaults, and the static limit against the quasi-static model.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <cstdio>
#include <string>

#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/config/yaml_tree.h"
#include "hydrojet_control/plant/plant.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"
#include "plant_fixtures.h"
#include "test_helpers.h"

using namespace hydrojet;
using test::exact_plant;

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
  EXPECT_EQ(key("plant: {valves: []}"), "plant.valves");
  EXPECT_EQ(key("plant: {valves: {dead_zone: 0.1}}"), "plant.valves");
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

// A time that is not finite, or lies more than an hour ahead, is refused with a reason and leaves the
// plant where it was (an unbounded integration, or a cast of inf to a step count, otherwise).
TEST(Plant, RefusesATimeNotFiniteOrTooFarAhead) {
  const plant::PlantModel p = exact_plant(test::scene("hydrojet_0deg"));
  plant::Plant pl(p, 1);
  ASSERT_TRUE(pl.advance_to(0.01)) << pl.error();
  for (const double t : {std::numeric_limits<double>::infinity(), std::nan(""), 0.01 + 3600.5}) {
    EXPECT_FALSE(pl.advance_to(t)) << t;
    EXPECT_NE(pl.error().find("advance_to: time"), std::string::npos) << pl.error();
    EXPECT_EQ(pl.time(), 0.01);
  }
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
