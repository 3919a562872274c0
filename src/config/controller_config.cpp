#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/util/files.h"

#include <cmath>
#include <algorithm>

namespace hydrojet {
namespace config {
namespace {

/// Controller options are "a/b" paths; errors are ParamError naming them.
using Tree = YamlTree<ParamError>;

/// A key that names one of two choices, `first` or `second` (as their to_string names them): the one
/// it names; anything else fails naming the key.
template <typename Choice>
Choice read_choice(Tree& p, const char* key, Choice current, Choice first, Choice second) {
  const std::string name = p.text(key, control::to_string(current));
  if (name == control::to_string(first)) return first;
  if (name == control::to_string(second)) return second;
  p.fail(key, std::string("must be '") + control::to_string(first) + "' or '" + control::to_string(second) +
                  "', got '" + name + "'");
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

/// Gains, limits, safety and path (ControllerOptions), validated; an error names the key.
void read_controller_options(Tree& p, control::ControllerOptions& c) {
  // Each numeric parameter: its key, the core's field name (as ControllerOptions::validate() names
  // it) and where it lives.
  const struct {
    const char* key;
    const char* field;
    double* value;
  } numbers[] = {
      {"gains/kp", "kp", &c.kp},
      {"gains/kd", "kd", &c.kd},
      {"gains/ki", "ki", &c.ki},
      {"gains/max_integral", "max_integral", &c.max_integral},
      {"gains/feedforward", "feedforward", &c.feedforward},
      {"gains/damping", "damping", &c.damping},
      {"limits/max_force", "max_force", &c.max_force},
      {"limits/max_force_rate", "max_force_rate", &c.max_force_rate},
      {"limits/max_common_force_rate", "max_common_force_rate", &c.max_common_force_rate},
      {"fast_path_rate", "fast_path_rate", &c.fast_path_rate},
      {"limits/max_angular_rate", "max_angular_rate", &c.max_angular_rate},
      {"limits/reachable_force_fraction", "reachable_force_fraction", &c.reachable_force_fraction},
      {"allocation_weight", "allocation_weight", &c.allocation_weight},
      {"allocation_smoothing", "allocation_smoothing", &c.allocation_smoothing},
      {"safety/max_oscillation", "max_oscillation", &c.max_oscillation},
      {"safety/sample_period", "sample_period", &c.sample_period},
      {"safety/min_stability_margin", "min_stability_margin", &c.min_stability_margin},
      {"safety/unreachable_tolerance", "unreachable_tolerance", &c.unreachable_tolerance},
      {"safety/flow_fault_tolerance", "flow_fault_tolerance", &c.flow_fault_tolerance},
      {"safety/flow_fault_time", "flow_fault_time", &c.flow_fault_time},
      {"approach/tolerance", "approach_tolerance", &c.approach.tolerance},
      {"approach/settle_time", "approach_settle_time", &c.approach.settle_time},
      {"approach/timeout", "approach_timeout", &c.approach.timeout},
      {"path/theta_start", "path.theta_start", &c.path.theta_start},
      {"path/theta_end", "path.theta_end", &c.path.theta_end},
      {"path/phi_start", "path.phi_start", &c.path.phi_start},
      {"path/phi_end", "path.phi_end", &c.path.phi_end},
      {"path/duration", "path.duration", &c.path.duration},
      {"modal/kp", "modal.kp", &c.modal.kp},
      {"modal/ki", "modal.ki", &c.modal.ki},
      {"modal/gain_speed", "modal.gain_speed", &c.modal.gain_speed},
      {"modal/damping_gain", "modal.damping_gain", &c.modal.damping_gain},
      {"modal/actuator_lag", "modal.actuator_lag", &c.modal.actuator_lag},
      {"modal/rounding_force", "modal.rounding_force", &c.modal.rounding_force},
      {"modal/tip_mass_scale", "modal.tip_mass_scale", &c.modal.tip_mass_scale},
      {"modal/damping_time", "modal.damping_time", &c.modal.damping_time},
      {"modal/tracker_sigma", "modal.tracker_sigma", &c.modal.tracker_sigma},
      {"modal/velocity_noise", "modal.velocity_noise", &c.modal.velocity_noise},
      {"modal/disturbance_noise", "modal.disturbance_noise", &c.modal.disturbance_noise},
  };
  for (const auto& n : numbers) *n.value = p.number(n.key, *n.value);
  c.stale_periods = p.integer("safety/stale_periods", c.stale_periods);
  c.max_solver_failures = p.integer("safety/max_solver_failures", c.max_solver_failures);
  c.integrate_from_measured = p.boolean("integrate_from_measured", c.integrate_from_measured);
  c.control_law =
      read_choice(p, "control_law", c.control_law, control::ControlLaw::kPapers, control::ControlLaw::kModal);
  c.path_type = read_choice(p, "path/type", c.path_type, control::PathType::kSpiral, control::PathType::kNone);
  const std::string err = c.validate();
  if (!err.empty()) {
    const std::string field = err.substr(0, err.find(':'));
    std::string k = field == "stale_periods" || field == "max_solver_failures" ? "safety/" + field : field;
    for (const auto& n : numbers)
      if (field == n.field) k = n.key;
    p.fail(k, err.substr(std::min(err.size(), field.size() + 2)));
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
  read_controller_options(p, o.controller);
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
  return parse_controller_options(root);
}

}  // namespace config
}  // namespace hydrojet
