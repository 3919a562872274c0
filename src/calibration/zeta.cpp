#include "hydrojet_control/calibration/zeta.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/control/robot_model.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace calibration {

namespace {

/// Unloaded tip tilt [rad] that a precurvature's resolution stands for: 0.5 1/m over the HydroJet's 9 cm.
constexpr double kTiltResolution = 0.045;
constexpr double kScaleResolution = 0.2;   ///< relative, for E, G and the scales
constexpr double kMountResolution = 0.05;  ///< [rad] ≈ 2.9°

bool at_tip(const rod::Actuator& a, double L) { return a.at >= L * (1.0 - 1e-12); }

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t"), b = s.find_last_not_of(" \t");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

}  // namespace

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

void Zeta::add(const std::string& name, const std::string& unit, ParamKind kind, int segment, int axis,
               bool logarithmic, double resolution, double start) {
  Parameter p;
  p.name = name;
  p.unit = unit;
  p.kind = kind;
  p.segment = segment;
  p.axis = axis;
  p.logarithmic = logarithmic;
  p.resolution = resolution;
  params_.push_back(p);
  start_.conservativeResize(static_cast<Eigen::Index>(params_.size()));
  start_[start_.size() - 1] = start;
}

Zeta::Zeta(const config::Scene& scene, const CrossSection& cs) : scene_(scene), cs_(cs) {
  const rod::RodModel& m = scene.rod;
  if (m.actuators.empty())
    throw config::SceneError("actuators", "none: the calibration fits the tip's orientation under actuator inputs");
  const double L = m.length();
  for (int i = 0; i < m.input_count(); ++i) (at_tip(m.actuators[i], L) ? mount_inputs_ : body_inputs_).push_back(i);
  const Eigen::Vector3d mount_start = scene.jets ? scene.jets->misalignment : Eigen::Vector3d::Zero();

  paper_form_ = scene.jets.has_value() && m.segments.size() == 1;
  if (paper_form_) {
    const std::string e = cs.validate();
    if (!e.empty()) throw std::invalid_argument("cross-section " + e);
    const rod::RodSegment& r = m.segments.front();
    add("ux", "1/m", ParamKind::kPrecurvatureX, 0, 0, false, 0.5, r.precurvature.x());
    add("uy", "1/m", ParamKind::kPrecurvatureY, 0, 0, false, 0.5, r.precurvature.y());
    add("E", "Pa", ParamKind::kYoungsModulus, 0, 0, true, kScaleResolution,
        0.5 * (r.stiffness.x() + r.stiffness.y()) / cs.second_moment());
    add("G", "Pa", ParamKind::kShearModulus, 0, 0, true, kScaleResolution, r.stiffness.z() / cs.polar_moment());
  } else {
    const int S = static_cast<int>(m.segments.size());
    for (int k = 0; k < S; ++k) {
      const rod::RodSegment& r = m.segments[k];
      const std::string n = std::to_string(k + 1);
      add("ux" + n, "1/m", ParamKind::kPrecurvatureX, k, 0, false, kTiltResolution / r.length, r.precurvature.x());
      add("uy" + n, "1/m", ParamKind::kPrecurvatureY, k, 0, false, kTiltResolution / r.length, r.precurvature.y());
      add("bend" + n, "", ParamKind::kBendingScale, k, 0, true, kScaleResolution, 1.0);
    }
    if (S >= 2) {
      common_bend_ = size();
      add("bend", "", ParamKind::kBendingScale, -1, 0, true, kScaleResolution, 1.0);
    }
    add("twist", "", ParamKind::kTorsionScale, -1, 0, true, kScaleResolution, 1.0);
  }
  body_rod_ = m;
  body_rod_.actuators.clear();
  for (int i : body_inputs_) body_rod_.actuators.push_back(m.actuators[i]);
  if (!mount_inputs_.empty()) {
    first_mount_ = size();
    static const char* names[3] = {"da", "db", "dg"};
    for (int a = 0; a < 3; ++a) add(names[a], "rad", ParamKind::kMount, -1, a, false, kMountResolution, mount_start[a]);
  }
}

int Zeta::index(const std::string& name) const {
  for (int i = 0; i < size(); ++i)
    if (params_[i].name == name) return i;
  return -1;
}

std::string Zeta::names() const {
  std::string s;
  for (const Parameter& p : params_) s += (s.empty() ? "" : ", ") + p.name;
  return s;
}

