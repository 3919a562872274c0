// Reads a node's private parameters (loaded from YAML by roslaunch) through the core's YAML
// parsers, so that the node and the ROS-free tools validate alike. Errors name the key ("~gains/kp").
#pragma once

#include <string>
#include <vector>

#include <ros/ros.h>
#include <yaml-cpp/yaml.h>

#include "hydrojet_control/config/controller_config.h"

namespace hydrojet {
namespace ros_bridge {

/// The parameter tree under a node handle's namespace as YAML.
YAML::Node private_params_as_yaml(const ros::NodeHandle& pnh);

/// Controller options from ~ (see config/controller.yaml); throws config::ParamError("~key: ...").
/// `mirrored`: top-level keys that are not options but another component's copy of them under ~,
/// skipped (dynamic_reconfigure writes its parameters there, so a controller restarted under the same
/// name finds them; the node sets them anew from the options at start).
config::ControllerNodeOptions read_controller_options(const ros::NodeHandle& pnh,
                                                      const std::vector<std::string>& mirrored = {});

}  // namespace ros_bridge
}  // namespace hydrojet
