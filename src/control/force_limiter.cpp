#include "hydrojet_control/control/force_limiter.h"

namespace hydrojet {
namespace control {

Eigen::Vector2d ForceLimiter::limit(const Eigen::Vector2d& target, double dt) {
  Eigen::Vector2d step = target - previous_;
  const double max_step = max_rate_ * dt;
  if (step.norm() > max_step) step *= max_step / step.norm();
  Eigen::Vector2d f = previous_ + step;
  if (f.norm() > max_magnitude_) f *= max_magnitude_ / f.norm();
  previous_ = f;
  return f;
}

}  // namespace control
}  // namespace hydrojet
