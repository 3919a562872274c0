#include "hydrojet_control/sim/closed_loop_run.h"

#include "hydrojet_control/identification/free_vibration.h"
#include "hydrojet_control/util/json_writer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

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

/// One cycle of the path (path time t [s]): what the controller saw and the plant's truth.
RunSample record(const plant::Plant& plant, const control::ControllerOutput& out, double t) {
  RunSample s;
  s.t = t;
  s.desired = out.desired_direction;
  s.measured = out.measured_direction;
  s.truth = plant.tip_rotation().col(2).normalized();
  s.tip_position = plant.tip_position();
  s.error_geodesic = out.error_geodesic;
  s.error_pitch_yaw = out.error_pitch_yaw;
  s.error_true = control::geodesic_error(out.desired_direction, s.truth);
  s.jet_force = plant.jet_forces();
  s.contact_force = plant.contact().normal_force;
  s.clearance = plant.contact().clearance;
  s.external_force = plant.external_force();
  s.contact_flag = out.contact.in_contact;
  s.external_force_estimate = out.contact.force;
  return s;
}

/// The error statistics of the recorded samples.
void summarise(RunResult& r) {
  std::vector<double> e;
  double s2 = 0.0, p2 = 0.0, t2 = 0.0;
  for (const RunSample& s : r.samples) {
    e.push_back(s.error_geodesic);
    s2 += s.error_geodesic * s.error_geodesic;
    p2 += s.error_pitch_yaw * s.error_pitch_yaw;
    t2 += s.error_true * s.error_true;
  }
  if (e.empty()) return;
  r.rms = std::sqrt(s2 / e.size());
  r.rms_pitch_yaw = std::sqrt(p2 / e.size());
  r.rms_true = std::sqrt(t2 / e.size());
  r.median = quantile(e, 0.5);
  r.q1 = quantile(e, 0.25);
  r.q3 = quantile(e, 0.75);
  r.max = *std::max_element(e.begin(), e.end());
}

/// The jets' mean total flow over the samples by eq. (26) [m^3/s].
double water_flow(const control::RobotModel& model, const std::vector<RunSample>& samples) {
  if (samples.empty()) return 0.0;
  double sum = 0.0;
  for (const RunSample& s : samples)
    for (int i = 0; i < s.jet_force.size(); ++i)
      if (model.rod.actuators[i].type == rod::ActuatorType::kJet)
        sum += actuation::flow_from_force(std::max(s.jet_force[i], 0.0), model.nozzle);
  return sum / samples.size();
}

}  // namespace

ContactSummary summarise_contact(const std::vector<RunSample>& samples, double dt) {
  constexpr double kOnset = 0.02, kMissed = 0.03, kQuietBeforeOnset = 0.5, kQuietForFalse = 0.3, kAfterDetection = 0.3;
  ContactSummary c;
  double quiet = 0.0;  // [s] the true normal force has been zero
  // This contact began after kQuietBeforeOnset of none: its first kOnset is an onset (taps below kOnset
  // that bounce off before it do not disarm it).
  bool armed = false;
  double onset = -1.0;     // [s] of an onset not yet flagged (< 0: none)
  double detected = -1.0;  // [s] the flag was first up on this contact (< 0: not yet, or no contact)
  double err2 = 0.0;
  for (const RunSample& s : samples) {
    const bool touching = s.contact_force > 0.0;
    if (touching && quiet >= kQuietBeforeOnset) armed = true;
    if (touching && armed && s.contact_force > kOnset) {
      if (onset >= 0.0)  // the last one was never flagged: its delay is at least this long
        c.detection_delay_s =
            std::isnan(c.detection_delay_s) ? s.t - onset : std::max(c.detection_delay_s, s.t - onset);
      ++c.onsets, onset = s.t, armed = false;
    }
    if (s.contact_flag && onset >= 0.0) {
      c.detection_delay_s = std::isnan(c.detection_delay_s) ? s.t - onset : std::max(c.detection_delay_s, s.t - onset);
      onset = -1.0;
    }
    if (!touching) detected = -1.0;
    if (touching && s.contact_flag && detected < 0.0) detected = s.t;  // the flag is up on this contact
    if (detected >= 0.0 && s.t - detected >= kAfterDetection)
      c.max_contact_force_after_detection_n = std::isnan(c.max_contact_force_after_detection_n)
                                                  ? s.contact_force
                                                  : std::max(c.max_contact_force_after_detection_n, s.contact_force);
    if (s.contact_force > kMissed && !s.contact_flag) c.missed_contact_s += dt;
    quiet = touching ? 0.0 : quiet + dt;
    if (s.contact_flag && quiet >= kQuietForFalse) c.false_contact_s += dt;
    c.max_contact_force_n = std::max(c.max_contact_force_n, s.contact_force);
    c.min_clearance_m = std::min(c.min_clearance_m, s.clearance);
    err2 += (s.external_force_estimate - s.external_force).squaredNorm();
  }
  if (onset >= 0.0 && !samples.empty()) {  // never flagged: to the run's end
    const double d = samples.back().t - onset;
    c.detection_delay_s = std::isnan(c.detection_delay_s) ? d : std::max(c.detection_delay_s, d);
  }
  if (!samples.empty()) c.external_force_rms_error_n = std::sqrt(err2 / samples.size());
  return c;
}

