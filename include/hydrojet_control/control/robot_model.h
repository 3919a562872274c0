// What the controller needs from a scene: the rod model and its solver, the jets and their nozzles,
// and per-jet vectors sized by the jet map (three jets for the HydroJet's eq. 24).
// ROS-free (Eigen, the rod and actuation libraries).
#pragma once

#include <Eigen/Core>

#include "hydrojet_control/actuation/flow_regulator.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/rod/shooting_solver.h"
#include "hydrojet_control/rod/stability.h"

namespace hydrojet {
namespace control {

/// Storage bound of a JetVector (no heap allocation); the jet count itself comes from the jet map.
constexpr int kMaxJets = 8;
/// One entry per jet (flows, jet forces, valve duties), sized by the jet map's column count.
using JetVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxJets, 1>;

/// Inputs the controller needs from a scene: the rod model, the jets and the nozzles.
struct RobotModel {
  rod::RodModel rod;
  rod::ShootingOptions solver;
  rod::ActuatedSet actuated = rod::lateral_force_actuation();
  actuation::JetGeometry jets;
  actuation::Nozzle nozzle;
  JetVector max_jet_force = Eigen::Vector3d(0.243, 0.224, 0.244);  ///< q_max [N], one per jet
  actuation::FlowRegulatorOptions flow;  ///< per-jet PI flow regulator (the same for every jet)
};

}  // namespace control
}  // namespace hydrojet
