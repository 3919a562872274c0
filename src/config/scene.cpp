#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/util/files.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

namespace hydrojet {
namespace config {
namespace {

/// Scene keys are dotted paths ("rod.length"); errors are SceneError naming them.
using Tree = YamlTree<SceneError>;

/// The keys of one piece of rod: the single-rod section or one item of rod.segments.
constexpr std::initializer_list<const char*> kRodKeys = {"length",         "bending_stiffness", "torsional_stiffness",
                                                         "youngs_modulus", "shear_modulus",     "outer_diameter",
                                                         "inner_diameter", "precurvature",      "linear_density",
                                                         "model",          "shear_stiffness",   "axial_stiffness"};

/// Stiffness from `k`bending_stiffness/torsional_stiffness, or from moduli and diameters (then also
/// EA and GA for the Cosserat rod). `k` is the key prefix ("rod." or "" for a segment's own tree).
void parse_stiffness(Tree& t, const std::string& k, rod::RodSegment* p) {
  const bool direct = t.has(k + "bending_stiffness") || t.has(k + "torsional_stiffness");
  const bool moduli = t.has(k + "youngs_modulus") || t.has(k + "shear_modulus") || t.has(k + "outer_diameter") ||
                      t.has(k + "inner_diameter");
  if (direct && moduli)
    t.fail(k + "bending_stiffness", "give either bending/torsional stiffness or moduli and diameters, not both");
  if (moduli) {
    const double E = t.positive(k + "youngs_modulus");
    const double G = t.positive(k + "shear_modulus");
    const double D = t.positive(k + "outer_diameter");
    const double d = t.nonnegative(k + "inner_diameter");
    if (d >= D) t.fail(k + "inner_diameter", "must be smaller than " + t.key(k + "outer_diameter"));
    const double I = M_PI * (std::pow(D, 4) - std::pow(d, 4)) / 64.0;  // hollow cylinder
    p->stiffness = rod::Vec3(E * I, E * I, G * 2.0 * I);               // J = 2 I
    const double A = M_PI * (D * D - d * d) / 4.0;                     // Cosserat: EA, GA
    p->axial_stiffness = E * A;
    p->shear_stiffness = G * A;
  } else {
    const std::vector<double> ei = t.numbers(k + "bending_stiffness", 2);
    for (int i = 0; i < 2; ++i)
      if (!(ei[i] > 0.0))
        t.fail(k + "bending_stiffness[" + std::to_string(i) + "]", "must be positive, got " + Tree::format(ei[i]));
    p->stiffness = rod::Vec3(ei[0], ei[1], t.positive(k + "torsional_stiffness"));
  }
}

/// `k`model: kirchhoff (default, or `inherited`) | cosserat. The Cosserat rod needs K_se = diag(GA,
/// GA, EA): the keys shear_stiffness and axial_stiffness [N], or moduli and diameters (GA = G·A, EA = E·A).
void parse_kind(Tree& t, const std::string& k, const std::string& inherited, bool segment, rod::RodSegment* p,
                rod::RodKind* out) {
  const std::string kind = t.text(k + "model", inherited);
  if (kind != "kirchhoff" && kind != "cosserat")
    t.fail(k + "model", "must be kirchhoff or cosserat, got '" + kind + "'");
  if (segment && kind != inherited)
    t.fail(k + "model", "every segment has the model of rod.model ('" + inherited + "')");
  if (kind == "kirchhoff") {
    for (const char* key : {"shear_stiffness", "axial_stiffness"})
      if (t.has(k + key)) t.fail(k + key, "only with model: cosserat");
    *out = rod::RodKind::kKirchhoff;
    p->shear_stiffness = p->axial_stiffness = 0.0;
    return;
  }
  *out = rod::RodKind::kCosserat;
  p->shear_stiffness = t.positive(k + "shear_stiffness", p->shear_stiffness);
  p->axial_stiffness = t.positive(k + "axial_stiffness", p->axial_stiffness);
  if (!(p->shear_stiffness > 0.0))
    t.fail(k + "shear_stiffness", "missing (model: cosserat needs it, or moduli and diameters)");
  if (!(p->axial_stiffness > 0.0))
    t.fail(k + "axial_stiffness", "missing (model: cosserat needs it, or moduli and diameters)");
}

/// One uniform piece of rod under the key prefix `k`.
void parse_piece(Tree& t, const std::string& k, const std::string& inherited_kind, bool segment, rod::RodSegment* p,
                 rod::RodKind* kind) {
  p->length = t.positive(k + "length");
  parse_stiffness(t, k, p);
  parse_kind(t, k, inherited_kind, segment, p, kind);
  p->precurvature = t.vec3<rod::Vec3>(k + "precurvature", rod::Vec3::Zero());
  p->linear_density = t.nonnegative(k + "linear_density", 0.0);
}

/// rod.segments: base to tip, each with the single-rod keys.
void parse_segments(Tree& t, const YAML::Node& rod_node, Scene* s) {
  t.keys("rod", {"segments", "model"});
  t.allow("rod.segments");
  const YAML::Node list = rod_node["segments"];
  if (!list.IsSequence() || list.size() == 0) t.fail("rod.segments", "must be a non-empty list of segments");
  const std::string kind = t.text("rod.model", "kirchhoff");
  if (kind != "kirchhoff" && kind != "cosserat")
    t.fail("rod.model", "must be kirchhoff or cosserat, got '" + kind + "'");
  for (size_t i = 0; i < list.size(); ++i) {
    Tree item(list[i], '.', "rod.segments[" + std::to_string(i) + "].");
    if (!list[i].IsMap()) item.fail("", "must be a mapping of single-rod keys");
    item.keys("", kRodKeys);
    rod::RodSegment piece;
    parse_piece(item, "", kind, true, &piece, &s->rod.kind);
    s->rod.segments.push_back(piece);
  }
}

void parse_rod(Tree& t, Scene* s) {
  const YAML::Node node = t.section("rod");
  if (node["segments"]) return parse_segments(t, node, s);
  t.keys("rod", kRodKeys);
  rod::RodSegment piece;
  parse_piece(t, "rod.", "kirchhoff", false, &piece, &s->rod.kind);
  s->rod.segments = {piece};
}

void parse_tip(Tree& t, Scene* s) {
  const YAML::Node tip = t.section("tip");
  t.keys("tip", {"mass", "radius", "actuated"});
  s->rod.tip_mass = t.nonnegative("tip.mass");
  s->rod.tip_radius = t.nonnegative("tip.radius", s->rod.tip_radius);
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
  actuation::JetGeometry jets;
  jets.misalignment = t.vec3<rod::Vec3>("jets.misalignment");
  const rod::Vec3 qmax = t.vec3<rod::Vec3>("jets.max_force");
  for (int i = 0; i < 3; ++i)
    if (!(qmax[i] > 0.0))
      t.fail("jets.max_force[" + std::to_string(i) + "]", "must be positive, got " + Tree::format(qmax[i]));
  s->nozzle.inlet_area = t.positive("jets.inlet_area");
  s->nozzle.outlet_area = t.positive("jets.outlet_area");
  s->nozzle.water_density = t.positive("jets.water_density");
  if (s->nozzle.outlet_area >= s->nozzle.inlet_area)
    t.fail("jets.outlet_area", "must be smaller than jets.inlet_area (else the thrust of eq. 26 is not positive)");
  jets.nozzle_offset = t.number("jets.nozzle_offset", 0.0);
  s->jets = jets;
  s->rod.actuators = control::jet_actuators(jets, qmax, s->rod.length());
}

/// An item of a list section: its own tree, keys checked, errors named "<list>[i].<key>".
Tree list_item(Tree& t, const YAML::Node& list, const std::string& name, size_t i,
               std::initializer_list<const char*> allowed) {
  Tree item(list[i], '.', name + "[" + std::to_string(i) + "].");
  if (!list[i].IsMap()) item.fail("", "must be a mapping");
  item.keys("", allowed);
  return item;
}

/// A list section (absent: empty list).
YAML::Node list_section(Tree& t, const YAML::Node& root, const std::string& name) {
  t.allow(name);
  const YAML::Node list = root[name];
  if (!list.IsSequence()) t.fail(name, "must be a list");
  return list;
}

/// An arc length in (0, L] [m]; `fallback` < 0: required.
double arc_length(Tree& item, const std::string& key, double L, double fallback = -1.0) {
  const double at = fallback < 0.0 ? item.number(key) : item.number(key, fallback);
  if (!(at > 0.0 && at <= L * (1.0 + 1e-12))) item.fail(key, "must lie in (0, L] = (0, " + Tree::format(L) + "] m");
  return std::min(at, L);
}

/// loads: point loads along the body besides the tip's.
void parse_loads(Tree& t, const YAML::Node& root, Scene* s) {
  const YAML::Node list = list_section(t, root, "loads");
  for (size_t i = 0; i < list.size(); ++i) {
    Tree item = list_item(t, list, "loads", i, {"at", "mass", "force", "moment", "frame"});
    rod::PointLoad l;
    l.at = arc_length(item, "at", s->rod.length());
    l.mass = item.nonnegative("mass", 0.0);
    l.force = item.vec3<rod::Vec3>("force", rod::Vec3::Zero());
    l.moment = item.vec3<rod::Vec3>("moment", rod::Vec3::Zero());
    const std::string frame = item.text("frame", "body");
    if (frame != "body" && frame != "base") item.fail("frame", "must be body or base, got '" + frame + "'");
    l.frame = frame == "body" ? rod::LoadFrame::kBody : rod::LoadFrame::kBase;
    s->rod.loads.push_back(l);
  }
}

rod::Actuator parse_actuator(Tree& item, size_t i, double L) {
  rod::Actuator a;
  a.name = item.text("name", "actuator" + std::to_string(i + 1));
  a.at = arc_length(item, "at", L, L);
  a.position = item.vec3<rod::Vec3>("position", rod::Vec3::Zero());
  a.direction = item.vec3<rod::Vec3>("direction");
  if (!(std::abs(a.direction.norm() - 1.0) <= 1e-6))
    item.fail("direction", "must be a unit vector (within 1e-6), its norm is " + Tree::format(a.direction.norm()));
  a.max_force = item.number("max_force");
  a.min_force = item.number("min_force", 0.0);
  if (!(a.min_force <= a.max_force)) item.fail("max_force", "must be >= min_force (" + Tree::format(a.min_force) + ")");
  const std::string type = item.text("type", "force");
  if (type != "force" && type != "jet") item.fail("type", "must be force or jet, got '" + type + "'");
  a.type = type == "force" ? rod::ActuatorType::kForce : rod::ActuatorType::kJet;
  if (a.type == rod::ActuatorType::kJet && a.min_force < 0.0)
    item.fail("min_force", "a jet only pushes (eq. 26): must be >= 0, got " + Tree::format(a.min_force));
  return a;
}

/// actuators: N inputs anywhere along the body (instead of `jets`).
void parse_actuators(Tree& t, const YAML::Node& root, Scene* s) {
  const YAML::Node list = list_section(t, root, "actuators");
  if (list.size() == 0 || list.size() > static_cast<size_t>(rod::kMaxInputs))
    t.fail("actuators", "must list 1 to " + std::to_string(rod::kMaxInputs) + " actuators");
  for (size_t i = 0; i < list.size(); ++i) {
    Tree item =
        list_item(t, list, "actuators", i, {"name", "at", "position", "direction", "max_force", "min_force", "type"});
    s->rod.actuators.push_back(parse_actuator(item, i, s->rod.length()));
  }
}

/// nozzle: the thrust equation's areas and density (eq. 26), for actuators of type jet.
void parse_nozzle(Tree& t, Scene* s) {
  t.section("nozzle");
  t.keys("nozzle", {"inlet_area", "outlet_area", "water_density"});
  s->nozzle.inlet_area = t.positive("nozzle.inlet_area");
  s->nozzle.outlet_area = t.positive("nozzle.outlet_area");
  s->nozzle.water_density = t.positive("nozzle.water_density");
  if (s->nozzle.outlet_area >= s->nozzle.inlet_area)
    t.fail("nozzle.outlet_area", "must be smaller than nozzle.inlet_area (else the thrust of eq. 26 is not positive)");
}

/// The three jets of eq. (24) as actuators at the tip: direction = the jet's force direction, the
/// nozzle offset as the point of application (moment (d e_z) × f).
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
  parse_rod(t, &s);
  parse_tip(t, &s);
  s.solver.cold_stability_check = s.actuated;
  s.rod.gravity = t.vec3<rod::Vec3>("gravity");
  if (t.has("solver")) parse_solver(t, &s.solver);
  if (t.has("jets") && t.has("actuators")) t.fail("actuators", "give either jets (the HydroJet's three) or actuators");
  if (t.has("jets")) parse_jets(t, &s);
  if (t.has("loads")) parse_loads(t, root, &s);
  if (t.has("actuators")) parse_actuators(t, root, &s);
  if (t.has("nozzle")) parse_nozzle(t, &s);
  for (size_t i = 0; i < s.rod.actuators.size(); ++i)
    if (s.rod.actuators[i].type == rod::ActuatorType::kJet && !s.jets && !t.has("nozzle"))
      t.fail("actuators[" + std::to_string(i) + "].type",
             "jet needs the nozzle section (inlet_area, outlet_area, water_density)");
  return s;
}

Scene load_scene(const std::string& path) {
  std::string text;
  if (const std::string err = util::read_regular_file(path, &text); !err.empty())
    throw SceneError("scene", "cannot read file '" + path + "': " + err);
  return parse_scene(text);
}

}  // namespace config
}  // namespace hydrojet

namespace hydrojet {
namespace config {

control::RobotModel make_controller_model(const Scene& scene, const actuation::FlowRegulatorOptions& flow) {
  if (scene.rod.actuators.empty())
    throw SceneError("jets", "missing (the controller needs the jets, or an actuators section)");
  control::RobotModel m;
  m.rod = scene.rod;
  m.solver = scene.solver;
  m.nozzle = scene.nozzle;
  m.flow = flow;
  return m;
}

}  // namespace config
}  // namespace hydrojet
