// Reads a node's private parameters (loaded from YAML by roslaunch) into the core's option structs,
// validating types and ranges and rejecting unknown keys. Errors name the key ("~gains/kp").
#pragma once

#include <xmlrpcpp/XmlRpcValue.h>

#include <set>
#include <stdexcept>
#include <string>

#include "hydrojet_control/actuation/flow_regulator.h"
#include "hydrojet_control/control/controller.h"

namespace hydrojet {
namespace ros_bridge {

class ParamError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Typed access to a tree of parameters, with the set of keys that were read kept so that
/// unknown keys can be reported.
class ParamTree {
 public:
  explicit ParamTree(const XmlRpc::XmlRpcValue& root) : root_(root) {}
  bool has(const std::string& path) const;
  double number(const std::string& path, double fallback);
  int integer(const std::string& path, int fallback);
  bool boolean(const std::string& path, bool fallback);
  std::string text(const std::string& path, const std::string& fallback);
  /// Throws ParamError naming the first key present in the tree but never read.
  void reject_unknown() const;

 private:
  const XmlRpc::XmlRpcValue* find(const std::string& path) const;
  XmlRpc::XmlRpcValue root_;
  std::set<std::string> read_;
};

struct ControllerNodeOptions {
  std::string scene;                  ///< scene YAML path
  double rate = 100.0;                ///< control rate [Hz]
  bool autostart = false;             ///< start the path as soon as data arrive
  std::string base_frame = "base";    ///< frame of the rod model (REP 105-style name)
  control::ControllerParams controller;
  actuation::FlowRegulatorParameters flow;
};

/// Reads ~scene, ~rate, ~mode, ~autostart, ~gains/*, ~limits/*, ~allocation_weight, ~safety/*,
/// ~path/*, ~flow_regulator/*, ~base_frame. Throws ParamError naming the bad key.
ControllerNodeOptions read_controller_options(const XmlRpc::XmlRpcValue& private_params);

}  // namespace ros_bridge
}  // namespace hydrojet
