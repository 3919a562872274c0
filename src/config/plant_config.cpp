#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/config/surface_yaml.h"
#include "hydrojet_control/util/files.h"

#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

namespace hydrojet {
namespace config {
namespace {

/// Plant keys are dotted paths ("plant.tracker.latency"); errors are SceneError naming them.
using Tree = YamlTree<SceneError>;

void parse_valve(const YAML::Node& n, const std::string& path, plant::ValveModel* v) {
  if (!n.IsMap()) throw SceneError(path, "must be a mapping");
  Tree t(n, '.', path + ".");
  t.keys("", {"max_flow", "dead_zone", "exponent", "hysteresis", "time_constant", "saturation"});
  v->max_flow = t.number("max_flow", v->max_flow);
  v->dead_zone = t.number("dead_zone", v->dead_zone);
  v->exponent = t.number("exponent", v->exponent);
  v->hysteresis = t.number("hysteresis", v->hysteresis);
  v->time_constant = t.number("time_constant", v->time_constant);
  v->saturation = t.number("saturation", v->saturation);
  const std::string e = v->validate();
  if (!e.empty()) t.fail(e.substr(0, e.find(':')), e.substr(e.find(':') + 2));
}

/// One surface of plant.environment.surfaces (its path names it in errors).
plant::Surface parse_surface(const YAML::Node& n, const std::string& path) {
  if (!n.IsMap()) throw SceneError(path, "must be a mapping");
  Tree t(n, '.', path + ".");
  plant::Surface s;
  static_cast<geometry::Surface&>(s) = read_surface_shape(t, {"stiffness", "damping", "friction"});
  s.stiffness = t.number("stiffness", s.stiffness);
  s.damping = t.number("damping", s.damping);
  s.friction = t.number("friction", s.friction);
  const std::string e = s.validate();
  if (!e.empty()) t.fail(e.substr(0, e.find(':')), e.substr(e.find(':') + 2));
  return s;
}

/// One load of plant.external_loads.
plant::ExternalLoad parse_load(const YAML::Node& n, const std::string& path) {
  if (!n.IsMap()) throw SceneError(path, "must be a mapping");
  Tree t(n, '.', path + ".");
  t.keys("", {"start", "end", "force", "moment", "frame"});
  plant::ExternalLoad l;
  l.start = t.number("start", 0.0);
  l.end = t.number("end", std::numeric_limits<double>::infinity());
  if (!(l.end >= l.start)) t.fail("end", "must not be before start");
  l.force = t.vec3<Eigen::Vector3d>("force", l.force);
  l.moment = t.vec3<Eigen::Vector3d>("moment", l.moment);
  const std::string frame = t.text("frame", "tip");
  if (frame != "tip" && frame != "base") t.fail("frame", "must be tip or base (got '" + frame + "')");
  l.tip_frame = frame == "tip";
  return l;
}

/// plant.environment (tip_radius, surfaces) and plant.external_loads.
void parse_environment(Tree& t, plant::PlantModel* p) {
  plant::Environment& env = p->environment;
  t.keys("plant.environment", {"tip_radius", "surfaces"});
  env.tip_radius = t.nonnegative("plant.environment.tip_radius", env.tip_radius);
  for (const char* list : {"plant.environment.surfaces", "plant.external_loads"}) {
    if (!t.has(list)) continue;
    t.allow(list);
    const YAML::Node v = t.find(list);
    if (!v.IsSequence()) t.fail(list, "must be a list of mappings");
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string at = std::string(list) + "[" + std::to_string(i) + "]";
      if (std::string(list) == "plant.environment.surfaces")
        env.surfaces.push_back(parse_surface(v[i], at));
      else
        env.loads.push_back(parse_load(v[i], at));
    }
  }
}

/// The root of a plant file's text; SceneError("plant", ...) when it is not YAML.
YAML::Node load_yaml(const std::string& text) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw SceneError("plant", std::string("malformed YAML: ") + e.what());
  }
}

