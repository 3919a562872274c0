// Options of the PD resolved-rates controller (paper §4, eqs. 17–20, Algorithm 1): loop mode, gains,
// limits, safety thresholds and the path. Their defaults equal config/controller.yaml (checked by
// test_controller); validate() enforces the ranges of cfg/Controller.cfg for the live gains.
// ROS-free (Eigen only).
#pragma once

#include <string>

#include "hydrojet_control/control/approach.h"
#include "hydrojet_control/control/modal_law.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

enum class LoopMode { kClosed, kOpen };
const char* to_string(LoopMode m);

/// What the controller does at start: follow the spiral of `path` (§7.1), or hold the measured direction.
enum class PathType { kSpiral, kNone };
const char* to_string(PathType t);

/// The law that turns the error into inputs: the paper's (eqs. 17–20 with the fast-path elements), or
/// the model-based one (modal_law.h) on a path whose clock runs, the paper's for every other source.
enum class ControlLaw { kPapers, kModal };
const char* to_string(ControlLaw l);

/// Gains, limits and safety thresholds. validate() names the first bad field.
struct ControllerOptions {
  LoopMode mode = LoopMode::kClosed;
  ControlLaw control_law = ControlLaw::kModal;
  ModalLawOptions modal;  ///< the modal law's gains and estimator (modal_law.h)
  double kp = 3.0;        ///< K_p of eq. (17) [1/s]: fraction of the direction error corrected per second
  double kd = 0.0;        ///< K_d of eq. (17) [-]: weight of the error change per step
  /// K_i [1/s²]: the integral of the direction error (for fast paths): the law of eq. (17) integrates the
  /// tip force, so it is type 1 and a path at speed v leaves an error ≈ (1 − gain ratio)·v/K_p when
  /// the model's gain differs from the plant's; K_i makes it type 2 (no steady error on a ramp).
  /// Weighted by the reference's speed (fast_path_rate), with its leak the law is nearly type 2: the
  /// ramp error becomes (1 − gain ratio)·v / (K_p + K_i w / ((1 − w) K_p)), 7× smaller than K_p's
  /// alone at 0.3 rad/s with the defaults, 1.7× at 0.1 rad/s; fast_path_rate 0 gives type 2.
  double ki = 6.0;
  double max_integral = 0.1;    ///< |∫x_err dt| is kept below this [rad s] (anti-windup)
  double feedforward = 1.0;     ///< weight of the path's own motion per step [-] (0 = pure PD)
  double damping = 0.02;        ///< μ of the damped pseudo-inverse of eq. (19) [rad/N]
  double max_force = 0.30;      ///< magnitude limit of the commanded tip force [N]
  double max_force_rate = 1.0;  ///< rate limit of the commanded tip force [N/s]
  /// v₀ [rad/s] of the fast-path elements: K_i and allocation_smoothing act with the weight
  /// w = v²/(v² + v₀²) of the reference's speed v (fast_path_weight()); the integral leaks at
  /// (1 − w) K_p. A moving path (the ramp the integral is for) gets them nearly whole; a slow one (the
  /// paper's 600 s spiral, w ≤ 0.04) nearly the paper's law, without the integral's hunting through
  /// the valves' hysteresis; a reference that has stopped, the paper's law once the integral has
  /// leaked away (1/K_p). 0: both act at every speed.
  double fast_path_rate = 0.1;
  double max_angular_rate = 0.25;  ///< the reference moves toward a new target at most this fast [rad/s]
  /// The reachable set is swept with this fraction of each jet's q_max: authority kept in reserve for
  /// the closed loop (model mismatch, valves that saturate below their nominal flow) [-], in (0, 1].
  double reachable_force_fraction = 0.8;
  double allocation_weight = 1e-6;  ///< λ of eq. (20) [-]
  /// While the reference moves, the corners of the bounded allocation are rounded [-]: along the
  /// jets' common mode (inputs the rod does not feel: jet_common_mode()) the inputs take the least
  /// common mode plus a smooth maximum of the jets' margins over their lower bounds
  /// (round_allocation()) of scale σ ‖f‖, σ this and f the step's tip force; by the weight w
  /// (fast_path_rate), the offset moving at most at max_common_force_rate. Each
  /// time the tip force turns past a jet the box QP's active set changes and every jet's force rate
  /// steps; through the jets' unequal valve lags and the thrust law's √ that step is a tip-force
  /// transient that kicks the first bending mode. Rounded, the jets' forces are smooth
  /// functions of the tip force; with the scale in proportion to ‖f‖, the same function of its
  /// direction at every magnitude (a corner is rounded over the same angle), and nothing at f = 0.
  /// A reference that never moved: nothing (the paper's allocation, no water spent); one that has
  /// stopped: the offset decays at max_common_force_rate (fast_path_rate 0: w = 1 at every speed).
  /// 0: off. Force actuators: untouched.
  double allocation_smoothing = 0.3;
  /// The rounding's offset along the common mode changes at most this fast [N/s] (rising, and
  /// decaying when the reference stops). The jets' valves lag unequally (0.035–0.05 s), so a fast
  /// change of their common force is a tip-force kick: at 0.1 N/s (and at max_force_rate) the
  /// offset's removal when an operator target near the reachable set's edge was reached (tip
  /// force 0.21 N) rang the rod into a growing oscillation and an abort in a simulation of the
  /// rostest operator_clipped; 0.05 N/s did not there (the rostest itself also needs the operator
  /// reserve cap of Controller::round_corners). It costs nothing on the 20 s spiral but on A at 30°.
  double max_common_force_rate = 0.05;
  /// Base of the new wrench command: false = the previous command (default), true = the measured
  /// w_a as printed in Algorithm 1, line 9.
  bool integrate_from_measured = false;
  // Safety (§7.3 and the brief); see SafetyMonitor.
  double max_oscillation = 0.5;         ///< abort when the desired–measured tip angle exceeds this [rad]
                                        ///< (armed once the tip has come within the limit)
  double sample_period = 0.01;          ///< tracker and flow sample period [s]
  int stale_periods = 3;                ///< data older than stale_periods·sample_period is stale
  int max_solver_failures = 2;          ///< abort after this many non-converged solves in a row
  double min_stability_margin = 0.5;    ///< abort when σ_c (eq. 23) falls below this [N/m]
  double unreachable_tolerance = 1e-3;  ///< allocation residual [N] above which the force is out of reach
  double flow_fault_tolerance = 3e-6;   ///< |measured − commanded flow| that counts as a jet fault [m^3/s]
  double flow_fault_time = 0.5;         ///< a deviation twice the tolerance trips after this long [s]
                                        ///< (the excess over the tolerance is integrated)
  /// When an approached path's clock starts (approach.h): the tip settled on its first direction.
  ApproachOptions approach;
  PathType path_type = PathType::kSpiral;  ///< at start: the spiral `path`, or hold (kNone)
  SpiralPath path;

  /// Empty when valid, else "<field>: <what is wrong>". The gains and limits that
  /// dynamic_reconfigure may change must lie in the ranges of cfg/Controller.cfg.
  std::string validate() const;
};

}  // namespace control
}  // namespace hydrojet
