// Scene YAML loading and validation: every bad key is named in the error; the shared YAML reader.
#include <gtest/gtest.h>

#include <cmath>

#include "hydrojet_control/config/scene.h"
#include "test_helpers.h"

using hydrojet::config::parse_scene;
using hydrojet::config::SceneError;

namespace {

const char* kGood = R"(
rod:
  length: 0.09
  bending_stiffness: [6.01e-4, 5.0e-4]
  torsional_stiffness: 2.23e-4
  precurvature: [0.034, 0.88, 0.0]
  linear_density: 0.01
tip:
  mass: 0.00258
gravity: [0.0, 0.0, 9.81]
)";

std::string error_key(const std::string& yaml) {
  try {
    parse_scene(yaml);
  } catch (const SceneError& e) {
    return e.key();
  }
  return "(no error)";
}

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const size_t i = s.find(from);
  EXPECT_NE(i, std::string::npos) << from;
  return s.replace(i, from.size(), to);
}

}  // namespace

TEST(Scene, ParsesAllKeys) {
  const auto s = parse_scene(kGood);
  EXPECT_DOUBLE_EQ(s.rod.segments[0].length, 0.09);
  EXPECT_DOUBLE_EQ(s.rod.segments[0].stiffness[0], 6.01e-4);
  EXPECT_DOUBLE_EQ(s.rod.segments[0].stiffness[1], 5.0e-4);
  EXPECT_DOUBLE_EQ(s.rod.segments[0].stiffness[2], 2.23e-4);
  EXPECT_DOUBLE_EQ(s.rod.segments[0].precurvature[1], 0.88);
  EXPECT_DOUBLE_EQ(s.rod.segments[0].linear_density, 0.01);
  EXPECT_DOUBLE_EQ(s.rod.tip_mass, 0.00258);
  EXPECT_DOUBLE_EQ(s.rod.gravity[2], 9.81);
}

TEST(Scene, ShippedScenesLoad) {
  const auto a = hydrojet::test::scene("hydrojet_0deg");
  const auto b = hydrojet::test::scene("hydrojet_30deg");
  EXPECT_NEAR(a.rod.gravity.norm(), 9.81, 1e-9);
  EXPECT_NEAR(b.rod.gravity.norm(), 9.81, 1e-9);
  // 30° between the two gravity directions.
  EXPECT_NEAR(std::acos(a.rod.gravity.normalized().dot(b.rod.gravity.normalized())), M_PI / 6, 1e-9);
}

// Hollow cylinder: EI = E·π(D⁴ − d⁴)/64, GJ = G·π(D⁴ − d⁴)/32.
TEST(Scene, ModuliAndDiametersGiveStiffness) {
  const auto s = parse_scene(R"(
rod: {length: 0.09, youngs_modulus: 1.0e5, shear_modulus: 3.4e4, outer_diameter: 0.008, inner_diameter: 0.006}
tip: {mass: 0.0}
gravity: [0, 0, 0]
)");
  const double I = M_PI * (std::pow(0.008, 4) - std::pow(0.006, 4)) / 64.0;
  EXPECT_NEAR(s.rod.segments[0].stiffness[0], 1.0e5 * I, 1e-15);
  EXPECT_NEAR(s.rod.segments[0].stiffness[2], 3.4e4 * 2 * I, 1e-15);
}

