// The resolved-rates law of the paper, §4, eqs. (17)–(20) (Algorithm 1, lines 5 to 12): a PD
// correction plus feedforward on the tip-direction error, resolved into new actuator inputs through
// the damped pseudo-inverse of R^h J_q (the actuation Jacobian; R^h C^b W for tip actuators), bounded.
// ROS-free (Eigen, the rod and actuation libraries).
#pragma once

#include <Eigen/Core>
#include <string>

#include "hydrojet_control/control/robot_model.h"
#include "hydrojet_control/rod/rod_solver.h"

namespace hydrojet {
namespace control {

/// The fast-path elements' weight at the reference's speed `rate` [rad/s]: rate² / (rate² + min_rate²),
/// 1 when min_rate is 0 (PdOptions::fast_path_rate).
double fast_path_weight(double rate, double min_rate);

/// The PD's gains (`pd/` in the controller file): eq. (17) plus an integral for fast paths.
struct PdOptions {
  double kp = 3.0;  ///< K_p of eq. (17) [1/s]: fraction of the direction error corrected per second
  double kd = 0.0;  ///< K_d of eq. (17) [-]: weight of the error change per step
  /// K_i [1/s²] of the direction error's integral: it makes the law type 2 on a moving path (eq. 17
  /// alone leaves (1 − gain ratio)·v/K_p on a ramp); weighted by the path's speed, leaking as it slows.
  double ki = 6.0;
  double max_integral = 0.1;  ///< |∫x_err dt| is kept below this [rad s] (anti-windup)
  double feedforward = 1.0;   ///< weight of the path's own motion per step [-] (0 = pure PD)
  /// v₀ [rad/s]: the fast-path elements (K_i, the allocation's rounding, the modal law's shaping) act
  /// with w = v²/(v² + v₀²) of the reference's speed v; 0: whole at every speed.
  double fast_path_rate = 0.1;
  /// Empty when valid, else "<field>: <what is wrong>"; the live gains within cfg/Controller.cfg's bounds.
  std::string validate() const;
};

/// eqs. (17)–(18), Algorithm 1 line 5: x_cntr = PD(x_err) + feedforward. Remembers the previous
/// error and desired direction for the derivative and feedforward terms.
class DirectionPd {
 public:
  /// Starts afresh: the next step has neither a derivative nor a feedforward term.
  void reset() {
    primed_ = false;
    speed_ = 0.0;
    skipped_ = 0.0;
    held_axis_.setZero();
  }

  /// A cycle of dt [s] without a correction (the controller held its inputs): x_des's motion over it
  /// arrives with the next correction(), whose speed is then taken over both cycles (its feedforward
  /// moves the inputs by both, as none moved them on this one).
  void skip(double dt) {
    if (primed_ && dt > 0.0) skipped_ += dt;
  }

  /// x_err is the rotation vector taking the observed tip direction onto the desired one (both
  /// unit, base frame); returns
  ///   x_cntr = K_p dt x_err + K_i dt ∫w x_err dt + K_d (x_err − x_err,prev) + k_ff ∠(x_des,prev → x_des)   [rad],
  /// the rotation (base frame) the tip direction should make this step. dt [s]. w: fast_path_weight()
  /// of x_des's speed; the integral leaks at (1 − w) K_p. The gains are `gains`' (the modal law passes
  /// its own K_p and K_i).
  Vec3 correction(const Vec3& observed, const Vec3& desired, double dt, const PdOptions& gains);
  /// From the next correction() on, the error is not integrated outward along `axis` (a rotation
  /// vector; zero: along none): the inputs' bounds or the force limits took that motion from the last
  /// step (conditional integration, the integral's anti-windup at a jet's bound). Set every step.
  void hold_integral(const Vec3& axis) { held_axis_ = axis.norm() > 0.0 ? Vec3(axis.normalized()) : Vec3::Zero(); }
  /// The reference's speed over the last correction() [rad/s] (0 before the second).
  double speed() const { return speed_; }

