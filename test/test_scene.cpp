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
  EXPECT_DOUBLE_EQ(s.model.rod.length, 0.09);
  EXPECT_DOUBLE_EQ(s.model.rod.stiffness[0], 6.01e-4);
  EXPECT_DOUBLE_EQ(s.model.rod.stiffness[1], 5.0e-4);
  EXPECT_DOUBLE_EQ(s.model.rod.stiffness[2], 2.23e-4);
  EXPECT_DOUBLE_EQ(s.model.rod.precurvature[1], 0.88);
  EXPECT_DOUBLE_EQ(s.model.rod.linear_density, 0.01);
  EXPECT_DOUBLE_EQ(s.model.tip_mass, 0.00258);
  EXPECT_DOUBLE_EQ(s.model.gravity[2], 9.81);
}

TEST(Scene, ShippedScenesLoad) {
  const auto a = hydrojet::test::scene("hydrojet_0deg");
  const auto b = hydrojet::test::scene("hydrojet_30deg");
  EXPECT_NEAR(a.model.gravity.norm(), 9.81, 1e-9);
  EXPECT_NEAR(b.model.gravity.norm(), 9.81, 1e-9);
  // 30° between the two gravity directions.
  EXPECT_NEAR(std::acos(a.model.gravity.normalized().dot(b.model.gravity.normalized())), M_PI / 6, 1e-9);
}

// Hollow cylinder: EI = E·π(D⁴ − d⁴)/64, GJ = G·π(D⁴ − d⁴)/32.
TEST(Scene, ModuliAndDiametersGiveStiffness) {
  const auto s = parse_scene(R"(
rod: {length: 0.09, youngs_modulus: 1.0e5, shear_modulus: 3.4e4, outer_diameter: 0.008, inner_diameter: 0.006}
tip: {mass: 0.0}
gravity: [0, 0, 0]
)");
  const double I = M_PI * (std::pow(0.008, 4) - std::pow(0.006, 4)) / 64.0;
  EXPECT_NEAR(s.model.rod.stiffness[0], 1.0e5 * I, 1e-15);
  EXPECT_NEAR(s.model.rod.stiffness[2], 3.4e4 * 2 * I, 1e-15);
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

// rod.model: cosserat with K_se from the keys, or from moduli and the cross-section; the solver keys
// of the numerics part; bad combinations name the key.
TEST(Scene, CosseratModelAndSolverKeys) {
  const auto s = parse_scene(std::string(kGood) + R"(solver:
  integrator: cvode-bdf
  tolerance: 1.0e-8
  shooting_segments: 4
  accuracy_tolerance: 0
)");
  EXPECT_EQ(s.model.rod.kind, hydrojet::rod::RodKind::kKirchhoff);
  EXPECT_EQ(s.solver.integrator.type, hydrojet::rod::IntegratorType::kCvodeBdf);
  EXPECT_EQ(s.solver.shooting_segments, 4);
  EXPECT_EQ(s.solver.accuracy_tolerance, 0.0);
  const auto c = parse_scene(
      replace(kGood, "  linear_density: 0.01\n",
              "  linear_density: 0.01\n  model: cosserat\n  shear_stiffness: 0.4\n  axial_stiffness: 1.3\n"));
  EXPECT_EQ(c.model.rod.kind, hydrojet::rod::RodKind::kCosserat);
  EXPECT_DOUBLE_EQ(c.model.rod.shear_stiffness, 0.4);
  EXPECT_DOUBLE_EQ(c.model.rod.axial_stiffness, 1.3);
  const auto m = parse_scene(R"(
rod: {length: 0.09, model: cosserat, youngs_modulus: 1.0e5, shear_modulus: 3.4e4, outer_diameter: 0.008, inner_diameter: 0.006}
tip: {mass: 0.0}
gravity: [0, 0, 0]
)");
  const double A = M_PI * (0.008 * 0.008 - 0.006 * 0.006) / 4.0;
  EXPECT_NEAR(m.model.rod.axial_stiffness, 1.0e5 * A, 1e-12);
  EXPECT_NEAR(m.model.rod.shear_stiffness, 3.4e4 * A, 1e-12);
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