TEST(Scene, ErrorsNameTheKey) {
  EXPECT_EQ(error_key(replace(kGood, "  length: 0.09\n", "")), "rod.length");
  EXPECT_EQ(error_key(replace(kGood, "6.01e-4, 5.0e-4", "-6.01e-4, 5.0e-4")), "rod.bending_stiffness[0]");
  EXPECT_EQ(error_key(replace(kGood, "2.23e-4", "0")), "rod.torsional_stiffness");
  EXPECT_EQ(error_key(replace(kGood, "0.034, 0.88, 0.0", ".nan, 0.88, 0.0")), "rod.precurvature[0]");
  EXPECT_EQ(error_key(replace(kGood, "0.034, 0.88, 0.0", "0.034, 0.88")), "rod.precurvature");
  EXPECT_EQ(error_key(replace(kGood, "  mass: 0.00258", "  mass: heavy")), "tip.mass");
  EXPECT_EQ(error_key(replace(kGood, "  mass: 0.00258", "  mass: -1")), "tip.mass");
  EXPECT_EQ(error_key(replace(kGood, "  mass: 0.00258", "  mass: 0.00258\n  colour: red")), "tip.colour");
  EXPECT_EQ(error_key(replace(kGood, "  length: 0.09", "  length: 0.09\n  lenght: 0.1")), "rod.lenght");
  EXPECT_EQ(error_key(replace(kGood, "gravity: [0.0, 0.0, 9.81]\n", "")), "gravity");
  EXPECT_EQ(error_key(replace(kGood, "tip:\n  mass: 0.00258\n", "")), "tip");
  EXPECT_EQ(error_key("rod: [1, 2"), "scene");  // malformed YAML
  EXPECT_EQ(error_key(std::string(kGood) + "solver: {integrator: euler}\n"), "solver.integrator");
  EXPECT_EQ(error_key(std::string(kGood) + "solver: {steps: 2.5}\n"), "solver.steps");
  EXPECT_EQ(error_key(std::string(kGood) + "solver: {stepz: 2}\n"), "solver.stepz");
  // Unknown top-level sections are allowed (later tools add their own).
  EXPECT_EQ(error_key(std::string(kGood) + "plant: {anything: 1}\n"), "(no error)");
}

// Found by fuzz_scene_yaml (test/fuzz/, docs/robustness.md): a key that is not a plain name (a flow
// list or mapping as a key, or a null key) escaped as yaml-cpp's BadConversion and ended the process.
// Now a SceneError names the section that holds it.
TEST(Scene, KeysThatAreNotNamesAreRefusedNamingTheSection) {
  EXPECT_EQ(error_key(replace(kGood, "  length: 0.09\n", "  length: 0.09\n  ? [a, b]\n  : 1\n")), "rod");
  EXPECT_EQ(error_key(replace(kGood, "  mass: 0.00258", "  mass: 0.00258\n  ~: 1")), "tip");
  EXPECT_EQ(error_key(std::string(kGood) + "solver:\n  ? [a]\n  : 1\n"), "solver");
}

// rod.model: cosserat with K_se from the keys, or from moduli and the cross-section; the solver keys
// of the numerics part; bad combinations name the key.
TEST(Scene, CosseratModelAndSolverKeys) {
  const auto s = parse_scene(std::string(kGood) + R"(solver:
  integrator: cvode-bdf
  tolerance: 1.0e-8
  shooting_segments: 4
  accuracy_tolerance: 0
)");
  EXPECT_EQ(s.rod.kind, hydrojet::rod::RodKind::kKirchhoff);
  EXPECT_EQ(s.solver.integrator.type, hydrojet::rod::IntegratorType::kCvodeBdf);
  EXPECT_EQ(s.solver.shooting_segments, 4);
  EXPECT_EQ(s.solver.accuracy_tolerance, 0.0);
  const auto c = parse_scene(
      replace(kGood, "  linear_density: 0.01\n",
              "  linear_density: 0.01\n  model: cosserat\n  shear_stiffness: 0.4\n  axial_stiffness: 1.3\n"));
  EXPECT_EQ(c.rod.kind, hydrojet::rod::RodKind::kCosserat);
  EXPECT_DOUBLE_EQ(c.rod.segments[0].shear_stiffness, 0.4);
  EXPECT_DOUBLE_EQ(c.rod.segments[0].axial_stiffness, 1.3);
  const auto m = parse_scene(R"(
rod: {length: 0.09, model: cosserat, youngs_modulus: 1.0e5, shear_modulus: 3.4e4, outer_diameter: 0.008, inner_diameter: 0.006}
tip: {mass: 0.0}
gravity: [0, 0, 0]
)");
  const double A = M_PI * (0.008 * 0.008 - 0.006 * 0.006) / 4.0;
  EXPECT_NEAR(m.rod.segments[0].axial_stiffness, 1.0e5 * A, 1e-12);
  EXPECT_NEAR(m.rod.segments[0].shear_stiffness, 3.4e4 * A, 1e-12);
  EXPECT_EQ(error_key(replace(kGood, "  linear_density: 0.01\n", "  linear_density: 0.01\n  model: timoshenko\n")),
            "rod.model");
  EXPECT_EQ(error_key(replace(kGood, "  linear_density: 0.01\n", "  linear_density: 0.01\n  model: cosserat\n")),
            "rod.shear_stiffness");
  EXPECT_EQ(error_key(replace(kGood, "  linear_density: 0.01\n",
                              "  linear_density: 0.01\n  model: cosserat\n  shear_stiffness: 0.4\n")),
            "rod.axial_stiffness");
  EXPECT_EQ(error_key(replace(kGood, "  linear_density: 0.01\n", "  linear_density: 0.01\n  axial_stiffness: 1.3\n")),
            "rod.axial_stiffness");
  EXPECT_EQ(error_key(std::string(kGood) + "solver: {shooting_segments: -1}\n"), "solver.shooting_segments");
  EXPECT_EQ(error_key(std::string(kGood) + "solver: {accuracy_tolerance: -1}\n"), "solver.accuracy_tolerance");
}

