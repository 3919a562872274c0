#include "hydrojet_control/plant/plant.h"

#include <cmath>

namespace hydrojet {
namespace plant {

std::string PlantModel::validate() const {
  const std::string r = rod.validate();
  if (!r.empty()) return "dynamics." + r;
  for (int i = 0; i < 3; ++i) {
    const std::string v = valves[i].validate();
    if (!v.empty()) return "valves[" + std::to_string(i) + "]." + v;
  }
  std::string e = tracker.validate();
  if (!e.empty()) return "tracker." + e;
  e = flow.validate();
  if (!e.empty()) return "flow_sensors." + e;
  e = actuation::validate(nozzle);
  if (!e.empty()) return "nozzle: " + e;
  if (!std::isfinite(base_tilt) || std::abs(base_tilt) > M_PI / 2) return "base_tilt: must lie in [-pi/2, pi/2] rad";
  if (!(internal_dt > 0.0 && internal_dt <= 0.01)) return "internal_dt: must lie in (0, 0.01] s";
  if (!(command_timeout > 0.0)) return "command_timeout: must be positive";
  return "";
}

Eigen::Matrix3d base_orientation(double tilt) {
  return Eigen::AngleAxisd(M_PI + tilt, Eigen::Vector3d::UnitX()).toRotationMatrix();
}

Plant::Plant(const PlantModel& p, unsigned seed)
    : model_(p),
      jets_(p.jets),
      hydraulics_(p.valves),
      tracker_(
          p.sensor_noise ? p.tracker : TrackerNoise{0, 0, 0, 0, p.tracker.dropout_rate, p.tracker.dropout_duration},
          seed),
      flow_sensors_(p.sensor_noise ? p.flow : FlowNoise{0, 0}, seed + 7919u),
      R_tracker_base_(base_orientation(p.base_tilt)) {
  const std::string err = model_.validate();
  if (!err.empty()) throw std::invalid_argument("plant: " + err);
  // Gravity in the base frame from the base orientation (tracker z is up).
  model_.rod.model.gravity = R_tracker_base_.transpose() * Eigen::Vector3d(0, 0, -model_.gravity);
  rod_.reset(new DynamicRod(model_.rod));
  reset();
}

bool Plant::reset() {
  t_ = 0.0;
  t_command_ = -1e300;
  duty_.setZero();
  hydraulics_.reset();
  error_.clear();
  if (!rod_->reset_to_static(rod::TipWrench{})) {
    error_ = "rod: " + rod_->last_error();
    return false;
  }
  return true;
}

void Plant::command(const Eigen::Vector3d& duty, double t) {
  duty_ = duty;
  t_command_ = t;
}

Eigen::Vector3d Plant::jet_forces() const {
  const Eigen::Vector3d q = hydraulics_.flows();
  return {actuation::force_from_flow(q[0], model_.nozzle), actuation::force_from_flow(q[1], model_.nozzle),
          actuation::force_from_flow(q[2], model_.nozzle)};
}

bool Plant::advance_to(double t) {
  if (!(t > t_ + 1e-12)) return true;
  // Equal internal steps no longer than internal_dt that land exactly on t (no sliver steps: the
  // implicit rod step conditions badly as dt -> 0).
  const double span = t - t_;
  const int n = std::max(1, static_cast<int>(std::ceil(span / model_.internal_dt - 1e-9)));
  const double dt = span / n;
  const double t0 = t_;
  for (int i = 1; i <= n; ++i) {
    // Command timeout: the valves close when the controller goes silent.
    timed_out_ = t_ - t_command_ > model_.command_timeout;
    const Eigen::Vector3d duty = timed_out_ ? Eigen::Vector3d::Zero() : duty_;
    hydraulics_.step(duty, dt);
    const actuation::Vec6 w = jets_.wrench(jet_forces());
    rod::TipWrench tw;
    tw.force = w.head<3>();
    tw.moment = w.tail<3>();
    if (!rod_->step(tw, dt)) {
      error_ = "rod: " + rod_->last_error();
      return false;
    }
    t_ = i == n ? t : t0 + i * dt;
  }
  return true;
}

TrackerSample Plant::tracker_sample() {
  SensorPose base, tip;
  base.position = model_.base_position;
  base.orientation = Eigen::Quaterniond(R_tracker_base_);
  tip.position = model_.base_position + R_tracker_base_ * rod_->tip_position();
  tip.orientation = Eigen::Quaterniond(R_tracker_base_ * rod_->tip_rotation());
  return tracker_.sample(t_, tip, base);
}

Eigen::Vector3d Plant::flow_sample() { return flow_sensors_.sample(hydraulics_.flows()); }

}  // namespace plant
}  // namespace hydrojet
