// PD resolved-rates control of the tip direction (paper §4, eqs. 17–20, Algorithm 1), closed loop
// with tracker feedback or open loop with the model's prediction (§7.3), guarded by the safety
// monitor. One cycle, update(), runs these named steps:
//   time and sensor checks (SafetyMonitor) → observe_jets (Algorithm 1, line 4) → solve_model
//   (line 6) → solver and stability checks → track_path (x_des, x_obs) → oscillation check →
//   command_force (lines 5, 7, 9/12: DirectionPd, force_change, ForceLimiter) → actuate (eq. 20,
//   eq. 26, flow regulators: JetActuation) → finish_cycle.
// ROS-free (Eigen, the rod and actuation libraries). Time is passed in; nothing reads a clock.
#pragma once

#include <string>
#include <vector>

#include "hydrojet_control/control/controller_io.h"
#include "hydrojet_control/control/controller_options.h"
#include "hydrojet_control/control/force_limiter.h"
#include "hydrojet_control/control/jet_actuation.h"
#include "hydrojet_control/control/resolved_rates.h"
#include "hydrojet_control/control/robot_model.h"
#include "hydrojet_control/control/safety_monitor.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

class Controller {
 public:
  Controller(const RobotModel& model, const ControllerOptions& params);

  /// Starts the path at time t (also after an abort or the end). Jets start from zero.
  void start(double t);
  /// Stops: jets to zero, state idle.
  void stop();
  /// Switches between closed and open loop (takes effect on the next update).
  void set_mode(LoopMode mode) { params_.mode = mode; }
  /// New gains/limits (validated by the caller); the state is kept.
  void set_params(const ControllerOptions& p);
  const ControllerOptions& params() const { return params_; }
  ControllerState state() const { return state_; }
  /// Number of jets (entries of every JetVector in and out).
  int jet_count() const { return jets_.jet_count(); }

  /// One cycle of Algorithm 1. Call at the control rate with the latest samples.
  ControllerOutput update(const ControllerInputs& in);

  /// Backbone of the model at the last converged solve: segments+1 points [m], base frame.
  std::vector<Vec3> model_shape(int segments) const { return solver_.shape(segments); }

  /// The model's forward kinematics at jet forces q [N] (for open-loop prediction and tests).
  rod::RodSolution model_fk(const JetVector& q);

 private:
  // The steps of update(), in order. Those returning a string return the abort reason (empty: go on).
  ControllerOutput resting_output() const;
  void observe_jets(const JetVector& flows, ControllerOutput& out) const;
  rod::RodSolution solve_model(const rod::Vec6& wrench);
  ControllerOutput hold(ControllerOutput out, const JetVector& flows, double dt);
  std::string check_stability(const rod::Compliance& compliance, ControllerOutput& out) const;
  void track_path(const ControllerInputs& in, const rod::RodSolution& sol, ControllerOutput& out) const;
  std::string command_force(const rod::RodSolution& sol, const rod::Compliance& compliance, double dt,
                            ControllerOutput& out);
  std::string actuate(const JetVector& flows, double dt, ControllerOutput& out);
  ControllerOutput finish_cycle(ControllerOutput out);
  ControllerOutput abort(ControllerOutput out, const std::string& why);

  rod::ActuatedSet actuated_;  ///< the actuated wrench components (stability of eq. 23)
  ControllerOptions params_;
  JetActuation jets_;
  rod::ShootingSolver solver_;
  SafetyMonitor monitor_;
  DirectionPd pd_;
  ForceLimiter limiter_;
  ControllerState state_ = ControllerState::kIdle;
  std::string abort_reason_;
  double t_start_ = 0.0;
  double t_last_ = 0.0;
  bool first_cycle_ = true;       ///< no complete cycle since start(): dt = sample_period, limiter from w_a
  ControllerOutput last_output_;  ///< returned again for a repeated tick at the same time
};

}  // namespace control
}  // namespace hydrojet