// The shared reader behind scene, plant, controller, rig and node options (config/yaml_tree.h).
namespace {
struct TreeError : hydrojet::config::KeyError {
  using KeyError::KeyError;
};
using Tree = hydrojet::config::YamlTree<TreeError>;

/// The key named by the error `f` throws, or "(no error)".
template <class F>
std::string tree_error(F f) {
  try {
    f();
  } catch (const TreeError& e) {
    return e.key() + " | " + e.detail();
  }
  return "(no error)";
}
}  // namespace

TEST(YamlTree, TypedReadsFallbacksAndNamedErrors) {
  const YAML::Node y = YAML::Load("gains: {kp: 3, kd: ~, name: x}\nsteps: 4\nlist: [1, 2, 3]\nflag: yes\n");
  Tree t(y, '/', "~");
  EXPECT_EQ(t.number("gains/kp", 0.0), 3.0);
  EXPECT_EQ(t.number("gains/kd", 0.5), 0.5);    // null counts as absent
  EXPECT_EQ(t.number("gains/ki", 0.25), 0.25);  // absent
  EXPECT_EQ(t.integer("steps", 1, 1, 10), 4);
  EXPECT_TRUE(t.boolean("flag", false));
  EXPECT_EQ(t.vec3<hydrojet::rod::Vec3>("list"), hydrojet::rod::Vec3(1, 2, 3));
  EXPECT_EQ(tree_error([&] { t.number("gains/name", 0.0); }), "~gains/name | must be a number, got 'x'");
  EXPECT_EQ(tree_error([&] { t.number("gains/kf"); }), "~gains/kf | missing");
  EXPECT_EQ(tree_error([&] { t.integer("steps", 1, 5, 10); }), "~steps | must be an integer in [5, 10], got 4");
  EXPECT_EQ(tree_error([&] { t.positive("gains/kp", 1.0), t.nonnegative("gains/kp"), t.positive("gains/kd", -1.0); }),
            "(no error)");  // a fallback is not validated
  EXPECT_EQ(tree_error([&] { t.numbers("list", 2); }), "~list | must be a list of 2 numbers");
  EXPECT_EQ(tree_error([&] { t.boolean("gains/name", false); }), "~gains/name | must be true or false, got 'x'");
  // gains/name was read above (as a bad number): everything has been asked for.
  EXPECT_EQ(tree_error([&] { t.reject_unknown(); }), "(no error)");

  const YAML::Node z = YAML::Load("a: {b: 1, c: {d: 2}}\ne: .inf\n");
  Tree u(z, '.');
  EXPECT_EQ(u.number("a.b", 0.0), 1.0);
  EXPECT_EQ(tree_error([&] { u.reject_unknown(); }), "a.c.d | unknown key");  // nested, named by full path
  EXPECT_EQ(tree_error([&] { u.number("e", 0.0); }), "e | must be finite, got .inf");
  EXPECT_EQ(tree_error([&] { u.keys("a", {"b"}); }), "a.c | unknown key");
  EXPECT_EQ(tree_error([&] { u.keys("a.b", {"x"}); }), "a.b | must be a mapping");
  EXPECT_EQ(tree_error([&] { u.section("q"); }), "q | missing");
  u.allow("a.c");  // a sub-map handled as one value
  EXPECT_EQ(tree_error([&] { u.reject_unknown(); }), "(no error)");
}

// --- Any follower-actuated rod: rod.segments, loads, actuators --------------------------------------