void read_sensors(plant::Plant& plant, double t, control::ControllerInputs& in) {
  const plant::TrackerSample ts = plant.tracker_sample();
  if (ts.valid) {
    in.tip_valid = true;
    in.tip_stamp = ts.stamp;
    const Eigen::Matrix3d base = ts.base.orientation.toRotationMatrix();
    in.tip_rotation = base.transpose() * ts.tip.orientation.toRotationMatrix();
    in.tip_position = base.transpose() * (ts.tip.position - ts.base.position);
  }
  in.flows = plant.flow_sample();
  in.forces = plant.force_sample();
  in.flow_valid = true;
  in.flow_stamp = t;
  in.t = t;
}

const char* to_string(RunStart s) { return s == RunStart::kRest ? "rest" : "on-path"; }

bool parse_run_start(const std::string& name, RunStart* start) {
  for (const RunStart s : {RunStart::kRest, RunStart::kOnPath})
    if (name == to_string(s)) {
      *start = s;
      return true;
    }
  return false;
}

Episode::Episode(const plant::PlantModel& model, unsigned seed, double control_period)
    : plant_(model, seed), dt_(control_period) {
  if (!(control_period >= 1e-4 && control_period <= 1.0))
    throw std::invalid_argument("control_period: must lie in [1e-4, 1] s");
}

bool Episode::advance() {
  if (!plant_.advance_to(t())) return false;
  read_sensors(plant_, t(), in_);
  return true;
}

bool Episode::settle(double seconds) {
  const long settle_steps = std::lround(seconds / dt_);
  const rod::InputVector shut = rod::InputVector::Zero(plant_.input_count());
  if (!plant_.error().empty() || !advance()) return false;
  while (steps_ < settle_steps)
    if (!step(shut)) return false;
  return true;
}

bool Episode::step(const rod::InputVector& command) {
  plant_.command(command, t());
  ++steps_;
  return advance();
}

