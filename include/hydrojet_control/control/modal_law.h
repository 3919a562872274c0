// The model-based law ("modal"): the paper's law is quasi-static; this one knows that the tip moves
// through the rod's first bending mode toward the equilibrium of the forces the jets make.
//
// Estimator. Per Cartesian component of the tip direction (base frame), with s the model's
// quasi-static direction at the measured actuator forces (the solve of Algorithm 1, line 6, at
// q_obs: the flow sensors measure the actuators, so their lag needs no state of its own):
//   ẏ = v,   v̇ = ω² (s + d − y) − 2ζω v,   ḋ = noise     (y the tip direction, d the model's error),
// a Kalman filter (the components share one covariance) estimates
// (y, v, d) from the tracker. ω is the first lateral mode (modal_model.h) at the current
// equilibrium with the capsule's expected fill; ζ = ω τ_kv / 2 (Kelvin–Voigt damping).
//
// Law. The paper's PD on the tracker (eq. 17, with its own gains: DirectionPd) plus the change,
// step to step, of a direction the forces should add quasi-statically, w·m with
//   m = (τ_a + 2ζ/ω) ṙ + (1/ω² + 2ζτ_a/ω) r̈ − k_v (v̂ − ṙ)/ω
// and w the fast-path weight of the path's speed (fast_path_rate: a slow path gets the paper's law),
// r the path ahead (its preview): the first two terms invert the mode and the flow loop's residual
// lag τ_a for the path's own motion (the feedforward of (1 + τ_a s)(1 + 2ζs/ω + s²/ω²), without its
// τ_a r⃛/ω² term), the last damps the mode on the estimated rate. Damped,
// the mode lets the PD's gains rise with the path's speed (to K_p 5, K_i 12: they ring the undamped
// rod; a slow path keeps the paper's gains, which let less of the tracker's noise through). ROS-free
// (Eigen).
#pragma once

#include <deque>
#include <utility>

#include <Eigen/Core>

#include "hydrojet_control/control/direction_law.h"
#include "hydrojet_control/control/modal_model.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

/// The modal law's options: the reduced model's (lateral_modes: the capsule's expected fill
/// tip_mass_scale, its inertia, the probes) and the law's own.
struct ModalLawOptions : ModalOptions {
  ModalLawOptions() { tip_mass_scale = 3.0; }  ///< water fills the capsule (the plants: ×1.5–4)
  /// K_p of the PD under the modal law on a plant whose tracker has no latency [1/s]; a latency L
  /// and a flow lag τ (identified) scale it by (T + τ_a)/(T + max(τ_a, τ) + L) (T the sample
  /// period, τ_a actuator_lag; modal_gains), never below the paper's ...
  double kp = 5.0;
  double ki = 12.0;  ///< ... and K_i, by that ratio squared [1/s²]
  /// v_s [rad/s]: the PD's gains move from the paper's law's (gains/*) to kp, ki with the weight
  /// v²/(v² + v_s²) of the reference's speed v (fast_path_weight); 0: kp, ki at every speed.
  double gain_speed = 0.25;
  double damping_gain = 0.3;  ///< k_v: feedback on ṙ − v̂, per ω [-]
  /// τ_a [s]: the flow loop's lag left after the regulators' lead; the shaping inverts it with the mode.
  double actuator_lag = 0.03;
  /// [N] the allocation's rounding acts as if the tip force were at least this, with the gain
  /// schedule's weight: the jets keep a common flow through the centre of a fast path (Controller).
  double rounding_force = 0.15;
  double damping_time = 0.02;      ///< τ_kv the law assumes: ζ = ω τ / 2 [s]
  double tracker_sigma = 0.0075;   ///< tracker noise per direction component [-]
  double velocity_noise = 0.5;     ///< process noise on v̇ [1/s^1.5] (unmodelled forces)
  double disturbance_noise = 0.1;  ///< random walk of d [1/√s] (the model error moves with the path)
  /// [rad] the supervisor: the tracking error's swing at the mode's frequency (ModalLaw::swing) above
  /// this falls back to the paper's law at once ...
  double ring_amplitude = 0.1;
  /// [s] ... which hands back over this time once the swing has stayed below half of it this long.
  double recover_time = 2.0;
  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};

