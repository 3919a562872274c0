// Options of the rig driver (config/rig.yaml, rig_node's private parameters) parsed and validated
// key by key: an unknown key or an invalid value throws RigConfigError("<key>: <what>"), e.g.
// "tracker/rate: must lie in (0, 1000] Hz". ROS-free (yaml-cpp); header-only so that the device
// library itself stays dependency-free.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "hydrojet_control/config/yaml_tree.h"
#include "hydrojet_control/devices/aurora_client.h"
#include "hydrojet_control/devices/flow_sensors.h"
#include "hydrojet_control/devices/valve_board.h"

namespace hydrojet {
namespace devices {

/// A rig option is missing or invalid: RigConfigError("tracker/rate", "must lie in (0, 1000] Hz"),
/// or one message "<key>: <what>".
class RigConfigError : public config::KeyError {
 public:
  using config::KeyError::KeyError;
  explicit RigConfigError(const std::string& message) : config::KeyError("", message) {}
};

struct RigConfig {
  std::string scene;                      ///< scene YAML (nozzle areas for the jet force, eq. 26)
  std::string tracker_frame = "tracker";  ///< frame of the poses (the field generator)
  std::string tip_frame = "tip_sensor";   ///< tf child frames
  std::string base_frame = "base_sensor";
  double reconnect_period = 1.0;  ///< [s], every device
  AuroraConfig tracker;
  std::array<FlowSensorConfig, 3> flow;  ///< jets 1, 2, 3
  double flow_rate = 50.0;               ///< nominal lines per second per sensor (diagnostics) [Hz]
  double flow_publish_rate = 100.0;      ///< jets/state checks per second [Hz]
  bool invalidate_on_reject = true;      ///< a rejected line makes that jet invalid until the next good one
  SerialValveBoardConfig valves;
  ValveLoopConfig valve_loop;
};

/// Multiplier from a flow unit to [m^3/s]: mL/min, L/min, L/h, mL/s, uL/min, m3/s (case-insensitive);
/// 0 for an unknown unit.
inline double flow_unit_scale(const std::string& unit) {
  std::string u;
  for (char c : unit) u.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  if (u == "ml/min") return 1e-6 / 60.0;
  if (u == "l/min") return 1e-3 / 60.0;
  if (u == "l/h") return 1e-3 / 3600.0;
  if (u == "ml/s") return 1e-6;
  if (u == "ul/min") return 1e-9 / 60.0;
  if (u == "m3/s" || u == "m^3/s") return 1.0;
  return 0.0;
}

namespace rig_config_detail {

/// The shared reader (config/yaml_tree.h) plus the one type only the rig has: an integer given as
/// a number or as hex text ("0x0A", "0A"; a launch-file <param> gives a string).
class Tree : public config::YamlTree<RigConfigError> {
 public:
  using config::YamlTree<RigConfigError>::YamlTree;
  long hex_or_int(const std::string& path, long fallback) {
    allow(path);
    const YAML::Node n = find(path);
    if (!n.IsDefined()) return fallback;
    if (!n.IsScalar()) fail(path, "must be an integer or hex text");
    try {
      return n.as<long>();
    } catch (const YAML::Exception&) {
    }
    std::string s = n.Scalar();
    if (s.size() > 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) s = s.substr(2);
    if (s.empty() || s.size() > 8) fail(path, "must be an integer or hex text");
    long v = 0;
    for (char c : s) {
      if (!std::isxdigit(static_cast<unsigned char>(c))) fail(path, "must be an integer or hex text");
      v = v * 16 + (std::isdigit(static_cast<unsigned char>(c)) ? c - '0' : std::toupper(c) - 'A' + 10);
    }
    return v;
  }
};

/// Re-labels a core validate() message "<field>: <what>" with its YAML section.
inline void check(const std::string& section, const std::string& err) {
  if (!err.empty()) throw RigConfigError(section + "/" + err);
}

}  // namespace rig_config_detail

/// Parses the rig options. `scene` is required, as are the device ports (tracker/port,
/// flow/ports/jet1..jet3, valves/port); everything else has the defaults of config/rig.yaml.
/// @throws RigConfigError("<key>: <what>") on a missing, unknown or invalid key.
inline RigConfig parse_rig_config(const YAML::Node& root) {
  using rig_config_detail::check;
  if (root.IsDefined() && !root.IsNull() && !root.IsMap()) throw RigConfigError("(root): must be a mapping");
  rig_config_detail::Tree p(root);
  RigConfig c;
  c.scene = p.text("scene", "");
  if (c.scene.empty()) throw RigConfigError("scene: missing (path of the scene YAML, for the nozzle areas)");
  c.tracker_frame = p.text("tracker_frame", c.tracker_frame);
  c.tip_frame = p.text("tip_frame", c.tip_frame);
  c.base_frame = p.text("base_frame", c.base_frame);
  for (const auto& f : {std::make_pair("tracker_frame", &c.tracker_frame), std::make_pair("tip_frame", &c.tip_frame),
                        std::make_pair("base_frame", &c.base_frame)}) {
    if (f.second->empty() || (*f.second)[0] == '/')
      throw RigConfigError(std::string(f.first) + ": must be a non-empty frame name without a leading '/'");
  }
  if (c.tip_frame == c.base_frame || c.tip_frame == c.tracker_frame || c.base_frame == c.tracker_frame)
    throw RigConfigError("tip_frame: tracker_frame, tip_frame and base_frame must differ");
  c.reconnect_period = p.number("reconnect_period", c.reconnect_period);
  if (!(c.reconnect_period >= 0.05 && c.reconnect_period <= 60.0))
    throw RigConfigError("reconnect_period: must lie in [0.05, 60] s");
  p.allow("diagnostic_period");  // read by diagnostic_updater itself

  // Tracker (NDI Aurora).
  AuroraConfig& a = c.tracker;
  a.port = p.text("tracker/port", "");
  if (a.port.empty()) throw RigConfigError("tracker/port: missing (serial device of the Aurora)");
  a.baud = p.integer("tracker/baud", a.baud);
  const long tip = p.hex_or_int("tracker/tip_handle", a.tip_handle);
  const long base = p.hex_or_int("tracker/base_handle", a.base_handle);
  if (tip < 1 || tip > 0xFF) throw RigConfigError("tracker/tip_handle: must lie in [0x01, 0xFF]");
  if (base < 1 || base > 0xFF) throw RigConfigError("tracker/base_handle: must lie in [0x01, 0xFF]");
  a.tip_handle = static_cast<uint8_t>(tip);
  a.base_handle = static_cast<uint8_t>(base);
  a.rate = p.number("tracker/rate", a.rate);
  a.reply_timeout = p.number("tracker/reply_timeout", a.reply_timeout);
  a.command_timeout = p.number("tracker/command_timeout", a.command_timeout);
  a.reset_timeout = p.number("tracker/reset_timeout", a.reset_timeout);
  a.timeout = p.number("tracker/timeout", a.timeout);
  const long mask = p.hex_or_int("tracker/out_of_volume_mask", a.out_of_volume_mask);
  if (mask < 0 || mask > 0xFFFFFFFFL) throw RigConfigError("tracker/out_of_volume_mask: must be a 32-bit mask");
  a.out_of_volume_mask = static_cast<uint32_t>(mask);
  const std::string prio = p.text("tracker/tracking_priority", std::string(1, a.tracking_priority));
  if (prio.size() != 1) throw RigConfigError("tracker/tracking_priority: must be S, D or B");
  a.tracking_priority = prio[0];
  a.bx_options = p.text("tracker/bx_options", a.bx_options);
  a.reconnect_period = c.reconnect_period;
  check("tracker", a.validate());

  // Flow sensors.
  FlowLineFormat fmt;
  fmt.regex = p.text("flow/format/regex", "");
  fmt.field_index = p.integer("flow/format/field_index", 0);
  const std::string sep = p.text("flow/format/separator", ",");
  if (sep.size() != 1) throw RigConfigError("flow/format/separator: must be one character");
  fmt.separator = sep[0];
  const std::string unit = p.text("flow/format/unit", "");
  if (unit.empty()) throw RigConfigError("flow/format/unit: missing (mL/min, L/min, L/h, mL/s, uL/min or m3/s)");
  const double unit_scale = flow_unit_scale(unit);
  if (unit_scale == 0.0)
    throw RigConfigError("flow/format/unit: '" + unit + "' is not one of mL/min, L/min, L/h, mL/s, uL/min, m3/s");
  const double scale = p.number("flow/format/scale", 1.0);
  if (!(scale > 0.0)) throw RigConfigError("flow/format/scale: must be > 0");
  fmt.scale_to_m3_per_s = unit_scale * scale;
  const int flow_baud = p.integer("flow/baud", 9600);
  const double flow_timeout = p.number("flow/timeout", 0.25);
  const int max_line = p.integer("flow/max_line_length", 128);
  const std::string start = p.text("flow/start_command", "");
  c.flow_rate = p.number("flow/rate", c.flow_rate);
  if (!(c.flow_rate > 0.0 && c.flow_rate <= 1000.0)) throw RigConfigError("flow/rate: must lie in (0, 1000] Hz");
  c.flow_publish_rate = p.number("flow/publish_rate", c.flow_publish_rate);
  if (!(c.flow_publish_rate > 0.0 && c.flow_publish_rate <= 1000.0))
    throw RigConfigError("flow/publish_rate: must lie in (0, 1000] Hz");
  c.invalidate_on_reject = p.boolean("flow/invalidate_on_reject", c.invalidate_on_reject);
  for (int i = 0; i < 3; ++i) {
    const std::string key = "flow/ports/jet" + std::to_string(i + 1);
    FlowSensorConfig& f = c.flow[i];
    f.name = "flow sensor " + std::to_string(i + 1);
    f.port = p.text(key, "");
    if (f.port.empty())
      throw RigConfigError(key + ": missing (serial device of jet " + std::to_string(i + 1) + "'s flow sensor)");
    f.baud = flow_baud;
    f.format = fmt;
    f.timeout = flow_timeout;
    f.reconnect_period = c.reconnect_period;
    f.max_line_length = max_line < 0 ? 0 : static_cast<size_t>(max_line);
    f.start_command = start;
    const std::string err = f.validate();
    if (!err.empty()) {
      const std::string field = err.substr(0, err.find(':'));
      const std::string rest = err.substr(field.size());
      if (field == "port") throw RigConfigError(key + rest);
      if (field == "regex" || field == "field_index" || field == "separator" || field == "scale")
        throw RigConfigError("flow/format/" + err);
      throw RigConfigError("flow/" + err);
    }
  }

  // Valves.
  c.valves.port = p.text("valves/port", "");
  if (c.valves.port.empty()) throw RigConfigError("valves/port: missing (serial device of the valve board)");
  c.valves.baud = p.integer("valves/baud", c.valves.baud);
  c.valves.ack_timeout = p.number("valves/ack_timeout", c.valves.ack_timeout);
  check("valves", c.valves.validate());
  c.valve_loop.rate = p.number("valves/rate", c.valve_loop.rate);
  c.valve_loop.max_failures = p.integer("valves/max_failures", c.valve_loop.max_failures);
  c.valve_loop.command_timeout = p.number("command_timeout", c.valve_loop.command_timeout);
  c.valve_loop.reconnect_period = c.reconnect_period;
  const std::string verr = c.valve_loop.validate();
  if (!verr.empty()) throw RigConfigError(verr.compare(0, 15, "command_timeout") == 0 ? verr : "valves/" + verr);

  // One port, one device.
  const std::string ports[] = {a.port, c.flow[0].port, c.flow[1].port, c.flow[2].port, c.valves.port};
  const char* keys[] = {"tracker/port", "flow/ports/jet1", "flow/ports/jet2", "flow/ports/jet3", "valves/port"};
  for (int j = 1; j < 5; ++j)
    for (int i = 0; i < j; ++i)
      if (ports[i] == ports[j])
        throw RigConfigError(std::string(keys[j]) + ": '" + ports[j] + "' is already " + keys[i] +
                             " (one device per port)");
  p.reject_unknown();
  return c;
}

}  // namespace devices
}  // namespace hydrojet
