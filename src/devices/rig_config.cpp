// Rig options: config/rig.yaml / rig_node's private parameters, parsed key by key (see rig_config.h).
#include "hydrojet_control/devices/rig_config.h"

#include <cctype>

namespace hydrojet {
namespace devices {
namespace {

/// The shared reader (config/yaml_tree.h) plus the one type only the rig has: an integer given as
/// a number or as hex text ("0x0A", "0A"; a launch-file <param> gives a string).
class Tree : public config::YamlTree<RigOptionsError> {
 public:
  using config::YamlTree<RigOptionsError>::YamlTree;
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
void check(const std::string& section, const std::string& err) {
  if (!err.empty()) throw RigOptionsError(section + "/" + err);
}

/// tracker_frame, tip_frame, base_frame: non-empty, no leading '/', all different.
void parse_frames(Tree& p, RigOptions* c) {
  c->tracker_frame = p.text("tracker_frame", c->tracker_frame);
  c->tip_frame = p.text("tip_frame", c->tip_frame);
  c->base_frame = p.text("base_frame", c->base_frame);
  for (const auto& f : {std::make_pair("tracker_frame", &c->tracker_frame), std::make_pair("tip_frame", &c->tip_frame),
                        std::make_pair("base_frame", &c->base_frame)}) {
    if (f.second->empty() || (*f.second)[0] == '/')
      throw RigOptionsError(std::string(f.first) + ": must be a non-empty frame name without a leading '/'");
  }
  if (c->tip_frame == c->base_frame || c->tip_frame == c->tracker_frame || c->base_frame == c->tracker_frame)
    throw RigOptionsError("tip_frame: tracker_frame, tip_frame and base_frame must differ");
}

/// tracker/srom_files: {port handle (hex text or integer): tool-definition file}. Each file is read
/// here, so that a missing or oversized one stops the start naming its key.
void parse_srom_files(Tree& p, AuroraOptions* a) {
  p.allow("tracker/srom_files");
  const YAML::Node n = p.find("tracker/srom_files");
  if (!n.IsDefined()) return;
  if (!n.IsMap()) throw RigOptionsError("tracker/srom_files: must be a mapping {port handle: file}");
  for (const auto& kv : n) {
    const std::string key = "tracker/srom_files/" + kv.first.Scalar();
    YAML::Node one;
    one["h"] = kv.first;
    long h = -1;
    try {
      h = Tree(one).hex_or_int("h", -1);
    } catch (const RigOptionsError&) {
      h = -1;  // named below with the full key
    }
    if (h < 1 || h > 0xFF)
      throw RigOptionsError(key + ": the key must be a port handle in [0x01, 0xFF] (hex text like 0A, or 0x0A)");
    if (!kv.second.IsScalar() || kv.second.Scalar().empty())
      throw RigOptionsError(key + ": must be the path of a tool-definition (.rom) file");
    const uint8_t handle = static_cast<uint8_t>(h);
    if (a->srom_files.count(handle)) throw RigOptionsError(key + ": port handle given twice");
    std::vector<uint8_t> data;
    std::string err;
    if (!load_srom(kv.second.Scalar(), &data, &err)) throw RigOptionsError(key + ": " + err);
    a->srom_files[handle] = kv.second.Scalar();
  }
}

/// tracker/...: the NDI Aurora (port required).
void parse_tracker(Tree& p, RigOptions* c) {
  AuroraOptions& a = c->tracker;
  a.port = p.text("tracker/port", "");
  if (a.port.empty()) throw RigOptionsError("tracker/port: missing (serial device of the Aurora)");
  a.baud = p.integer("tracker/baud", a.baud);
  const long tip = p.hex_or_int("tracker/tip_handle", a.tip_handle);
  const long base = p.hex_or_int("tracker/base_handle", a.base_handle);
  if (tip < 1 || tip > 0xFF) throw RigOptionsError("tracker/tip_handle: must lie in [0x01, 0xFF]");
  if (base < 1 || base > 0xFF) throw RigOptionsError("tracker/base_handle: must lie in [0x01, 0xFF]");
  a.tip_handle = static_cast<uint8_t>(tip);
  a.base_handle = static_cast<uint8_t>(base);
  a.rate = p.number("tracker/rate", a.rate);
  a.reply_timeout = p.number("tracker/reply_timeout", a.reply_timeout);
  a.command_timeout = p.number("tracker/command_timeout", a.command_timeout);
  a.reset_timeout = p.number("tracker/reset_timeout", a.reset_timeout);
  a.timeout = p.number("tracker/timeout", a.timeout);
  const long mask = p.hex_or_int("tracker/out_of_volume_mask", a.out_of_volume_mask);
  if (mask < 0 || mask > 0xFFFFFFFFL) throw RigOptionsError("tracker/out_of_volume_mask: must be a 32-bit mask");
  a.out_of_volume_mask = static_cast<uint32_t>(mask);
  const std::string prio = p.text("tracker/tracking_priority", std::string(1, a.tracking_priority));
  if (prio.size() != 1) throw RigOptionsError("tracker/tracking_priority: must be S, D or B");
  a.tracking_priority = prio[0];
  a.bx_options = p.text("tracker/bx_options", a.bx_options);
  const std::string format = p.text("tracker/reply_format", to_string(a.reply_format));
  if (format == "bx")
    a.reply_format = AuroraOptions::ReplyFormat::kBx;
  else if (format == "tx")
    a.reply_format = AuroraOptions::ReplyFormat::kTx;
  else
    throw RigOptionsError("tracker/reply_format: '" + format + "' is not bx or tx");
  a.tx_fallback = p.boolean("tracker/tx_fallback", a.tx_fallback);
  a.latency = p.number("tracker/latency", a.latency);
  parse_srom_files(p, &a);
  a.reconnect_period = c->reconnect_period;
  check("tracker", a.validate());
}

/// flow/format/...: how a line is read. The unit is required (no default: a wrong unit is a
/// factor of 1000 in the flow); `scale` is an extra factor (1: none).
FlowLineFormat parse_flow_format(Tree& p, const FlowLineFormat& defaults) {
  FlowLineFormat fmt = defaults;
  fmt.regex = p.text("flow/format/regex", fmt.regex);
  fmt.field_index = p.integer("flow/format/field_index", fmt.field_index);
  const std::string sep = p.text("flow/format/separator", std::string(1, fmt.separator));
  if (sep.size() != 1) throw RigOptionsError("flow/format/separator: must be one character");
  fmt.separator = sep[0];
  const std::string unit = p.text("flow/format/unit", "");
  if (unit.empty()) throw RigOptionsError("flow/format/unit: missing (mL/min, L/min, L/h, mL/s, uL/min or m3/s)");
  const double unit_scale = flow_unit_scale(unit);
  if (unit_scale == 0.0)
    throw RigOptionsError("flow/format/unit: '" + unit + "' is not one of mL/min, L/min, L/h, mL/s, uL/min, m3/s");
  const double scale = p.number("flow/format/scale", 1.0);
  if (!(scale > 0.0)) throw RigOptionsError("flow/format/scale: must be > 0");
  fmt.scale_to_m3_per_s = unit_scale * scale;
  return fmt;
}

/// Re-labels a FlowSensorOptions::validate() message of jet sensor `key` with its YAML key.
void check_flow_sensor(const std::string& key, const std::string& err) {
  if (err.empty()) return;
  const std::string field = err.substr(0, err.find(':'));
  const std::string rest = err.substr(field.size());
  if (field == "port") throw RigOptionsError(key + rest);
  if (field == "regex" || field == "field_index" || field == "separator" || field == "scale")
    throw RigOptionsError("flow/format/" + err);
  throw RigOptionsError("flow/" + err);
}

/// flow/...: the three jets' sensors share every setting but the port (required).
void parse_flow(Tree& p, RigOptions* c) {
  FlowSensorOptions shared = c->flow[0];
  shared.format = parse_flow_format(p, shared.format);
  shared.baud = p.integer("flow/baud", shared.baud);
  shared.timeout = p.number("flow/timeout", shared.timeout);
  const int max_line = p.integer("flow/max_line_length", static_cast<int>(shared.max_line_length));
  shared.max_line_length = max_line < 0 ? 0 : static_cast<size_t>(max_line);
  shared.start_command = p.text("flow/start_command", shared.start_command);
  shared.reconnect_period = c->reconnect_period;
  c->flow_rate = p.number("flow/rate", c->flow_rate);
  if (!(c->flow_rate > 0.0 && c->flow_rate <= 1000.0)) throw RigOptionsError("flow/rate: must lie in (0, 1000] Hz");
  c->flow_publish_rate = p.number("flow/publish_rate", c->flow_publish_rate);
  if (!(c->flow_publish_rate > 0.0 && c->flow_publish_rate <= 1000.0))
    throw RigOptionsError("flow/publish_rate: must lie in (0, 1000] Hz");
  c->invalidate_on_reject = p.boolean("flow/invalidate_on_reject", c->invalidate_on_reject);
  for (size_t i = 0; i < c->flow.size(); ++i) {
    const std::string jet = std::to_string(i + 1);
    const std::string key = "flow/ports/jet" + jet;
    FlowSensorOptions f = shared;
    f.name = c->flow[i].name;
    f.port = p.text(key, "");
    if (f.port.empty()) throw RigOptionsError(key + ": missing (serial device of jet " + jet + "'s flow sensor)");
    check_flow_sensor(key, f.validate());
    c->flow[i] = f;
  }
}

/// valves/... and command_timeout: the valve board (port required) and the valve loop.
void parse_valves(Tree& p, RigOptions* c) {
  c->valves.port = p.text("valves/port", "");
  if (c->valves.port.empty()) throw RigOptionsError("valves/port: missing (serial device of the valve board)");
  c->valves.baud = p.integer("valves/baud", c->valves.baud);
  c->valves.ack_timeout = p.number("valves/ack_timeout", c->valves.ack_timeout);
  check("valves", c->valves.validate());
  c->valve_loop.rate = p.number("valves/rate", c->valve_loop.rate);
  c->valve_loop.max_failures = p.integer("valves/max_failures", c->valve_loop.max_failures);
  c->valve_loop.command_timeout = p.number("command_timeout", c->valve_loop.command_timeout);
  c->valve_loop.reconnect_period = c->reconnect_period;
  const std::string err = c->valve_loop.validate();
  if (!err.empty()) throw RigOptionsError(err.compare(0, 15, "command_timeout") == 0 ? err : "valves/" + err);
}

/// One port, one device.
void check_one_device_per_port(const RigOptions& c) {
  const std::string ports[] = {c.tracker.port, c.flow[0].port, c.flow[1].port, c.flow[2].port, c.valves.port};
  const char* keys[] = {"tracker/port", "flow/ports/jet1", "flow/ports/jet2", "flow/ports/jet3", "valves/port"};
  for (int j = 1; j < 5; ++j)
    for (int i = 0; i < j; ++i)
      if (ports[i] == ports[j])
        throw RigOptionsError(std::string(keys[j]) + ": '" + ports[j] + "' is already " + keys[i] +
                              " (one device per port)");
}

}  // namespace

std::array<FlowSensorOptions, 3> jet_flow_sensors() {
  std::array<FlowSensorOptions, 3> f;
  for (size_t i = 0; i < f.size(); ++i) f[i].name = "flow sensor " + std::to_string(i + 1);
  return f;
}

double flow_unit_scale(const std::string& unit) {
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

RigOptions parse_rig_options(const YAML::Node& root) {
  if (root.IsDefined() && !root.IsNull() && !root.IsMap()) throw RigOptionsError("(root): must be a mapping");
  Tree p(root);
  RigOptions c;
  c.scene = p.text("scene", "");
  if (c.scene.empty()) throw RigOptionsError("scene: missing (path of the scene YAML, for the nozzle areas)");
  parse_frames(p, &c);
  c.reconnect_period = p.number("reconnect_period", c.reconnect_period);
  if (!(c.reconnect_period >= 0.05 && c.reconnect_period <= 60.0))
    throw RigOptionsError("reconnect_period: must lie in [0.05, 60] s");
  p.allow("diagnostic_period");  // read by diagnostic_updater itself
  parse_tracker(p, &c);
  parse_flow(p, &c);
  parse_valves(p, &c);
  check_one_device_per_port(c);
  p.reject_unknown();
  return c;
}

}  // namespace devices
}  // namespace hydrojet
