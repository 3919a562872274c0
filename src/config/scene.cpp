#include "hydrojet_control/config/scene.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

namespace hydrojet {
namespace config {
namespace {

std::string fmt(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

void check_keys(const YAML::Node& node, const std::string& section, const std::set<std::string>& allowed) {
  if (!node.IsMap()) throw SceneError(section, "must be a mapping");
  for (const auto& kv : node) {
    const std::string k = kv.first.as<std::string>();
    if (!allowed.count(k)) throw SceneError(section + "." + k, "unknown key");
  }
}

double get_double(const YAML::Node& node, const std::string& key) {
  if (!node) throw SceneError(key, "missing");
  if (!node.IsScalar()) throw SceneError(key, "must be a number");
  double v;
  try {
    v = node.as<double>();
  } catch (const YAML::Exception&) {
    throw SceneError(key, "must be a number, got '" + node.Scalar() + "'");
  }
  if (!std::isfinite(v)) throw SceneError(key, "must be finite, got " + node.Scalar());
  return v;
}

double get_positive(const YAML::Node& node, const std::string& key) {
  const double v = get_double(node, key);
  if (!(v > 0.0)) throw SceneError(key, "must be positive, got " + fmt(v));
  return v;
}

double get_nonnegative(const YAML::Node& node, const std::string& key) {
  const double v = get_double(node, key);
  if (v < 0.0) throw SceneError(key, "must not be negative, got " + fmt(v));
  return v;
}

std::vector<double> get_vector(const YAML::Node& node, const std::string& key, size_t n) {
  if (!node) throw SceneError(key, "missing");
  if (!node.IsSequence() || node.size() != n)
    throw SceneError(key, "must be a list of " + std::to_string(n) + " numbers");
  std::vector<double> out;
  for (size_t i = 0; i < n; ++i) out.push_back(get_double(node[i], key + "[" + std::to_string(i) + "]"));
  return out;
}

rod::Vec3 get_vec3(const YAML::Node& node, const std::string& key) {
  const auto v = get_vector(node, key, 3);
  return rod::Vec3(v[0], v[1], v[2]);
}

int get_int(const YAML::Node& node, const std::string& key, int lo, int hi) {
  const double v = get_double(node, key);
  if (v != std::floor(v) || v < lo || v > hi)
    throw SceneError(key, "must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + fmt(v));
  return static_cast<int>(v);
}

void parse_rod(const YAML::Node& r, rod::RodParameters* p) {
  check_keys(r, "rod", {"length", "bending_stiffness", "torsional_stiffness", "youngs_modulus",
                        "shear_modulus", "outer_diameter", "inner_diameter", "precurvature",
                        "linear_density", "model", "shear_stiffness", "axial_stiffness"});
  p->length = get_positive(r["length"], "rod.length");
  const bool direct = r["bending_stiffness"] || r["torsional_stiffness"];
  const bool moduli = r["youngs_modulus"] || r["shear_modulus"] || r["outer_diameter"] || r["inner_diameter"];
  if (direct && moduli)
    throw SceneError("rod.bending_stiffness", "give either bending/torsional stiffness or moduli and diameters, not both");
  if (moduli) {
    const double E = get_positive(r["youngs_modulus"], "rod.youngs_modulus");
    const double G = get_positive(r["shear_modulus"], "rod.shear_modulus");
    const double D = get_positive(r["outer_diameter"], "rod.outer_diameter");
    const double d = get_nonnegative(r["inner_diameter"], "rod.inner_diameter");
    if (d >= D) throw SceneError("rod.inner_diameter", "must be smaller than rod.outer_diameter");
    const double I = M_PI * (std::pow(D, 4) - std::pow(d, 4)) / 64.0;  // hollow cylinder
    p->stiffness = rod::Vec3(E * I, E * I, G * 2.0 * I);                  // J = 2 I
    const double A = M_PI * (D * D - d * d) / 4.0;                        // Cosserat: EA, GA
    p->axial_stiffness = E * A;
    p->shear_stiffness = G * A;
  } else {
    const auto ei = get_vector(r["bending_stiffness"], "rod.bending_stiffness", 2);
    for (int i = 0; i < 2; ++i)
      if (!(ei[i] > 0.0))
        throw SceneError("rod.bending_stiffness[" + std::to_string(i) + "]", "must be positive, got " + fmt(ei[i]));
    p->stiffness = rod::Vec3(ei[0], ei[1], get_positive(r["torsional_stiffness"], "rod.torsional_stiffness"));
  }
  // rod.model: kirchhoff (default) | cosserat. The Cosserat rod needs K_se = diag(GA, GA, EA): the
  // keys shear_stiffness and axial_stiffness [N], or moduli and diameters (GA = G·A, EA = E·A).
  std::string kind = "kirchhoff";
  if (r["model"]) kind = r["model"].IsScalar() ? r["model"].Scalar() : "";
  if (kind != "kirchhoff" && kind != "cosserat")
    throw SceneError("rod.model", "must be kirchhoff or cosserat, got '" + kind + "'");
  if (kind == "kirchhoff") {
    for (const char* k : {"shear_stiffness", "axial_stiffness"})
      if (r[k]) throw SceneError(std::string("rod.") + k, "only with rod.model: cosserat");
    p->kind = rod::RodKind::kKirchhoff;
    p->shear_stiffness = p->axial_stiffness = 0.0;
  } else {
    p->kind = rod::RodKind::kCosserat;
    if (r["shear_stiffness"]) p->shear_stiffness = get_positive(r["shear_stiffness"], "rod.shear_stiffness");
    if (r["axial_stiffness"]) p->axial_stiffness = get_positive(r["axial_stiffness"], "rod.axial_stiffness");
    if (!(p->shear_stiffness > 0.0))
      throw SceneError("rod.shear_stiffness", "missing (rod.model: cosserat needs it, or moduli and diameters)");
    if (!(p->axial_stiffness > 0.0))
      throw SceneError("rod.axial_stiffness", "missing (rod.model: cosserat needs it, or moduli and diameters)");
  }
  p->precurvature = r["precurvature"] ? get_vec3(r["precurvature"], "rod.precurvature") : rod::Vec3::Zero();
  p->linear_density = r["linear_density"] ? get_nonnegative(r["linear_density"], "rod.linear_density") : 0.0;
}

void parse_tip(const YAML::Node& t, Scene* s) {
  check_keys(t, "tip", {"mass", "actuated"});
  s->model.tip_mass = get_nonnegative(t["mass"], "tip.mass");
  if (t["actuated"]) {
    static const char* names[6] = {"fx", "fy", "fz", "mx", "my", "mz"};
    const YAML::Node& a = t["actuated"];
    if (!a.IsSequence() || a.size() == 0) throw SceneError("tip.actuated", "must be a non-empty list of fx fy fz mx my mz");
    s->actuated.fill(false);
    for (size_t i = 0; i < a.size(); ++i) {
      const std::string n = a[i].IsScalar() ? a[i].Scalar() : "";
      int k = 0;
      while (k < 6 && n != names[k]) ++k;
      if (k == 6) throw SceneError("tip.actuated[" + std::to_string(i) + "]", "unknown component '" + n + "' (fx fy fz mx my mz)");
      s->actuated[k] = true;
    }
  }
}

void parse_solver(const YAML::Node& n, rod::ShootingSettings* st) {
  check_keys(n, "solver", {"integrator", "steps", "tolerance", "residual_tolerance", "max_iterations",
                           "max_continuation_steps", "shooting_segments", "accuracy_tolerance"});
  if (n["integrator"]) {
    const std::string name = n["integrator"].IsScalar() ? n["integrator"].Scalar() : "";
    if (!rod::parse_integrator(name, &st->integrator.type))
      throw SceneError("solver.integrator", "unknown integrator '" + name + "' (" + rod::integrator_names() + ")");
  }
  if (n["steps"]) st->integrator.steps = get_int(n["steps"], "solver.steps", 1, 100000);
  if (n["tolerance"]) st->integrator.tolerance = get_positive(n["tolerance"], "solver.tolerance");
  if (n["residual_tolerance"]) st->residual_tolerance = get_positive(n["residual_tolerance"], "solver.residual_tolerance");
  if (n["max_iterations"]) st->max_iterations = get_int(n["max_iterations"], "solver.max_iterations", 1, 1000);
  if (n["max_continuation_steps"])
    st->max_continuation_steps = get_int(n["max_continuation_steps"], "solver.max_continuation_steps", 0, 100000);
  if (n["shooting_segments"])
    st->shooting_segments = get_int(n["shooting_segments"], "solver.shooting_segments", 0, 256);
  if (n["accuracy_tolerance"])
    st->accuracy_tolerance = get_nonnegative(n["accuracy_tolerance"], "solver.accuracy_tolerance");
}

void parse_jets(const YAML::Node& n, Scene* s) {
  check_keys(n, "jets", {"misalignment", "max_force", "inlet_area", "outlet_area", "water_density", "nozzle_offset"});
  s->has_jets = true;
  s->jets.misalignment = get_vec3(n["misalignment"], "jets.misalignment");
  const rod::Vec3 qmax = get_vec3(n["max_force"], "jets.max_force");
  for (int i = 0; i < 3; ++i)
    if (!(qmax[i] > 0.0)) throw SceneError("jets.max_force[" + std::to_string(i) + "]", "must be positive, got " + fmt(qmax[i]));
  s->max_jet_force = qmax;
  s->nozzle.inlet_area = get_positive(n["inlet_area"], "jets.inlet_area");
  s->nozzle.outlet_area = get_positive(n["outlet_area"], "jets.outlet_area");
  s->nozzle.water_density = get_positive(n["water_density"], "jets.water_density");
  if (s->nozzle.outlet_area >= s->nozzle.inlet_area)
    throw SceneError("jets.outlet_area", "must be smaller than jets.inlet_area (else the thrust of eq. 26 is not positive)");
  s->jets.nozzle_offset = n["nozzle_offset"] ? get_double(n["nozzle_offset"], "jets.nozzle_offset") : 0.0;
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
  Scene s;
  if (!root["rod"]) throw SceneError("rod", "missing");
  parse_rod(root["rod"], &s.model.rod);
  if (!root["tip"]) throw SceneError("tip", "missing");
  parse_tip(root["tip"], &s);
  s.model.gravity = get_vec3(root["gravity"], "gravity");
  if (root["solver"]) parse_solver(root["solver"], &s.solver);
  if (root["jets"]) parse_jets(root["jets"], &s);
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

control::ControllerModel make_controller_model(const Scene& scene, const actuation::FlowRegulatorParameters& flow) {
  if (!scene.has_jets) throw SceneError("jets", "missing (the controller needs the jet geometry)");
  control::ControllerModel m;
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