/// plant.mismatch.*
void parse_mismatch(Tree& t, plant::ModelMismatch* m) {
  const std::string M = "plant.mismatch.";
  t.keys("plant.mismatch", {"precurvature_offset", "bending_stiffness_scale", "torsional_stiffness_scale",
                            "misalignment_offset", "tip_mass_scale", "base_tilt_offset"});
  m->precurvature_offset = t.vec3(M + "precurvature_offset", m->precurvature_offset);
  m->misalignment_offset = t.vec3(M + "misalignment_offset", m->misalignment_offset);
  m->bending_stiffness_scale = t.positive(M + "bending_stiffness_scale", m->bending_stiffness_scale);
  m->torsional_stiffness_scale = t.positive(M + "torsional_stiffness_scale", m->torsional_stiffness_scale);
  m->tip_mass_scale = t.nonnegative(M + "tip_mass_scale", m->tip_mass_scale);
  m->base_tilt_offset = t.number(M + "base_tilt_offset", m->base_tilt_offset);
}

/// plant.dynamics.*, plant.tracker.*, plant.flow_sensors.*, plant.command_timeout.
void parse_dynamics_and_sensors(Tree& t, plant::PlantModel* p) {
  const std::string D = "plant.dynamics.";
  t.keys("plant.dynamics", {"shear_stiffness", "axial_stiffness", "kelvin_voigt_time", "linear_drag", "tip_drag",
                            "tip_angular_drag", "tip_inertia", "linear_density", "nodes", "internal_dt", "alpha"});
  t.keys("plant.tracker",
         {"position_sigma", "angle_sigma", "position_quantum", "latency", "dropout_rate", "dropout_duration"});
  t.keys("plant.flow_sensors", {"sigma", "quantum"});
  // Optional numbers: key (below its section) and where it lives.
  const std::pair<std::string, double*> numbers[] = {
      {D + "shear_stiffness", &p->rod.shear_stiffness},
      {D + "axial_stiffness", &p->rod.axial_stiffness},
      {D + "kelvin_voigt_time", &p->rod.kelvin_voigt_time},
      {D + "linear_drag", &p->rod.linear_drag},
      {D + "tip_drag", &p->rod.tip_drag},
      {D + "tip_angular_drag", &p->rod.tip_angular_drag},
      {D + "alpha", &p->rod.alpha},
      {D + "internal_dt", &p->internal_dt},
      {"plant.tracker.position_sigma", &p->tracker.position_sigma},
      {"plant.tracker.angle_sigma", &p->tracker.angle_sigma},
      {"plant.tracker.position_quantum", &p->tracker.position_quantum},
      {"plant.tracker.latency", &p->tracker.latency},
      {"plant.tracker.dropout_rate", &p->tracker.dropout_rate},
      {"plant.tracker.dropout_duration", &p->tracker.dropout_duration},
      {"plant.flow_sensors.sigma", &p->flow.sigma},
      {"plant.flow_sensors.quantum", &p->flow.quantum},
      {"plant.command_timeout", &p->command_timeout},
      {"plant.thruster_time_constant", &p->thruster_time_constant},
  };
  for (const auto& n : numbers) *n.second = t.number(n.first, *n.second);
  // ρA of a one-segment rod (a robot of several segments keeps each segment's own).
  if (p->rod.rod.segments.size() == 1) {
    double& rho_a = p->rod.rod.segments[0].linear_density;
    rho_a = t.number(D + "linear_density", rho_a);
  } else if (t.has(D + "linear_density")) {
    t.number(D + "linear_density", 0.0);  // checked, not used
  }
  p->rod.tip_inertia = t.vec3(D + "tip_inertia", p->rod.tip_inertia);
  p->rod.nodes = t.integer(D + "nodes", p->rod.nodes);
}

/// plant.valves: a list of valve mappings, jet i's the i-th (in turn when there are fewer than jets);
/// each over the default valve in its place.
void parse_valves(Tree& t, plant::PlantModel* p) {
  if (!t.has("plant.valves")) return;
  t.allow("plant.valves");
  const YAML::Node v = t.find("plant.valves");
  if (!v.IsSequence() || v.size() < 1 || v.size() > static_cast<size_t>(rod::kMaxInputs))
    t.fail("plant.valves", "must be a list of 1 to " + std::to_string(rod::kMaxInputs) + " valve mappings");
  const std::vector<plant::ValveModel> defaults = p->valves;
  p->valves.resize(v.size());
  for (size_t i = 0; i < v.size(); ++i) {
    p->valves[i] = defaults[i % defaults.size()];
    parse_valve(v[i], "plant.valves[" + std::to_string(i) + "]", &p->valves[i]);
  }
}

