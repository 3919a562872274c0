#include "hydrojet_control/control/controller.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <sstream>

namespace hydrojet {
namespace control {

const char* to_string(LoopMode m) { return m == LoopMode::kClosed ? "closed" : "open"; }

const char* to_string(ControllerState s) {
  switch (s) {
    case ControllerState::kIdle: return "idle";
    case ControllerState::kRunning: return "running";
    case ControllerState::kFinished: return "finished";
    case ControllerState::kAborted: return "aborted";
  }
  return "unknown";
}

std::string ControllerParams::validate() const {
  auto bad = [](const char* field, double v, const char* rule) {
    std::ostringstream os;
    os << field << ": " << rule << ", got " << v;
    return os.str();
  };
  auto finite_nonneg = [](double v) { return std::isfinite(v) && v >= 0.0; };
  auto finite_pos = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!finite_nonneg(kp)) return bad("kp", kp, "must be finite and >= 0");
  if (!finite_nonneg(kd)) return bad("kd", kd, "must be finite and >= 0");
  if (!finite_nonneg(feedforward)) return bad("feedforward", feedforward, "must be finite and >= 0");
  if (!finite_pos(damping)) return bad("damping", damping, "must be finite and > 0");
  if (!finite_pos(max_force)) return bad("max_force", max_force, "must be finite and > 0");
  if (!finite_pos(max_force_rate)) return bad("max_force_rate", max_force_rate, "must be finite and > 0");
  if (!finite_nonneg(allocation_weight)) return bad("allocation_weight", allocation_weight, "must be finite and >= 0");
  if (!finite_pos(max_oscillation)) return bad("max_oscillation", max_oscillation, "must be finite and > 0");
  if (!finite_pos(sample_period)) return bad("sample_period", sample_period, "must be finite and > 0");
  if (stale_periods < 1) return bad("stale_periods", stale_periods, "must be >= 1");
  if (max_solver_failures < 1) return bad("max_solver_failures", max_solver_failures, "must be >= 1");
  if (!finite_nonneg(min_stability_margin))
    return bad("min_stability_margin", min_stability_margin, "must be finite and >= 0");
  if (!finite_pos(unreachable_tolerance))
    return bad("unreachable_tolerance", unreachable_tolerance, "must be finite and > 0");
  if (!finite_pos(flow_fault_tolerance))
    return bad("flow_fault_tolerance", flow_fault_tolerance, "must be finite and > 0");
  if (!finite_pos(flow_fault_time)) return bad("flow_fault_time", flow_fault_time, "must be finite and > 0");
  if (!finite_pos(path.duration)) return bad("path.duration", path.duration, "must be finite and > 0");
  if (!(path.theta_start >= 0 && path.theta_start <= M_PI / 2))
    return bad("path.theta_start", path.theta_start, "must lie in [0, pi/2]");
  if (!(path.theta_end >= 0 && path.theta_end <= M_PI / 2))
    return bad("path.theta_end", path.theta_end, "must lie in [0, pi/2]");
  if (!std::isfinite(path.phi_start)) return bad("path.phi_start", path.phi_start, "must be finite");
  if (!std::isfinite(path.phi_end)) return bad("path.phi_end", path.phi_end, "must be finite");
  return "";
}

Controller::Controller(const ControllerModel& model, const ControllerParams& params)
    : model_(model), params_(params), jet_map_(model.jets), solver_(model.rod, model.solver), regulators_(model.flow) {}

void Controller::start(double t) {
  state_ = ControllerState::kRunning;
  abort_reason_.clear();
  t_start_ = t;
  t_last_ = t;
  first_cycle_ = true;
  prev_force_cmd_.setZero();
  solver_failures_ = 0;
  oscillation_armed_ = false;
  flow_fault_integral_.setZero();
  last_flow_command_.setZero();
  regulators_.reset();
}

void Controller::stop() {
  state_ = ControllerState::kIdle;
  prev_force_cmd_.setZero();
  regulators_.reset();
}

ControllerOutput Controller::abort(ControllerOutput out, const std::string& why) {
  state_ = ControllerState::kAborted;
  abort_reason_ = why;
  regulators_.reset();
  prev_force_cmd_.setZero();
  out.state = state_;
  out.reason = why;
  out.valve_command.setZero();
  out.jet_force_command.setZero();
  out.flow_command.setZero();
  out.wrench_command.setZero();
  return out;
}

rod::RodSolution Controller::model_fk(const Vec3& q) {
  rod::TipWrench w;
  const rod::Vec6 wa = jet_map_.wrench(q);
  w.force = wa.head<3>();
  w.moment = wa.tail<3>();
  return solver_.solve(w);
}

ControllerOutput Controller::update(const ControllerInputs& in) {
  ControllerOutput out;
  out.state = state_;
  out.reason = abort_reason_;
  if (state_ == ControllerState::kIdle || state_ == ControllerState::kAborted) return out;  // jets at zero

  const double dt = first_cycle_ ? params_.sample_period : in.t - t_last_;
  if (!std::isfinite(in.t) || dt < 0.0) return abort(out, "time went backwards (dt = " + std::to_string(dt) + " s)");
  if (dt == 0.0) return last_output_;  // a repeated tick at the same time: nothing new to do
  t_last_ = in.t;
  out.path_time = in.t - t_start_;

  // Sensor health: stale, missing or non-finite data stops the jets.
  const double stale_after = params_.stale_periods * params_.sample_period + 1e-9;
  if (!in.tip_valid) return abort(out, "tracker: no valid tip pose");
  if (in.t - in.tip_stamp > stale_after)
    return abort(out, "tracker: tip pose stale (" + std::to_string(in.t - in.tip_stamp) + " s old)");
  if (!in.tip_rotation.allFinite()) return abort(out, "tracker: non-finite tip pose");
  if (!in.flow_valid) return abort(out, "flow: no valid flow sample");
  if (in.t - in.flow_stamp > stale_after)
    return abort(out, "flow: samples stale (" + std::to_string(in.t - in.flow_stamp) + " s old)");
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(in.flows[i]) || in.flows[i] < 0.0)
      return abort(
          out, "flow: jet " + std::to_string(i + 1) + " reading invalid (" + std::to_string(in.flows[i]) + " m^3/s)");

