#include "hydrojet_control/control/robot_model.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hydrojet {
namespace control {

std::vector<rod::Actuator> jet_actuators(const actuation::JetGeometry& jets, const Vec3& max_force, double length) {
  const actuation::JetMap map(jets);
  std::vector<rod::Actuator> out;
  for (int i = 0; i < 3; ++i) {
    rod::Actuator a;
    a.name = "jet" + std::to_string(i + 1);
    a.at = length;
    a.direction = map.wrench_matrix().col(i).head<3>();
    a.position = rod::Vec3(0.0, 0.0, jets.nozzle_offset);
    a.max_force = max_force[i];
    a.type = rod::ActuatorType::kJet;
    out.push_back(a);
  }
  return out;
}

Vec3 jet_max_force(const rod::RodModel& rod) {
  return Vec3(rod.actuators.at(0).max_force, rod.actuators.at(1).max_force, rod.actuators.at(2).max_force);
}

ActuatedModel::ActuatedModel(const RobotModel& model) : solver_(model.rod, model.solver) {
  const rod::RodModel& m = solver_.model();
  const int n = input_count();
  if (n < 1) throw std::invalid_argument("actuators: the robot needs at least one actuator");
  lower_.resize(n);
  upper_.resize(n);
  tip_wrenches_.setZero(6, n);
  for (int i = 0; i < n; ++i) {
    const rod::Actuator& a = m.actuators[i];
    lower_[i] = a.min_force;  // ≥ 0 for a jet (RodModel::validate)
    upper_[i] = a.max_force;
    if (a.at >= m.length()) tip_wrenches_.col(i) = a.unit_wrench();
  }
}

ActuatedModel::Linearisation ActuatedModel::linearise() {
  Linearisation lin;
  const rod::Compliance C = solver_.compliance();
  lin.body_compliance = C.body;
  lin.actuation = C.actuation;
  // All actuators at the tip of one segment: J_q = C^b W, so W itself moves the tip as the inputs do.
  if (rod().tip_actuated_uniform())
    lin.wrenches = tip_wrenches_;
  else
    lin.wrenches = rod::equivalent_tip_wrenches(C.body, C.actuation);
  lin.ok = C.ok && lin.body_compliance.allFinite() && lin.actuation.allFinite() && lin.wrenches.allFinite();
  return lin;
}

rod::StabilityReport ActuatedModel::stability(const Linearisation& lin) const {
  return rod::stability(lin.body_compliance, lin.wrenches, rod().length());
}

}  // namespace control
}  // namespace hydrojet
