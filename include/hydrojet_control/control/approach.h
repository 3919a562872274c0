// The approach to a path: a path is followed from where it begins, as a trajectory executor does.
// The reference first moves to the path's first direction (at the operator rate limit,
// Reference), the tip settles there, and only then does the path's clock start. ApproachMonitor
// decides when the tip has settled, or that it will not. ROS-free (Eigen only).
//
// Settled: the reference is on the first direction and, over the last settle_time seconds, the RMS
// of the loop's error (x_obs to x_des: the tracker in closed loop, the model in open loop) and the RMS
// angle of the measured tip about its mean (still, not ringing) are both at most `tolerance`.
// Failed: not settled `timeout` seconds after the reference reached the first direction.
#pragma once

#include <deque>
#include <string>

#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

struct ApproachOptions {
  double tolerance = 0.02;   ///< [rad] RMS error and RMS spread over the window (tracker noise: ~0.007)
  double settle_time = 0.3;  ///< [s] the window (about one period of the rod's first mode)
  double timeout = 5.0;      ///< [s] after the reference reached the first direction
  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};

class ApproachMonitor {
 public:
  enum class Verdict { kMoving, kSettling, kSettled, kFailed };

  /// std::invalid_argument naming the field when `options` is not valid (so does set_options).
  explicit ApproachMonitor(const ApproachOptions& options = {});
  void set_options(const ApproachOptions& options);
  /// A new approach: forgets the window.
  void reset();
  /// One cycle at t [s]: whether the reference is on the path's first direction, the loop's error
  /// [rad] and the measured tip direction (unit, base frame).
  Verdict update(double t, bool reference_there, double loop_error, const Vec3& measured);
  /// [s] how long the reference has been on the first direction without the tip settling (0 before).
  double settling_for(double t) const { return reached_ ? t - reached_at_ : 0.0; }
  /// Why it failed (after kFailed): the error and spread it saw, and the bounds.
  const std::string& failure() const { return failure_; }

 private:
  struct Sample {
    double t;
    double error;
    Vec3 measured;
  };
  /// RMS of the window's errors and RMS angle of its directions about their mean [rad].
  void window_stats(double* rms_error, double* spread) const;

  ApproachOptions options_;
  std::deque<Sample> window_;
  bool reached_ = false;
  double reached_at_ = 0.0;  ///< [s] when the reference reached the first direction
  std::string failure_;
};

}  // namespace control
}  // namespace hydrojet
