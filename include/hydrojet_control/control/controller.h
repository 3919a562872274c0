// PD resolved-rates control of the tip direction (paper §4, eqs. 17–20, Algorithm 1), closed loop
// with tracker feedback or open loop with the model's prediction (§7.3), guarded by the safety
// monitor. One cycle, update(), runs these named steps:
//   time and sensor checks (SafetyMonitor) → observe_jets (Algorithm 1, line 4) → solve_model
//   (line 6: equilibrium, C^b and the actuation Jacobian J_q, ActuatedModel) → solver and stability
//   checks → track_reference (x_des from the Reference: the operator's source, rate-limited and
//   clipped to the reachable set; x_obs) → oscillation check → command_inputs (line 5: the law,
//   DirectionLaw: the paper's or the modal law; lines 7, 9/12: input_step, eq. 19 on J_q and eq. 20's
//   bounds in one box QP, rate and magnitude limits; the corners rounded, CornerRounding) → actuate
//   (eq. 26, flow regulators: JetActuation) → finish_cycle.
// Any follower-actuated robot (segments, point loads, N actuators anywhere); the HydroJet's results are
// those of the tip-force formulation (resolved_rates.h).
// ROS-free (Eigen, the rod and actuation libraries). Time is passed in; nothing reads a clock.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "hydrojet_control/control/approach.h"
#include "hydrojet_control/control/contact.h"
#include "hydrojet_control/control/controller_io.h"
#include "hydrojet_control/control/controller_options.h"
#include "hydrojet_control/control/direction_law.h"
#include "hydrojet_control/control/jet_actuation.h"
#include "hydrojet_control/control/learned_reach.h"
#include "hydrojet_control/control/mode_probe.h"
#include "hydrojet_control/control/plant_identification.h"
#include "hydrojet_control/control/reachable_set.h"
#include "hydrojet_control/control/reference.h"
#include "hydrojet_control/control/resolved_rates.h"
#include "hydrojet_control/control/robot_model.h"
#include "hydrojet_control/control/safety_monitor.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

class Controller {
 public:
  /// Computes the reachable sets of `model` once, σ_c ≥ safety.min_stability_margin: the one for
  /// operator targets with jet forces up to limits.reachable_force_fraction · q_max, the one for
  /// path points with q_max (the same set when the fraction is 1). The law is the one
  /// options.control_law names (make_direction_law). std::invalid_argument naming the key when
  /// `options` is not valid.
  Controller(const RobotModel& model, const ControllerOptions& options);
  /// The same with the law given (its PD gains are options.pd's from then on).
  Controller(const RobotModel& model, const ControllerOptions& options, std::unique_ptr<DirectionLaw> law);

  /// Starts at time t (also after an abort or the end); jets start from zero. What drives: the
  /// commands given since the last stop or abort, else the configured path.type (the spiral from
  /// its start, or hold the measured direction).
  void start(double t);
  /// Stops: jets to zero, state idle; forgets the commands.
  void stop();

  // Operator commands (the latest wins; see Reference). Running: they take effect on the next
  // update() (a finished path goes back to running). Idle or aborted: kept for the next start().
  /// Follow `path` from time t [s]: by default approached first (its clock starts once the tip has
  /// settled on its first direction, approach.h) and clipped to the reachable set as operator
  /// targets are (an operator's path); the experiment follows its designed paths as the paper did.
  void follow(std::shared_ptr<const Path> path, double t, Reference::PathStart start = Reference::PathStart::kApproach,
              Reference::PathClip clip = Reference::PathClip::kOperator);
  /// Move to the fixed direction `target` (base frame, any length); kDirection or kLookAt. False,
  /// and nothing changes, when `target` is not finite or is zero (Reference::aim).
  bool aim(const Vec3& target, Source source);
  /// View rates (up, right) [rad/s] about the tip frame's +x, +y axes until time `until` [s]; kJoy or kKeyboard.
  void turn(const Eigen::Vector2d& up_right, Source source, double until);
  /// Hold the reference where it is.
  void hold();
  /// Commands were given while idle or aborted; start() will use them.
  bool commands_pending() const { return commands_pending_; }
  const Reference& reference() const { return reference_; }
  /// The set operator targets are clipped to (with the force reserve; the one rviz shows).
  const ReachableSet& reachable_set() const { return *reachable_; }
  /// The set path points are clipped to (full q_max).
  const ReachableSet& path_reachable_set() const { return *path_reachable_; }
  /// The same, shared (keep-out regions are built over it: KeepOut).
  std::shared_ptr<const ReachableSet> shared_path_reachable_set() const { return path_reachable_; }
  /// The capsule's contact sphere about the tip [m] (the robot description's tip.radius).
  double tip_radius() const { return model_.rod().tip_radius; }
  /// The reach the jets have shown on this plant (it clips both sets' targets).
  const LearnedReach& learned_reach() const { return reference_.learned_reach(); }

