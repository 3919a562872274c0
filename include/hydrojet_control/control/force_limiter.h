// Rate and magnitude limiter of the commanded tip force (f_x, f_y) (Algorithm 1, lines 9/12: the
// new command is the previous one plus a limited step). ROS-free (Eigen only).
#pragma once

#include <Eigen/Core>

namespace hydrojet {
namespace control {

class ForceLimiter {
 public:
  /// max_magnitude [N] bounds |f|, max_rate [N/s] bounds |f − f_prev| / dt. Both > 0.
  ForceLimiter(double max_magnitude, double max_rate) { set_limits(max_magnitude, max_rate); }

  void set_limits(double max_magnitude, double max_rate) {
    max_magnitude_ = max_magnitude;
    max_rate_ = max_rate;
  }
  /// Sets the previous command (start of a path, after an abort) without limiting [N].
  void reset(const Eigen::Vector2d& force = Eigen::Vector2d::Zero()) { previous_ = force; }

  /// Limits the step from the previous command towards target [N] to max_rate·dt (keeping its
  /// direction), then the result's magnitude to max_magnitude (keeping its direction); the result
  /// becomes the previous command. dt [s] ≥ 0.
  Eigen::Vector2d limit(const Eigen::Vector2d& target, double dt);

  /// The last command returned by limit() (or set by reset()) [N].
  const Eigen::Vector2d& previous() const { return previous_; }

 private:
  double max_magnitude_ = 0.0;
  double max_rate_ = 0.0;
  Eigen::Vector2d previous_ = Eigen::Vector2d::Zero();
};

}  // namespace control
}  // namespace hydrojet
