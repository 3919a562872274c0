#include "hydrojet_control/calibration/zeta.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace hydrojet {
namespace calibration {

namespace {
const char* const kNames[kNumParams] = {"ux", "uy", "E", "G", "da", "db", "dg"};
const char* const kUnits[kNumParams] = {"1/m", "1/m", "Pa", "Pa", "rad", "rad", "rad"};
}  // namespace

const char* param_name(int i) { return i >= 0 && i < kNumParams ? kNames[i] : "?"; }
const char* param_unit(int i) { return i >= 0 && i < kNumParams ? kUnits[i] : "?"; }

int param_index(const std::string& name) {
  for (int i = 0; i < kNumParams; ++i)
    if (name == kNames[i]) return i;
  return -1;
}

ParamMask parse_param_list(const std::string& list) {
  ParamMask m;
  m.fill(false);
  std::stringstream ss(list);
  std::string item;
  int n = 0;
  while (std::getline(ss, item, ',')) {
    const size_t a = item.find_first_not_of(" \t"), b = item.find_last_not_of(" \t");
    item = a == std::string::npos ? "" : item.substr(a, b - a + 1);
    const int i = param_index(item);
    if (i < 0) throw std::invalid_argument("unknown parameter '" + item + "' (ux, uy, E, G, da, db, dg)");
    if (m[i]) throw std::invalid_argument("parameter '" + item + "' given twice");
    m[i] = true;
    ++n;
  }
  if (n == 0) throw std::invalid_argument("empty parameter list (ux, uy, E, G, da, db, dg)");
  return m;
}

double CrossSection::second_moment() const {
  return M_PI * (std::pow(outer_diameter, 4) - std::pow(inner_diameter, 4)) / 64.0;
}

std::string CrossSection::validate() const {
  if (!(std::isfinite(outer_diameter) && outer_diameter > 0.0)) return "outer_diameter: must be positive";
  if (!(std::isfinite(inner_diameter) && inner_diameter >= 0.0)) return "inner_diameter: must not be negative";
  if (!(inner_diameter < outer_diameter)) return "inner_diameter: must be smaller than outer_diameter";
  return "";
}

CrossSection cross_section_from_scene_text(const std::string& text, const CrossSection& fallback) {
  CrossSection cs = fallback;
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw config::SceneError("scene", std::string("malformed YAML: ") + e.what());
  }
  if (!root.IsMap() || !root["rod"] || !root["rod"].IsMap()) return cs;
  config::YamlTree<config::SceneError> t(root, '.');
  cs.outer_diameter = t.number("rod.outer_diameter", cs.outer_diameter);
  cs.inner_diameter = t.number("rod.inner_diameter", cs.inner_diameter);
  const std::string e = cs.validate();
  if (!e.empty()) throw config::SceneError("rod." + e.substr(0, e.find(':')), e.substr(e.find(':') + 2));
  return cs;
}

ZetaVector zeta_from_scene(const config::Scene& scene, const CrossSection& cs) {
  const rod::RodSegment& r = scene.rod.segments.front();
  ZetaVector z;
  z[kUx] = r.precurvature.x();
  z[kUy] = r.precurvature.y();
  z[kE] = 0.5 * (r.stiffness.x() + r.stiffness.y()) / cs.second_moment();
  z[kG] = r.stiffness.z() / cs.polar_moment();
  z.tail<3>() = scene.jets ? scene.jets->misalignment : Eigen::Vector3d::Zero();
  return z;
}

config::Scene apply_zeta(const config::Scene& scene, const ZetaVector& z, const CrossSection& cs) {
  config::Scene s = scene;
  const double I = cs.second_moment();
  rod::RodSegment& r = s.rod.segments.front();
  r.stiffness = rod::Vec3(z[kE] * I, z[kE] * I, z[kG] * cs.polar_moment());
  r.precurvature.x() = z[kUx];
  r.precurvature.y() = z[kUy];
  actuation::JetGeometry jets = s.jets.value_or(actuation::JetGeometry());
  jets.misalignment = z.tail<3>();
  s.jets = jets;
  s.rod.actuators = control::jet_actuators(jets, control::jet_max_force(s.rod), s.rod.length());
  return s;
}

}  // namespace calibration
}  // namespace hydrojet
