// The jets' side of a control cycle, sized by the jet map (three jets for the HydroJet's eq. 24):
//   observation: measured flows → jet forces q_obs by the thrust equation (26) → w_a = A q_obs
//                (eq. 24, Algorithm 1 line 4);
//   command:     tip force → jet forces q by the bounded allocation of eq. (20) (Algorithm 1,
//                line 12) → flows by eq. (26) → valve duties by the per-jet PI flow regulators.
// ROS-free (Eigen, the rod and actuation libraries).
#pragma once

#include <vector>

#include "hydrojet_control/actuation/allocation.h"
#include "hydrojet_control/control/robot_model.h"

namespace hydrojet {
namespace control {

class JetActuation {
 public:
  /// The jets, nozzle, q_max and flow regulator of the model. Throws std::invalid_argument when
  /// max_jet_force does not have one entry per jet.
  explicit JetActuation(const RobotModel& model);

  int jet_count() const { return static_cast<int>(regulators_.size()); }
  /// A zero entry per jet.
  JetVector zeros() const { return JetVector::Zero(jet_count()); }

  /// Jet forces [N] for flows [m^3/s], eq. (26).
  JetVector forces_from_flows(const JetVector& flows) const;
  /// Flows [m^3/s] for jet forces [N], eq. (26) inverted.
  JetVector flows_for_forces(const JetVector& forces) const;
  /// Tip body wrench [N, N m] of jet forces q [N], eq. (24).
  rod::Vec6 wrench(const JetVector& q) const;

  /// eq. (20): jet forces within [0, q_max] whose planar force A q is closest to the tip force
  /// (f_x, f_y) [N], regularised by weight λ.
  actuation::AllocationResult allocate(const Eigen::Vector2d& force, double weight) const;

  /// One step of the per-jet PI flow regulators: valve duties [0, 1] for the commanded and
  /// measured flows [m^3/s] after dt [s].
  JetVector regulate(const JetVector& flow_command, const JetVector& measured_flows, double dt);
  /// Zeroes the regulators' integrators.
  void reset();

 private:
  actuation::JetMap map_;
  actuation::Nozzle nozzle_;
  JetVector max_force_;
  std::vector<actuation::FlowRegulator> regulators_;  ///< one per jet
};

}  // namespace control
}  // namespace hydrojet
