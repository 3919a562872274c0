#include "hydrojet_control/calibration/scene_writer.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

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

/// The stiffness and precurvature of one segment's node (the `rod` section or an item of
/// rod.segments) in the general form: bending and torsional stiffness written out (moduli and
/// diameters replaced, with EA and GA of a Cosserat rod kept as stiffness).
void write_segment(YAML::Node node, const rod::RodSegment& s, rod::RodKind kind) {
  const bool moduli = node["youngs_modulus"] || node["shear_modulus"] || node["outer_diameter"];
  for (const char* k : {"youngs_modulus", "shear_modulus", "outer_diameter", "inner_diameter"}) node.remove(k);
  YAML::Node ei(YAML::NodeType::Sequence);
  ei.push_back(number(s.stiffness.x()));
  ei.push_back(number(s.stiffness.y()));
  ei.SetStyle(YAML::EmitterStyle::Flow);
  node["bending_stiffness"] = ei;
  node["torsional_stiffness"] = number(s.stiffness.z());
  if (moduli && kind == rod::RodKind::kCosserat) {
    if (!node["shear_stiffness"]) node["shear_stiffness"] = number(s.shear_stiffness);
    if (!node["axial_stiffness"]) node["axial_stiffness"] = number(s.axial_stiffness);
  }
  node["precurvature"] = vec3(s.precurvature.x(), s.precurvature.y(), s.precurvature.z());
}

/// The paper's form: E, G and the diameters in the `rod` section, ũ_x, ũ_y, the jets' misalignments.
void write_paper_form(YAML::Node root, const ZetaVector& z, const CrossSection& cs) {
  YAML::Node rod = root["rod"];
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
  root["jets"]["misalignment"] = vec3(z[kDa], z[kDb], z[kDg]);
}

/// The general form: every segment's stiffness and precurvature, the tip actuators' mount.
void write_general_form(YAML::Node root, const Zeta& zeta, const ZetaVector& z) {
  const config::Scene fitted = zeta.apply(z);
  YAML::Node rod = root["rod"];
  const YAML::Node list = rod["segments"];
  const size_t S = fitted.rod.segments.size();
  if (list && !(list.IsSequence() && list.size() == S))
    throw config::SceneError("rod.segments", "not the scene's segments");
  for (size_t k = 0; k < S; ++k)
    write_segment(list ? YAML::Node(list[k]) : rod, fitted.rod.segments[k], fitted.rod.kind);
  if (zeta.mount_inputs().empty()) return;
  if (fitted.jets) {
    root["jets"]["misalignment"] =
        vec3(fitted.jets->misalignment.x(), fitted.jets->misalignment.y(), fitted.jets->misalignment.z());
    return;
  }
  YAML::Node acts = root["actuators"];
  if (!acts || !acts.IsSequence() || acts.size() != fitted.rod.actuators.size())
    throw config::SceneError("actuators", "not the scene's actuators");
  for (int i : zeta.mount_inputs()) {
    const rod::Actuator& a = fitted.rod.actuators[i];
    YAML::Node n = acts[i];
    n["position"] = vec3(a.position.x(), a.position.y(), a.position.z());
    n["direction"] = vec3(a.direction.x(), a.direction.y(), a.direction.z());
  }
}

}  // namespace

std::string calibrated_scene_yaml(const std::string& original, const Zeta& zeta, const ZetaVector& z,
                                  const std::string& comment, const YAML::Node& calibration) {
  YAML::Node root;
  try {
    root = YAML::Load(original);
  } catch (const YAML::Exception& e) {
    throw config::SceneError("scene", std::string("malformed YAML: ") + e.what());
  }
  if (!root.IsMap()) throw config::SceneError("scene", "must be a mapping");
  if (!root["rod"] || !root["rod"].IsMap()) throw config::SceneError("rod", "missing");
  if (zeta.scene().jets && !(root["jets"] && root["jets"].IsMap())) throw config::SceneError("jets", "missing");
  if (z.size() != zeta.size())
    throw std::invalid_argument("zeta: " + std::to_string(z.size()) + " values for " + std::to_string(zeta.size()) +
                                " parameters");
  if (zeta.paper_form())
    write_paper_form(root, z, zeta.cross_section());
  else
    write_general_form(root, zeta, z);
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
