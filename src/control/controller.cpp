#include "hydrojet_control/control/controller.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "hydrojet_control/identification/free_vibration.h"

namespace hydrojet {
namespace control {

namespace {

/// An approach still unsettled this fraction of its timeout in is probed as it is (approach()).
constexpr double kProbeUnsettledAfter = 0.5;

/// Probes at most (a fit refused, as when a load's step disturbed the record, is probed once more when
/// the approach probes next: settled again, or half its timeout in).
constexpr int kProbeRuns = 2;

/// The reachable set of `model` with each actuator's bounds scaled by `force_fraction` (0, 1].
std::shared_ptr<const ReachableSet> sweep_reachable_set(RobotModel model, const ControllerOptions& options,
                                                        double force_fraction) {
  for (rod::Actuator& a : model.rod.actuators) {
    a.min_force *= force_fraction;
    a.max_force *= force_fraction;
  }
  ReachableSetOptions o;
  o.min_stability_margin = options.safety.min_stability_margin;
  return std::make_shared<const ReachableSet>(ReachableSet::compute(model, o));
}

/// `options`, or std::invalid_argument naming the key.
const ControllerOptions& validated(const ControllerOptions& options) {
  if (std::string err = options.validate(); !err.empty()) throw std::invalid_argument(err);
  return options;
}

/// 1 for each input of `jets` that is a water jet, 0 for a force actuator.
InputVector jet_mask(const JetActuation& jets) {
  InputVector mask = jets.zeros();
  for (int i = 0; i < jets.input_count(); ++i) mask[i] = jets.is_jet(i) ? 1.0 : 0.0;
  return mask;
}

/// The same regions, field by field.
bool same_regions(const std::vector<KeepOutRegion>& a, const std::vector<KeepOutRegion>& b) {
  auto same = [](const KeepOutRegion& x, const KeepOutRegion& y) {
    return x.surface.type == y.surface.type && x.surface.point == y.surface.point &&
           x.surface.normal == y.surface.normal && x.surface.radii == y.surface.radii &&
           x.surface.inside == y.surface.inside && x.margin == y.margin;
  };
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), same);
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

Controller::Controller(const RobotModel& model, const ControllerOptions& options)
    : Controller(
          model, options,
          make_direction_law(validated(options).control_law, options.pd, options.modal, options.safety.sample_period)) {
}

Controller::Controller(const RobotModel& model, const ControllerOptions& options, std::unique_ptr<DirectionLaw> law)
    : options_(validated(options)),
      model_(model),
      jets_(model_.rod(), model.nozzle, model.flow),
      monitor_(options.safety, jets_.input_count()),
      law_(std::move(law)),
      rounding_(model_, jet_mask(jets_)),
      previous_command_(jets_.zeros()),
      path_reachable_(sweep_reachable_set(model, options, 1.0)),
      reachable_(options.limits.reachable_force_fraction == 1.0
                     ? path_reachable_
                     : sweep_reachable_set(model, options, options.limits.reachable_force_fraction)),
      reference_(options.limits.max_angular_rate, reachable_, path_reachable_),
      approach_(options.approach),
      previous_duty_(jets_.zeros()),
      previous_flows_(jets_.zeros()),
      contact_(options.contact, jets_.input_count(), model_.upper().size() ? model_.upper().maxCoeff() : 1.0),
      last_inputs_(jets_.zeros()) {
  if (!law_) throw std::invalid_argument("control_law: no law given");
  law_->set_pd(options.pd);
  // What the rig's identification file says (identification/file), else the first guesses.
  const PlantIdentity& known = options.identification.known;
  const bool known_valves =
      known.mode_identified && static_cast<int>(known.valve_time_constants_s.size()) == jets_.input_count();
  const InputVector top_flows = jets_.flows_for_forces(model_.upper());
  for (int i = 0; i < jets_.input_count(); ++i)
    valve_lags_.emplace_back(known_valves && known.valve_time_constants_s[i] > 0.0
                                 ? known.valve_time_constants_s[i]
                                 : options.modal.actuator_lag + model.flow.lead_time,
                             std::max(top_flows[i], 1e-9));
  identity_.valve_time_constants_s.assign(jets_.input_count(), 0.0);
  identity_.valve_plays.assign(jets_.input_count(), 0.0);
  if (known_valves && known.valves_identified && known.valve_plays.size() == known.valve_time_constants_s.size())
    identity_.valve_plays = known.valve_plays;  // inverted from the start, until the flows name them again
  identity_.tip_mass_scale = options.modal.tip_mass_scale;
  identity_.damping_time = options.modal.damping_time;
  if (known.mode_identified) {  // measured on this rig already: not probed again
    identity_.mode_identified = true;
    identity_.tip_mass_scale = known.tip_mass_scale;
    identity_.damping_time = known.damping_time;
    probed_ = true;
  }
  identity_.rod_tip_mass_scale = identity_.tip_mass_scale;
  identity_.rod_damping_time = identity_.damping_time;
  known_valves_ = known_valves && known.valves_identified;
  reference_.set_max_path_rate(options.limits.max_path_rate);
  tip_map_ = make_keep_out({});
  if (!options.keep_out.empty()) reference_.set_keep_out(make_keep_out(options.keep_out));
}

std::shared_ptr<const KeepOut> Controller::make_keep_out(const std::vector<KeepOutRegion>& regions) const {
  // Over the paths' set (full q_max): it holds the operator targets' set too.
  return std::make_shared<const KeepOut>(regions, model_.rod().tip_radius, path_reachable_);
}

void Controller::set_keep_out(std::shared_ptr<const KeepOut> keep_out) {
  options_.keep_out = keep_out ? keep_out->regions() : std::vector<KeepOutRegion>();
  reference_.set_keep_out(keep_out && !keep_out->regions().empty() ? std::move(keep_out) : nullptr);
}

void Controller::start(double t) {
  state_ = ControllerState::kRunning;
  abort_reason_.clear();
  t_start_ = t;
  t_last_ = t;
  first_cycle_ = true;
  monitor_.reset();
  law_->reset();
  reset_actuation();
  probe_.cancel();
  probe_pending_ = probe_unsettled_ = false;
  contact_.reset();
  was_in_contact_ = false;
  wall_since_ = -1.0;
  held_off_wall_ = held_ = false;
  if (fit_waiting_) probed_ = false;  // a start before the fit came back: probe again
  fit_waiting_ = job_ready_ = fit_delivered_ = false;
  if (!commands_pending_) start_configured_path(t);
  commands_pending_ = false;
}

void Controller::stop() {
  state_ = ControllerState::kIdle;
  reset_actuation();
  commands_pending_ = false;
}

void Controller::set_options(const ControllerOptions& options) {
  validated(options);
  std::shared_ptr<const KeepOut> keep_out;
  const bool new_regions = !same_regions(options.keep_out, options_.keep_out);
  if (new_regions) keep_out = make_keep_out(options.keep_out);
  std::unique_ptr<DirectionLaw> law =
      options.control_law == law_->kind()
          ? nullptr
          : make_direction_law(options.control_law, options.pd, options.modal, options.safety.sample_period);
  law_->set_pd(options.pd);
  if (law) law_ = std::move(law);
  options_ = options;
  monitor_.set_options(options.safety);
  reference_.set_max_angular_rate(options.limits.max_angular_rate);
  reference_.set_max_path_rate(options.limits.max_path_rate);
  approach_.set_options(options.approach);
  contact_.set_options(options.contact);
  if (new_regions) set_keep_out(std::move(keep_out));
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
  if (options_.path.type == PathType::kSpiral)
    reference_.follow(make_spiral(options_.path), t, Reference::PathStart::kJump);
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

  const double dt = first_cycle_ ? options_.safety.sample_period : in.t - t_last_;
  if (!std::isfinite(in.t) || dt < 0.0) return abort(out, "time went backwards (dt = " + std::to_string(dt) + " s)");
  if (dt == 0.0) return last_output_;  // a repeated tick at the same time: nothing new to do
  t_last_ = in.t;
  out.path_time = in.t - t_start_;

  // Sensor health and flow faults: stale, missing or non-finite data, or a jet that does not follow
  // its command, stops the jets.
  if (std::string why = monitor_.check_sensors(in); !why.empty()) return abort(out, why);
  if (std::string why = monitor_.check_flow_faults(in.flows, dt); !why.empty()) return abort(out, why);
  observe_plant(in, dt);

  if (std::string why = observe_jets(in, out); !why.empty()) return abort(out, why);  // Algorithm 1, line 4
  const rod::RodSolution sol = solve_model(out.jet_force_observed);                   // line 6
  out.solver_converged = sol.converged;
  if (std::string why = monitor_.check_solver(sol); !why.empty()) return abort(out, why);
  if (!sol.converged) return hold(out, in.flows, dt);
  out.model_tip_rotation = sol.tip_rotation;
  const ActuatedModel::Linearisation lin = model_.linearise();  // C^b (eq. 14) and J_q of line 6
  if (std::string why = check_stability(lin, out); !why.empty()) return abort(out, why);
  sense_contact(in, sol, lin, out);
  learn_keep_out_offset(in, out, dt);

  track_reference(in, sol, dt, out);
  react_to_contact(out);
  rejoin_reference(out, dt);
  if (std::string why = monitor_.check_oscillation(out.error_geodesic); !why.empty()) return abort(out, why);
  last_compliance_ = lin.body_compliance;
  last_inputs_ = out.jet_force_observed;

  if (probe_pending_) begin_probe(in.t, sol, lin);
  if (probing())
    probe(in, sol, out);
  else if (std::string why = command_inputs(in, sol, lin, dt, out); !why.empty())
    return abort(out, why);
  if (std::string why = actuate(in.flows, dt, out); !why.empty()) return abort(out, why);
  learn_reach(dt, out);
  previous_duty_ = out.valve_command;
  previous_flows_ = in.flows;
  duty_known_ = true;
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
  if (reference_.on_path()) law_->skip(dt);  // a path moves with time: the next cycle sees two cycles' motion
  out.jet_force_command.setZero();
  out.flow_command = jets_.flows_for_forces(out.jet_force_observed);
  out.valve_command = jets_.regulate(out.jet_force_observed, out.flow_command, flows, dt);
  previous_duty_ = out.valve_command;
  previous_flows_ = flows;
  duty_known_ = true;
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
  const bool closed = options_.mode == LoopMode::kClosed;
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
  out.reach_limited = reference_.reach_limited();
  out.kept_out = reference_.kept_out();
  out.time_scale = reference_.time_scale();
  out.error_geodesic = geodesic_error(out.desired_direction, out.measured_direction);
  out.error_pitch_yaw = pitch_yaw_error(out.desired_direction, out.measured_direction);
  approach(in.t, out);
}

// A path being approached: its clock starts once the tip has settled on its first direction; one
// that does not settle is a failure, and the reference holds where it is.
void Controller::approach(double t, ControllerOutput& out) {
  out.approaching = reference_.approaching();
  if (out.approaching && (probe_.active() || probe_pending_)) {  // the probe holds the path's clock
  } else if (out.approaching) {
    const double loop_error = geodesic_error(out.desired_direction, out.observed_direction);
    const bool probe_first = options_.identification.probe && !probed_ && options_.mode == LoopMode::kClosed;
    switch (approach_.update(t, reference_.at_path_start(), loop_error, out.measured_direction)) {
      case ApproachMonitor::Verdict::kSettled:
        if (probe_first) {
          probe_pending_ = true;  // the probe first (update), then the path
          probe_unsettled_ = false;
          break;
        }
        reference_.begin_path(t);
        out.approaching = false;
        break;
      case ApproachMonitor::Verdict::kFailed:
        out.path_failure = "approach: " + approach_.failure();
        reference_.hold();
        out.source = reference_.source();
        out.approaching = false;
        break;
      case ApproachMonitor::Verdict::kSettling:
        // A tip that rings on the law's first guesses (a mode lighter or less damped than they
        // say) is measured as it is, half the timeout in; the approach then starts over on the fit.
        if (probe_first && approach_.settling_for(t) >= std::max(options_.approach.settle_time,
                                                                 kProbeUnsettledAfter * options_.approach.timeout))
          probe_pending_ = probe_unsettled_ = true;
        break;
      default: break;
    }
  }
  out.approach_time = reference_.approach_time();
  if (reference_.path()) out.path_time = reference_.path_time(t);  // other sources: time since start
}

// Line 5: x_cntr by the law (DirectionLaw), then lines 7, 9/12: the new inputs by eq. (19) on J_q
// within the bounds of eq. (20), rate- and magnitude-limited (input_step), based on the previous
// command (which keeps the flow loop's lag out of this integrator, docs/controller.md), and their
// corners rounded (CornerRounding).
std::string Controller::command_inputs(const ControllerInputs& in, const rod::RodSolution& sol,
                                       const ActuatedModel::Linearisation& lin, double dt, ControllerOutput& out) {
  LawCycle cycle;
  cycle.t = in.t;
  cycle.dt = dt;
  cycle.closed_loop = options_.mode == LoopMode::kClosed;
  cycle.observed = out.observed_direction;
  cycle.desired = out.desired_direction;
  cycle.measured = out.measured_direction;
  cycle.measured_stamp = std::min(in.tip_stamp, in.t);
  cycle.model = &model_;
  cycle.solution = &sol;
  cycle.linearisation = &lin;
  cycle.observed_inputs = &out.jet_force_observed;
  cycle.reference = &reference_;
  cycle.saturated = !first_cycle_ && at_bound(previous_command_);
  cycle.near_bound = !first_cycle_ && at_bound(previous_command_, kNearBound);
  const Vec3 x_cntr = law_->correction(cycle);
  out.law_weight = law_->supervisor_weight();
  out.mode_swing = law_->swing();
  if (first_cycle_) previous_command_ = out.jet_force_observed;
  InputStepOptions o;
  o.damping = options_.allocation.damping;
  o.allocation_weight = options_.allocation.weight;
  o.max_force_step = options_.limits.max_force_rate * dt;
  o.max_force = options_.limits.max_force;
  o.length = model_.rod().length();
  const InputStep step =
      input_step(sol.tip_rotation, lin, x_cntr, previous_command_, model_.lower(), model_.upper(), o);
  if (!step.ok) return step.message;
  law_->bounded(step.lost, sol.tip_rotation.col(2));
  previous_command_ = step.q;
  CornerRounding::Cycle rounding;
  rounding.speed_weight = law_->fast_path_weight();
  rounding.min_force = law_->rounding_force();
  // A jet may rise to its q_max on a path, to the operator reserve for any other source (as the
  // reference's own sets, Reference).
  rounding.top = reference_.source() == Source::kPath ? 1.0 : options_.limits.reachable_force_fraction;
  rounding.dt = dt;
  out.jet_force_command = rounding_.apply(step.q, lin, rounding, options_.allocation);
  out.force_reachable = step.bound_cost <= options_.safety.unreachable_tolerance;
  out.wrench_command = model_.tip_wrench(out.jet_force_command);
  return "";
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
  duty_known_ = false;
  rounding_.reset();
  previous_command_ = jets_.zeros();
  jets_.reset();
}

// What the plant shows every cycle: the tracker's latency (a new sample's stamp) and each jet's lag
// (the duty held since the last cycle against the flows then and now). The modal law takes them.
void Controller::observe_plant(const ControllerInputs& in, double dt) {
  new_tracker_sample_ = in.tip_valid && in.tip_stamp != last_stamp_;
  if (new_tracker_sample_) {
    latency_.add(in.t, in.tip_stamp);
    last_stamp_ = in.tip_stamp;
  }
  identity_.tracker_latency_s = latency_.latency();
  bool identified = true;
  for (int i = 0; i < jets_.input_count(); ++i) {
    if (!jets_.is_jet(i)) continue;
    if (duty_known_) valve_lags_[i].add(previous_flows_[i], previous_duty_[i], in.flows[i], dt);
    identity_.valve_time_constants_s[i] = valve_lags_[i].time_constant();
    if (valve_lags_[i].identified()) identity_.valve_plays[i] = valve_lags_[i].play();
    if (valve_lags_[i].identified() || known_valves_)
      jets_.set_play(i, law_->inverts_play() ? kPlayInverted * identity_.valve_plays[i] : 0.0);
    identified = identified && valve_lags_[i].identified();
  }
  identity_.valves_identified = identified || known_valves_;
  law_->adopt(identity_, jets_.flow_regulator());
}

// The reach the jets show (closed loop, not while probing): a jet at its top with the error staying
// outward limits the reference there, a plant ringing under the paper's law everywhere (learned_reach.h).
void Controller::learn_reach(double dt, const ControllerOutput& out) {
  if (options_.mode != LoopMode::kClosed || probe_.active()) return;
  reference_.learned_reach().update(at_bound(out.jet_force_command), out.measured_direction, out.desired_direction, dt);
  reference_.learned_reach().ring(law_->plant_rings(), out.desired_direction, dt);
}

// The external tip force from the tracker's pose against the model's, and the detector (contact.h).
void Controller::sense_contact(const ControllerInputs& in, const rod::RodSolution& sol,
                               const ActuatedModel::Linearisation& lin, ControllerOutput& out) {
  ContactCycle c;
  c.t = in.t;
  c.new_sample = new_tracker_sample_;
  c.stamp = std::min(in.tip_stamp, in.t);
  c.measured_rotation = in.tip_rotation;
  c.measured_position = in.tip_position;
  c.model_rotation = sol.tip_rotation;
  c.model_position = sol.tip_position;
  c.compliance = lin.ok ? lin.body_compliance : rod::Mat6::Constant(std::nan(""));
  c.inputs = out.jet_force_observed;
  if (lin.ok) c.input_wrenches = lin.wrenches;
  c.pressing = held_off_wall_;  // last cycle's hold_off_wall only (the lead cap and the rejoin do not press)
  // The supervisor's weight holds its last value where it does not run (open loop, the probe and its fit).
  c.ringing = options_.mode == LoopMode::kClosed && !probing() && law_->supervisor_weight() < 1.0;
  out.contact = contact_.update(c);
}

// Where the tracker puts the tip against where the model puts it at the same measured direction, low-
// passed (kKeepOutOffsetTime) in free space, with or without regions: they are checked with it, so that a plant
// softer or bent otherwise than the model keeps its capsule out too. Frozen in contact (the surface
// moves the tip off the model) and without a tip position.
void Controller::learn_keep_out_offset(const ControllerInputs& in, const ControllerOutput& out, double dt) {
  if (!new_tracker_sample_ || out.contact.in_contact || !in.tip_position.allFinite()) return;
  const Vec3 raw = in.tip_position - tip_map_->tip_position(in.tip_rotation.col(2));
  if (!raw.allFinite() || raw.norm() > kMaxKeepOutOffset) return;
  const Vec3 offset = reference_.keep_out_offset();
  reference_.set_keep_out_offset(offset + std::min(1.0, dt / kKeepOutOffsetTime) * (raw - offset));
}

// In contact (contact/reaction): the law observes where the tip would be without the force (its
// integral does not wind into the surface), and the reference goes no deeper past the tip, along
// the turn the estimated normal makes, than comply's push would put it; tangentially it slides,
// leading the tip by no more than max_force would turn it (a normal read turned is not trusted).
// hold and retreat aim at or off the surface and end a path. A push under which
// the tip gives way (half the turn it makes in free space, since the onset) is a load, not a
// surface: it is handed to the estimator's load and the law compensates it as before.
void Controller::react_to_contact(ControllerOutput& out) {
  const ContactState& c = out.contact;
  const bool onset = c.in_contact && !was_in_contact_;
  was_in_contact_ = c.in_contact;
  held_off_wall_ = false;
  if (!c.in_contact) {
    remember_wall(out);
    return;
  }
  const Vec3 x = out.measured_direction;
  const Vec3 turn = contact_.deflection(c.normal);  // how a unit force along the normal turns the tip
  const Vec3 free_side = turn - turn.dot(x) * x;
  const double compliance = free_side.norm();  // [rad/N]
  if (!(compliance > 1e-9)) return;            // a force along the tip's axis: nothing to turn away from
  const Vec3 d = free_side / compliance;
  const double target = ContactOptions::kComplyFraction * options_.contact.max_force;
  const double push = std::max(c.reading.dot(c.normal), 0.0);  // as the detector reads it: the model's turn
  if (onset) {
    contact_onset_ = x;
    if (options_.contact.reaction != ContactReaction::kComply) {
      const double back = options_.contact.reaction == ContactReaction::kRetreat
                              ? std::max(2.0 * compliance * options_.contact.max_force, 0.05)
                              : 0.0;
      if (reference_.source() == Source::kPath)
        out.path_failure = std::string("contact: the tip met a surface (") + to_string(options_.contact.reaction) + ")";
      reference_.aim(x + back * d, Source::kDirection);
      commanded();
    }
  }
  const double give = (x - contact_onset_).dot(d);  // the tip's give to the free side since the onset
  if (push > 0.5 * c.threshold && give > std::max(kLoadTravel, 0.5 * compliance * push) && contact_.load_fits()) {
    contact_.take_as_load(t_last_);
    out.contact = contact_.state();
    was_in_contact_ = false;
    wall_since_ = -1.0;
    return;
  }
  if (options_.mode == LoopMode::kClosed) out.observed_direction = (x - c.deflection).normalized();
  wall_x_ = x;
  wall_d_ = d;
  wall_allowed_ = compliance * target;
  wall_since_ = t_last_;
  held_off_wall_ = hold_off_wall(out);
  // Whatever the normal's estimate (an uncalibrated model reads it turned), the reference leads the
  // tip by no more than max_force would turn it, in any direction.
  const Vec3 axis = x.cross(out.desired_direction);
  const double lead = geodesic_error(x, out.desired_direction), most = compliance * options_.contact.max_force;
  if (lead > most && axis.norm() > 1e-12) set_desired(out, Eigen::AngleAxisd(most, axis.normalized()) * x);
}

// After a release the reference stays off the surface where it was met (no deeper past the tip's
// last direction in contact than comply's push, the allowance growing at kWallRelax) until it needs
// no holding: a path still behind the wall neither presses into it again at once nor jumps back.
void Controller::remember_wall(ControllerOutput& out) {
  if (wall_since_ < 0.0) return;
  wall_allowed_ += kWallRelax * std::max(t_last_ - wall_since_, 0.0);
  wall_since_ = t_last_;
  held_off_wall_ = hold_off_wall(out);
  if (!held_off_wall_) wall_since_ = -1.0;  // the reference is free of it
}

// The reference no deeper past wall_x_ along wall_d_ than wall_allowed_ (tangentially free: the tip
// slides); false when it needed no holding.
bool Controller::hold_off_wall(ControllerOutput& out) {
  const double depth = (wall_x_ - out.desired_direction).dot(wall_d_);  // the reference's, past the tip
  if (depth <= wall_allowed_) return false;
  set_desired(out, (out.desired_direction + (depth - wall_allowed_) * wall_d_).normalized());
  return true;
}

// Once the contact no longer holds the reference, it returns to where its source (path, operator)
// has gone meanwhile at kRejoinRate instead of jumping there: a wall whose normal was read wrongly
// (an uncalibrated model) held it along the wrong side, and the jump at the release rang the rod
// into the abort.
void Controller::rejoin_reference(ControllerOutput& out, double dt) {
  if (out.contact.in_contact || out.contact_clip_angle > 0.0) {
    held_ = true;
    held_direction_ = out.desired_direction;
    return;
  }
  if (!held_) return;
  const Vec3 axis = held_direction_.cross(out.desired_direction);
  const double gap = geodesic_error(held_direction_, out.desired_direction);
  const double step = kRejoinRate * std::max(dt, 0.0);
  if (gap <= step || !(axis.norm() > 1e-12)) {
    held_ = false;
    return;
  }
  set_desired(out, Eigen::AngleAxisd(step, axis.normalized()) * held_direction_);
  held_direction_ = out.desired_direction;
}

// The reference moved by the contact's handling: how far, and the errors against it.
void Controller::set_desired(ControllerOutput& out, const Vec3& direction) {
  out.contact_clip_angle += geodesic_error(out.desired_direction, direction);
  out.desired_direction = direction;
  out.error_geodesic = geodesic_error(out.desired_direction, out.measured_direction);
  out.error_pitch_yaw = pitch_yaw_error(out.desired_direction, out.measured_direction);
}

// A jet commanded to the learned reach's saturation (97 % of its q_max) or more: the forces have no
// authority left that way.
bool Controller::at_bound(const InputVector& command, double margin) const {
  const double saturation = reference_.learned_reach().options().saturation - margin;
  for (int i = 0; i < jets_.input_count() && i < command.size(); ++i)
    if (model_.upper()[i] > 0.0 && command[i] >= saturation * model_.upper()[i]) return true;
  return false;
}

// The modes' options: the modal law's, with the fill identified (or its first guess).
ModalOptions Controller::mode_options() const {
  ModalOptions o = options_.modal;
  o.tip_mass_scale = identity_.tip_mass_scale;
  return o;
}

// The probe starts at the settled inputs (mode_probe.h); a probe that cannot start says why and the
// path begins.
void Controller::begin_probe(double t, const rod::RodSolution& sol, const ActuatedModel::Linearisation& lin) {
  probe_pending_ = false;
  probed_ = true;
  const ModalModel modes = !lin.ok || has_body_mass(model_.rod())
                               ? lateral_modes(model_.solver(), last_inputs_, rod::TipWrench(), mode_options())
                               : lateral_modes(model_.rod(), lin.body_compliance, mode_options());
  InputStepOptions o;
  o.damping = options_.allocation.damping;
  o.allocation_weight = options_.allocation.weight;
  o.max_force_step = options_.limits.max_force;
  o.max_force = options_.limits.max_force;
  o.length = model_.rod().length();
  const double a = options_.identification.probe_amplitude;
  const Vec3 axes[4] = {a * sol.tip_rotation.col(0), -a * sol.tip_rotation.col(0), a * sol.tip_rotation.col(1),
                        -a * sol.tip_rotation.col(1)};
  InputVector turns[4];
  std::string error = modes.ok ? "" : modes.error;
  for (int k = 0; k < 4 && error.empty(); ++k) {
    const InputStep s =
        input_step(sol.tip_rotation, lin, axes[k], previous_command_, model_.lower(), model_.upper(), o);
    if (!s.ok) error = s.message;
    turns[k] = s.q;
  }
  if (!error.empty()) {
    identity_.mode_error = "probe: " + error;
    if (!probe_unsettled_) reference_.begin_path(t);  // unsettled: the approach goes on (settles or fails)
    return;
  }
  probe_inputs_ = last_inputs_;
  ++probe_runs_;
  probe_.begin(t, previous_command_, turns, model_.lower(), model_.upper(), sol.tip_rotation, modes.frequency(0));
}

// A cycle of the probe: its inputs, the record; at its end the fit and the law told.
void Controller::probe(const ControllerInputs& in, const rod::RodSolution& sol, ControllerOutput& out) {
  out.approaching = true;
  if (probe_.active()) {
    probe_.record(sol.tip_rotation.col(2), out.measured_direction);
    if (probe_.done(in.t)) {
      ProbeJob job;
      job.record = probe_.finish(options_.safety.sample_period, latency_.latency());
      job.omega_guess = probe_.omega_guess();
      job.robot = model_.rod();
      job.inputs = probe_inputs_;
      job.tip_mass_scale = identity_.tip_mass_scale;
      job.index = probe_runs_;
      if (fit_inline_) {
        adopt_probe_result(job.run());
      } else {
        job_ = std::move(job);
        job_ready_ = fit_waiting_ = true;
        fit_wait_start_ = in.t;
      }
    }
  } else if (fit_delivered_ || in.t - fit_wait_start_ > 2.0) {  // waiting for the owner's fit
    ProbeJob::Result result = delivered_result_;
    if (!fit_delivered_) result.mode.ok = false, result.mode.error = "no fit came back within 2 s";
    adopt_probe_result(result);
  }
  out.jet_force_command = probe_.active() ? probe_.inputs(in.t) : previous_command_;
  previous_command_ = out.jet_force_command;
  out.wrench_command = model_.tip_wrench(out.jet_force_command);
}

bool Controller::take_probe_job(ProbeJob* job) {
  if (!job_ready_) return false;
  *job = std::move(job_);
  job_ready_ = false;
  return true;
}

void Controller::deliver_probe_result(const ProbeJob::Result& result) {
  if (!fit_waiting_ || result.index != probe_runs_) return;  // a restart or a new probe since: of nothing now
  delivered_result_ = result;
  fit_delivered_ = true;
}

// The probe's fit: the capsule's fill and the damping time the law takes (or why not), and the
// dynamic rod's; the path's clock starts once the tip has settled again (approach), the chirp's
// ringing and the law's reset over.
void Controller::adopt_probe_result(const ProbeJob::Result& result) {
  const identification::ModeFit& fit = result.mode;
  fit_waiting_ = job_ready_ = fit_delivered_ = false;
  identity_.mode_identified = fit.ok;
  identity_.mode_error = fit.ok ? "" : "probe: " + fit.error;
  if (!fit.ok && probe_runs_ < kProbeRuns) probed_ = false;  // again, when the approach probes next
  if (fit.ok) {
    identity_.tip_mass_scale = result.tip_mass_scale;
    identity_.damping_time = result.damping_time;
    identity_.rod_tip_mass_scale = result.rod_ok ? result.rod_tip_mass_scale : identity_.tip_mass_scale;
    identity_.rod_damping_time = result.rod_ok ? result.rod_damping_time : identity_.damping_time;
    if (!result.rod_ok) identity_.mode_error = "probe: " + result.rod_error;
  }
  law_->adopt(identity_, jets_.flow_regulator());
  law_->reset();
  approach_.reset();
}

// The mode about the present equilibrium: the robot's dynamic rod's free vibration at the jets'
// forces, with the fill and damping time that reproduce the probe's fit (or the first guesses); the
// modal model's where the rod has none.
PlantIdentity Controller::identity() const {
  PlantIdentity id = identity_;
  const identification::ModeFit free = identification::free_vibration_mode(
      robot_dynamics(model_.rod(), id.rod_tip_mass_scale, id.rod_damping_time), last_inputs_);
  if (free.ok) {
    id.mode_hz = free.hz();
    id.damping_ratio = free.zeta;
    return id;
  }
  const ModalModel modes = has_body_mass(model_.rod())
                               ? lateral_modes(model_.solver(), last_inputs_, rod::TipWrench(), mode_options())
                               : lateral_modes(model_.rod(), last_compliance_, mode_options());
  if (modes.ok) {
    id.mode_hz = modes.frequency(0) / (2.0 * M_PI);
    id.damping_ratio = 0.5 * modes.frequency(0) * id.damping_time;
  }
  return id;
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