  /// Keep-out regions over this robot's reachable set (keep_out.h), for set_keep_out: const and
  /// thread-safe, so that a node builds them off the control loop. std::invalid_argument naming the
  /// key (keep_out[i]/…) when a region is invalid or they leave no direction free.
  std::shared_ptr<const KeepOut> make_keep_out(const std::vector<KeepOutRegion>& regions) const;
  /// The regions the reference keeps out of from the next cycle (null or empty: none).
  void set_keep_out(std::shared_ptr<const KeepOut> keep_out);

  /// Switches between closed and open loop (takes effect on the next update).
  void set_mode(LoopMode mode) { options_.mode = mode; }
  /// New gains, limits and keep-out regions (std::invalid_argument naming the key when not valid; nothing changes
  /// then); the state is kept. Another control_law starts a new law; the modal law's options are read at construction
  /// (and at a change of law) only.
  void set_options(const ControllerOptions& options);
  const ControllerOptions& options() const { return options_; }
  /// The law that acts.
  const DirectionLaw& law() const { return *law_; }
  ControllerState state() const { return state_; }
  /// Why it aborted (empty unless aborted).
  const std::string& abort_reason() const { return abort_reason_; }
  /// What the controller has measured of the plant (the mode at the last cycle's equilibrium).
  PlantIdentity identity() const;

  // The probe's fit (Ceres, then the dynamic rod: some 0.2 s) off the control loop: an owner with a
  // thread of its own (the node) calls set_fit_inline(false), takes each job the probe leaves, runs
  // it and hands its result back; meanwhile the jets hold and the path waits (2 s at most, then it
  // starts with the first guesses). By default the controller fits in the cycle the probe ends (the
  // experiment, tests).
  void set_fit_inline(bool inline_fit) { fit_inline_ = inline_fit; }
  /// A probe's record waits for its fit: moved into *job (run it with job->run()).
  bool take_probe_job(ProbeJob* job);
  /// The result of the job taken last; used on the next cycle.
  void deliver_probe_result(const ProbeJob::Result& result);
  /// Number of jets (entries of every InputVector in and out).
  int input_count() const { return jets_.input_count(); }

  /// One cycle of Algorithm 1. Call at the control rate with the latest samples.
  ControllerOutput update(const ControllerInputs& in);

  /// Backbone of the model at the last converged solve: segments+1 points [m], base frame.
  std::vector<Vec3> model_shape(int segments) const { return model_.shape(segments); }

  /// The model's forward kinematics at inputs q [N] (for open-loop prediction and tests).
  rod::RodSolution model_fk(const InputVector& q);

 private:
  // The steps of update(), in order. Those returning a string return the abort reason (empty: go on).
  ControllerOutput resting_output() const;
  std::string observe_jets(const ControllerInputs& in, ControllerOutput& out) const;
  rod::RodSolution solve_model(const InputVector& q);
  ControllerOutput hold(ControllerOutput out, const InputVector& flows, double dt);
  std::string check_stability(const ActuatedModel::Linearisation& lin, ControllerOutput& out) const;
  void start_configured_path(double t);
  void commanded();
  void track_reference(const ControllerInputs& in, const rod::RodSolution& sol, double dt, ControllerOutput& out);
  void approach(double t, ControllerOutput& out);
  void observe_plant(const ControllerInputs& in, double dt);
  /// The share of a valve's identified play its regulator inverts: an inverted play wider than the
  /// valve's acts as a relay and hunts (an exact inversion did, near the valves' dead zones).
  static constexpr double kPlayInverted = 0.8;
  void learn_reach(double dt, const ControllerOutput& out);
  void sense_contact(const ControllerInputs& in, const rod::RodSolution& sol, const ActuatedModel::Linearisation& lin,
                     ControllerOutput& out);
  void react_to_contact(ControllerOutput& out);
  void remember_wall(ControllerOutput& out);
  bool hold_off_wall(ControllerOutput& out);
  void rejoin_reference(ControllerOutput& out, double dt);
  static void set_desired(ControllerOutput& out, const Vec3& direction);
  void learn_keep_out_offset(const ControllerInputs& in, const ControllerOutput& out, double dt);
  static constexpr double kKeepOutOffsetTime = 1.0;  ///< [s] the tip offset's low-pass
  static constexpr double kMaxKeepOutOffset = 0.02;  ///< [m] larger: a tracker fault, not a model error
  /// A jet commanded to its saturation (less `margin`, a fraction of its bound) or more.
  bool at_bound(const InputVector& command, double margin = 0.0) const;
  /// The probe drives the jets, or its fit is awaited: the law does not run.
  bool probing() const { return probe_.active() || fit_waiting_; }
  static constexpr double kNearBound = 0.1;  ///< the modal law's authority returns below 0.87 of a bound
  void begin_probe(double t, const rod::RodSolution& sol, const ActuatedModel::Linearisation& lin);
  void probe(const ControllerInputs& in, const rod::RodSolution& sol, ControllerOutput& out);
  void adopt_probe_result(const ProbeJob::Result& result);
  ModalOptions mode_options() const;
  std::string command_inputs(const ControllerInputs& in, const rod::RodSolution& sol,
                             const ActuatedModel::Linearisation& lin, double dt, ControllerOutput& out);
  std::string actuate(const InputVector& flows, double dt, ControllerOutput& out);
  ControllerOutput finish_cycle(ControllerOutput out);
  ControllerOutput abort(ControllerOutput out, const std::string& why);
  void reset_actuation();

