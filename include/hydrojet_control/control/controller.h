// PD resolved-rates control of the tip direction (paper §4, eqs. 17–20, Algorithm 1), closed loop
// with tracker feedback or open loop with the model's prediction (§7.3), plus the safety monitor.
// ROS-free (Eigen, the rod and actuation libraries). Time is passed in; nothing reads a clock.
#pragma once

#include <string>

#include "hydrojet_control/actuation/allocation.h"
#include "hydrojet_control/actuation/flow_regulator.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/control/task_space.h"
#include "hydrojet_control/rod/shooting_solver.h"
#include "hydrojet_control/rod/stability.h"

namespace hydrojet {
namespace control {

enum class LoopMode { kClosed, kOpen };
enum class ControllerState { kIdle, kRunning, kFinished, kAborted };
const char* to_string(LoopMode m);
const char* to_string(ControllerState s);

/// Gains, limits and safety thresholds. validate() names the first bad field.
struct ControllerParams {
  LoopMode mode = LoopMode::kClosed;
  double kp = 4.0;                  ///< K_p of eq. (17) [1/s]: fraction of the direction error corrected per second
  double kd = 0.2;                  ///< K_d of eq. (17) [-]: weight of the error change per step
  double feedforward = 1.0;         ///< weight of the path's own motion per step [-] (0 = pure PD)
  double damping = 0.02;            ///< μ of the damped pseudo-inverse of eq. (19) [rad/N]
  double max_force = 0.30;          ///< magnitude limit of the commanded tip force [N]
  double max_force_rate = 1.0;      ///< rate limit of the commanded tip force [N/s]
  double allocation_weight = 1e-6;  ///< λ of eq. (20) [-]
  /// Base of the new wrench command: false = the previous command (default), true = the measured
  /// w_a as printed in Algorithm 1, line 9.
  bool integrate_from_measured = false;
  // Safety (§7.3 and the brief)
  double max_oscillation = 0.5;         ///< abort when the desired–measured tip angle exceeds this [rad]
                                        ///< (armed once the tip has come within the limit)
  double sample_period = 0.01;          ///< tracker and flow sample period [s]
  int stale_periods = 3;                ///< data older than stale_periods·sample_period is stale
  int max_solver_failures = 2;          ///< abort after this many non-converged solves in a row
  double min_stability_margin = 0.5;    ///< abort when σ_c (eq. 23) falls below this [N/m]
  double unreachable_tolerance = 1e-3;  ///< allocation residual [N] above which the force is out of reach
  double flow_fault_tolerance = 3e-6;   ///< |measured − commanded flow| that counts as a jet fault [m^3/s]
  double flow_fault_time = 0.5;         ///< a deviation twice the tolerance trips after this long [s]
                                        ///< (the excess over the tolerance is integrated)
  SpiralPath path;

  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};

/// One control cycle's inputs: the latest tracker and flow samples with their stamps.
struct ControllerInputs {
  double t = 0.0;                        ///< now [s]
  bool tip_valid = false;                ///< a tracker sample has arrived and is marked valid
  double tip_stamp = -1e300;             ///< [s]
  Mat3 tip_rotation = Mat3::Identity();  ///< measured tip frame in the base frame
  bool flow_valid = false;
  double flow_stamp = -1e300;  ///< [s]
  Vec3 flows = Vec3::Zero();   ///< measured flow per jet [m^3/s]
};

/// One control cycle's result. valve_command is what goes to the valves.
struct ControllerOutput {
  ControllerState state = ControllerState::kIdle;
  std::string reason;                             ///< why it aborted (empty otherwise)
  Vec3 valve_command = Vec3::Zero();              ///< valve duty per jet [0, 1]
  Vec3 jet_force_command = Vec3::Zero();          ///< q from eq. (20) [N]
  Vec3 flow_command = Vec3::Zero();               ///< flow for q by the thrust equation (26) [m^3/s]
  Vec3 jet_force_observed = Vec3::Zero();         ///< q_obs from measured flow [N]
  rod::Vec6 wrench_observed = rod::Vec6::Zero();  ///< w_a = A q_obs (Algorithm 1, line 4)
  rod::Vec6 wrench_command = rod::Vec6::Zero();   ///< w_a + ẇ^b after limits
  Vec3 desired_direction = Vec3::UnitZ();         ///< x_des: tip z-axis, base frame
  Vec3 observed_direction = Vec3::UnitZ();        ///< x_obs used by the loop (tracker or model)
  Vec3 measured_direction = Vec3::UnitZ();        ///< from the tracker (for metrics, both modes)
  Mat3 model_tip_rotation = Mat3::Identity();
  double error_geodesic = 0.0;   ///< ∠(x_des, measured) [rad]
  double error_pitch_yaw = 0.0;  ///< the paper's norm of the (pitch, yaw) difference [rad]
  double path_time = 0.0;        ///< [s] since start
  bool solver_converged = false;
  double stability_margin = 0.0;   ///< σ_c [N/m]
  double stability_eig_min = 0.0;  ///< min Re eig(S) [N/m]
  bool force_reachable = true;
};

/// Inputs the controller needs from a scene: the rod model, the jets and the nozzles.
struct ControllerModel {
  rod::RodModel rod;
  rod::ShootingSettings solver;
  rod::ActuatedSet actuated = rod::lateral_force_actuation();
  actuation::JetGeometry jets;
  actuation::NozzleParameters nozzle;
  Vec3 max_jet_force = Vec3(0.243, 0.224, 0.244);  ///< q_max [N]
  actuation::FlowRegulatorParameters flow;         ///< per-jet PI flow regulator (same for the three jets)
};

class Controller {
 public:
  Controller(const ControllerModel& model, const ControllerParams& params);