namespace {
const char* kGeneral = R"(
rod:
  segments:
    - length: 0.05
      bending_stiffness: [1.2e-3, 1.2e-3]
      torsional_stiffness: 4.5e-4
      linear_density: 0.02
    - length: 0.04
      youngs_modulus: 1.0e6
      shear_modulus: 3.4e5
      outer_diameter: 0.008
      inner_diameter: 0.0
      precurvature: [0.0, 1.0, 0.0]
tip: {mass: 0.001}
gravity: [0.0, 0.0, -9.81]
loads:
  - {at: 0.05, mass: 0.001}
  - {at: 0.02, force: [0.0, 0.01, 0.0], moment: [0.0, 0.0, 0.001], frame: base}
actuators:
  - {name: thruster1, at: 0.05, position: [0.004, 0.0, 0.0], direction: [0.0, 1.0, 0.0], max_force: 0.1}
  - {direction: [-1.0, 0.0, 0.0], max_force: 0.2, min_force: -0.2}
)";
}  // namespace

TEST(SceneGeneral, SegmentsLoadsAndActuators) {
  const hydrojet::config::Scene s = parse_scene(kGeneral);
  ASSERT_EQ(s.rod.segments.size(), 2u);
  EXPECT_FALSE(s.rod.tip_actuated_uniform());
  EXPECT_NEAR(s.rod.length(), 0.09, 1e-15);
  EXPECT_EQ(s.rod.segments[0].stiffness, hydrojet::rod::Vec3(1.2e-3, 1.2e-3, 4.5e-4));
  EXPECT_DOUBLE_EQ(s.rod.segments[0].linear_density, 0.02);
  // Moduli and diameters: E·I and G·J = G·2I with I = π D⁴ / 64 (solid).
  const double I = M_PI * std::pow(0.008, 4) / 64.0;
  EXPECT_NEAR(s.rod.segments[1].stiffness.x(), 1.0e6 * I, 1e-15);
  EXPECT_NEAR(s.rod.segments[1].stiffness.z(), 3.4e5 * 2 * I, 1e-15);
  EXPECT_EQ(s.rod.segments[1].precurvature, hydrojet::rod::Vec3(0.0, 1.0, 0.0));
  ASSERT_EQ(s.rod.loads.size(), 2u);
  EXPECT_EQ(s.rod.loads[0].frame, hydrojet::rod::LoadFrame::kBody);  // the default
  EXPECT_DOUBLE_EQ(s.rod.loads[0].mass, 0.001);
  EXPECT_EQ(s.rod.loads[1].frame, hydrojet::rod::LoadFrame::kBase);
  EXPECT_EQ(s.rod.loads[1].moment, hydrojet::rod::Vec3(0.0, 0.0, 0.001));
  ASSERT_EQ(s.rod.actuators.size(), 2u);
  EXPECT_FALSE(s.jets.has_value());  // actuators, not the HydroJet's jets section
  const hydrojet::rod::Actuator& a = s.rod.actuators[0];
  EXPECT_EQ(a.name, "thruster1");
  EXPECT_DOUBLE_EQ(a.at, 0.05);
  // The unit wrench is (d, p × d): (0, 1, 0) at (0.004, 0, 0) gives the moment 0.004 e_z.
  EXPECT_NEAR((a.unit_wrench() - (hydrojet::rod::Vec6() << 0, 1, 0, 0, 0, 0.004).finished()).norm(), 0.0, 1e-15);
  const hydrojet::rod::Actuator& b = s.rod.actuators[1];
  EXPECT_EQ(b.name, "actuator2");
  EXPECT_DOUBLE_EQ(b.at, 0.09);  // default: the tip
  EXPECT_DOUBLE_EQ(b.min_force, -0.2);
  EXPECT_EQ(b.type, hydrojet::rod::ActuatorType::kForce);
  EXPECT_EQ(s.rod.gravity, hydrojet::rod::Vec3(0.0, 0.0, -9.81));
  EXPECT_DOUBLE_EQ(s.rod.tip_mass, 0.001);
}