  // Actuator fault: a jet whose measured flow stays far from the flow it was commanded (a valve stuck
  // open or closed, a blocked line) cannot be controlled; the flow loop would only wind up. The
  // excess deviation beyond the tolerance is integrated, so that a gross fault trips sooner than a
  // marginal one: trip when ∫(|ΔQ| − tol)⁺ dt ≥ tol · flow_fault_time.
  for (int i = 0; i < 3; ++i) {
    const double excess = std::abs(in.flows[i] - last_flow_command_[i]) - params_.flow_fault_tolerance;
    flow_fault_integral_[i] = excess > 0.0 ? flow_fault_integral_[i] + excess * dt : 0.0;
    if (flow_fault_integral_[i] >= params_.flow_fault_tolerance * params_.flow_fault_time)
      return abort(out, "flow: jet " + std::to_string(i + 1) + " does not follow its command (measured " +
                            std::to_string(in.flows[i]) + " m^3/s, commanded " + std::to_string(last_flow_command_[i]) +
                            " m^3/s): valve stuck or line blocked");
  }

  // Algorithm 1, line 4: w_a = A q_obs, with q_obs from measured flow by the thrust equation (26).
  for (int i = 0; i < 3; ++i) out.jet_force_observed[i] = actuation::force_from_flow(in.flows[i], model_.nozzle);
  out.wrench_observed = jet_map_.wrench(out.jet_force_observed);

  // Line 6: forward kinematics and C^b at w_a (eqs. 6, 9, 12, 14).
  rod::TipWrench wa;
  wa.force = out.wrench_observed.head<3>();
  wa.moment = out.wrench_observed.tail<3>();
  const rod::RodSolution sol = solver_.solve(wa);
  out.solver_converged = sol.converged;
  if (!sol.converged) {
    if (++solver_failures_ >= params_.max_solver_failures)
      return abort(out, "model: rod solver did not converge " + std::to_string(solver_failures_) + " times in a row (" +
                            sol.message + ")");
    // Hold the previous command for one cycle.
    out.jet_force_command.setZero();
    const Vec3 q_hold = out.jet_force_observed;
    for (int i = 0; i < 3; ++i) out.flow_command[i] = actuation::flow_from_force(q_hold[i], model_.nozzle);
    out.valve_command = regulators_.update(out.flow_command, in.flows, dt);
    last_output_ = out;
    return out;
  }
  solver_failures_ = 0;
  const rod::Compliance C = solver_.compliance();
  const rod::StabilityReport st = rod::stability(C.body, model_.actuated);
  out.stability_margin = st.margin;
  out.stability_eig_min = st.eig_min;
  out.model_tip_rotation = sol.tip_rotation;
  if (!C.ok || !st.ok) return abort(out, "model: compliance not finite");
  if (st.eig_min <= 0.0)
    return abort(out, "stability: equilibrium unstable (min Re eig S = " + std::to_string(st.eig_min) + ")");
  if (st.margin < params_.min_stability_margin)
    return abort(out, "stability: sigma_c = " + std::to_string(st.margin) + " N/m below margin " +
                          std::to_string(params_.min_stability_margin));

