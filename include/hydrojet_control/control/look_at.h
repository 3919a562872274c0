// Aim the camera at a point (issue 13): the camera looks along the tip z-axis, so the tip direction d
// must make the line through the tip p_tip(d) along d pass through the point P. The tip position moves
// with the direction, so d is found on the model: a fixed-point iteration on the direction,
// d ← normalize(P − p_tip(d)), where p_tip(d) comes from an inner damped Newton on the lateral tip force
// using the C^b columns (the map of force_change, eq. 19) — each warm-started from the previous call.
// The controller then tracks d in closed loop with the tracker. ROS-free; own solver, so the
// controller's warm start is not disturbed.
#pragma once

#include <memory>
#include <string>

#include "hydrojet_control/control/robot_model.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

struct LookAtOptions {
  int max_iterations = 20;      ///< fixed-point iterations on the direction
  double tolerance = 1e-6;      ///< [m]: distance of P from the tip's line that counts as aimed
  double min_distance = 0.005;  ///< P closer to the tip than this [m] is refused
  std::string validate() const;
};

struct LookAtResult {
  bool ok = false;
  Vec3 direction = Vec3::UnitZ();    ///< unit, base frame
  Vec3 tip_position = Vec3::Zero();  ///< model tip position [m] for that direction, base frame
  double miss_distance = 0.0;        ///< distance of P from the line through the tip along direction [m]
  int iterations = 0;
  std::string message;  ///< why not ok (behind the camera, too close, no convergence, ...)
};

class LookAtSolver {
 public:
  LookAtSolver(const RobotModel& model, const LookAtOptions& options = LookAtOptions());
  /// Direction that aims the tip's z-axis at `point` [m] (base frame), warm-started from the last call.
  LookAtResult solve(const Vec3& point);
  /// Forget the warm start.
  void reset();

 private:
  struct Impl;
  std::shared_ptr<Impl> impl_;
};

}  // namespace control
}  // namespace hydrojet
