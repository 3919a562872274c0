#include "hydrojet_control/control/disturbance_observer.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace control {

std::string DisturbanceObserverOptions::validate() const {
  std::ostringstream os;
  if (!(std::isfinite(time_constant) && time_constant > 0.0))
    os << "observer.time_constant: must be finite and > 0, got " << time_constant;
  else if (!(std::isfinite(max_force) && max_force >= 0.0))
    os << "observer.max_force: must be finite and >= 0, got " << max_force;
  else if (!(std::isfinite(damping) && damping > 0.0))
    os << "observer.damping: must be finite and > 0, got " << damping;
  return os.str();
}

void DisturbanceObserver::update(const Vec3& model_direction, const Vec3& measured_direction, const Mat3& tip_rotation,
                                 const rod::Mat6& body_compliance, double dt) {
  if (!(dt > 0.0) || !model_direction.allFinite() || !measured_direction.allFinite() || !tip_rotation.allFinite() ||
      !body_compliance.allFinite())
    return;
  const Vec3 d = model_direction.normalized();
  const Mat3 M = -so3::hat(d) * tip_rotation * body_compliance.block<3, 3>(3, 0);  // δd per tip force
  const Vec3 e = rotation_between(d, measured_direction.normalized()).cross(d);    // δd wanted
  const Mat3 H = M.transpose() * M + o_.damping * o_.damping * Mat3::Identity();
  const Vec3 step = H.ldlt().solve(M.transpose() * e);
  if (!step.allFinite()) return;
  force_ += std::min(1.0, dt / o_.time_constant) * step;
  const double n = force_.norm();
  if (n > o_.max_force) force_ *= o_.max_force / n;
}

}  // namespace control
}  // namespace hydrojet
