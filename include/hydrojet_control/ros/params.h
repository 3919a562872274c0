// Reads a node's private parameters (loaded from YAML by roslaunch) through the core's YAML
// parsers, so that the node and the ROS-free tools validate alike. Errors name the key ("~gains/kp").
#pragma once

#include <ros/ros.h>
#include <yaml-cpp/yaml.h>

#include "hydrojet_control/config/controller_config.h"

namespace hydrojet {
namespace ros_bridge {

/// The parameter tree under a node handle's namespace as YAML.
YAML::Node private_params_as_yaml(const ros::NodeHandle& pnh);

/// Controller options from ~ (see config/controller.yaml); throws config::ParamError("~key: ...").
config::ControllerNodeOptions read_controller_options(const ros::NodeHandle& pnh);

}  // namespace ros_bridge
}  // namespace hydrojet
