#include "hydrojet_control/config/plant_config.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

namespace hydrojet {
namespace config {
namespace {

void check_keys(const YAML::Node& node, const std::string& section, const std::set<std::string>& allowed) {
  if (!node.IsMap()) throw SceneError(section, "must be a mapping");
  for (const auto& kv : node) {
    const std::string k = kv.first.as<std::string>();
    if (!allowed.count(k)) throw SceneError(section + "." + k, "unknown key");
  }
}

/// Reads an optional finite number into *v.
void opt(const YAML::Node& n, const std::string& key, const std::string& path, double* v) {
  if (!n[key]) return;
  try {
    *v = n[key].as<double>();
  } catch (const YAML::Exception&) {
    throw SceneError(path + "." + key, "must be a number");
  }
  if (!std::isfinite(*v)) throw SceneError(path + "." + key, "must be finite");
}

void opt_vec3(const YAML::Node& n, const std::string& key, const std::string& path, Eigen::Vector3d* v) {
  if (!n[key]) return;
  const YAML::Node& s = n[key];
  if (!s.IsSequence() || s.size() != 3) throw SceneError(path + "." + key, "must be a list of 3 numbers");
  for (int i = 0; i < 3; ++i) {
    try {
      (*v)[i] = s[i].as<double>();
    } catch (const YAML::Exception&) {
      throw SceneError(path + "." + key + "[" + std::to_string(i) + "]", "must be a number");
    }
    if (!std::isfinite((*v)[i])) throw SceneError(path + "." + key + "[" + std::to_string(i) + "]", "must be finite");
  }
}

void parse_valve(const YAML::Node& n, const std::string& path, plant::ValveParameters* v) {
  check_keys(n, path, {"max_flow", "dead_zone", "exponent", "hysteresis", "time_constant", "saturation"});
  opt(n, "max_flow", path, &v->max_flow);
  opt(n, "dead_zone", path, &v->dead_zone);
  opt(n, "exponent", path, &v->exponent);
  opt(n, "hysteresis", path, &v->hysteresis);
  opt(n, "time_constant", path, &v->time_constant);
  opt(n, "saturation", path, &v->saturation);
  const std::string e = v->validate();
  if (!e.empty()) throw SceneError(path + "." + e.substr(0, e.find(':')), e.substr(e.find(':') + 2));
}

}  // namespace

plant::PlantParameters make_plant(const Scene& nominal, const std::string& text) {
  if (!nominal.has_jets) throw SceneError("jets", "missing (the plant needs the jet geometry)");
  plant::PlantParameters p;
  p.rod.model = nominal.model;
  p.jets = nominal.jets;
  p.nozzle = nominal.nozzle;
  // Per-jet hydraulics differ a little by default (three valves are never identical).
  p.valves[0].max_flow = 1.60e-5, p.valves[0].dead_zone = 0.05, p.valves[0].time_constant = 0.04;
  p.valves[1].max_flow = 1.52e-5, p.valves[1].dead_zone = 0.08, p.valves[1].time_constant = 0.05;
  p.valves[2].max_flow = 1.66e-5, p.valves[2].dead_zone = 0.04, p.valves[2].time_constant = 0.035;
  const Eigen::Vector3d g = nominal.model.gravity;
  if (std::abs(g.x()) > 1e-9 * (1.0 + g.norm()))
    throw SceneError("gravity", "the plant tilts its base about x only: gravity[0] must be 0");
  p.gravity = g.norm();
  p.base_tilt = g.norm() > 0 ? std::atan2(g.y(), g.z()) : 0.0;

  // Default model mismatch: what the nominal (calibrated) model does not capture.
  Eigen::Vector3d du(0.0, 0.0, 0.0), dmis(0.0, 0.0, 0.0);
  double ei_scale = 1.0, gj_scale = 1.0, mass_scale = 1.0;

  if (!text.empty()) {
    YAML::Node root;
    try {
      root = YAML::Load(text);
    } catch (const YAML::Exception& e) {
      throw SceneError("plant", std::string("malformed YAML: ") + e.what());
    }
    const YAML::Node n = root["plant"];
    if (!n) throw SceneError("plant", "missing section");
    check_keys(n, "plant", {"mismatch", "dynamics", "valves", "tracker", "flow_sensors", "sensor_noise",
                            "command_timeout", "base_position"});
    if (n["mismatch"]) {
      const YAML::Node m = n["mismatch"];
      check_keys(m, "plant.mismatch", {"precurvature_offset", "bending_stiffness_scale", "torsional_stiffness_scale",
                                       "misalignment_offset", "tip_mass_scale", "base_tilt_offset"});
      opt_vec3(m, "precurvature_offset", "plant.mismatch", &du);
      opt_vec3(m, "misalignment_offset", "plant.mismatch", &dmis);
      opt(m, "bending_stiffness_scale", "plant.mismatch", &ei_scale);
      opt(m, "torsional_stiffness_scale", "plant.mismatch", &gj_scale);
      opt(m, "tip_mass_scale", "plant.mismatch", &mass_scale);
      double tilt_offset = 0.0;
      opt(m, "base_tilt_offset", "plant.mismatch", &tilt_offset);
      p.base_tilt += tilt_offset;
      if (!(ei_scale > 0)) throw SceneError("plant.mismatch.bending_stiffness_scale", "must be positive");
      if (!(gj_scale > 0)) throw SceneError("plant.mismatch.torsional_stiffness_scale", "must be positive");
      if (!(mass_scale >= 0)) throw SceneError("plant.mismatch.tip_mass_scale", "must not be negative");
    }
    if (n["dynamics"]) {
      const YAML::Node d = n["dynamics"];
      const std::string P = "plant.dynamics";
      check_keys(d, P, {"shear_stiffness", "axial_stiffness", "kelvin_voigt_time", "linear_drag", "tip_drag",
                        "tip_angular_drag", "tip_inertia", "linear_density", "nodes", "internal_dt", "alpha"});
      opt(d, "shear_stiffness", P, &p.rod.shear_stiffness);
      opt(d, "axial_stiffness", P, &p.rod.axial_stiffness);
      opt(d, "kelvin_voigt_time", P, &p.rod.kelvin_voigt_time);
      opt(d, "linear_drag", P, &p.rod.linear_drag);
      opt(d, "tip_drag", P, &p.rod.tip_drag);
      opt(d, "tip_angular_drag", P, &p.rod.tip_angular_drag);
      opt_vec3(d, "tip_inertia", P, &p.rod.tip_inertia);
      opt(d, "linear_density", P, &p.rod.model.rod.linear_density);
      opt(d, "alpha", P, &p.rod.alpha);
      opt(d, "internal_dt", P, &p.internal_dt);
      if (d["nodes"]) {
        double nodes = 0;
        opt(d, "nodes", P, &nodes);
        if (nodes != std::floor(nodes)) throw SceneError(P + ".nodes", "must be an integer");
        p.rod.nodes = static_cast<int>(nodes);
      }
    }
    if (n["valves"]) {
      const YAML::Node v = n["valves"];
      if (!v.IsSequence() || v.size() != 3) throw SceneError("plant.valves", "must be a list of 3 valve mappings");
      for (int i = 0; i < 3; ++i) parse_valve(v[i], "plant.valves[" + std::to_string(i) + "]", &p.valves[i]);
    }
    if (n["tracker"]) {
      const YAML::Node t = n["tracker"];
      const std::string P = "plant.tracker";
      check_keys(t, P, {"position_sigma", "angle_sigma", "position_quantum", "latency", "dropout_rate", "dropout_duration"});
      opt(t, "position_sigma", P, &p.tracker.position_sigma);
      opt(t, "angle_sigma", P, &p.tracker.angle_sigma);
      opt(t, "position_quantum", P, &p.tracker.position_quantum);
      opt(t, "latency", P, &p.tracker.latency);
      opt(t, "dropout_rate", P, &p.tracker.dropout_rate);
      opt(t, "dropout_duration", P, &p.tracker.dropout_duration);
    }
    if (n["flow_sensors"]) {
      const YAML::Node f = n["flow_sensors"];
      check_keys(f, "plant.flow_sensors", {"sigma", "quantum"});
      opt(f, "sigma", "plant.flow_sensors", &p.flow.sigma);
      opt(f, "quantum", "plant.flow_sensors", &p.flow.quantum);
    }
    if (n["sensor_noise"]) {
      try {
        p.sensor_noise = n["sensor_noise"].as<bool>();
      } catch (const YAML::Exception&) {
        throw SceneError("plant.sensor_noise", "must be true or false");
      }
    }
    opt(n, "command_timeout", "plant", &p.command_timeout);
    opt_vec3(n, "base_position", "plant", &p.base_position);
  }
  p.rod.model.rod.precurvature += du;
  p.rod.model.rod.stiffness.head<2>() *= ei_scale;
  p.rod.model.rod.stiffness[2] *= gj_scale;
  p.rod.model.tip_mass *= mass_scale;
  p.jets.misalignment += dmis;
  const std::string e = p.validate();
  if (!e.empty()) throw SceneError("plant." + e.substr(0, e.find(':')), e.find(':') == std::string::npos ? e : e.substr(e.find(':') + 2));
  return p;
}

plant::PlantParameters load_plant(const Scene& nominal, const std::string& path) {
  if (path.empty()) return make_plant(nominal, "");
  std::ifstream f(path);
  if (!f) throw SceneError("plant", "cannot read file '" + path + "'");
  std::stringstream ss;
  ss << f.rdbuf();
  return make_plant(nominal, ss.str());
}

}  // namespace config
}  // namespace hydrojet
