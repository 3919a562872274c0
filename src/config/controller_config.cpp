#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/config/surface_yaml.h"
#include "hydrojet_control/util/files.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

namespace hydrojet {
namespace config {
namespace {

/// Controller options are "a/b" paths; errors are ParamError naming them.
using Tree = YamlTree<ParamError>;

/// A key that names one of `choices` (as their to_string names them): the one it names; anything else
/// fails naming the key and the choices.
template <typename Choice, typename... More>
Choice read_choice(Tree& p, const char* key, Choice current, Choice first, More... more) {
  const std::string name = p.text(key, control::to_string(current));
  std::string names;
  for (const Choice c : {first, more...}) {
    if (name == control::to_string(c)) return c;
    names += std::string(names.empty() ? "'" : "', '") + control::to_string(c);
  }
  p.fail(key, "must be one of " + names + "', got '" + name + "'");
}

/// The node's own options: scene, rate, autostart, base_frame and the loop mode.
void read_node_options(Tree& p, ControllerNodeOptions& o) {
  o.scene = p.text("scene", o.scene);
  o.rate = p.number("rate", o.rate);
  if (!(o.rate >= 1.0 && o.rate <= 1000.0)) p.fail("rate", "must lie in [1, 1000] Hz");
  o.autostart = p.boolean("autostart", o.autostart);
  o.base_frame = p.text("base_frame", o.base_frame);
  o.controller.mode = read_choice(p, "mode", o.controller.mode, control::LoopMode::kClosed, control::LoopMode::kOpen);
}

/// Keys that moved to the group of their owner: still read from the old place, with a warning naming
/// the new key.
constexpr std::pair<const char*, const char*> kMovedKeys[] = {
    {"gains/kp", "pd/kp"},
    {"gains/kd", "pd/kd"},
    {"gains/ki", "pd/ki"},
    {"gains/max_integral", "pd/max_integral"},
    {"gains/feedforward", "pd/feedforward"},
    {"fast_path_rate", "pd/fast_path_rate"},
    {"gains/damping", "allocation/damping"},
    {"allocation_weight", "allocation/weight"},
    {"allocation_smoothing", "allocation/smoothing"},
    {"limits/max_common_force_rate", "allocation/max_common_force_rate"},
};

/// The key that holds `key`'s value: its old place (kMovedKeys) when only that is given, with a
/// warning; both given fail naming the old one.
std::string source_of(Tree& p, const std::string& key, std::vector<std::string>& warnings) {
  for (const auto& [old_key, new_key] : kMovedKeys) {
    if (key != new_key || !p.has(old_key)) continue;
    if (p.has(new_key)) p.fail(old_key, "moved to " + p.key(new_key) + "; give it there only");
    warnings.push_back(std::string(p.key(old_key)) + ": deprecated, read as " + p.key(new_key) + "; write " +
                       p.key(new_key) + " instead");
    return old_key;
  }
  return key;
}

/// Keys whose option was removed: accepted at the value the controller now always uses, with a warning.
void read_removed(Tree& p, std::vector<std::string>& warnings) {
  const char* key = "integrate_from_measured";
  if (!p.has(key)) return;
  if (p.boolean(key, false)) p.fail(key, "removed: the step's base is always the previous command");
  warnings.push_back(p.key(key) + ": removed (the step's base is always the previous command); ignored");
}

/// keep_out: a list of regions (surfaces with a margin), each checked; errors name keep_out[i]/key.
void read_keep_out(Tree& p, std::vector<control::KeepOutRegion>& regions) {
  if (!p.has("keep_out")) return;
  p.allow("keep_out");
  const YAML::Node list = p.find("keep_out");
  if (!list.IsSequence()) p.fail("keep_out", "must be a list of regions (type plane|sphere|ellipsoid, margin)");
  regions.clear();
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string at = p.key("keep_out[" + std::to_string(i) + "]");
    if (!list[i].IsMap()) throw ParamError(at, "must be a mapping");
    Tree t(list[i], '/', at + "/");
    control::KeepOutRegion r;
    r.surface = read_surface_shape(t, {"margin"});
    r.margin = t.number("margin", r.margin);
    if (std::string e = r.validate(); !e.empty()) t.fail(e.substr(0, e.find(':')), e.substr(e.find(':') + 2));
    regions.push_back(r);
  }
}

/// Every option of ControllerOptions at its key, the group's path (pd/kp is pd.kp), validated; an
/// error names the key it was read from.
void read_controller_options(Tree& p, control::ControllerOptions& c, std::vector<std::string>& warnings) {
  const struct {
    const char* key;
    double* value;
  } numbers[] = {
      {"pd/kp", &c.pd.kp},
      {"pd/kd", &c.pd.kd},
      {"pd/ki", &c.pd.ki},
      {"pd/max_integral", &c.pd.max_integral},
      {"pd/feedforward", &c.pd.feedforward},
      {"pd/fast_path_rate", &c.pd.fast_path_rate},
      {"limits/max_force", &c.limits.max_force},
      {"limits/max_force_rate", &c.limits.max_force_rate},
      {"limits/max_angular_rate", &c.limits.max_angular_rate},
      {"limits/reachable_force_fraction", &c.limits.reachable_force_fraction},
      {"limits/max_path_rate", &c.limits.max_path_rate},
      {"allocation/damping", &c.allocation.damping},
      {"allocation/weight", &c.allocation.weight},
      {"allocation/smoothing", &c.allocation.smoothing},
      {"allocation/max_common_force_rate", &c.allocation.max_common_force_rate},
      {"safety/max_oscillation", &c.safety.max_oscillation},
      {"safety/sample_period", &c.safety.sample_period},
      {"safety/min_stability_margin", &c.safety.min_stability_margin},
      {"safety/unreachable_tolerance", &c.safety.unreachable_tolerance},
      {"safety/flow_fault_tolerance", &c.safety.flow_fault_tolerance},
      {"safety/flow_fault_time", &c.safety.flow_fault_time},
      {"approach/tolerance", &c.approach.tolerance},
      {"approach/settle_time", &c.approach.settle_time},
      {"approach/timeout", &c.approach.timeout},
      {"path/theta_start", &c.path.theta_start},
      {"path/theta_end", &c.path.theta_end},
      {"path/phi_start", &c.path.phi_start},
      {"path/phi_end", &c.path.phi_end},
      {"path/duration", &c.path.duration},
      {"modal/kp", &c.modal.kp},
      {"modal/ki", &c.modal.ki},
      {"modal/gain_speed", &c.modal.gain_speed},
      {"modal/damping_gain", &c.modal.damping_gain},
      {"modal/actuator_lag", &c.modal.actuator_lag},
      {"modal/rounding_force", &c.modal.rounding_force},
      {"modal/tip_mass_scale", &c.modal.tip_mass_scale},
      {"modal/damping_time", &c.modal.damping_time},
      {"modal/tracker_sigma", &c.modal.tracker_sigma},
      {"modal/velocity_noise", &c.modal.velocity_noise},
      {"modal/disturbance_noise", &c.modal.disturbance_noise},
      {"modal/ring_amplitude", &c.modal.ring_amplitude},
      {"modal/recover_time", &c.modal.recover_time},
      {"identification/probe_amplitude", &c.identification.probe_amplitude},
      {"contact/force_threshold", &c.contact.force_threshold},
      {"contact/max_force", &c.contact.max_force},
  };
  std::map<std::string, std::string> read_from;  // key -> where its value was read (a moved key's old place)
  for (const auto& n : numbers) {
    const std::string from = source_of(p, n.key, warnings);
    if (from != n.key) read_from[n.key] = from;
    *n.value = p.number(from, *n.value);
  }
  c.safety.stale_periods = p.integer("safety/stale_periods", c.safety.stale_periods);
  c.safety.max_solver_failures = p.integer("safety/max_solver_failures", c.safety.max_solver_failures);
  c.identification.probe = p.boolean("identification/probe", c.identification.probe);
  c.identification.file = p.text("identification/file", c.identification.file);
  read_removed(p, warnings);
  c.control_law =
      read_choice(p, "control_law", c.control_law, control::ControlLaw::kPapers, control::ControlLaw::kModal);
  c.path.type = read_choice(p, "path/type", c.path.type, control::PathType::kSpiral, control::PathType::kNone);
  c.contact.reaction = read_choice(p, "contact/reaction", c.contact.reaction, control::ContactReaction::kComply,
                                   control::ContactReaction::kHold, control::ContactReaction::kRetreat);
  read_keep_out(p, c.keep_out);
  const std::string err = c.validate();
  if (!err.empty()) {
    const std::string key = err.substr(0, err.find(':'));
    const auto moved = read_from.find(key);
    p.fail(moved == read_from.end() ? key : moved->second, err.substr(std::min(err.size(), key.size() + 2)));
  }
}

/// Joystick teleoperation (config/teleop.yaml), validated; an error names the key.
void read_teleop(Tree& p, TeleopOptions& t) {
  const struct {
    const char* key;
    int* value;
  } indices[] = {{"teleop/axis_up", &t.axis_up},
                 {"teleop/axis_right", &t.axis_right},
                 {"teleop/deadman_button", &t.deadman_button}};
  for (const auto& i : indices) {
    *i.value = p.integer(i.key, *i.value);
    if (*i.value < 0) p.fail(i.key, "must be an index >= 0");
  }
  for (auto [key, value] :
       {std::pair{"teleop/scale_up", &t.scale_up}, std::pair{"teleop/scale_right", &t.scale_right}}) {
    *value = p.number(key, *value);
    if (!(std::abs(*value) <= 2.0)) p.fail(key, "must lie in [-2, 2] rad/s");
  }
  t.timeout = p.number("teleop/timeout", t.timeout);
  if (!(t.timeout > 0.0 && t.timeout <= 10.0)) p.fail("teleop/timeout", "must lie in (0, 10] s");
}

}  // namespace

void read_flow_regulator(YamlTree<ParamError>& p, actuation::FlowRegulatorOptions& f) {
  f.kp = p.number("flow_regulator/kp", f.kp);
  f.ki = p.number("flow_regulator/ki", f.ki);
  f.feedforward = p.number("flow_regulator/feedforward", f.feedforward);
  f.lead_time = p.number("flow_regulator/lead_time", f.lead_time);
  f.valve_exponent = p.number("flow_regulator/valve_exponent", f.valve_exponent);
  f.output_min = p.number("flow_regulator/output_min", f.output_min);
  f.output_max = p.number("flow_regulator/output_max", f.output_max);
  const std::string ferr = actuation::validate(f);
  if (!ferr.empty()) {
    const size_t sp = ferr.find(' ');
    p.fail("flow_regulator/" + ferr.substr(0, sp), ferr.substr(std::min(ferr.size(), sp + 1)));
  }
}

ControllerNodeOptions parse_controller_options(const YAML::Node& root) {
  if (root.IsDefined() && !root.IsNull() && !root.IsMap()) throw ParamError("(root)", "must be a mapping");
  Tree p(root);
  ControllerNodeOptions o;
  read_node_options(p, o);
  read_controller_options(p, o.controller, o.warnings);
  read_flow_regulator(p, o.flow_regulator);
  read_teleop(p, o.teleop);
  p.reject_unknown();
  return o;
}

ControllerNodeOptions load_controller_options(const std::string& path) {
  YAML::Node root;
  std::string text;
  if (const std::string err = util::read_regular_file(path, &text); !err.empty())
    throw ParamError("controller options: cannot read file '" + path + "': " + err);
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ParamError(std::string("controller options: malformed YAML: ") + e.what());
  }
  ControllerNodeOptions o = parse_controller_options(root);
  if (std::string& file = o.controller.identification.file; !file.empty()) {
    const size_t slash = path.rfind('/');
    if (file[0] != '/' && slash != std::string::npos) file = path.substr(0, slash + 1) + file;
    o.controller.identification.known = load_identification(file);
  }
  return o;
}

