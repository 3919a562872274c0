#include "hydrojet_control/calibration/scene_writer.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "hydrojet_control/config/scene.h"

namespace hydrojet {
namespace calibration {

std::string yaml_number(double v) {
  if (!std::isfinite(v)) return "null";
  // The shortest of %.15g / %.16g / %.17g that reads back exactly (0.09, not 0.089999999999999997).
  char b[40];
  for (int digits = 15; digits <= 17; ++digits) {
    std::snprintf(b, sizeof(b), "%.*g", digits, v);
    if (std::strtod(b, nullptr) == v) break;
  }
  std::string s = b;
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";  // stays a float for any reader
  return s;
}

namespace {

YAML::Node number(double v) { return YAML::Node(yaml_number(v)); }

YAML::Node vec3(double a, double b, double c) {
  YAML::Node n(YAML::NodeType::Sequence);
  n.push_back(number(a));
  n.push_back(number(b));
  n.push_back(number(c));
  n.SetStyle(YAML::EmitterStyle::Flow);
  return n;
}

double scalar(const YAML::Node& n, double fallback) {
  try {
    return n ? n.as<double>() : fallback;
  } catch (const YAML::Exception&) {
    return fallback;
  }
}

}  // namespace

std::string calibrated_scene_yaml(const std::string& original, const ZetaVector& z, const CrossSection& cs,
                                  const std::string& comment, const YAML::Node& calibration) {
  YAML::Node root;
  try {
    root = YAML::Load(original);
  } catch (const YAML::Exception& e) {
    throw config::SceneError("scene", std::string("malformed YAML: ") + e.what());
  }
  if (!root.IsMap()) throw config::SceneError("scene", "must be a mapping");
  YAML::Node rod = root["rod"];
  if (!rod || !rod.IsMap()) throw config::SceneError("rod", "missing");
  YAML::Node jets = root["jets"];
  if (!jets || !jets.IsMap()) throw config::SceneError("jets", "missing");

  const double uz = rod["precurvature"] && rod["precurvature"].IsSequence() && rod["precurvature"].size() == 3
                        ? scalar(rod["precurvature"][2], 0.0)
                        : 0.0;
  rod.remove("bending_stiffness");
  rod.remove("torsional_stiffness");
  rod["youngs_modulus"] = number(z[kE]);
  rod["shear_modulus"] = number(z[kG]);
  rod["outer_diameter"] = number(cs.outer_diameter);
  rod["inner_diameter"] = number(cs.inner_diameter);
  rod["precurvature"] = vec3(z[kUx], z[kUy], uz);
  jets["misalignment"] = vec3(z[kDa], z[kDb], z[kDg]);
  root.remove("calibration");
  if (calibration.IsDefined() && !calibration.IsNull()) root["calibration"] = calibration;

  std::ostringstream o;
  if (!comment.empty()) {
    std::istringstream c(comment);
    for (std::string line; std::getline(c, line);) o << "# " << line << "\n";
  }
  YAML::Emitter e;
  e << root;
  o << e.c_str() << "\n";
  return o.str();
}

}  // namespace calibration
}  // namespace hydrojet