  // Task space: desired, measured and model tip directions (base frame).
  out.desired_direction = params_.path.direction_at(out.path_time);
  out.measured_direction = in.tip_rotation.col(2).normalized();
  const Vec3 model_dir = sol.tip_rotation.col(2);
  out.observed_direction = params_.mode == LoopMode::kClosed ? out.measured_direction : model_dir;
  out.error_geodesic = geodesic_error(out.desired_direction, out.measured_direction);
  out.error_pitch_yaw = pitch_yaw_error(out.desired_direction, out.measured_direction);
  // §7.3: abort on oscillations larger than max_oscillation. The monitor arms once the tip is within
  // the limit of the commanded direction, so that a far-away static target can still be reached.
  if (out.error_geodesic <= params_.max_oscillation) oscillation_armed_ = true;
  if (oscillation_armed_ && out.error_geodesic > params_.max_oscillation)
    return abort(out, "oscillation: tip " + std::to_string(out.error_geodesic) +
                          " rad from the commanded direction (limit " + std::to_string(params_.max_oscillation) + ")");

  // eqs. (17)–(18): x_err as the rotation vector taking x_obs onto x_des; PD on it, plus the
  // path's own motion this step as feedforward.
  const Vec3 err = rotation_between(out.observed_direction, out.desired_direction);
  if (first_cycle_) {
    prev_error_ = err;
    prev_desired_ = out.desired_direction;
  }
  const Vec3 x_cntr = params_.kp * dt * err + params_.kd * (err - prev_error_) +
                      params_.feedforward * rotation_between(prev_desired_, out.desired_direction);
  prev_error_ = err;
  prev_desired_ = out.desired_direction;

  // eq. (19): ẇ^b = (R^h C^b)^† x_cntr on the actuated force columns. Only the change of the tip
  // direction matters, δd = ω × d = −d^ R(L) C^b_ω δf, so the map is projected onto the plane ⊥ d and
  // inverted with a damped pseudo-inverse (Levenberg–Marquardt damping μ near singularities).
  const Eigen::Matrix<double, 3, 2> J_omega = sol.tip_rotation * C.body.block<3, 2>(3, 0);
  const Eigen::Matrix<double, 3, 2> M = -so3::hat(model_dir) * J_omega;
  const Vec3 dd = x_cntr.cross(model_dir);
  const Eigen::Matrix2d H = M.transpose() * M + params_.damping * params_.damping * Eigen::Matrix2d::Identity();
  const Eigen::Vector2d df = H.ldlt().solve(M.transpose() * dd);

  // Algorithm 1, line 9/12: new force = base + ẇ^b, rate- and magnitude-limited. The paper's base
  // is w_a (measured); by default the previous command is the base, which keeps the flow loop's lag
  // out of this integrator (README, "Controller").
  if (first_cycle_) prev_force_cmd_ = out.wrench_observed.head<2>();
  Eigen::Vector2d f = (params_.integrate_from_measured ? out.wrench_observed.head<2>() : prev_force_cmd_) + df;
  Eigen::Vector2d step = f - prev_force_cmd_;
  const double max_step = params_.max_force_rate * dt;
  if (step.norm() > max_step) step *= max_step / step.norm();
  f = prev_force_cmd_ + step;
  if (f.norm() > params_.max_force) f *= params_.max_force / f.norm();
  if (!f.allFinite()) return abort(out, "control: non-finite force command");
  prev_force_cmd_ = f;
  first_cycle_ = false;
  out.wrench_command.setZero();
  out.wrench_command.head<2>() = f;

  // eq. (20): bounded allocation over the three jets.
  const actuation::AllocationResult alloc =
      actuation::allocate(jet_map_.planar(), f, Vec3::Zero(), model_.max_jet_force, params_.allocation_weight);
  if (!alloc.ok) return abort(out, "allocation: " + alloc.message);
  out.jet_force_command = alloc.q;
  out.force_reachable = alloc.residual_norm <= params_.unreachable_tolerance;

  // Actuator feedback: flow for each jet force by eq. (26), then the per-jet PI flow regulators.
  for (int i = 0; i < 3; ++i) out.flow_command[i] = actuation::flow_from_force(alloc.q[i], model_.nozzle);
  out.valve_command = regulators_.update(out.flow_command, in.flows, dt);
  last_flow_command_ = out.flow_command;

  if (params_.path.finished(out.path_time)) state_ = ControllerState::kFinished;
  out.state = state_ == ControllerState::kFinished ? ControllerState::kFinished : ControllerState::kRunning;
  last_output_ = out;
  return out;
}

}  // namespace control
}  // namespace hydrojet