/// The Kalman filter of the modal law (see above).
class ModalEstimator {
 public:
  bool initialised() const { return initialised_; }
  void reset() { initialised_ = false; }
  /// Starts at tracker direction z and model direction s: at rest, d = z − s, with the covariance
  /// diag(σ², (σω)², (0.03)²) (σ: tracker_sigma).
  void start(const Vec3& z, const Vec3& s, double omega, const ModalLawOptions& o);
  /// One step of dt [s] with the model's direction s held over it (mode ω [rad/s], ζ), then the
  /// update with the tracker's z (skipped when z is not finite).
  void step(const Vec3& s, const Vec3& z, double omega, double zeta, double dt, const ModalLawOptions& o);
  Vec3 direction() const { return x_.row(0).transpose(); }
  Vec3 rate() const { return x_.row(1).transpose(); }
  Vec3 model_error() const { return x_.row(2).transpose(); }
  /// Rows y, v, d; columns the base frame's x, y, z.
  const Eigen::Matrix3d& state() const { return x_; }
  /// The covariance of each component's (y, v, d).
  const Eigen::Matrix3d& covariance() const { return P_; }

 private:
  bool initialised_ = false;
  Eigen::Matrix3d x_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d P_ = Eigen::Matrix3d::Zero();
};

/// The PD's gains at full speed (kp, ki; the rest default) on a loop whose tracker lags by `latency`
/// [s] and whose flow loop lags by `flow_lag` [s] (identified; below actuator_lag counts as it): the
/// tuning's delay D₀ = T + τ_a (sample_period, actuator_lag) over the loop's D = T + max(τ_a,
/// flow_lag) + latency scales kp, so the crossover's phase lag k_p·D stays that of the tuning, and ki
/// by its square, so the PI's zero keeps its place under the crossover.
PdOptions modal_gains(const ModalLawOptions& o, double sample_period, double latency, double flow_lag = 0.0);
/// (T + τ_a) / (T + max(τ_a, flow_lag) + latency): how much of the law's own rise the loop's delays
/// leave; scales its PD gains (modal_gains) and its damping gain.
double lag_ratio(const ModalLawOptions& o, double sample_period, double latency, double flow_lag);

/// The lag [s] left of a valve of lag `valve_lag` [s] under its flow regulator: the proportional
/// part's loop gain K = kp / feedforward (a valve whose flow is linear in its duty up to 1 /
/// feedforward at full duty) shortens it to valve_lag / (1 + K), and the feedforward's lead takes
/// lead_time off.
double flow_loop_lag(double valve_lag, const actuation::FlowRegulatorOptions& flow);

/// The PD's gains at the gain schedule's `weight` in [0, 1]: from the paper's `pd` toward `top`
/// (modal_gains), never below the paper's (a loop too late for the modal law's rise keeps them).
PdOptions scheduled_gains(const PdOptions& pd, const PdOptions& top, double weight);

/// The (A, B) of one component's (y, v, d) over dt [s] with s held (exact: the exponential of the
/// augmented generator).
void modal_transition(double omega, double zeta, double dt, Eigen::Matrix3d* A, Eigen::Vector3d* B);

/// The path near now (base frame): ṙ and r̈ a step ahead, and ṙ now.
struct ReferenceMotion {
  Vec3 rate = Vec3::Zero();      ///< ṙ [1/s]
  Vec3 accel = Vec3::Zero();     ///< r̈ [1/s²]
  Vec3 rate_now = Vec3::Zero();  ///< ṙ now [1/s]
};

/// m = (τ_a + 2ζ/ω) ṙ + (1/ω² + 2ζτ_a/ω) r̈ − k_v (v̂ − ṙ_now)/ω: the direction the forces add to
/// the PD's (see above; τ_a = o.actuator_lag).
Vec3 modal_shaping(const ReferenceMotion& r, const Vec3& estimated_rate, double omega, double zeta,
                   const ModalLawOptions& o);