control::PlantIdentity load_identification(const std::string& path) {
  std::string text;
  if (const std::string err = util::read_regular_file(path, &text); !err.empty())
    throw ParamError("identification/file", "cannot read '" + path + "': " + err);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ParamError("identification/file", "'" + path + "': malformed YAML: " + e.what());
  }
  if (!root.IsMap() || !root["identification"].IsMap())
    throw ParamError("identification/file", "'" + path + "': must hold a mapping `identification`");
  Tree p(root);
  control::PlantIdentity id;
  const struct {
    const char* key;
    double* value;
    double lo, hi;
  } numbers[] = {{"identification/tip_mass_scale", &id.tip_mass_scale, 0.1, 100.0},
                 {"identification/damping_time", &id.damping_time, 0.0, 1.0},
                 {"identification/tracker_latency_s", &id.tracker_latency_s, 0.0, 1.0},
                 {"identification/mode_hz", &id.mode_hz, 0.0, 1e3},
                 {"identification/damping_ratio", &id.damping_ratio, 0.0, 10.0}};
  for (const auto& n : numbers) {
    *n.value = p.number(n.key);
    if (!(*n.value >= n.lo && *n.value <= n.hi))
      p.fail(n.key, "must lie in [" + util::num(n.lo) + ", " + util::num(n.hi) + "], got " + util::num(*n.value));
  }
  id.valve_time_constants_s = p.number_list("identification/valve_time_constants_s", 1, 8);
  for (const double tau : id.valve_time_constants_s)
    if (!(tau >= 0.0 && tau <= 1.0)) p.fail("identification/valve_time_constants_s", "each must lie in [0, 1] s");
  // The valves' plays (a file written before identify measured them has none: zero, not inverted).
  if (p.has("identification/valve_plays")) {
    id.valve_plays = p.numbers("identification/valve_plays", id.valve_time_constants_s.size());
    for (const double play : id.valve_plays)
      if (!(play >= 0.0 && play <= 0.2)) p.fail("identification/valve_plays", "each must lie in [0, 0.2] of the duty");
  } else {
    id.valve_plays.assign(id.valve_time_constants_s.size(), 0.0);
  }
  id.valves_identified = p.boolean("identification/valves_identified", true);
  p.reject_unknown();
  id.mode_identified = true;
  return id;
}

}  // namespace config
}  // namespace hydrojet
