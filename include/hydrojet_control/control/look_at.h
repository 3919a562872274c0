// Aim the camera at a point: the camera looks along the tip z-axis, so the tip direction d
// must make the line through the tip p_tip along d pass through the point P, with P in front. The tip
// position moves with the direction, so d is found on the model as the fixed point d = u(d),
// u = (P − p_tip)/|P − p_tip|, solved by a damped Gauss–Newton iteration on the actuator inputs q of
// the residual u − d, each step a box QP within the inputs' bounds. Its Jacobian comes from the
// actuation Jacobian J_q (as the controller's step, resolved_rates.h): the tip direction turns by
// −d̂ R J_q,ω per input and the tip moves by R J_q,v, which turns u. The plain iteration d ← u(d) ignores that second
// term: its error shrinks per step only by the factor |∂p_tip/∂d| / |P − p_tip|, and |∂p_tip/∂d| ≈ 0.060 m/rad for the
// HydroJet at rest, so it stalls at 6 cm and diverges closer; the Newton iteration converges in 2–3 iterations from 8
// mm to 1 m (test_operator_core). Inputs stay within their bounds (for the HydroJet 0 ≤ q ≤ q_max, eq. 24).
// Warm-started from the previous successful call (its solution and J_q are kept: a call for a point that moved a little
// costs one solve + J_q). The controller then tracks d in closed loop with the tracker. ROS-free; own solver, so the
// controller's warm start is not disturbed.
#pragma once

#include <memory>
#include <string>

#include "hydrojet_control/control/robot_model.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

struct LookAtOptions {
  int max_iterations = 20;       ///< Gauss–Newton iterations (each one model solve + C^b), ≥ 1
  double tolerance = 1e-6;       ///< [m]: distance of P from the tip's line that counts as aimed
  double min_distance = 0.005;   ///< P closer to the tip than this [m] is refused (> 0)
  double max_distance = 1000.0;  ///< P farther than this [m] is refused (> min_distance): aim a direction instead
  std::string validate() const;
};

struct LookAtResult {
  bool ok = false;
  Vec3 direction = Vec3::UnitZ();    ///< unit, base frame
  Vec3 tip_position = Vec3::Zero();  ///< model tip position [m] for that direction, base frame
  double miss_distance = 0.0;        ///< distance of P from the line through the tip along direction [m]
  InputVector inputs;                ///< actuator inputs q [N] of that model solution, within their bounds
  /// Lateral tip force (f_x, f_y) [N], tip frame, of the actuators at the tip at those inputs.
  Eigen::Vector2d tip_force = Eigen::Vector2d::Zero();
  int iterations = 0;
  /// Why not ok (behind the camera, too close, out of the jets' reach, no convergence, ...). When not
  /// ok, direction, tip_position and tip_force are the last iterate (the warm start is not moved).
  std::string message;
  /// Not ok only because the point is out of the jets' reach: `direction` is then the closest aim
  /// (the inputs' bounds block the step toward it), a usable clipped target.
  bool out_of_reach = false;
};

class LookAtSolver {
 public:
  /// Throws std::invalid_argument when the options or the model are invalid.
  LookAtSolver(const RobotModel& model, const LookAtOptions& options = LookAtOptions());
  /// Direction that aims the tip's z-axis at `point` [m] (base frame), warm-started from the last
  /// successful call.
  LookAtResult solve(const Vec3& point);
  /// Forget the warm start.
  void reset();

 private:
  struct Impl;
  std::shared_ptr<Impl> impl_;
};

}  // namespace control
}  // namespace hydrojet
