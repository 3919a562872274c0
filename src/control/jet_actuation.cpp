#include "hydrojet_control/control/jet_actuation.h"

#include <stdexcept>
#include <string>

namespace hydrojet {
namespace control {

JetActuation::JetActuation(const RobotModel& model)
    : map_(model.jets),
      nozzle_(model.nozzle),
      max_force_(model.max_jet_force),
      regulators_(map_.wrench_matrix().cols(), actuation::FlowRegulator(model.flow)) {
  if (max_force_.size() != jet_count())
    throw std::invalid_argument("max_jet_force: " + std::to_string(max_force_.size()) + " entries for " +
                                std::to_string(jet_count()) + " jets");
}

JetVector JetActuation::forces_from_flows(const JetVector& flows) const {
  JetVector q(flows.size());
  for (int i = 0; i < flows.size(); ++i) q[i] = actuation::force_from_flow(flows[i], nozzle_);
  return q;
}

JetVector JetActuation::flows_for_forces(const JetVector& forces) const {
  JetVector flows(forces.size());
  for (int i = 0; i < forces.size(); ++i) flows[i] = actuation::flow_from_force(forces[i], nozzle_);
  return flows;
}

rod::Vec6 JetActuation::wrench(const JetVector& q) const { return map_.wrench(q); }

actuation::AllocationResult JetActuation::allocate(const Eigen::Vector2d& force, double weight) const {
  return actuation::allocate(map_.planar(), force, zeros(), max_force_, weight);
}

JetVector JetActuation::regulate(const JetVector& flow_command, const JetVector& measured_flows, double dt) {
  JetVector duty(jet_count());
  for (int i = 0; i < jet_count(); ++i) duty[i] = regulators_[i].update(flow_command[i], measured_flows[i], dt);
  return duty;
}

void JetActuation::reset() {
  for (actuation::FlowRegulator& r : regulators_) r.reset();
}

}  // namespace control
}  // namespace hydrojet
