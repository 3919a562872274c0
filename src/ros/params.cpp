#include "hydrojet_control/ros/params.h"

namespace hydrojet {
namespace ros_bridge {
namespace {

YAML::Node to_yaml(XmlRpc::XmlRpcValue& v) {
  switch (v.getType()) {
    case XmlRpc::XmlRpcValue::TypeStruct: {
      YAML::Node n(YAML::NodeType::Map);
      for (auto it = v.begin(); it != v.end(); ++it) n[it->first] = to_yaml(it->second);
      return n;
    }
    case XmlRpc::XmlRpcValue::TypeArray: {
      YAML::Node n(YAML::NodeType::Sequence);
      for (int i = 0; i < v.size(); ++i) n.push_back(to_yaml(v[i]));
      return n;
    }
    case XmlRpc::XmlRpcValue::TypeBoolean: return YAML::Node(static_cast<bool>(v));
    case XmlRpc::XmlRpcValue::TypeInt: return YAML::Node(static_cast<int>(v));
    case XmlRpc::XmlRpcValue::TypeDouble: return YAML::Node(static_cast<double>(v));
    case XmlRpc::XmlRpcValue::TypeString: {
      // Keep strings strings: a quoted scalar never converts to a number or bool.
      YAML::Node n(static_cast<std::string>(v));
      n.SetStyle(YAML::EmitterStyle::Flow);
      return n;
    }
    default: return YAML::Node();
  }
}

}  // namespace

YAML::Node private_params_as_yaml(const ros::NodeHandle& pnh) {
  XmlRpc::XmlRpcValue v;
  if (!pnh.getParam(pnh.getNamespace(), v)) return YAML::Node(YAML::NodeType::Map);
  return to_yaml(v);
}

config::ControllerNodeOptions read_controller_options(const ros::NodeHandle& pnh,
                                                      const std::vector<std::string>& mirrored) {
  try {
    YAML::Node params = private_params_as_yaml(pnh);
    for (const std::string& key : mirrored) params.remove(key);
    config::ControllerNodeOptions o = config::parse_controller_options(params);
    if (o.scene.empty()) throw config::ParamError("scene", "missing (path of the scene YAML)");
    return o;
  } catch (const config::ParamError& e) {  // private parameters: name them ~key
    if (e.key().empty()) throw config::ParamError(std::string("~") + e.what());
    throw config::ParamError("~" + e.key(), e.detail());
  }
}

}  // namespace ros_bridge
}  // namespace hydrojet
