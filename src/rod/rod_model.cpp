#include "hydrojet_control/rod/rod_model.h"

#include <cmath>

namespace hydrojet {
namespace rod {

namespace {

std::string item(const char* list, size_t i, const char* key) {
  return std::string(list) + "[" + std::to_string(i) + "]." + key + ": ";
}

bool finite(const Vec3& v) { return v.allFinite(); }

}  // namespace

std::string RodModel::check_inputs(const Eigen::Ref<const Eigen::VectorXd>& q) const {
  if (q.size() != input_count())
    return "the robot has " + std::to_string(input_count()) + " actuator(s), got " + std::to_string(q.size()) +
           " input(s)";
  for (int i = 0; i < q.size(); ++i) {
    const Actuator& a = actuators[i];
    if (!(q[i] >= a.min_force && q[i] <= a.max_force))
      return "input " + std::to_string(i + 1) + " (" + a.name + ") = " + std::to_string(q[i]) +
             " N lies outside [min_force, max_force] = [" + std::to_string(a.min_force) + ", " +
             std::to_string(a.max_force) + "] N";
  }
  return "";
}

std::string RodModel::validate() const {
  if (segments.empty()) return "segments: at least one segment is needed";
  if (!(tip_radius >= 0.0 && tip_radius <= 1.0)) return "tip_radius: must lie in [0, 1] m";
  for (size_t i = 0; i < segments.size(); ++i) {
    const RodSegment& g = segments[i];
    if (!(g.length > 0.0) || !std::isfinite(g.length)) return item("segments", i, "length") + "must be > 0";
    if (!finite(g.stiffness) || !(g.stiffness.minCoeff() > 0.0))
      return item("segments", i, "stiffness") + "each of EIx, EIy, GJ must be > 0";
    if (!finite(g.precurvature)) return item("segments", i, "precurvature") + "must be finite";
    if (!(g.linear_density >= 0.0) || !std::isfinite(g.linear_density))
      return item("segments", i, "linear_density") + "must be >= 0";
    if (kind == RodKind::kCosserat && !(g.shear_stiffness > 0.0 && g.axial_stiffness > 0.0 &&
                                        std::isfinite(g.shear_stiffness) && std::isfinite(g.axial_stiffness)))
      return item("segments", i, "shear_stiffness") + "a Cosserat rod needs shear and axial stiffness > 0";
  }
  const double L = length();
  const auto on_rod = [L](double s) { return s > 0.0 && s <= L * (1.0 + 1e-12); };
  for (size_t i = 0; i < loads.size(); ++i) {
    const PointLoad& l = loads[i];
    if (!on_rod(l.at)) return item("loads", i, "at") + "must lie in (0, L]";
    if (!(l.mass >= 0.0) || !std::isfinite(l.mass)) return item("loads", i, "mass") + "must be >= 0";
    if (!finite(l.force) || !finite(l.moment)) return item("loads", i, "force") + "force and moment must be finite";
  }
  if (actuators.size() > static_cast<size_t>(kMaxInputs))
    return "actuators: at most " + std::to_string(kMaxInputs) + " actuators";
  for (size_t i = 0; i < actuators.size(); ++i) {
    const Actuator& a = actuators[i];
    if (!on_rod(a.at)) return item("actuators", i, "at") + "must lie in (0, L]";
    if (!finite(a.position)) return item("actuators", i, "position") + "must be finite";
    if (!finite(a.direction) || !(std::abs(a.direction.norm() - 1.0) <= 1e-6))
      return item("actuators", i, "direction") + "must be a unit vector (within 1e-6)";
    if (!std::isfinite(a.min_force) || !std::isfinite(a.max_force) || !(a.min_force <= a.max_force))
      return item("actuators", i, "max_force") + "bounds must be finite and ordered (min_force <= max_force)";
    if (a.type == ActuatorType::kJet && a.min_force < 0.0)
      return item("actuators", i, "min_force") + "a jet only pushes (eq. 26): must be >= 0";
  }
  if (!(tip_mass >= 0.0) || !std::isfinite(tip_mass)) return "tip_mass: must be >= 0";
  if (!finite(gravity)) return "gravity: must be finite";
  return "";
}

bool RodModel::tip_actuated_uniform() const {
  if (segments.size() != 1 || !loads.empty()) return false;
  for (const Actuator& a : actuators)
    if (a.at < length()) return false;
  return true;
}

}  // namespace rod
}  // namespace hydrojet