 private:
  bool primed_ = false;
  Vec3 prev_error_ = Vec3::Zero();
  Vec3 prev_desired_ = Vec3::UnitZ();
  Vec3 integral_ = Vec3::Zero();   ///< ∫ w x_err dt [rad s]
  double speed_ = 0.0;             ///< x_des's speed over the last step [rad/s]
  double skipped_ = 0.0;           ///< time since the last correction, before this step [s] (skip)
  Vec3 held_axis_ = Vec3::Zero();  ///< hold_integral
};

/// For allocation_smoothing: the jets' common mode of the linearised rod: inputs on the jets
/// alone that move the tip by nothing to first order (the null space of J_q's jet columns; J_q:
/// tip twist per unit input), the one nearest to every jet equal, scaled to a largest entry of 1.
/// Zero when there is none that raises every jet (fewer jets than the rank of their tip motion, or
/// jets that cannot cancel). jets[i] ≠ 0: input i is a jet (force actuators are left out).
InputVector jet_common_mode(const rod::ActuationJacobian& actuation, const InputVector& jets);

/// Inputs q's corners rounded along the common mode n (jet_common_mode(), n_i > 0 on the jets it
/// covers). With the margins y_i = (q_i − lower_i)/n_i over those jets and y₀ their least (0 where
/// the box QP put a jet on its bound), q's least common mode is q − y₀ n (excess y₀), and the
/// rounding adds to it
///   c = scale · log Σ_i exp(−(y_i − y₀)/scale)   [N, at the jet with n_i = 1],
/// the log-sum-exp smooth maximum of the −y_i less their maximum −y₀: q − y₀ n + c n is a smooth
/// function of the tip force (at most scale · log m over the least common mode, m jets; c → 0 as
/// the other jets' margins grow). scale ≤ 0 (or NaN): c = 0, the least common mode.
struct AllocationRounding {
  double excess = 0.0;  ///< max(0, y₀): q's common mode above its least [N]
  double amount = 0.0;  ///< c [N]
};
AllocationRounding round_allocation(const InputVector& q, const InputVector& lower, const InputVector& mode,
                                    double scale);

/// The allocation's options (`allocation/` in the controller file): eq. (19)'s damping, eq. (20)'s
/// weight and the rounding of the bounded allocation's corners (CornerRounding).
struct AllocationOptions {
  double damping = 0.02;  ///< μ of the damped pseudo-inverse of eq. (19) [rad/N]
  double weight = 1e-6;   ///< λ of eq. (20) [-]
  /// σ [-]: while the reference moves, the corners of the bounded allocation are rounded along the
  /// jets' common mode at the scale σ ‖f‖ (f the step's tip force); 0: off (docs/controller.md).
  double smoothing = 0.3;
  /// The rounding's offset along the common mode changes at most this fast [N/s]: the valves lag
  /// unequally, so a fast change of the jets' common force is a tip-force kick.
  double max_common_force_rate = 0.05;
  /// Empty when valid, else "<field>: <what is wrong>"; damping within cfg/Controller.cfg's bounds.
  std::string validate() const;
};

/// The rounding of the bounded allocation's corners (AllocationOptions::smoothing): the step's
/// inputs q plus a n along the jets' common mode n. Each time the tip force turns past a jet the box
/// QP's active set changes and every jet's force rate steps, a tip-force transient through the jets'
/// unequal valve lags; rounded, the jets' forces are smooth functions of the tip force.
class CornerRounding {
 public:
  /// What the cycle gives the rounding besides the linearisation.
  struct Cycle {
    double speed_weight = 0.0;  ///< w of the reference's speed (fast_path_weight): the target's weight
    double min_force = 0.0;     ///< [N] the scale acts as if the tip force were at least this
    double top = 1.0;           ///< a jet may be raised to this fraction of its q_max
    double dt = 0.0;            ///< [s]
  };
  /// The inputs of `model` that are jets (jets[i] = 1, force actuators 0).
  CornerRounding(const ActuatedModel& model, const InputVector& jets);
  /// No offset, no mode (start, stop, abort).
  void reset();
  /// q rounded: the target of a is w (c − y₀) (round_allocation at the scale σ max(‖f‖, min_force),
  /// f the step's tip wrench with moments as forces at the arm L); a moves at most at
  /// max_common_force_rate (decaying along the last mode when the option is off or the mode vanishes)
  /// and stays within the bounds (no jet below its lower bound, none above top · q_max).
  InputVector apply(const InputVector& q, const ActuatedModel::Linearisation& lin, const Cycle& cycle,
                    const AllocationOptions& options);

