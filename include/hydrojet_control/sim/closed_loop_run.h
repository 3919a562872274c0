// One run of the §7 experiment in a single process, no transport: the controller (Algorithm 1)
// against the simulated plant, in lockstep at the control rate. Deterministic for a seed.
// ROS-free (the control and plant libraries).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/plant/plant.h"

namespace hydrojet {
namespace sim {

/// One control cycle as recorded.
struct RunSample {
  double t = 0.0;                ///< path time [s]
  Eigen::Vector3d desired;       ///< x_des, tip z-axis (base frame)
  Eigen::Vector3d measured;      ///< from the tracker
  Eigen::Vector3d tip_position;  ///< true tip position [m], base frame
  double error_geodesic = 0.0;   ///< [rad]
  double error_pitch_yaw = 0.0;  ///< [rad]
  rod::InputVector jet_force;    ///< true actuator forces [N], one per actuator
};

struct RunResult {
  bool completed = false;                                         ///< reached the end of the path without an abort
  double aborted_at = -1.0;                                       ///< path time of the abort [s], < 0 if none
  std::string reason;                                             ///< abort reason
  double rms = 0.0, median = 0.0, q1 = 0.0, q3 = 0.0, max = 0.0;  ///< of error_geodesic [rad]
  double rms_pitch_yaw = 0.0;                                     ///< of the paper's metric [rad]
  double wall_seconds = 0.0;
  double simulated_seconds = 0.0;
  std::vector<RunSample> samples;
};

/// Runs the controller's path (params.path) on the plant from rest until the path ends (plus
/// `settle` seconds before starting) or an abort. The error statistics cover the path only.
RunResult run_path(const control::RobotModel& model, const control::ControllerOptions& params,
                   const plant::PlantModel& plant, unsigned seed, double control_period = 0.01, double settle = 1.0);

}  // namespace sim
}  // namespace hydrojet