RunResult run_path(const control::RobotModel& model, const control::ControllerOptions& params,
                   const plant::PlantModel& plant_params, unsigned seed, const RunPlan& plan) {
  const auto wall0 = std::chrono::steady_clock::now();
  RunResult r;
  r.start = plan.start;
  Episode episode(plant_params, seed, plan.control_period);
  control::Controller controller(model, params);
  const std::shared_ptr<const control::Path> path =
      plan.path ? plan.path : std::shared_ptr<const control::Path>(control::make_spiral(params.path));
  const bool approach = plan.start == RunStart::kOnPath;
  // The approach is bounded by the controller (the reference's way there at max_angular_rate, then
  // approach.timeout); this only bounds the loop.
  const double approach_bound = approach ? M_PI / params.limits.max_angular_rate + params.approach.timeout + 1.0 : 0.0;
  // The path's own time, or its length at limits/max_path_rate where time scaling slows it, and the
  // probe of the first mode (mode_probe.h).
  double length = 0.0;
  for (double s = 0.0; s < path->duration(); s += 0.01)
    length += control::geodesic_error(path->direction_at(s), path->direction_at(s + 0.01));
  const double path_bound = std::max(path->duration(), length / params.limits.max_path_rate) + path->duration() +
                            control::ModeProbe::kSeconds;
  const long last_step =
      std::lround(plan.settle / plan.control_period) + std::lround((approach_bound + path_bound) / plan.control_period);
  double path_start = -1.0;  // [s] simulated time of the path clock's start
  double weight = 1.0;       // the law's supervisor weight at the last sample
  bool ok = episode.settle(plan.settle);
  if (ok) {
    controller.follow(path, episode.t(),
                      approach ? control::Reference::PathStart::kApproach : control::Reference::PathStart::kJump,
                      control::Reference::PathClip::kDesigned);
    controller.start(episode.t());
  }
  while (ok) {
    const double t = episode.t();
    const control::ControllerOutput out = controller.update(episode.sensors());
    if (out.state == control::ControllerState::kAborted || !out.path_failure.empty()) {
      r.aborted_at = path_start >= 0 ? t - path_start : 0.0;
      r.reason = out.state == control::ControllerState::kAborted ? out.reason : out.path_failure;
      break;
    }
    if (!out.approaching) {
      if (path_start < 0) path_start = t, r.approach_time = out.approach_time;
      r.samples.push_back(record(episode.plant(), out, t - path_start));
      if (out.law_weight < 1.0) r.supervised_s += plan.control_period;
      if (out.reach_limited) r.reach_limited_s += plan.control_period;
      if (out.kept_out) r.keep_out_s += plan.control_period;
      r.time_scale = out.time_scale;
      if (out.law_weight == 0.0 && weight > 0.0) ++r.supervisor_fallbacks;
      weight = out.law_weight;
      if (out.state == control::ControllerState::kFinished) {
        r.completed = true;
        break;
      }
    }
    if (episode.steps() >= last_step) break;
    ok = episode.step(out.valve_command);
  }
  if (!ok) {
    r.reason = "plant: " + episode.error();
    r.aborted_at = path_start >= 0 ? episode.t() - path_start : 0.0;
  }
  if (!r.completed && r.reason.empty()) r.reason = "the run's time bound passed before the path ended";
  summarise(r);
  r.contact = summarise_contact(r.samples, plan.control_period);
  r.identified = controller.identity();
  r.truth = plant_truth(episode.plant());
  r.water_flow = water_flow(model, r.samples);
  r.simulated_seconds = r.samples.empty() ? 0.0 : r.samples.back().t + (path_start >= 0 ? path_start : 0.0);
  r.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return r;
}

control::PlantIdentity plant_truth(const plant::Plant& plant) {
  const plant::PlantModel& m = plant.model();
  control::PlantIdentity truth;
  truth.tracker_latency_s = m.sensor_noise ? m.tracker.latency : 0.0;
  truth.valve_time_constants_s.assign(plant.input_count(), 0.0);
  truth.valve_plays.assign(plant.input_count(), 0.0);
  for (int i = 0; i < plant.input_count(); ++i)
    if (plant.is_jet(i)) {
      const plant::ValveModel& v = m.valves[plant.valve_of(i) % m.valves.size()];
      truth.valve_time_constants_s[i] = v.time_constant;
      truth.valve_plays[i] = v.hysteresis;
    }
  rod::TipWrench w;
  w.force = m.external_tip_force;
  w.moment = m.external_tip_moment;
  const identification::ModeFit fit = identification::free_vibration_mode(m.rod, plant.jet_forces(), w);
  if (!fit.ok) return truth;
  truth.mode_identified = true;
  truth.mode_hz = fit.hz();
  truth.damping_ratio = fit.zeta;
  return truth;
}

std::string identity_json(const control::PlantIdentity& id, bool identified) {
  util::JsonObject o;
  if (id.mode_hz > 0.0)
    o.add("mode_hz", id.mode_hz).add("damping_ratio", id.damping_ratio);
  else
    o.add_null("mode_hz").add_null("damping_ratio");
  o.add("valve_time_constants_s",
        Eigen::Map<const Eigen::VectorXd>(id.valve_time_constants_s.data(), id.valve_time_constants_s.size()));
  o.add("tracker_latency_s", id.tracker_latency_s);
  if (!id.valve_plays.empty())
    o.add("valve_plays", Eigen::Map<const Eigen::VectorXd>(id.valve_plays.data(), id.valve_plays.size()));
  if (identified) {  // what was measured, and what is still the controller file's first guess
    o.add("mode_identified", id.mode_identified).add("valves_identified", id.valves_identified);
    if (!id.mode_error.empty()) o.add("mode_error", id.mode_error);
  }
  return o.str();
}

RunResult run_path(const control::RobotModel& model, const control::ControllerOptions& params,
                   const plant::PlantModel& plant, unsigned seed, double control_period, double settle) {
  RunPlan plan;
  plan.control_period = control_period;
  plan.settle = settle;
  return run_path(model, params, plant, seed, plan);
}

}  // namespace sim
}  // namespace hydrojet
