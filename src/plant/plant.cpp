#include "hydrojet_control/plant/plant.h"

#include <algorithm>
#include <cmath>

namespace hydrojet {
namespace plant {

namespace {

/// The jets of the plant: its actuators of type jet.
int valve_count(const PlantModel& p) {
  int n = 0;
  for (const rod::Actuator& a : p.rod.rod.actuators) n += a.type == rod::ActuatorType::kJet;
  return n;
}

}  // namespace

std::string PlantModel::validate() const {
  const std::string r = rod.validate();
  if (!r.empty()) return "dynamics." + r;
  if (valves.empty()) return "valves: none (at least one model, used in turn by the jets)";
  for (size_t i = 0; i < valves.size(); ++i) {
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
  if (!(std::isfinite(thruster_time_constant) && thruster_time_constant >= 0.0))
    return "thruster_time_constant: must be finite and >= 0";
  if (!external_tip_force.allFinite()) return "external_tip_force: must be finite";
  if (!external_tip_moment.allFinite()) return "external_tip_moment: must be finite";
  if (rod.rod.actuators.empty()) return "dynamics.rod.actuators: the robot has none";
  if (std::string env = environment.validate(); !env.empty()) return "environment." + env;
  return "";
}

Eigen::Matrix3d base_orientation(double tilt) {
  return Eigen::AngleAxisd(M_PI + tilt, Eigen::Vector3d::UnitX()).toRotationMatrix();
}

Plant::Plant(const PlantModel& p, unsigned seed)
    : model_(p),
      hydraulics_(p.valves, valve_count(p)),
      tracker_(
          p.sensor_noise ? p.tracker : TrackerNoise{0, 0, 0, 0, p.tracker.dropout_rate, p.tracker.dropout_duration},
          seed),
      flow_sensors_(p.sensor_noise ? p.flow : FlowNoise{0, 0}, seed + 7919u),
      R_tracker_base_(base_orientation(p.base_tilt)) {
  const std::string err = model_.validate();
  if (!err.empty()) throw std::invalid_argument("plant: " + err);
  // Gravity in the base frame from the base orientation (tracker z is up).
  model_.rod.rod.gravity = R_tracker_base_.transpose() * Eigen::Vector3d(0, 0, -model_.gravity);
  const int n = model_.rod.rod.input_count();
  drive_scale_ = thrust_ = duty_ = rod::InputVector::Zero(n);
  for (int i = 0, valve = 0; i < n; ++i) {
    const rod::Actuator& a = model_.rod.rod.actuators[i];
    jet_.push_back(a.type == rod::ActuatorType::kJet);
    valve_of_.push_back(jet_[i] ? valve++ : -1);
    drive_scale_[i] = std::max(std::abs(a.min_force), std::abs(a.max_force));
  }
  rod_.reset(new rod::DynamicRod(model_.rod));
  reset();
}

bool Plant::reset() {
  t_ = 0.0;
  t_command_ = -1e300;
  duty_.setZero();
  thrust_.setZero();
  hydraulics_.reset();
  rod_->set_inputs(rod::InputVector::Zero(input_count()));
  error_.clear();
  contact_ = Contact{};
  external_force_.setZero();
  if (!rod_->reset_to_static(rod::TipWrench{})) {
    error_ = "rod: " + rod_->last_error();
    return false;
  }
  return true;
}

void Plant::command(const rod::InputVector& duty, double t) {
  const bool ok = duty.size() == input_count() && duty.allFinite();
  duty_ = ok ? duty : rod::InputVector(rod::InputVector::Zero(input_count()));  // a broken command closes the valves
  t_command_ = t;
}

rod::InputVector Plant::flows() const {
  const rod::InputVector valves = hydraulics_.flows();
  rod::InputVector q = rod::InputVector::Zero(input_count());
  for (int i = 0; i < input_count(); ++i)
    if (jet_[i]) q[i] = valves[valve_of_[i]];
  return q;
}

rod::InputVector Plant::jet_forces() const {
  const rod::InputVector q = flows();
  rod::InputVector f(input_count());
  for (int i = 0; i < input_count(); ++i) f[i] = jet_[i] ? actuation::force_from_flow(q[i], model_.nozzle) : thrust_[i];
  return f;
}

void Plant::step_actuators(const rod::InputVector& duty, double dt) {
  rod::InputVector valve_duty(hydraulics_.size());
  for (int i = 0; i < input_count(); ++i) {
    if (jet_[i]) {
      valve_duty[valve_of_[i]] = duty[i];
      continue;
    }
    const double target = std::clamp(duty[i], -1.0, 1.0) * drive_scale_[i];
    const double tau = model_.thruster_time_constant;
    thrust_[i] = tau > 0.0 ? thrust_[i] + (target - thrust_[i]) * (1.0 - std::exp(-dt / tau)) : target;
  }
  hydraulics_.step(valve_duty, dt);
}

bool Plant::advance_to(double t) {
  if (!std::isfinite(t) || t - t_ > kMaxAdvance) {
    error_ = "advance_to: time " + std::to_string(t) + " s is not finite or lies more than " +
             std::to_string(kMaxAdvance) + " s ahead of " + std::to_string(t_) + " s";
    return false;
  }
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
    step_actuators(timed_out_ ? rod::InputVector(rod::InputVector::Zero(input_count())) : duty_, dt);
    rod_->set_inputs(jet_forces());  // every actuator acts at its own node
    if (!step_rod(dt)) return false;
    t_ = i == n ? t : t0 + i * dt;
  }
  return true;
}

// Near a surface (within the capsule's travel this step and its own radius) the rod steps in
// substeps of contact_step: the contact force is held over each, as the rod's own wrench is.
bool Plant::step_rod(double dt) {
  int substeps = 1;
  if (!model_.environment.surfaces.empty()) {
    const Contact near = plant::contact(model_.environment, rod_->tip_position(), rod_->tip_velocity());
    if (near.clearance < rod_->tip_velocity().norm() * dt + model_.environment.tip_radius)
      substeps = std::clamp(static_cast<int>(std::ceil(dt / contact_step(model_.environment, contact_mass()) - 1e-9)),
                            1, 1000);
  }
  const double h = dt / substeps;
  for (int k = 0; k < substeps; ++k) {
    if (!rod_->step(tip_wrench(t_ + k * h), h)) {
      error_ = "rod: " + rod_->last_error();
      return false;
    }
  }
  return true;
}

// The mass the capsule meets a wall with: its own, or a gram when the tip carries none (the body's).
double Plant::contact_mass() const { return model_.rod.rod.tip_mass > 0.0 ? model_.rod.rod.tip_mass : 1e-3; }

rod::TipWrench Plant::tip_wrench(double t) {
  const Eigen::Matrix3d R = rod_->tip_rotation();
  const Eigen::Vector3d p = rod_->tip_position();
  Eigen::Vector3d force, moment;
  loads_at(model_.environment, t, R, &force, &moment);
  contact_ =
      model_.environment.surfaces.empty() ? Contact{} : plant::contact(model_.environment, p, rod_->tip_velocity());
  if (contact_.touching) {
    force += contact_.force;
    moment += (contact_.point - p).cross(contact_.force);  // the force acts where the capsule touches
  }
  rod::TipWrench w;
  w.force = model_.external_tip_force + R.transpose() * force;
  w.moment = model_.external_tip_moment + R.transpose() * moment;
  external_force_ = R * w.force;
  return w;
}

TrackerSample Plant::tracker_sample() {
  SensorPose base, tip;
  base.position = model_.base_position;
  base.orientation = Eigen::Quaterniond(R_tracker_base_);
  tip.position = model_.base_position + R_tracker_base_ * rod_->tip_position();
  tip.orientation = Eigen::Quaterniond(R_tracker_base_ * rod_->tip_rotation());
  return tracker_.sample(t_, tip, base);
}

rod::InputVector Plant::flow_sample() {
  rod::InputVector q = flow_sensors_.sample(flows());
  for (int i = 0; i < input_count(); ++i)
    if (!jet_[i]) q[i] = 0.0;
  return q;
}

rod::InputVector Plant::force_sample() { return jet_forces(); }

}  // namespace plant
}  // namespace hydrojet