/// The modal law as a DirectionLaw: the estimator, the PD with its gain schedule, the shaping and the
/// rounding force. In open loop, and on every source but a path whose clock runs, the paper's law.
class ModalLaw : public DirectionLaw {
 public:
  /// The paper's gains `pd` (a slow path's), the modal law's `options`; sample_period [s] is the
  /// preview's step. std::invalid_argument naming the field when either is not valid.
  ModalLaw(const PdOptions& pd, const ModalLawOptions& options, double sample_period);
  void reset() override;
  Vec3 correction(const LawCycle& c) override;
  /// modal/rounding_force with the gain schedule's weight.
  double rounding_force() const override { return gain_weight() * options_.rounding_force; }
  ControlLaw kind() const override { return ControlLaw::kModal; }
  /// The identified fill and damping time replace modal/tip_mass_scale and modal/damping_time (their
  /// first guesses).
  void adopt(const PlantIdentity& identity, const actuation::FlowRegulatorOptions& flow) override;
  /// Where it drives (closed loop, on a path whose clock runs): near the dead zones, where the jets
  /// sit on an approach or a hold, the inverted play hunted (the path keeps a common flow).
  bool inverts_play() const override { return drives_; }
  const ModalLawOptions& options() const { return options_; }
  const ModalEstimator& estimator() const { return estimator_; }
  /// The tracking error's swing at the mode's frequency [rad] (the supervisor's measure).
  double swing() const override { return swing_; }
  /// The supervisor's share of the modal law in [0, 1]: 0 fell back to the paper's law (the mode
  /// rang, or a jet is at its bound).
  double supervisor_weight() const override { return supervisor_weight_ * authority_; }
  /// Fallen back to the paper's law, the swing's peak grew over the last 0.25 s window, past 1.2
  /// ring_amplitude: the paper's law does not calm it either (watch_fallback).
  bool plant_rings() const override { return plant_rings_; }
  /// Its PD's integral does not wind along what the bounds took (DirectionPd::hold_integral), under
  /// its own gains and the paper's alike (the supervisor's fall-back keeps the hold).
  void bounded(const Vec3& lost, const Vec3& d) override;
  /// [rad] a step's loss under this is not held: eq. (20)'s λ pulls the jets' common mode onto
  /// their lower bounds every step, which shifts the tip's step by some 1e-8 rad (λ 1e-6; 1e-7 at
  /// 1e-5); a jet at its top loses ~1e-3 rad a step at the reach's edge.
  static constexpr double kHeldLoss = 1e-5;

 private:
  void estimate(const LawCycle& c);
  void supervise(const LawCycle& c);
  void watch_fallback(double dt);
  void forget_fallback();
  void advance(ModalEstimator& e, double from, double to, const Vec3& z) const;
  double damping_ratio() const;
  double gain_weight() const;
  Vec3 shaping_step(const LawCycle& c);

  ModalLawOptions options_;
  double sample_period_;
  ModalEstimator estimator_;
  bool drives_ = false;  ///< this cycle: closed loop, on a running path, estimator started
  /// s, the model's direction at the measured inputs, from each cycle's time [s] on (the recent ones)
  std::deque<std::pair<double, Vec3>> inputs_;
  double time_ = 0.0;            ///< [s] of the estimator's last step: the stamp of the last tracker sample it took
  ModalEstimator now_;           ///< the estimator predicted from time_ to the cycle's time (the tracker's latency)
  bool shaping_primed_ = false;  ///< previous_damping_, previous_feedforward_ hold the last step's m
  Vec3 previous_damping_ = Vec3::Zero();      ///< m's damping at the last step
  Vec3 previous_feedforward_ = Vec3::Zero();  ///< m's feedforward at the last step
  double latency_ = 0.0;                      ///< the tracker's latency identified [s] (adopt)
  double flow_lag_ = 0.0;                     ///< the flow loop's lag from the valves' identified lags [s] (adopt)
  double omega_ = 0.0;                        ///< the first mode at the current equilibrium [rad/s] (0: none yet)
  double swing_ = 0.0;                        ///< [rad] (swing())
  double band_power_ = 0.0;                   ///< the band-passed error's mean square over ~0.1 s
  Vec3 band_x_[2], band_y_[2];                ///< the band-pass's last two inputs and outputs
  double supervisor_weight_ = 1.0;            ///< (supervisor_weight())
  double authority_ = 1.0;                    ///< 0 while a jet is held at its bound (supervise)
  double saturated_for_ = 0.0;                ///< [s] a jet has been at its bound
  double calm_for_ = 0.0;                     ///< [s] the swing has stayed below half of ring_amplitude
  double fallen_for_ = 0.0;                   ///< [s] into the current window of the fall-back (watch_fallback)
  double window_peak_ = 0.0;                  ///< [rad] the swing's peak in the current window
  double last_window_peak_ = 0.0;             ///< [rad] ... and in the last (0: none yet)
  bool plant_rings_ = false;                  ///< (plant_rings()): the last window's verdict (watch_fallback)
};

}  // namespace control
}  // namespace hydrojet