 private:
  InputVector jets_, lower_, upper_;
  double length_;
  double common_force_ = 0.0;  ///< a: the offset along common_mode_ now [N]
  InputVector common_mode_;    ///< the jets' common mode last found (empty: none yet)
};

/// Limits and weights of one step of the law on the actuation Jacobian (from AllocationOptions and LimitOptions).
struct InputStepOptions {
  double damping = 0.02;            ///< μ of eq. (19) [rad/N], on the tip-force change
  double allocation_weight = 1e-6;  ///< λ of eq. (20) [-]: the smallest inputs among equally good ones
  double max_force_step = 0.01;     ///< bound on the step's tip-force change [N] (max_force_rate · dt)
  double max_force = 0.30;          ///< bound on the commanded tip force [N]
  double length = 0.09;             ///< L [m]: moments count as forces at this arm in the damping
};

struct InputStep {
  InputVector q;  ///< the new inputs [N], within [lower, upper]
  /// Tip force [N] that the input bounds cost: ‖W_f (q − q_free)‖ with q_free the step without
  /// bounds (0 when the step lies within reach; compared with unreachable_tolerance).
  double bound_cost = 0.0;
  /// The tip direction's change the bounds and limits took from the step [rad, base frame, ⊥ the
  /// tip direction]: M (q_free − q).
  Vec3 lost = Vec3::Zero();
  bool ok = false;
  std::string message;  ///< why not ok (the inputs are then the base, clamped into the bounds)
};

/// eq. (19) on the actuation Jacobian, Algorithm 1 lines 7 to 12 in input space: the tip
/// direction d turns by δd = ω × d = −d̂ R J_q,ω δq per input change δq, so with M = −d̂ R(L) J_q,ω
/// (3×N, rank ≤ 2: only the task, the tip direction, is resolved) the new inputs are
///   q = argmin_{lower ≤ q ≤ upper} ‖M (q − base) − x_cntr × d‖² + μ² ‖W̃ (q − base)‖² + λ ‖q‖²,
/// W̃ = the equivalent tip wrenches per input (lin.wrenches) with moments divided by L: the damped
/// pseudo-inverse (R^h J_q)^† restricted to the task and bounded in one exact box QP (bounded_allocation.h).
/// Then the step's tip-force change ‖W_f (q − base)‖ and the tip force ‖W_f q‖ are scaled into their
/// limits (the box contains base and 0, so q stays within it). For the HydroJet (J_q = C^b W, W the
/// jets' 6×3 wrench matrix, W q = (f_x, f_y, 0, ...)) the tip force W q takes exactly eq. (19)'s step,
/// δf = (MᵀM + μ²)⁻¹Mᵀ(x_cntr × d) on the force block of C^b, and q is eq. (20)'s allocation of it, as
/// long as no bound is active. base: the previous command (or w_a's inputs) [N], clamped into the box.
InputStep input_step(const Mat3& tip_rotation, const ActuatedModel::Linearisation& lin, const Vec3& x_cntr,
                     const InputVector& base, const InputVector& lower, const InputVector& upper,
                     const InputStepOptions& options);

}  // namespace control
}  // namespace hydrojet