ParamMask Zeta::parse(const std::string& list) const {
  ParamMask m(size(), false);
  std::stringstream ss(list);
  std::string item;
  int n = 0;
  while (std::getline(ss, item, ',')) {
    item = trim(item);
    const int i = index(item);
    if (i < 0) throw std::invalid_argument("unknown parameter '" + item + "' (" + names() + ")");
    if (m[i]) throw std::invalid_argument("parameter '" + item + "' given twice");
    m[i] = true;
    ++n;
  }
  if (n == 0) throw std::invalid_argument("empty parameter list (" + names() + ")");
  if (common_bend_ >= 0 && m[common_bend_])
    for (int k : segment_bending_scales())
      if (m[k])
        throw std::invalid_argument("'bend' and '" + params_[k].name +
                                    "' scale the same stiffness: fit one common scale or one per segment");
  return m;
}

ParamMask Zeta::default_fit() const {
  ParamMask m(size(), true);
  if (common_bend_ >= 0) m[common_bend_] = false;
  bool twists = false;  // an actuator with a moment about its body z axis
  for (const rod::Actuator& a : scene_.rod.actuators) twists = twists || std::abs(a.unit_wrench()[5]) > 1e-12;
  for (int i = 0; i < size(); ++i)
    if (params_[i].kind == ParamKind::kTorsionScale && !twists) m[i] = false;
  return m;
}

std::vector<int> Zeta::segment_bending_scales() const {
  std::vector<int> out;
  if (common_bend_ < 0) return out;
  for (int i = 0; i < size(); ++i)
    if (params_[i].kind == ParamKind::kBendingScale && params_[i].segment >= 0) out.push_back(i);
  return out;
}

ParamMask Zeta::with_common_bending_scale(const ParamMask& mask) const {
  ParamMask m = mask;
  if (common_bend_ < 0) return m;
  for (int k : segment_bending_scales()) m[k] = false;
  m[common_bend_] = true;
  return m;
}

Eigen::Vector3d Zeta::mount_rotation(const ZetaVector& z) const {
  return first_mount_ < 0 ? Eigen::Vector3d::Zero() : Eigen::Vector3d(z.segment<3>(first_mount_));
}

rod::RodModel Zeta::rod_without_mount(const ZetaVector& z) const {
  rod::RodModel m = body_rod_;
  for (int i = 0; i < size(); ++i) {
    const Parameter& p = params_[i];
    const double v = z[i];
    for (int k = 0; k < static_cast<int>(m.segments.size()); ++k) {
      if (p.segment >= 0 && p.segment != k) continue;
      rod::RodSegment& s = m.segments[k];
      switch (p.kind) {
        case ParamKind::kPrecurvatureX: s.precurvature.x() = v; break;
        case ParamKind::kPrecurvatureY: s.precurvature.y() = v; break;
        case ParamKind::kYoungsModulus: s.stiffness.x() = s.stiffness.y() = v * cs_.second_moment(); break;
        case ParamKind::kShearModulus: s.stiffness.z() = v * cs_.polar_moment(); break;
        case ParamKind::kBendingScale: s.stiffness.head<2>() *= v; break;
        case ParamKind::kTorsionScale: s.stiffness.z() *= v; break;
        case ParamKind::kMount: break;
      }
    }
  }
  return m;
}

Eigen::Matrix<double, 6, Eigen::Dynamic> Zeta::mount_wrenches(const Eigen::Vector3d& delta) const {
  const int n = static_cast<int>(mount_inputs_.size());
  Eigen::Matrix<double, 6, Eigen::Dynamic> W(6, n);
  if (scene_.jets) {  // eq. 24: the misalignments rotate each jet about the tip z axis
    actuation::JetGeometry g = *scene_.jets;
    g.misalignment = delta;
    W = actuation::JetMap(g).wrench_matrix();
    return W;
  }
  const Eigen::Matrix3d R = so3::exp(delta);
  for (int c = 0; c < n; ++c) {
    const rod::Actuator& a = scene_.rod.actuators[mount_inputs_[c]];
    const Eigen::Vector3d d = R * a.direction, p = R * a.position;
    W.col(c) << d, p.cross(d);
  }
  return W;
}

config::Scene Zeta::apply(const ZetaVector& z) const {
  config::Scene s = scene_;
  const rod::RodModel rod = rod_without_mount(z);
  s.rod.segments = rod.segments;
  const Eigen::Vector3d delta = mount_rotation(z);
  if (first_mount_ < 0) return s;
  if (s.jets) {
    s.jets->misalignment = delta;
    s.rod.actuators = control::jet_actuators(*s.jets, control::jet_max_force(s.rod), s.rod.length());
    return s;
  }
  const Eigen::Matrix3d R = so3::exp(delta);
  for (int i : mount_inputs_) {
    rod::Actuator& a = s.rod.actuators[i];
    a.direction = (R * a.direction).normalized();
    a.position = R * a.position;
  }
  return s;
}

}  // namespace calibration
}  // namespace hydrojet
