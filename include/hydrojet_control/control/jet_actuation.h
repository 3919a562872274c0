// The actuators' side of a control cycle, one entry per actuator of the model (the HydroJet's three
// jets of eq. 24, or any follower actuators a scene describes):
//   observation: jets: measured flows → jet forces q_obs by the thrust equation (26); actuators of
//                type force: their measured force (Algorithm 1, line 4);
//   command:     inputs q → jets: flows by eq. (26) → valve duties by the per-jet PI flow
//                regulators; force actuators: the drive q / max(|q_min|, |q_max|) in [−1, 1] (0 = off).
// ROS-free (Eigen, the rod and actuation libraries).
#pragma once

#include <vector>

#include "hydrojet_control/control/robot_model.h"

namespace hydrojet {
namespace control {

class JetActuation {
 public:
  /// The actuators of `body` (at least one), the jets' nozzle and flow regulator.
  JetActuation(const rod::RodModel& body, const actuation::Nozzle& nozzle, const actuation::FlowRegulatorOptions& flow);

  int input_count() const { return static_cast<int>(jet_.size()); }
  /// Actuator i is a water jet (flow-driven, eq. 26); else it takes its force directly.
  bool is_jet(int i) const { return jet_[i]; }
  /// A zero entry per actuator.
  InputVector zeros() const { return InputVector::Zero(input_count()); }

  /// Inputs q_obs [N]: jets from their measured flows [m^3/s] by eq. (26), force actuators their
  /// measured forces [N].
  InputVector observed_forces(const InputVector& flows, const InputVector& forces) const;
  /// Flows [m^3/s] for inputs q [N] by eq. (26) inverted; 0 for force actuators.
  InputVector flows_for_forces(const InputVector& forces) const;

  /// One step of the drives: jets by their PI flow regulators (valve duty [0, 1] for the commanded
  /// and measured flows [m^3/s] after dt [s]); force actuators the drive of the commanded input q.
  InputVector regulate(const InputVector& q, const InputVector& flow_command, const InputVector& measured_flows,
                       double dt);
  /// Zeroes the regulators' integrators.
  void reset();
  /// Jet i's valve has this play [duty] (identified): its regulator inverts it.
  void set_play(int i, double width) { regulators_[i].set_play(width); }
  /// The jets' flow regulator (the same for every actuator).
  const actuation::FlowRegulatorOptions& flow_regulator() const { return regulators_.front().options(); }

 private:
  actuation::Nozzle nozzle_;
  std::vector<bool> jet_;
  InputVector drive_scale_;                           ///< max(|q_min|, |q_max|) [N] per actuator
  std::vector<actuation::FlowRegulator> regulators_;  ///< one per actuator (used by the jets)
};

}  // namespace control
}  // namespace hydrojet