  /// Starts the path at time t (also after an abort or the end). Jets start from zero.
  void start(double t);
  /// Stops: jets to zero, state idle.
  void stop();
  /// Switches between closed and open loop (takes effect on the next update).
  void set_mode(LoopMode mode) { params_.mode = mode; }
  /// New gains/limits (validated by the caller); the state is kept.
  void set_params(const ControllerParams& p) { params_ = p; }
  const ControllerParams& params() const { return params_; }
  ControllerState state() const { return state_; }

  /// One cycle of Algorithm 1. Call at the control rate with the latest samples.
  ControllerOutput update(const ControllerInputs& in);

  /// Backbone of the model at the last converged solve: segments+1 points [m], base frame.
  std::vector<Vec3> model_shape(int segments) const { return solver_.shape(segments); }

  /// The model's forward kinematics at jet forces q [N] (for open-loop prediction and tests).
  rod::RodSolution model_fk(const Vec3& q);

 private:
  ControllerOutput abort(ControllerOutput out, const std::string& why);

  ControllerModel model_;
  ControllerParams params_;
  actuation::JetMap jet_map_;
  rod::ShootingSolver solver_;
  actuation::FlowRegulatorBank regulators_;
  ControllerState state_ = ControllerState::kIdle;
  std::string abort_reason_;
  double t_start_ = 0.0;
  double t_last_ = 0.0;
  bool first_cycle_ = true;
  Vec3 prev_error_ = Vec3::Zero();
  Vec3 prev_desired_ = Vec3::UnitZ();
  Eigen::Vector2d prev_force_cmd_ = Eigen::Vector2d::Zero();
  int solver_failures_ = 0;
  bool oscillation_armed_ = false;
  ControllerOutput last_output_;             ///< returned again for a repeated tick at the same time
  Vec3 flow_fault_integral_ = Vec3::Zero();  ///< ∫(|ΔQ| − tol)⁺ dt per jet [m^3]
  Vec3 last_flow_command_ = Vec3::Zero();
};

}  // namespace control
}  // namespace hydrojet
