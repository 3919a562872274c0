#include "hydrojet_control/sim/closed_loop_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace hydrojet {
namespace sim {
namespace {

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const size_t i = static_cast<size_t>(pos);
  const double f = pos - i;
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}

}  // namespace

RunResult run_path(const control::ControllerModel& model, const control::ControllerParams& params,
                   const plant::PlantParameters& plant_params, unsigned seed, double dt, double settle) {
  const auto wall0 = std::chrono::steady_clock::now();
  RunResult r;
  plant::Plant plant(plant_params, seed);
  control::Controller controller(model, params);
  const int settle_steps = static_cast<int>(std::lround(settle / dt));
  const int path_steps = static_cast<int>(std::lround(params.path.duration / dt));
  Eigen::Vector3d last_flows = Eigen::Vector3d::Zero();
  control::ControllerInputs in;
  for (int k = 0; k <= settle_steps + path_steps; ++k) {
    const double t = k * dt;
    if (!plant.advance_to(t)) {
      r.reason = "plant: " + plant.error();
      r.aborted_at = t - settle;
      break;
    }
    if (k == settle_steps) controller.start(t);
    // Sensors, as the rig driver would deliver them.
    const plant::TrackerSample ts = plant.tracker_sample();
    if (ts.valid) {
      in.tip_valid = true;
      in.tip_stamp = ts.stamp;
      in.tip_rotation = (ts.base.orientation.toRotationMatrix().transpose() * ts.tip.orientation.toRotationMatrix());
    }
    last_flows = plant.flow_sample();
    in.flow_valid = true;
    in.flow_stamp = t;
    in.flows = last_flows;
    in.t = t;
    const control::ControllerOutput out = controller.update(in);
    plant.command(out.valve_command, t);
    if (k < settle_steps) continue;
    if (out.state == control::ControllerState::kAborted) {
      r.aborted_at = t - settle;
      r.reason = out.reason;
      break;
    }
    RunSample s;
    s.t = t - settle;
    s.desired = out.desired_direction;
    s.measured = out.measured_direction;
    s.tip_position = plant.tip_position();
    s.error_geodesic = out.error_geodesic;
    s.error_pitch_yaw = out.error_pitch_yaw;
    s.jet_force = plant.jet_forces();
    r.samples.push_back(s);
    if (out.state == control::ControllerState::kFinished) {
      r.completed = true;
      break;
    }
  }
  std::vector<double> e;
  double s2 = 0.0, p2 = 0.0;
  for (const RunSample& s : r.samples) {
    e.push_back(s.error_geodesic);
    s2 += s.error_geodesic * s.error_geodesic;
    p2 += s.error_pitch_yaw * s.error_pitch_yaw;
  }
  if (!e.empty()) {
    r.rms = std::sqrt(s2 / e.size());
    r.rms_pitch_yaw = std::sqrt(p2 / e.size());
    r.median = quantile(e, 0.5);
    r.q1 = quantile(e, 0.25);
    r.q3 = quantile(e, 0.75);
    r.max = *std::max_element(e.begin(), e.end());
  }
  r.simulated_seconds = r.samples.empty() ? 0.0 : r.samples.back().t + settle;
  r.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return r;
}

}  // namespace sim
}  // namespace hydrojet
