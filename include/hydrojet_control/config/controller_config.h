// Controller options from YAML (config/controller.yaml): gains, limits, safety, path and the flow
// regulator. The same parser serves controller_node (its private ROS parameters, converted to
// YAML) and the ROS-free tools (experiment). Errors name the key ("gains/kp: must be ...").
#pragma once

#include <yaml-cpp/yaml.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "hydrojet_control/actuation/flow_regulator.h"
#include "hydrojet_control/config/yaml_tree.h"
#include "hydrojet_control/control/controller.h"

namespace hydrojet {
namespace config {

/// An option is missing or invalid: ParamError("gains/kp", "must be a number"), or one message
/// for the options as a whole.
class ParamError : public KeyError {
 public:
  using KeyError::KeyError;
  explicit ParamError(const std::string& message) : KeyError("", message) {}
};

/// The rig's per-jet PI flow regulator (duty per m^3/s), as in config/controller.yaml.
inline actuation::FlowRegulatorOptions rig_flow_regulator() {
  actuation::FlowRegulatorOptions f;
  f.feedforward = 62500.0;  // [1/(m^3/s)] ≈ 1 / flow at full duty
  f.kp = 18750.0;           // [1/(m^3/s)]
  f.ki = 312500.0;          // [1/m^3]
  f.lead_time = 0.01;       // [s]
  f.valve_exponent = 0.8;   // flow ∝ duty^0.8
  return f;
}

/// Rate teleoperation by joystick (sensor_msgs/Joy, ROS joy conventions: axes in [−1, 1], stick pushed
/// UP or LEFT reads +1). The view rate of a direction is scale × axis value [rad/s]; up = about the tip
/// frame's +x axis, right = about its +y axis. Defaults equal config/teleop.yaml (test_controller).
struct TeleopOptions {
  int axis_up = 1;            ///< axis that tilts the view up (+) and down (−): left stick vertical
  double scale_up = 0.1;      ///< [rad/s] at full deflection; + : stick up (+1) tilts the view up
  int axis_right = 0;         ///< axis that turns the view right and left: left stick horizontal
  double scale_right = -0.1;  ///< [rad/s]; − : stick right reads −1 and turns the view right
  int deadman_button = 4;     ///< must be held (1) for the axes to act: LB on an Xbox-style pad
  double timeout = 0.5;       ///< no joy or keyboard message for this long [s]: hold
};

/// Options of controller_node and the tools that run the controller. Default values equal
/// config/controller.yaml (checked field by field by test_controller).
struct ControllerNodeOptions {
  std::string scene;                ///< scene YAML path (required by the node, optional for tools)
  double rate = 100.0;              ///< control rate [Hz]
  bool autostart = false;           ///< start the path as soon as data arrive
  std::string base_frame = "base";  ///< frame of the rod model (REP 105-style name)
  control::ControllerOptions controller;
  actuation::FlowRegulatorOptions flow_regulator = rig_flow_regulator();
  TeleopOptions teleop;  ///< teleop/* keys (config/teleop.yaml)
  /// Keys read from a deprecated place or ignored (each names the key and what to write instead); the
  /// node logs them, the tools print them.
  std::vector<std::string> warnings;
};

/// The flow_regulator/* keys of a parameter tree into f, validated; an error names the key (the
/// controller's options and the calibration recorder's read them alike).
void read_flow_regulator(YamlTree<ParamError>& tree, actuation::FlowRegulatorOptions& f);

/// Parses a mapping with keys scene, rate, mode, autostart, base_frame, control_law, pd/*, modal/*,
/// limits/*, allocation/*, safety/*, approach/*, path/*, flow_regulator/*, teleop/* (a key that moved
/// is read from its old place too, with a warning). Unknown keys and invalid values throw
/// ParamError("<key>: <what>").
ControllerNodeOptions parse_controller_options(const YAML::Node& root);
/// Reads a YAML file of controller options.
ControllerNodeOptions load_controller_options(const std::string& path);
/// The rig's identification file (what `identify` writes; identification/file of the controller
/// file): ParamError naming the key when unreadable or out of range.
control::PlantIdentity load_identification(const std::string& path);

}  // namespace config
}  // namespace hydrojet
