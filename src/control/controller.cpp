#include "hydrojet_control/control/controller.h"

#include <algorithm>
#include <limits>
#include <cmath>

#include "hydrojet_control/control/modal_model.h"

namespace hydrojet {
namespace control {

namespace {

/// The reachable set of `model` with each actuator's bounds scaled by `force_fraction` (0, 1].
std::shared_ptr<const ReachableSet> sweep_reachable_set(RobotModel model, const ControllerOptions& params,
                                                        double force_fraction) {
  for (rod::Actuator& a : model.rod.actuators) {
    a.min_force *= force_fraction;
    a.max_force *= force_fraction;
  }
  ReachableSetOptions o;
  o.min_stability_margin = params.min_stability_margin;
  return std::make_shared<const ReachableSet>(ReachableSet::compute(model, o));
}

}  // namespace

const char* to_string(ControllerState s) {
  switch (s) {
    case ControllerState::kIdle: return "idle";
    case ControllerState::kRunning: return "running";
    case ControllerState::kFinished: return "finished";
    case ControllerState::kAborted: return "aborted";
  }
  return "unknown";
}

Controller::Controller(const RobotModel& model, const ControllerOptions& params)
    : params_(params),
      model_(model),
      jets_(model_.rod(), model.nozzle, model.flow),
      monitor_(params, jets_.input_count()),
      previous_command_(jets_.zeros()),
      path_reachable_(sweep_reachable_set(model, params, 1.0)),
      reachable_(params.reachable_force_fraction == 1.0
                     ? path_reachable_
                     : sweep_reachable_set(model, params, params.reachable_force_fraction)),
      reference_(params.max_angular_rate, reachable_, path_reachable_),
      approach_(params.approach) {}

void Controller::start(double t) {
  state_ = ControllerState::kRunning;
  abort_reason_.clear();
  t_start_ = t;
  t_last_ = t;
  first_cycle_ = true;
  modal_.reset();
  shaping_primed_ = false;
  omega_ = 0.0;
  monitor_.reset();
  pd_.reset();
  reset_actuation();
  if (!commands_pending_) start_configured_path(t);
  commands_pending_ = false;
}

void Controller::stop() {
  state_ = ControllerState::kIdle;
  reset_actuation();
  commands_pending_ = false;
}

void Controller::set_params(const ControllerOptions& p) {
  params_ = p;
  monitor_.set_options(p);
  reference_.set_max_angular_rate(p.max_angular_rate);
  approach_.set_options(p.approach);
}

void Controller::follow(std::shared_ptr<const Path> path, double t, Reference::PathStart start,
                        Reference::PathClip clip) {
  reference_.follow(std::move(path), t, start, clip);
  approach_.reset();
  commanded();
}

bool Controller::aim(const Vec3& target, Source source) {
  if (!reference_.aim(target, source)) return false;
  commanded();
  return true;
}

void Controller::turn(const Eigen::Vector2d& up_right, Source source, double until) {
  reference_.turn(up_right, source, until);
  commanded();
}

void Controller::hold() {
  reference_.hold();
  commanded();
}

// The configured start: the spiral from its first point (as in the paper's experiment), or hold.
void Controller::start_configured_path(double t) {
  if (params_.path_type == PathType::kSpiral)
    reference_.follow(make_spiral(params_.path), t, Reference::PathStart::kJump);
  else
    reference_.hold();
}

// A command while idle or aborted waits for start(); a finished path gives way to it.
void Controller::commanded() {
  if (state_ == ControllerState::kIdle || state_ == ControllerState::kAborted)
    commands_pending_ = true;
  else if (state_ == ControllerState::kFinished)
    state_ = ControllerState::kRunning;
}

rod::RodSolution Controller::model_fk(const InputVector& q) { return solve_model(q); }

ControllerOutput Controller::update(const ControllerInputs& in) {
  ControllerOutput out = resting_output();
  if (state_ == ControllerState::kIdle || state_ == ControllerState::kAborted) return out;  // jets at zero

  const double dt = first_cycle_ ? params_.sample_period : in.t - t_last_;
  if (!std::isfinite(in.t) || dt < 0.0) return abort(out, "time went backwards (dt = " + std::to_string(dt) + " s)");
  if (dt == 0.0) return last_output_;  // a repeated tick at the same time: nothing new to do
  t_last_ = in.t;
  out.path_time = in.t - t_start_;

  // Sensor health and flow faults: stale, missing or non-finite data, or a jet that does not follow
  // its command, stops the jets.
  if (std::string why = monitor_.check_sensors(in); !why.empty()) return abort(out, why);
  if (std::string why = monitor_.check_flow_faults(in.flows, dt); !why.empty()) return abort(out, why);

  if (std::string why = observe_jets(in, out); !why.empty()) return abort(out, why);  // Algorithm 1, line 4
  const rod::RodSolution sol = solve_model(out.jet_force_observed);                   // line 6
  out.solver_converged = sol.converged;
  if (std::string why = monitor_.check_solver(sol); !why.empty()) return abort(out, why);
  if (!sol.converged) return hold(out, in.flows, dt);
  out.model_tip_rotation = sol.tip_rotation;
  const ActuatedModel::Linearisation lin = model_.linearise();  // C^b (eq. 14) and J_q of line 6
  if (std::string why = check_stability(lin, out); !why.empty()) return abort(out, why);

  track_reference(in, sol, dt, out);
  estimate_modes(in, sol, lin, out.jet_force_observed);
  if (std::string why = monitor_.check_oscillation(out.error_geodesic); !why.empty()) return abort(out, why);

  if (std::string why = command_inputs(sol, lin, dt, out); !why.empty()) return abort(out, why);
  if (std::string why = actuate(in.flows, dt, out); !why.empty()) return abort(out, why);
  return finish_cycle(out);
}

// The output of a cycle that commands nothing: state and abort reason, jets at zero.
ControllerOutput Controller::resting_output() const {
  ControllerOutput out;
  out.state = state_;
  out.reason = abort_reason_;
  out.valve_command = out.jet_force_command = out.flow_command = out.jet_force_observed = jets_.zeros();
  return out;
}

// Algorithm 1, line 4: q_obs from measured flow by the thrust equation (26) (jets) or the measured
// force (force actuators), and w_a = W q_obs.
std::string Controller::observe_jets(const ControllerInputs& in, ControllerOutput& out) const {
  const InputVector none = jets_.zeros();
  const bool have_forces = in.forces.size() == jets_.input_count();
  out.jet_force_observed = jets_.observed_forces(in.flows, have_forces ? in.forces : none);
  for (int i = 0; i < jets_.input_count(); ++i) {
    if (jets_.is_jet(i)) continue;
    if (!have_forces) return "force: no reading for actuator " + model_.rod().actuators[i].name;
    if (!std::isfinite(in.forces[i]))
      return "force: actuator " + model_.rod().actuators[i].name + " reading invalid (" + std::to_string(in.forces[i]) +
             " N)";
  }
  out.wrench_observed = model_.tip_wrench(out.jet_force_observed);
  return "";
}

// Line 6: forward kinematics at the inputs q (eqs. 6, 9, 12, 14); C^b and J_q follow from
// model_.linearise().
rod::RodSolution Controller::solve_model(const InputVector& q) { return model_.solve(q); }

// The solver did not converge (fewer times in a row than max_solver_failures): no new force this
// cycle; the flow regulators keep the jets at the flows of the observed jet forces.
ControllerOutput Controller::hold(ControllerOutput out, const InputVector& flows, double dt) {
  if (reference_.on_path()) pd_.skip(dt);  // a path moves with time: the next cycle sees two cycles' motion
  out.jet_force_command.setZero();
  out.flow_command = jets_.flows_for_forces(out.jet_force_observed);
  out.valve_command = jets_.regulate(out.jet_force_observed, out.flow_command, flows, dt);
  last_output_ = out;
  return out;
}

// Elastic stability of the model's equilibrium (§4.1, eqs. 21–23), reported and checked.
std::string Controller::check_stability(const ActuatedModel::Linearisation& lin, ControllerOutput& out) const {
  const rod::StabilityReport st = model_.stability(lin);
  out.stability_margin = st.margin;
  out.stability_eig_min = st.eig_min;
  rod::Compliance compliance;
  compliance.ok = lin.ok;
  compliance.body = lin.body_compliance;
  return monitor_.check_stability(compliance, st);
}

// Task space: desired, measured and model tip directions (base frame); x_obs is the tracker's in
// closed loop, the model's in open loop (§7.3). x_des is the reference one step on (its source,
// rate limit and clipping: Reference), starting at x_obs. The errors are always against the tracker.
void Controller::track_reference(const ControllerInputs& in, const rod::RodSolution& sol, double dt,
                                 ControllerOutput& out) {
  const bool closed = params_.mode == LoopMode::kClosed;
  const Mat3 tip_frame = closed ? in.tip_rotation : sol.tip_rotation;  // the camera's axes for rate sources
  out.measured_direction = in.tip_rotation.col(2).normalized();
  out.observed_direction = closed ? out.measured_direction : Vec3(sol.tip_rotation.col(2));
  if (first_cycle_) {
    reference_.start(out.observed_direction, t_start_);
    approach_.reset();
  }
  out.desired_direction = reference_.advance(in.t, dt, tip_frame);
  out.source = reference_.source();
  out.clipped = reference_.clipped();
  out.clip_angle = reference_.clip_angle();
  out.error_geodesic = geodesic_error(out.desired_direction, out.measured_direction);
  out.error_pitch_yaw = pitch_yaw_error(out.desired_direction, out.measured_direction);
  approach(in.t, out);
}

// A path being approached: its clock starts once the tip has settled on its first direction; one
// that does not settle is a failure, and the reference holds where it is.
void Controller::approach(double t, ControllerOutput& out) {
  out.approaching = reference_.approaching();
  if (out.approaching) {
    const double loop_error = geodesic_error(out.desired_direction, out.observed_direction);
    switch (approach_.update(t, reference_.at_path_start(), loop_error, out.measured_direction)) {
      case ApproachMonitor::Verdict::kSettled:
        reference_.begin_path(t);
        out.approaching = false;
        break;
      case ApproachMonitor::Verdict::kFailed:
        out.path_failure = "approach: " + approach_.failure();
        reference_.hold();
        out.source = reference_.source();
        out.approaching = false;
        break;
      default: break;
    }
  }
  out.approach_time = reference_.approach_time();
  if (reference_.path()) out.path_time = reference_.path_time(t);  // other sources: time since start
}

// The modal law's estimator (closed loop): the first mode at this equilibrium (with the capsule's
// expected fill), then one filter step with the model's direction at the last measured inputs and the
// tracker's direction.
void Controller::estimate_modes(const ControllerInputs& in, const rod::RodSolution& sol,
                                const ActuatedModel::Linearisation& lin, const InputVector& q_obs) {
  if (params_.control_law != ControlLaw::kModal || params_.mode != LoopMode::kClosed) {
    modal_.reset();  // starts afresh when the loop closes again
    return;
  }
  ModalOptions mo;
  mo.tip_mass_scale = params_.modal.tip_mass_scale;
  // A body whose mass is all at its tip needs only this cycle's C^b; one with mass of its own needs
  // the probe solves.
  const ModalModel modes = !lin.ok || has_body_mass(model_.rod())
                               ? lateral_modes(model_.solver(), q_obs, rod::TipWrench(), mo)
                               : lateral_modes(model_.rod(), lin.body_compliance, mo);
  if (modes.ok) omega_ = modes.frequency(0);
  if (!(omega_ > 0.0)) return;  // none yet: the paper's law drives
  const Vec3 s = sol.tip_rotation.col(2);
  const Vec3 z = in.tip_rotation.col(2).normalized();
  if (!modal_.initialised())
    modal_.start(z, s, omega_, params_.modal);
  else  // over the time since its last step (a held cycle, a solve that failed, is skipped)
    modal_.step(modal_input_, z, omega_, modal_damping_ratio(), in.t - modal_time_, params_.modal);
  modal_input_ = s;
  modal_time_ = in.t;
}

// ζ of the first mode: Kelvin–Voigt damping of time τ gives 2ζω = τω².
double Controller::modal_damping_ratio() const { return 0.5 * omega_ * params_.modal.damping_time; }

// The modal law drives a path whose clock runs, in closed loop, once its estimator has started.
bool Controller::modal_drives() const {
  return params_.control_law == ControlLaw::kModal && params_.mode == LoopMode::kClosed && modal_.initialised() &&
         reference_.on_path();
}

// The modal law's gain schedule: the weight of the reference's speed (modal/gain_speed) while it
// drives, else 0.
double Controller::modal_weight() const {
  return modal_drives() ? fast_path_weight(pd_.speed(), params_.modal.gain_speed) : 0.0;
}

// The PD's gains: from gains/* toward modal/* with the modal law's weight.
ControllerOptions Controller::law_gains() const {
  ControllerOptions gains = params_;
  if (const double w = modal_weight(); w > 0.0) {
    gains.kp = params_.kp + w * (params_.modal.kp - params_.kp);
    gains.ki = params_.ki + w * (params_.modal.ki - params_.ki);
  }
  return gains;
}

// The modal law's shaping (modal_shaping), as the change since the last step: x_cntr moves the
// forces by increments, so an added direction m(t) enters as the rotation d × (m(t) − m(t − dt)).
Vec3 Controller::shaping_step(const rod::RodSolution& sol, const ControllerOutput& out) {
  if (!modal_drives()) {
    shaping_primed_ = false;
    return Vec3::Zero();
  }
  const double h = params_.sample_period;
  const Vec3 a = reference_.preview(t_last_, h), b = reference_.preview(t_last_, 2 * h),
             c = reference_.preview(t_last_, 3 * h);
  ReferenceMotion r;
  r.rate = (c - a) / (2 * h);
  r.accel = (c - 2 * b + a) / (h * h);
  r.rate_now = (a - out.desired_direction) / h;
  // Weighted by the path's speed as the other fast-path elements (fast_path_rate): a slow path (the
  // paper's 600 s spiral) gets nearly the paper's law, without the estimated rate's noise.
  const Vec3 m = fast_path_weight(pd_.speed(), params_.fast_path_rate) *
                 modal_shaping(r, modal_.rate(), omega_, modal_damping_ratio(), params_.modal);
  const Vec3 step = shaping_primed_ ? Vec3(Vec3(sol.tip_rotation.col(2)).cross(m - previous_shaping_)) : Vec3::Zero();
  previous_shaping_ = m;
  shaping_primed_ = true;
  return step;
}

// Lines 5, 7, 9/12: x_cntr by PD (eqs. 17–18), then the new inputs by eq. (19) on J_q within the
// bounds of eq. (20), rate- and magnitude-limited (input_step). The paper's base is w_a (measured);
// by default the previous command is the base, which keeps the flow loop's lag out of this
// integrator (docs/controller.md).
std::string Controller::command_inputs(const rod::RodSolution& sol, const ActuatedModel::Linearisation& lin, double dt,
                                       ControllerOutput& out) {
  const Vec3 x_cntr =
      pd_.correction(out.observed_direction, out.desired_direction, dt, law_gains()) + shaping_step(sol, out);
  if (first_cycle_) previous_command_ = out.jet_force_observed;
  InputStepOptions o;
  o.damping = params_.damping;
  o.allocation_weight = params_.allocation_weight;
  o.max_force_step = params_.max_force_rate * dt;
  o.max_force = params_.max_force;
  o.length = model_.rod().length();
  const InputVector& base = params_.integrate_from_measured ? out.jet_force_observed : previous_command_;
  const InputStep step = input_step(sol.tip_rotation, lin, x_cntr, base, model_.lower(), model_.upper(), o);
  if (!step.ok) return step.message;
  previous_command_ = step.q;
  out.jet_force_command = round_corners(step.q, lin, dt);
  out.force_reachable = step.bound_cost <= params_.unreachable_tolerance;
  out.wrench_command = model_.tip_wrench(out.jet_force_command);
  return "";
}

// allocation_smoothing: the step's inputs with their corners rounded along the jets' common
// mode n: q + a n. At w = 1 the target of a is c − y₀ (round_allocation: q's least common mode plus
// the log-sum-exp amount at the scale σ ‖f‖, f the step's tip wrench with moments as forces at the
// arm L, ‖f‖ at least modal/rounding_force by the modal law's weight); at speed weight w it is
// w (c − y₀), so a still reference gets q itself. a moves at most at max_common_force_rate (also
// when the option is off or the mode vanishes: it decays along the last mode) and stays within the
// bounds (−y₀ ≤ a: no jet below its lower bound; at most each jet's room to its q_max on a path, to
// reachable_force_fraction of it otherwise, or 0), which come before the rate. The next step's base
// stays the QP's own q (previous_command_), so the rounding does not accumulate.
InputVector Controller::round_corners(const InputVector& q, const ActuatedModel::Linearisation& lin, double dt) {
  bool fresh = false;  // a mode found this cycle (else only the excess along the last one)
  double scale = 0.0;
  if (params_.allocation_smoothing > 0.0) {
    InputVector jets = jets_.zeros();
    for (int i = 0; i < jets_.input_count(); ++i) jets[i] = jets_.is_jet(i) ? 1.0 : 0.0;
    const InputVector mode = jet_common_mode(lin.actuation, jets);
    if (!mode.isZero()) {
      common_mode_ = mode;
      fresh = true;
      rod::Vec6 wrench = lin.wrenches * q;  // the mode adds none
      wrench.tail<3>() /= model_.rod().length();
      // Under the modal law, at least its rounding_force: near the path's centre every jet would
      // switch on from zero flow, where the valves come late.
      scale = params_.allocation_smoothing * std::max(wrench.norm(), modal_weight() * params_.modal.rounding_force);
    }
  }
  if (common_mode_.size() != q.size()) return q;  // never rounded
  const AllocationRounding r = round_allocation(q, model_.lower(), common_mode_, scale);
  const double target = fresh ? (r.amount - r.excess) * fast_path_weight(pd_.speed(), params_.fast_path_rate) : 0.0;
  // The bounds along the mode: down to the least common mode; up to the first jet at q_max on a
  // path, at the operator reserve (reachable_force_fraction q_max) for any other source, as the
  // reference's own sets (Reference).
  const double top = reference_.source() == Source::kPath ? 1.0 : params_.reachable_force_fraction;
  double room = std::numeric_limits<double>::infinity();
  for (int i = 0; i < q.size(); ++i)
    if (common_mode_[i] > 0.0) room = std::min(room, (top * model_.upper()[i] - q[i]) / common_mode_[i]);
  const double step = params_.max_common_force_rate * dt;
  common_force_ = std::clamp(target, common_force_ - step, common_force_ + step);
  common_force_ = std::clamp(common_force_, -r.excess, std::max(room, 0.0));
  if (common_force_ == 0.0) return q;
  return q + common_force_ * common_mode_;
}

// Eq. (26) and the actuator feedback: flow for each jet force and the per-jet PI flow regulators;
// force actuators get their drive.
std::string Controller::actuate(const InputVector& flows, double dt, ControllerOutput& out) {
  out.flow_command = jets_.flows_for_forces(out.jet_force_command);
  out.valve_command = jets_.regulate(out.jet_force_command, out.flow_command, flows, dt);
  monitor_.record_flow_command(out.flow_command);
  return "";
}

// A complete cycle: the path's end finishes it (control goes on, holding the end point).
ControllerOutput Controller::finish_cycle(ControllerOutput out) {
  first_cycle_ = false;
  if (reference_.path_finished(t_last_)) state_ = ControllerState::kFinished;
  out.state = state_;
  last_output_ = out;
  return out;
}

// The actuation as at rest: no previous command; flow regulators and rounding at zero
// (start, stop, abort).
void Controller::reset_actuation() {
  common_force_ = 0.0;
  common_mode_.resize(0);
  previous_command_ = jets_.zeros();
  jets_.reset();
}

// Stops the jets and latches the reason until the next start().
ControllerOutput Controller::abort(ControllerOutput out, const std::string& why) {
  state_ = ControllerState::kAborted;
  abort_reason_ = why;
  reset_actuation();
  out.state = state_;
  out.reason = why;
  out.valve_command.setZero();
  out.jet_force_command.setZero();
  out.flow_command.setZero();
  out.wrench_command.setZero();
  return out;
}

}  // namespace control
}  // namespace hydrojet