/// The `plant` section of a plant file over the defaults in *m and *p.
void parse_plant_section(const YAML::Node& root, plant::ModelMismatch* m, plant::PlantModel* p) {
  Tree t(root, '.');
  t.section("plant");
  t.keys("plant", {"mismatch", "dynamics", "valves", "tracker", "flow_sensors", "sensor_noise", "command_timeout",
                   "thruster_time_constant", "external_tip_force", "external_tip_moment", "base_position",
                   "environment", "external_loads"});
  parse_mismatch(t, m);
  parse_environment(t, p);
  parse_dynamics_and_sensors(t, p);
  parse_valves(t, p);
  p->sensor_noise = t.boolean("plant.sensor_noise", p->sensor_noise);
  p->base_position = t.vec3("plant.base_position", p->base_position);
  p->external_tip_force = t.vec3("plant.external_tip_force", p->external_tip_force);
  p->external_tip_moment = t.vec3("plant.external_tip_moment", p->external_tip_moment);
}

/// The plant as the nominal scene describes it: its rod and nozzles, and the base tilt read off its
/// gravity vector (which must lie in the base y–z plane).
plant::PlantModel nominal_plant(const Scene& nominal) {
  if (nominal.rod.actuators.empty())
    throw SceneError("jets", "missing (the plant needs the jets, or an actuators section)");
  plant::PlantModel p;
  p.rod.rod = nominal.rod;
  p.nozzle = nominal.nozzle;
  p.environment.tip_radius = nominal.rod.tip_radius;  // the robot's capsule, unless the plant file says otherwise
  const Eigen::Vector3d g = nominal.rod.gravity;
  if (std::abs(g.x()) > 1e-9 * (1.0 + g.norm()))
    throw SceneError("gravity", "the plant tilts its base about x only: gravity[0] must be 0");
  p.gravity = g.norm();
  p.base_tilt = g.norm() > 0 ? std::atan2(g.y(), g.z()) : 0.0;
  return p;
}

/// The truth: the nominal plant with the mismatch applied. Every segment gets the same offsets; the
/// HydroJet's jets (a `jets` section) their misalignment offset (δα, δβ, δγ), any other actuator i
/// a turn about its body z-axis by misalignment_offset[i mod 3].
void apply_mismatch(const plant::ModelMismatch& m, const Scene& nominal, plant::PlantModel* p) {
  p->base_tilt += m.base_tilt_offset;
  rod::RodModel& r = p->rod.rod;
  r.tip_mass *= m.tip_mass_scale;
  for (rod::RodSegment& sg : r.segments) {
    sg.precurvature += m.precurvature_offset;
    sg.stiffness.head<2>() *= m.bending_stiffness_scale;
    sg.stiffness[2] *= m.torsional_stiffness_scale;
  }
  if (nominal.jets) {
    actuation::JetGeometry truth = *nominal.jets;
    truth.misalignment += m.misalignment_offset;
    r.actuators = control::jet_actuators(truth, control::jet_max_force(r), r.length());
    return;
  }
  for (size_t i = 0; i < r.actuators.size(); ++i) {
    rod::Actuator& a = r.actuators[i];
    a.direction = Eigen::AngleAxisd(m.misalignment_offset[i % 3], Eigen::Vector3d::UnitZ()) * a.direction;
  }
}

}  // namespace

plant::PlantModel make_plant(const Scene& nominal, const std::string& text) {
  plant::PlantModel p = nominal_plant(nominal);
  plant::ModelMismatch mismatch;
  if (!text.empty()) parse_plant_section(load_yaml(text), &mismatch, &p);
  apply_mismatch(mismatch, nominal, &p);
  const std::string e = p.validate();
  if (!e.empty())
    throw SceneError("plant." + e.substr(0, e.find(':')),
                     e.find(':') == std::string::npos ? e : e.substr(e.find(':') + 2));
  return p;
}

plant::PlantModel load_plant(const Scene& nominal, const std::string& path) {
  if (path.empty()) return make_plant(nominal, "");
  std::string text;
  if (const std::string err = util::read_regular_file(path, &text); !err.empty())
    throw SceneError("plant", "cannot read file '" + path + "': " + err);
  return make_plant(nominal, text);
}

}  // namespace config
}  // namespace hydrojet
