#include "hydrojet_control/ros/params.h"

#include <cmath>
#include <sstream>

namespace hydrojet {
namespace ros_bridge {

namespace {
std::string key(const std::string& path) { return "~" + path; }

void collect(const XmlRpc::XmlRpcValue& v, const std::string& prefix, std::set<std::string>* out) {
  if (v.getType() != XmlRpc::XmlRpcValue::TypeStruct) {
    out->insert(prefix);
    return;
  }
  XmlRpc::XmlRpcValue copy = v;
  for (auto it = copy.begin(); it != copy.end(); ++it)
    collect(it->second, prefix.empty() ? it->first : prefix + "/" + it->first, out);
}
}  // namespace

const XmlRpc::XmlRpcValue* ParamTree::find(const std::string& path) const {
  const XmlRpc::XmlRpcValue* node = &root_;
  std::stringstream ss(path);
  std::string part;
  while (std::getline(ss, part, '/')) {
    if (node->getType() != XmlRpc::XmlRpcValue::TypeStruct || !node->hasMember(part)) return nullptr;
    node = &(*const_cast<XmlRpc::XmlRpcValue*>(node))[part];
  }
  return node;
}

bool ParamTree::has(const std::string& path) const { return find(path) != nullptr; }

double ParamTree::number(const std::string& path, double fallback) {
  read_.insert(path);
  const XmlRpc::XmlRpcValue* v = find(path);
  if (!v) return fallback;
  XmlRpc::XmlRpcValue c = *v;
  double out;
  if (c.getType() == XmlRpc::XmlRpcValue::TypeDouble) out = static_cast<double>(c);
  else if (c.getType() == XmlRpc::XmlRpcValue::TypeInt) out = static_cast<int>(c);
  else throw ParamError(key(path) + ": must be a number");
  if (!std::isfinite(out)) throw ParamError(key(path) + ": must be finite");
  return out;
}

int ParamTree::integer(const std::string& path, int fallback) {
  read_.insert(path);
  const XmlRpc::XmlRpcValue* v = find(path);
  if (!v) return fallback;
  if (v->getType() != XmlRpc::XmlRpcValue::TypeInt) throw ParamError(key(path) + ": must be an integer");
  XmlRpc::XmlRpcValue c = *v;
  return static_cast<int>(c);
}

bool ParamTree::boolean(const std::string& path, bool fallback) {
  read_.insert(path);
  const XmlRpc::XmlRpcValue* v = find(path);
  if (!v) return fallback;
  if (v->getType() != XmlRpc::XmlRpcValue::TypeBoolean) throw ParamError(key(path) + ": must be true or false");
  XmlRpc::XmlRpcValue c = *v;
  return static_cast<bool>(c);
}

std::string ParamTree::text(const std::string& path, const std::string& fallback) {
  read_.insert(path);
  const XmlRpc::XmlRpcValue* v = find(path);
  if (!v) return fallback;
  if (v->getType() != XmlRpc::XmlRpcValue::TypeString) throw ParamError(key(path) + ": must be a string");
  XmlRpc::XmlRpcValue c = *v;
  return static_cast<std::string>(c);
}

void ParamTree::reject_unknown() const {
  std::set<std::string> all;
  if (root_.getType() == XmlRpc::XmlRpcValue::TypeStruct) collect(root_, "", &all);
  for (const std::string& k : all)
    if (!read_.count(k)) throw ParamError(key(k) + ": unknown parameter");
}

ControllerNodeOptions read_controller_options(const XmlRpc::XmlRpcValue& private_params) {
  ParamTree p(private_params);
  ControllerNodeOptions o;
  o.scene = p.text("scene", "");
  if (o.scene.empty()) throw ParamError("~scene: missing (path of the scene YAML)");
  o.rate = p.number("rate", o.rate);
  if (!(o.rate >= 1.0 && o.rate <= 1000.0)) throw ParamError("~rate: must lie in [1, 1000] Hz");
  o.autostart = p.boolean("autostart", o.autostart);
  o.base_frame = p.text("base_frame", o.base_frame);
  const std::string mode = p.text("mode", "closed");
  if (mode == "closed") o.controller.mode = control::LoopMode::kClosed;
  else if (mode == "open") o.controller.mode = control::LoopMode::kOpen;
  else throw ParamError("~mode: must be 'closed' or 'open', got '" + mode + "'");

  // Each numeric parameter: its key, the core's field name (as ControllerParams::validate() names
  // it) and where it lives.
  control::ControllerParams& c = o.controller;
  const struct {
    const char* key;
    const char* field;
    double* value;
  } numbers[] = {
      {"gains/kp", "kp", &c.kp},
      {"gains/kd", "kd", &c.kd},
      {"gains/feedforward", "feedforward", &c.feedforward},
      {"gains/damping", "damping", &c.damping},
      {"limits/max_force", "max_force", &c.max_force},
      {"limits/max_force_rate", "max_force_rate", &c.max_force_rate},
      {"allocation_weight", "allocation_weight", &c.allocation_weight},
      {"safety/max_oscillation", "max_oscillation", &c.max_oscillation},
      {"safety/sample_period", "sample_period", &c.sample_period},
      {"safety/min_stability_margin", "min_stability_margin", &c.min_stability_margin},
      {"safety/unreachable_tolerance", "unreachable_tolerance", &c.unreachable_tolerance},
      {"path/theta_start", "path.theta_start", &c.path.theta_start},
      {"path/theta_end", "path.theta_end", &c.path.theta_end},
      {"path/phi_start", "path.phi_start", &c.path.phi_start},
      {"path/phi_end", "path.phi_end", &c.path.phi_end},
      {"path/duration", "path.duration", &c.path.duration},
  };
  for (const auto& n : numbers) *n.value = p.number(n.key, *n.value);
  c.stale_periods = p.integer("safety/stale_periods", c.stale_periods);
  c.max_solver_failures = p.integer("safety/max_solver_failures", c.max_solver_failures);
  c.integrate_from_measured = p.boolean("integrate_from_measured", c.integrate_from_measured);
  const std::string err = c.validate();
  if (!err.empty()) {
    const std::string field = err.substr(0, err.find(':'));
    std::string k = field == "stale_periods" || field == "max_solver_failures" ? "safety/" + field : field;
    for (const auto& n : numbers)
      if (field == n.field) k = n.key;
    throw ParamError("~" + k + err.substr(field.size()));
  }

  actuation::FlowRegulatorParameters& f = o.flow;
  f.kp = p.number("flow_regulator/kp", f.kp);
  f.ki = p.number("flow_regulator/ki", f.ki);
  f.feedforward = p.number("flow_regulator/feedforward", f.feedforward);
  f.output_min = p.number("flow_regulator/output_min", f.output_min);
  f.output_max = p.number("flow_regulator/output_max", f.output_max);
  const std::string ferr = actuation::validate(f);
  if (!ferr.empty()) throw ParamError("~flow_regulator/" + ferr.substr(0, ferr.find(' ')) + ":" + ferr.substr(ferr.find(' ')));
  p.reject_unknown();
  return o;
}

}  // namespace ros_bridge
}  // namespace hydrojet
