#include "hydrojet_control/control/jet_actuation.h"

#include <algorithm>
#include <cmath>

namespace hydrojet {
namespace control {

JetActuation::JetActuation(const rod::RodModel& body, const actuation::Nozzle& nozzle,
                           const actuation::FlowRegulatorOptions& flow)
    : nozzle_(nozzle),
      drive_scale_(InputVector::Zero(static_cast<int>(body.actuators.size()))),
      regulators_(body.actuators.size(), actuation::FlowRegulator(flow)) {
  for (size_t i = 0; i < body.actuators.size(); ++i) {
    const rod::Actuator& a = body.actuators[i];
    jet_.push_back(a.type == rod::ActuatorType::kJet);
    drive_scale_[i] = std::max(std::abs(a.min_force), std::abs(a.max_force));
  }
}

InputVector JetActuation::observed_forces(const InputVector& flows, const InputVector& forces) const {
  InputVector q(input_count());
  for (int i = 0; i < input_count(); ++i) q[i] = jet_[i] ? actuation::force_from_flow(flows[i], nozzle_) : forces[i];
  return q;
}

InputVector JetActuation::flows_for_forces(const InputVector& forces) const {
  InputVector flows(forces.size());
  for (int i = 0; i < forces.size(); ++i) flows[i] = jet_[i] ? actuation::flow_from_force(forces[i], nozzle_) : 0.0;
  return flows;
}

InputVector JetActuation::regulate(const InputVector& q, const InputVector& flow_command,
                                   const InputVector& measured_flows, double dt) {
  InputVector duty(input_count());
  for (int i = 0; i < input_count(); ++i)
    duty[i] = jet_[i] ? regulators_[i].update(flow_command[i], measured_flows[i], dt)
                      : (drive_scale_[i] > 0.0 ? std::clamp(q[i] / drive_scale_[i], -1.0, 1.0) : 0.0);
  return duty;
}

void JetActuation::reset() {
  for (actuation::FlowRegulator& r : regulators_) r.reset();
}

}  // namespace control
}  // namespace hydrojet