// A single-rod scene is one segment; a jets scene has the three jets of eq. (24) as actuators at L.
TEST(SceneGeneral, SingleRodAndJetsScenesAreTheSpecialCase) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const hydrojet::config::Scene s = hydrojet::test::scene(name);
    EXPECT_TRUE(s.rod.tip_actuated_uniform()) << name;
    ASSERT_EQ(s.rod.segments.size(), 1u);
    ASSERT_EQ(s.rod.actuators.size(), 3u);
    ASSERT_TRUE(s.jets.has_value());
    const hydrojet::actuation::JetMap map(*s.jets);
    const double q_max[3] = {0.243, 0.224, 0.244};  // the scenes' jets.max_force (Table 1)
    for (int i = 0; i < 3; ++i) {
      const hydrojet::rod::Actuator& a = s.rod.actuators[i];
      EXPECT_EQ(a.type, hydrojet::rod::ActuatorType::kJet);
      EXPECT_DOUBLE_EQ(a.at, s.rod.length());
      EXPECT_DOUBLE_EQ(a.max_force, q_max[i]);
      EXPECT_LT((a.unit_wrench() - map.wrench_matrix().col(i)).norm(), 1e-15) << name << " jet " << i;
    }
  }
}

TEST(SceneGeneral, ErrorsNameTheKey) {
  const std::string g = kGeneral;
  const struct {
    std::string yaml;
    const char* key;
  } cases[] = {
      {replace(g, "- length: 0.05", "- length: -0.05"), "rod.segments[0].length"},
      {replace(g, "      precurvature: [0.0, 1.0, 0.0]", "      precurvatur: [0.0, 1.0, 0.0]"),
       "rod.segments[1].precurvatur"},
      {replace(g, "rod:\n  segments:", "rod:\n  length: 0.09\n  segments:"), "rod.length"},
      {replace(g, "  - {at: 0.05, mass: 0.001}", "  - {at: 0.1, mass: 0.001}"), "loads[0].at"},
      {replace(g, "  - {at: 0.05, mass: 0.001}", "  - {at: 0.0, mass: 0.001}"), "loads[0].at"},
      {replace(g, "frame: base}", "frame: world}"), "loads[1].frame"},
      {replace(g, "direction: [0.0, 1.0, 0.0]", "direction: [0.0, 1.01, 0.0]"), "actuators[0].direction"},
      {replace(g, "max_force: 0.2, min_force: -0.2", "max_force: 0.2, min_force: 0.3"), "actuators[1].max_force"},
      {replace(g, "max_force: 0.2, min_force: -0.2", "max_force: 0.2, min_force: -0.2, type: jet"),
       "actuators[1].min_force"},  // a jet only pushes
      {replace(g, "{name: thruster1,", "{name: thruster1, type: jet,"), "actuators[0].type"},
      {replace(g, "{name: thruster1,", "{name: thruster1, type: hydraulic,"), "actuators[0].type"},
      {replace(g, "{name: thruster1,", "{nme: thruster1,"), "actuators[0].nme"},
      {replace(g, "actuators:\n",
               "jets: {misalignment: [0, 0, 0], max_force: [0.2, 0.2, 0.2], inlet_area: 1.0e-5, "
               "outlet_area: 5.0e-6, water_density: 1000}\nactuators:\n"),
       "actuators"},
      {replace(g, "      linear_density: 0.02", "      linear_density: 0.02\n      model: cosserat"),
       "rod.segments[0].model"},
  };
  for (const auto& c : cases) EXPECT_EQ(error_key(c.yaml), c.key) << c.yaml;
}

// The second robot shipped with the package.
TEST(SceneGeneral, TheSecondRobotLoads) {
  const hydrojet::config::Scene s = hydrojet::test::scene("two_segment_thrusters");
  EXPECT_EQ(s.rod.segments.size(), 2u);
  EXPECT_GT(s.rod.segments[0].stiffness.x(), s.rod.segments[1].stiffness.x());  // stiffer proximal
  EXPECT_GT(s.rod.segments[1].precurvature.norm(), 0.0);                        // precurved distal
  ASSERT_EQ(s.rod.loads.size(), 1u);
  EXPECT_DOUBLE_EQ(s.rod.loads[0].mass, 0.001);
  ASSERT_EQ(s.rod.actuators.size(), 6u);
  int at_tip = 0, with_arm = 0, mid = 0;
  for (const auto& a : s.rod.actuators) {
    at_tip += a.at == s.rod.length();
    mid += a.at < s.rod.length();
    with_arm += a.at == s.rod.length() && a.unit_wrench().tail<3>().norm() > 0.0;
  }
  EXPECT_EQ(at_tip, 4);
  EXPECT_EQ(mid, 2);
  EXPECT_EQ(with_arm, 1);
}
