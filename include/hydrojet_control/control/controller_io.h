// One control cycle's inputs (the latest tracker and flow samples) and result (valve duties and
// everything worth publishing). Per-actuator vectors are rod::InputVectors sized by the model.
// ROS-free (Eigen, the rod library).
#pragma once

#include <string>

#include <cmath>

#include "hydrojet_control/control/contact.h"
#include "hydrojet_control/control/reference.h"
#include "hydrojet_control/control/robot_model.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

enum class ControllerState { kIdle, kRunning, kFinished, kAborted };
const char* to_string(ControllerState s);

/// One control cycle's inputs: the latest tracker and flow samples with their stamps.
struct ControllerInputs {
  double t = 0.0;                                    ///< now [s]
  bool tip_valid = false;                            ///< a tracker sample has arrived and is marked valid
  double tip_stamp = -1e300;                         ///< [s]
  Mat3 tip_rotation = Mat3::Identity();              ///< measured tip frame in the base frame
  Vec3 tip_position = Vec3::Constant(std::nan(""));  ///< measured tip [m], base frame (NaN: not measured)
  bool flow_valid = false;
  double flow_stamp = -1e300;  ///< [s]
  InputVector flows;           ///< measured flow per jet [m^3/s] (one entry per actuator; 0 for force actuators)
  /// Measured force per actuator [N] (same stamp as the flows): read for actuators of type force only
  /// (a jet's force comes from its flow); may stay empty when the robot has none.
  InputVector forces;
};

/// One control cycle's result. valve_command is what goes to the valves.
struct ControllerOutput {
  ControllerState state = ControllerState::kIdle;
  std::string reason;         ///< why it aborted (empty otherwise)
  InputVector valve_command;  ///< per actuator: valve duty [0, 1] (jets), drive [−1, 1] (force actuators)
  InputVector
      jet_force_command;     ///< inputs q [N] of the step on J_q (eqs. 19–20), corners rounded (allocation_smoothing)
  InputVector flow_command;  ///< flow for q by the thrust equation (26) [m^3/s]; 0 for force actuators
  InputVector jet_force_observed;  ///< q_obs [N] from measured flow (jets) or force (force actuators)
  /// w_a = W q_obs: tip body wrench of the actuators at the tip (Algorithm 1, line 4) [N, N m]
  rod::Vec6 wrench_observed = rod::Vec6::Zero();
  rod::Vec6 wrench_command = rod::Vec6::Zero();  ///< W q: the same for the commanded inputs (jet_force_command)
  Vec3 desired_direction = Vec3::UnitZ();        ///< x_des: tip z-axis, base frame (the reference)
  Source source = Source::kHold;                 ///< who drives the reference
  bool clipped = false;                          ///< the target was outside the reachable set ...
  double clip_angle = 0.0;                       ///< ... and moved by this much [rad]
  Vec3 observed_direction = Vec3::UnitZ();       ///< x_obs used by the loop (tracker or model)
  Vec3 measured_direction = Vec3::UnitZ();       ///< from the tracker (for metrics, both modes)
  Mat3 model_tip_rotation = Mat3::Identity();
  double error_geodesic = 0.0;   ///< ∠(x_des, measured) [rad]
  double error_pitch_yaw = 0.0;  ///< the paper's norm of the (pitch, yaw) difference [rad]
  double path_time = 0.0;        ///< [s] along the path (0 while it is approached); other sources: since start
  bool approaching = false;      ///< a path drives and is being approached: its clock has not started
  double approach_time = 0.0;    ///< [s] the path's approach took (while approaching: so far; 0 for a jump)
  std::string path_failure;      ///< on the cycle a path's approach failed: why (the reference then holds)
  bool solver_converged = false;
  double stability_margin = 0.0;   ///< σ_c [N/m]
  double stability_eig_min = 0.0;  ///< min Re eig(S) [N/m]
  bool force_reachable = true;
  /// The law's supervisor (DirectionLaw::supervisor_weight): 1 the law acts whole, 0 it fell back to the
  /// paper's law because the mode rang (mode_swing [rad]).
  double law_weight = 1.0;
  double mode_swing = 0.0;
  /// The target lay beyond the reach the jets have shown (LearnedReach) and was clipped to it
  /// (clipped, clip_angle say by how much).
  bool reach_limited = false;
  double time_scale = 1.0;  ///< how much longer than written the path has taken so far (Reference::time_scale)
  /// The target, or the reference on its way, was moved out of a keep-out region (clipped, clip_angle).
  bool kept_out = false;
  /// The external tip force estimated and the contact detector's verdict (contact.h).
  ContactState contact;
  /// In contact, the reference was kept from going deeper than contact/max_force allows, or after it
  /// returns to its source at a bounded rate: by this much [rad].
  double contact_clip_angle = 0.0;
};

}  // namespace control
}  // namespace hydrojet
