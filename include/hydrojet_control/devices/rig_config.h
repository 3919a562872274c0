// Options of the rig driver (config/rig.yaml, rig_node's private parameters) parsed and validated
// key by key: an unknown key or an invalid value throws RigOptionsError("<key>: <what>"), e.g.
// "tracker/rate: must lie in (0, 1000] Hz". ROS-free (yaml-cpp). The default member values of
// RigOptions and of the device options it holds are those of config/rig.yaml (test_rig_core
// compares them field by field); the device ports, the scene and the flow unit have none.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <string>

#include "hydrojet_control/config/yaml_tree.h"
#include "hydrojet_control/devices/aurora_client.h"
#include "hydrojet_control/devices/flow_sensors.h"
#include "hydrojet_control/devices/valve_board.h"

namespace hydrojet {
namespace devices {

/// A rig option is missing or invalid: RigOptionsError("tracker/rate", "must lie in (0, 1000] Hz"),
/// or one message "<key>: <what>".
class RigOptionsError : public config::KeyError {
 public:
  using config::KeyError::KeyError;
  explicit RigOptionsError(const std::string& message) : config::KeyError("", message) {}
};

/// Default options of the three jets' flow sensors, named "flow sensor 1" ... "flow sensor 3".
std::array<FlowSensorOptions, 3> jet_flow_sensors();

struct RigOptions {
  std::string scene;                      ///< scene YAML (nozzle areas for the jet force, eq. 26)
  std::string tracker_frame = "tracker";  ///< frame of the poses (the field generator)
  std::string tip_frame = "tip_sensor";   ///< tf child frames
  std::string base_frame = "base_sensor";
  double reconnect_period = 1.0;  ///< [s], every device
  AuroraOptions tracker;
  std::array<FlowSensorOptions, 3> flow = jet_flow_sensors();  ///< jets 1, 2, 3
  double flow_rate = 50.0;           ///< nominal lines per second per sensor (diagnostics) [Hz]
  double flow_publish_rate = 100.0;  ///< jets/state checks per second [Hz]
  bool invalidate_on_reject = true;  ///< a rejected line makes that jet invalid until the next good one
  SerialValveBoardOptions valves;
  ValveLoopOptions valve_loop;
};

/// Multiplier from a flow unit to [m^3/s]: mL/min, L/min, L/h, mL/s, uL/min, m3/s (case-insensitive);
/// 0 for an unknown unit.
double flow_unit_scale(const std::string& unit);

/// Parses the rig options. `scene` is required, as are the device ports (tracker/port,
/// flow/ports/jet1..jet3, valves/port) and flow/format/unit; everything else has the defaults of
/// config/rig.yaml (the default member values of RigOptions).
/// @throws RigOptionsError("<key>: <what>") on a missing, unknown or invalid key.
RigOptions parse_rig_options(const YAML::Node& root);

}  // namespace devices
}  // namespace hydrojet
