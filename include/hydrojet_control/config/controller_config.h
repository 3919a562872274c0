// Controller options from YAML (config/controller.yaml): gains, limits, safety, path and the flow
// regulator. The same parser serves controller_node (its private ROS parameters, converted to
// YAML) and the ROS-free tools (experiment). Errors name the key ("gains/kp: must be ...").
#pragma once

#include <yaml-cpp/yaml.h>

#include <stdexcept>
#include <string>

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

struct ControllerOptions {
  std::string scene;                ///< scene YAML path (required by the node, optional for tools)
  double rate = 100.0;              ///< control rate [Hz]
  bool autostart = false;           ///< start the path as soon as data arrive
  std::string base_frame = "base";  ///< frame of the rod model (REP 105-style name)
  control::ControllerParams controller;
  actuation::FlowRegulatorParameters flow;
};

/// Parses a mapping with keys scene, rate, mode, autostart, base_frame, gains/*, limits/*,
/// allocation_weight, integrate_from_measured, safety/*, path/*, flow_regulator/*. Unknown keys and
/// invalid values throw ParamError("<key>: <what>").
ControllerOptions parse_controller_options(const YAML::Node& root);
/// Reads a YAML file of controller options.
ControllerOptions load_controller_options(const std::string& path);

}  // namespace config
}  // namespace hydrojet
