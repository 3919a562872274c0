#include "hydrojet_control/control/controller.h"

#include <cmath>

namespace hydrojet {
namespace control {

namespace {

/// The reachable set of `model` with each jet's q_max scaled by `force_fraction` (0, 1].
std::shared_ptr<const ReachableSet> sweep_reachable_set(RobotModel model, const ControllerOptions& params,
                                                        double force_fraction) {
  model.max_jet_force *= force_fraction;
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
    : actuated_(model.actuated),
      params_(params),
      jets_(model),
      solver_(model.rod, model.solver),
      monitor_(params, jets_.jet_count()),
      limiter_(params.max_force, params.max_force_rate),
      path_reachable_(sweep_reachable_set(model, params, 1.0)),
      reachable_(params.reachable_force_fraction == 1.0
                     ? path_reachable_
                     : sweep_reachable_set(model, params, params.reachable_force_fraction)),
      reference_(params.max_angular_rate, reachable_, path_reachable_) {}

void Controller::start(double t) {
  state_ = ControllerState::kRunning;
  abort_reason_.clear();
  t_start_ = t;
  t_last_ = t;
  first_cycle_ = true;
  limiter_.reset();
  monitor_.reset();
  pd_.reset();
  jets_.reset();
  if (!commands_pending_) start_configured_path(t);
  commands_pending_ = false;
}

void Controller::stop() {
  state_ = ControllerState::kIdle;
  limiter_.reset();
  jets_.reset();
  commands_pending_ = false;
}

void Controller::set_params(const ControllerOptions& p) {
  params_ = p;
  monitor_.set_options(p);
  limiter_.set_limits(p.max_force, p.max_force_rate);
  reference_.set_max_angular_rate(p.max_angular_rate);
}

void Controller::follow(std::shared_ptr<const Path> path, double t) {
  reference_.follow(std::move(path), t);
  commanded();
}

void Controller::aim(const Vec3& target, Source source) {
  reference_.aim(target, source);
  commanded();
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
    reference_.follow(make_spiral(params_.path), t, /*starts_at_path=*/true);
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

rod::RodSolution Controller::model_fk(const JetVector& q) { return solve_model(jets_.wrench(q)); }

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

  observe_jets(in.flows, out);                                    // Algorithm 1, line 4
  const rod::RodSolution sol = solve_model(out.wrench_observed);  // line 6
  out.solver_converged = sol.converged;
  if (std::string why = monitor_.check_solver(sol); !why.empty()) return abort(out, why);
  if (!sol.converged) return hold(out, in.flows, dt);
  out.model_tip_rotation = sol.tip_rotation;
  const rod::Compliance compliance = solver_.compliance();  // C^b of line 6 (eq. 14)
  if (std::string why = check_stability(compliance, out); !why.empty()) return abort(out, why);

  track_reference(in, sol, dt, out);
  if (std::string why = monitor_.check_oscillation(out.error_geodesic); !why.empty()) return abort(out, why);

  if (std::string why = command_force(sol, compliance, dt, out); !why.empty()) return abort(out, why);
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

// Algorithm 1, line 4: w_a = A q_obs, with q_obs from measured flow by the thrust equation (26).
void Controller::observe_jets(const JetVector& flows, ControllerOutput& out) const {
  out.jet_force_observed = jets_.forces_from_flows(flows);
  out.wrench_observed = jets_.wrench(out.jet_force_observed);
}

// Line 6: forward kinematics at the tip wrench w_a (eqs. 6, 9, 12, 14); C^b follows from
// solver_.compliance().
rod::RodSolution Controller::solve_model(const rod::Vec6& wrench) {
  rod::TipWrench w;
  w.force = wrench.head<3>();
  w.moment = wrench.tail<3>();
  return solver_.solve(w);
}

// The solver did not converge (fewer times in a row than max_solver_failures): no new force this
// cycle; the flow regulators keep the jets at the flows of the observed jet forces.
ControllerOutput Controller::hold(ControllerOutput out, const JetVector& flows, double dt) {
  out.jet_force_command.setZero();
  out.flow_command = jets_.flows_for_forces(out.jet_force_observed);
  out.valve_command = jets_.regulate(out.flow_command, flows, dt);
  last_output_ = out;
  return out;
}

// Elastic stability of the model's equilibrium (§4.1, eqs. 21–23), reported and checked.
std::string Controller::check_stability(const rod::Compliance& compliance, ControllerOutput& out) const {
  const rod::StabilityReport st = rod::stability(compliance.body, actuated_);
  out.stability_margin = st.margin;
  out.stability_eig_min = st.eig_min;
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
  if (first_cycle_) reference_.start(out.observed_direction, t_start_);
  out.desired_direction = reference_.advance(in.t, dt, tip_frame);
  out.source = reference_.source();
  out.clipped = reference_.clipped();
  out.clip_angle = reference_.clip_angle();
  out.error_geodesic = geodesic_error(out.desired_direction, out.measured_direction);
  out.error_pitch_yaw = pitch_yaw_error(out.desired_direction, out.measured_direction);
}

// Lines 5, 7 and 9/12 up to the wrench: x_cntr by PD (eqs. 17–18), ẇ^b by eq. (19), and the new
// force = base + ẇ^b, rate- and magnitude-limited. The paper's base is w_a (measured); by default
// the previous command is the base, which keeps the flow loop's lag out of this integrator
// (docs/controller.md).
std::string Controller::command_force(const rod::RodSolution& sol, const rod::Compliance& compliance, double dt,
                                      ControllerOutput& out) {
  const Vec3 x_cntr = pd_.correction(out.observed_direction, out.desired_direction, dt, params_);
  const Eigen::Vector2d df = force_change(sol.tip_rotation, compliance.body, x_cntr, params_.damping);
  const Eigen::Vector2d measured = out.wrench_observed.head<2>();
  if (first_cycle_) limiter_.reset(measured);
  const Eigen::Vector2d base = params_.integrate_from_measured ? measured : limiter_.previous();
  const Eigen::Vector2d f = limiter_.limit(base + df, dt);
  if (!f.allFinite()) return "control: non-finite force command";
  out.wrench_command.setZero();
  out.wrench_command.head<2>() = f;
  return "";
}

// eq. (20) (line 12): bounded allocation over the jets; then the actuator feedback: flow for each
// jet force by eq. (26) and the per-jet PI flow regulators.
std::string Controller::actuate(const JetVector& flows, double dt, ControllerOutput& out) {
  const actuation::AllocationResult alloc = jets_.allocate(out.wrench_command.head<2>(), params_.allocation_weight);
  if (!alloc.ok) return "allocation: " + alloc.message;
  out.jet_force_command = alloc.q;
  out.force_reachable = alloc.residual_norm <= params_.unreachable_tolerance;
  out.flow_command = jets_.flows_for_forces(out.jet_force_command);
  out.valve_command = jets_.regulate(out.flow_command, flows, dt);
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

// Stops the jets and latches the reason until the next start().
ControllerOutput Controller::abort(ControllerOutput out, const std::string& why) {
  state_ = ControllerState::kAborted;
  abort_reason_ = why;
  jets_.reset();
  limiter_.reset();
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