  ControllerOptions options_;
  ActuatedModel model_;  ///< equilibrium, C^b, J_q and stability at inputs q
  JetActuation jets_;
  SafetyMonitor monitor_;
  std::unique_ptr<DirectionLaw> law_;  ///< line 5: x_cntr from the error
  CornerRounding rounding_;
  InputVector previous_command_;  ///< the last step's inputs [N], before the rounding (the base of the next step)
  std::shared_ptr<const ReachableSet> path_reachable_;  ///< full q_max: path points
  std::shared_ptr<const ReachableSet> reachable_;       ///< with reserve: operator targets
  std::shared_ptr<const KeepOut> tip_map_;              ///< no regions: the model's tip position per direction
  Reference reference_;
  ApproachMonitor approach_;       ///< when a path's clock may start
  bool commands_pending_ = false;  ///< commands given while idle or aborted, for the next start()
  ControllerState state_ = ControllerState::kIdle;
  std::string abort_reason_;
  double t_start_ = 0.0;
  double t_last_ = 0.0;
  bool first_cycle_ = true;       ///< no complete cycle since start(): dt = sample_period, the step's base from q_obs
  ControllerOutput last_output_;  ///< returned again for a repeated tick at the same time

  // Identification of the plant present (plant_identification.h, mode_probe.h).
  PlantIdentity identity_;
  LatencyEstimator latency_;
  std::vector<ValveLagEstimator> valve_lags_;   ///< per actuator (used by the jets)
  InputVector previous_duty_, previous_flows_;  ///< the last cycle's valve command and measured flows
  bool duty_known_ = false;                     ///< previous_duty_ was commanded and held since
  double last_stamp_ = -1e300;                  ///< the tracker stamp last seen [s]
  ModeProbe probe_;
  bool probe_pending_ = false;    ///< an approached path settled: the probe starts this cycle
  bool probe_unsettled_ = false;  ///< ... or had not settled half its timeout in
  bool probed_ = false;           ///< the probe has run (once per controller), or the file gave the mode
  int probe_runs_ = 0;            ///< probes begun, a restart's included (a refused fit is probed once more)
  bool known_valves_ = false;     ///< the identification file gave every jet's lag
  bool fit_inline_ = true;        ///< set_fit_inline
  bool fit_waiting_ = false;      ///< the probe is over, its fit not yet adopted
  double fit_wait_start_ = 0.0;
  bool job_ready_ = false;  ///< job_ waits for take_probe_job
  ProbeJob job_;
  InputVector probe_inputs_;  ///< the jets' measured forces as the probe began
  bool fit_delivered_ = false;
  ProbeJob::Result delivered_result_;
  // Contact (contact.h).
  ContactEstimator contact_;
  bool new_tracker_sample_ = false;     ///< this cycle's tracker sample is new
  bool was_in_contact_ = false;         ///< the detector's flag at the last cycle
  Vec3 contact_onset_ = Vec3::UnitZ();  ///< the tip's direction when the present contact was flagged
  // Where the last contact held the reference back (hold_off_wall), relaxed after a release.
  Vec3 wall_x_ = Vec3::UnitZ();                ///< the tip's direction in contact
  Vec3 wall_d_ = Vec3::UnitX();                ///< the surface's free side as a turn of the tip (unit)
  double wall_allowed_ = 0.0;                  ///< [rad] how deep past wall_x_ the reference may go
  double wall_since_ = -1.0;                   ///< [s] the allowance's last update (negative: no wall)
  bool held_off_wall_ = false;                 ///< hold_off_wall moved the reference this cycle
  static constexpr double kWallRelax = 0.25;   ///< [rad/s] the allowance's growth after a release
  static constexpr double kLoadTravel = 0.03;  ///< [rad] the least give that can tell a load (react_to_contact)
  // Where the contact last held the reference (rejoin_reference): it returns to its source from there.
  bool held_ = false;
  Vec3 held_direction_ = Vec3::UnitZ();
  static constexpr double kRejoinRate = 1.0;  ///< [rad/s] faster than a path the law follows, slow enough not to ring
  rod::Mat6 last_compliance_ = rod::Mat6::Zero();  ///< C^b at the last cycle's equilibrium
  InputVector last_inputs_;                        ///< q_obs there [N]
};

}  // namespace control
}  // namespace hydrojet
