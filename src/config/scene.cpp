#include "hydrojet_control/config/scene.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <sstream>

namespace hydrojet {
namespace config {
namespace {

/// Scene keys are dotted paths ("rod.length"); errors are SceneError naming them.
using Tree = YamlTree<SceneError>;

void parse_rod(Tree& t, rod::ElasticRod* p) {
  t.section("rod");
  t.keys("rod",
         {"length", "bending_stiffness", "torsional_stiffness", "youngs_modulus", "shear_modulus", "outer_diameter",
          "inner_diameter", "precurvature", "linear_density", "model", "shear_stiffness", "axial_stiffness"});
  p->length = t.positive("rod.length");
  const bool direct = t.has("rod.bending_stiffness") || t.has("rod.torsional_stiffness");
  const bool moduli = t.has("rod.youngs_modulus") || t.has("rod.shear_modulus") || t.has("rod.outer_diameter") ||
                      t.has("rod.inner_diameter");
  if (direct && moduli)
    t.fail("rod.bending_stiffness", "give either bending/torsional stiffness or moduli and diameters, not both");
  if (moduli) {
    const double E = t.positive("rod.youngs_modulus");
    const double G = t.positive("rod.shear_modulus");
    const double D = t.positive("rod.outer_diameter");
    const double d = t.nonnegative("rod.inner_diameter");
    if (d >= D) t.fail("rod.inner_diameter", "must be smaller than rod.outer_diameter");
    const double I = M_PI * (std::pow(D, 4) - std::pow(d, 4)) / 64.0;  // hollow cylinder
    p->stiffness = rod::Vec3(E * I, E * I, G * 2.0 * I);               // J = 2 I
    const double A = M_PI * (D * D - d * d) / 4.0;                     // Cosserat: EA, GA
    p->axial_stiffness = E * A;
    p->shear_stiffness = G * A;
  } else {
    const std::vector<double> ei = t.numbers("rod.bending_stiffness", 2);
    for (int i = 0; i < 2; ++i)
      if (!(ei[i] > 0.0))
        t.fail("rod.bending_stiffness[" + std::to_string(i) + "]", "must be positive, got " + Tree::format(ei[i]));
    p->stiffness = rod::Vec3(ei[0], ei[1], t.positive("rod.torsional_stiffness"));
  }
  // rod.model: kirchhoff (default) | cosserat. The Cosserat rod needs K_se = diag(GA, GA, EA): the
  // keys shear_stiffness and axial_stiffness [N], or moduli and diameters (GA = G·A, EA = E·A).
  const std::string kind = t.text("rod.model", "kirchhoff");
  if (kind != "kirchhoff" && kind != "cosserat")
    t.fail("rod.model", "must be kirchhoff or cosserat, got '" + kind + "'");
  if (kind == "kirchhoff") {
    for (const char* k : {"rod.shear_stiffness", "rod.axial_stiffness"})
      if (t.has(k)) t.fail(k, "only with rod.model: cosserat");
    p->kind = rod::RodKind::kKirchhoff;
    p->shear_stiffness = p->axial_stiffness = 0.0;
  } else {
    p->kind = rod::RodKind::kCosserat;
    p->shear_stiffness = t.positive("rod.shear_stiffness", p->shear_stiffness);
    p->axial_stiffness = t.positive("rod.axial_stiffness", p->axial_stiffness);
    if (!(p->shear_stiffness > 0.0))
      t.fail("rod.shear_stiffness", "missing (rod.model: cosserat needs it, or moduli and diameters)");
    if (!(p->axial_stiffness > 0.0))
      t.fail("rod.axial_stiffness", "missing (rod.model: cosserat needs it, or moduli and diameters)");
  }
  p->precurvature = t.vec3<rod::Vec3>("rod.precurvature", rod::Vec3::Zero());
  p->linear_density = t.nonnegative("rod.linear_density", 0.0);
}

void parse_tip(Tree& t, Scene* s) {
  const YAML::Node tip = t.section("tip");
  t.keys("tip", {"mass", "actuated"});
  s->model.tip_mass = t.nonnegative("tip.mass");
  if (t.has("tip.actuated")) {
    t.allow("tip.actuated");
    static const char* names[6] = {"fx", "fy", "fz", "mx", "my", "mz"};
    const YAML::Node a = tip["actuated"];
    if (!a.IsSequence() || a.size() == 0) t.fail("tip.actuated", "must be a non-empty list of fx fy fz mx my mz");
    s->actuated.fill(false);
    for (size_t i = 0; i < a.size(); ++i) {
      const std::string n = a[i].IsScalar() ? a[i].Scalar() : "";
      int k = 0;
      while (k < 6 && n != names[k]) ++k;
      if (k == 6)
        t.fail("tip.actuated[" + std::to_string(i) + "]", "unknown component '" + n + "' (fx fy fz mx my mz)");
      s->actuated[k] = true;
    }
  }
}

void parse_solver(Tree& t, rod::ShootingOptions* st) {
  t.section("solver");
  t.keys("solver", {"integrator", "steps", "tolerance", "residual_tolerance", "max_iterations",
                    "max_continuation_steps", "shooting_segments", "accuracy_tolerance"});
  if (t.has("solver.integrator")) {
    const std::string name = t.text("solver.integrator", "");
    if (!rod::parse_integrator(name, &st->integrator.type))
      t.fail("solver.integrator", "unknown integrator '" + name + "' (" + rod::integrator_names() + ")");
  }
  st->integrator.steps = t.integer("solver.steps", st->integrator.steps, 1, 100000);
  st->integrator.tolerance = t.positive("solver.tolerance", st->integrator.tolerance);
  st->residual_tolerance = t.positive("solver.residual_tolerance", st->residual_tolerance);
  st->max_iterations = t.integer("solver.max_iterations", st->max_iterations, 1, 1000);
  st->max_continuation_steps = t.integer("solver.max_continuation_steps", st->max_continuation_steps, 0, 100000);
  st->shooting_segments = t.integer("solver.shooting_segments", st->shooting_segments, 0, 256);
  st->accuracy_tolerance = t.nonnegative("solver.accuracy_tolerance", st->accuracy_tolerance);
}

void parse_jets(Tree& t, Scene* s) {
  t.section("jets");
  t.keys("jets", {"misalignment", "max_force", "inlet_area", "outlet_area", "water_density", "nozzle_offset"});
  s->has_jets = true;
  s->jets.misalignment = t.vec3<rod::Vec3>("jets.misalignment");
  const rod::Vec3 qmax = t.vec3<rod::Vec3>("jets.max_force");
  for (int i = 0; i < 3; ++i)
    if (!(qmax[i] > 0.0))
      t.fail("jets.max_force[" + std::to_string(i) + "]", "must be positive, got " + Tree::format(qmax[i]));
  s->max_jet_force = qmax;
  s->nozzle.inlet_area = t.positive("jets.inlet_area");
  s->nozzle.outlet_area = t.positive("jets.outlet_area");
  s->nozzle.water_density = t.positive("jets.water_density");
  if (s->nozzle.outlet_area >= s->nozzle.inlet_area)
    t.fail("jets.outlet_area", "must be smaller than jets.inlet_area (else the thrust of eq. 26 is not positive)");
  s->jets.nozzle_offset = t.number("jets.nozzle_offset", 0.0);
}

}  // namespace

Scene parse_scene(const std::string& text) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw SceneError("scene", std::string("malformed YAML: ") + e.what());
  }
  if (!root.IsMap()) throw SceneError("scene", "must be a mapping with sections rod, tip, gravity");
  // Sections other than these are allowed (a scene may carry a tool's own section); unknown keys
  // inside them are not.
  Tree t(root, '.');
  Scene s;
  parse_rod(t, &s.model.rod);
  parse_tip(t, &s);
  s.model.gravity = t.vec3<rod::Vec3>("gravity");
  if (t.has("solver")) parse_solver(t, &s.solver);
  if (t.has("jets")) parse_jets(t, &s);
  return s;
}

Scene load_scene(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw SceneError("scene", "cannot read file '" + path + "'");
  std::stringstream ss;
  ss << f.rdbuf();
  return parse_scene(ss.str());
}

}  // namespace config
}  // namespace hydrojet

namespace hydrojet {
namespace config {

control::RobotModel make_controller_model(const Scene& scene, const actuation::FlowRegulatorOptions& flow) {
  if (!scene.has_jets) throw SceneError("jets", "missing (the controller needs the jet geometry)");
  control::RobotModel m;
  m.rod = scene.model;
  m.solver = scene.solver;
  m.actuated = scene.actuated;
  m.jets = scene.jets;
  m.nozzle = scene.nozzle;
  m.max_jet_force = scene.max_jet_force;
  m.flow = flow;
  return m;
}

}  // namespace config
}  // namespace hydrojet
