// What the controller measures of the plant it has, online and in closed loop, instead of assuming
// it: the tracker's latency (its stamps), each jet's flow-loop lag (commanded duty against measured
// flow), and the first lateral mode's frequency and damping (the tip's motion against the model's
// quasi-static direction), carried to any equilibrium by the robot's dynamic rod. The modal law uses
// them (modal_law.h); the experiment reports them (`identified`). ROS-free (Eigen, Ceres).
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hydrojet_control/control/task_space.h"
#include "hydrojet_control/identification/mode_fit.h"
#include "hydrojet_control/rod/dynamic_rod.h"

namespace hydrojet {
namespace control {

/// What is known of the plant: identified online (the probe, the flow sensors, the stamps), or the
/// controller file's first guess until then. The experiment's `identified` and `plant_truth` carry
/// the four reported fields.
struct PlantIdentity {
  double mode_hz = 0.0;                        ///< the first lateral mode at the current equilibrium [Hz] (0: none yet)
  double damping_ratio = 0.0;                  ///< its damping ratio ζ [-]
  std::vector<double> valve_time_constants_s;  ///< per actuator: the flow's lag behind the duty [s] (0: not a jet)
  double tracker_latency_s = 0.0;              ///< from a pose's measurement to its arrival [s]
  std::vector<double> valve_plays;             ///< per actuator: the valve's play (backlash) [duty] (0: none known)
  // What the modal law takes from them.
  bool mode_identified = false;  ///< the probe's fit holds (else: the first guess)
  /// Why the probe's fit, or the dynamic rod's, did not hold (empty: both did, or no probe yet).
  std::string mode_error;
  double tip_mass_scale = 0.0;  ///< the capsule's effective fill: the model's mode equals the one measured [-]
  double damping_time = 0.0;    ///< τ_kv = 2ζ/ω [s]
  // What the robot's dynamic rod takes (robot_dynamics): the same mode at the probe's equilibrium.
  double rod_tip_mass_scale = 0.0;  ///< its capsule's fill [-]
  double rod_damping_time = 0.0;    ///< its Kelvin–Voigt time [s]
  bool valves_identified = false;   ///< every jet's lag has enough data
};

/// The robot's dynamic rod: its model's statics (segments, capsule, jets, gravity), the capsule's
/// mass times `tip_mass_scale`, Kelvin–Voigt damping of time `damping_time`, DynamicRodModel's
/// defaults for the rest (no drag). Its free vibration (identification::free_vibration_mode) gives
/// the mode about any equilibrium, the follower load's effect on its damping included.
rod::DynamicRodModel robot_dynamics(const rod::RodModel& robot, double tip_mass_scale, double damping_time);

/// The probe's fit, off the control loop (Controller::take_probe_job): the record's mode
/// (identification::fit_mode), then the fill and damping time with which the robot's dynamic rod
/// vibrates so at the probe's equilibrium (`inputs`): from the modal model's, rescaled by
/// ω² ∝ 1/fill and ζ ∝ τ for at most six rounds, until within 0.5 % and 2 %.
struct ProbeJob {
  identification::ModeRecord record;
  double omega_guess = 0.0;     ///< the model's mode where the probe ran [rad/s]
  rod::RodModel robot;          ///< the controller's model
  rod::InputVector inputs;      ///< the jets' measured forces as the probe began [N]
  double tip_mass_scale = 0.0;  ///< the fill omega_guess was computed with
  int index = 0;                ///< which of the controller's probes (a late result of an earlier one is dropped)
  struct Result {
    int index = 0;                 ///< the job's
    identification::ModeFit mode;  ///< the record's
    /// What the modal law takes when the mode holds: the fill and damping time of the modal model.
    double tip_mass_scale = 0.0, damping_time = 0.0;
    bool rod_ok = false;  ///< the dynamic rod reproduces it (else: why, in rod_error)
    std::string rod_error;
    double rod_tip_mass_scale = 0.0, rod_damping_time = 0.0;
  };
  Result run() const;
  /// [rad] the most of the record a fit may leave unexplained: three times the tracker's specified
  /// noise per axis (Aurora, 0.3°). A fit of an undisturbed probe leaves the noise (0.007–0.008 rad
  /// on the simulated plant); a load's step during the record leaves 0.02–0.05 rad.
  static constexpr double kMaxResidual = 3.0 * 0.3 * M_PI / 180.0;
};

/// The identification (`identification/` in the controller file).
struct IdentificationOptions {
  /// Probe the first mode once the tip has settled on the first approached path's first direction
  /// (mode_probe.h), before its clock starts.
  bool probe = true;
  double probe_amplitude = 0.02;  ///< [rad] the probe turns the tip by about this, quasi-statically
  /// The rig's identification file (`identify`; empty: none), relative to the controller file.
  std::string file;
  /// What that file holds (config::load_controller_options reads it): a mode identified there is
  /// not probed again.
  PlantIdentity known;
  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};

/// The tracker's latency: the median of now − stamp over the last kWindow new samples.
class LatencyEstimator {
 public:
  static constexpr int kWindow = 101;
  void reset() { count_ = 0, next_ = 0; }
  /// A sample stamped `stamp` arrived by `now` [s] (ignored when not finite or from the future).
  void add(double now, double stamp);
  double latency() const;  ///< [s], 0 before any sample
  int samples() const { return count_; }

 private:
  std::array<double, kWindow> delays_{};
  int count_ = 0, next_ = 0;
};

/// A valve's lag τ from its duty u and measured flow f, sampled every dt: an output-error fit of
///   f = L_τ[g(e)],   L_τ the first-order lag of time τ,
/// with g the valve's unknown static curve as piecewise-linear over the duty (kKnots hat functions)
/// and e the duty past the valve's play (a backlash of unknown width). For a play and τ fixed, f is
/// linear in g's knot values (each hat function filtered through the lag), so least squares gives
/// them and the residual; the play and τ of least residual win, τ refined by a parabola in log τ.
/// The sensor's noise is only in f, not in the regressors: no bias from it (a one-step recursive
/// fit read the lags 30 % short in closed loop, docs/controller.md).
class ValveLagEstimator {
 public:
  /// g on these duties: closer at small openings, where dead zones put the curve's kink.
  static constexpr int kKnots = 14;
  static constexpr double kKnotDuty[kKnots] = {0.0,  0.02, 0.04, 0.06, 0.08, 0.1,  0.13,
                                               0.17, 0.22, 0.3,  0.4,  0.55, 0.75, 1.0};
  static constexpr int kPlays = 9;                          ///< play widths 0, kPlayStep, ..., 0.04 [duty]
  static constexpr double kPlayStep = 0.005;                ///< [duty]
  static constexpr int kLags = 12;                          ///< τ on a log grid from kMinLag to kMaxLag
  static constexpr double kMinLag = 0.015, kMaxLag = 0.25;  ///< [s]
  static constexpr int kRefreshEvery = 4;                   ///< one play's solves every this many samples
  /// prior_lag [s]: the estimate until the data say otherwise; max_flow [m^3/s]: the flows' scale.
  ValveLagEstimator(double prior_lag = 0.04, double max_flow = 1.6e-5);
  void reset();
  /// Flow `flow` [m^3/s] measured dt [s] after the duty `duty` was commanded at flow `previous_flow`.
  /// Bounded work: the fits' sums every call, one play's solves every kRefreshEvery calls.
  void add(double previous_flow, double duty, double flow, double dt);
  /// τ [s]: the fit's once identified(), the prior's until then.
  double time_constant() const { return identified() ? tau_ : prior_lag_; }
  /// The play's width that fits best [duty]: the grid's, refined by a parabola through its neighbours.
  double play() const { return play_; }
  /// Enough data: 50 steps where the flow moved by at least 0.5 % of max_flow, the least residual
  /// inside the lag grid, and τ's standard deviation (from the residual's curvature) within 10 % of τ.
  bool identified() const;

 private:
  using Vec = Eigen::Matrix<double, kKnots, 1>;
  using Mat = Eigen::Matrix<double, kKnots, kKnots>;
  struct Fit {
    Vec x = Vec::Zero();  ///< the hat functions of e, each through the lag
    Mat M = Mat::Zero();  ///< forgotten sums (times growth_) of x xᵀ, lower triangle ...
    Vec b = Vec::Zero();  ///< ... and of f x (f normalised by max_flow)
  };
  struct Play {
    double effective = 0.0;  ///< the duty past the play
    std::array<Fit, kLags> lags;
    std::array<double, kLags> residual{};  ///< the least squares' residual mean square, at the last refresh
  };
  void refresh(int play);
  void estimate();
  void rescale();

  double prior_lag_, scale_;
  double dt_ = 0.01;
  std::array<double, kLags> decay_{};   ///< exp(−dt/τ) per lag
  std::vector<Play> plays_;             ///< kPlays (on the heap: about 20 kB each)
  double sum_ff_ = 0.0, weight_ = 0.0;  ///< forgotten sums of f² and of 1 (times growth_)
  double growth_ = 1.0;                 ///< λ^-k: the weight of the newest sample in every sum
  int next_refresh_ = 0, refreshed_ = 0, calls_ = 0;
  bool fitted_ = false;
  double tau_ = 0.0, tau_sd_ = 1.0;  ///< [s], and its relative standard deviation
  double play_ = 0.0;                ///< [duty] (play())
  int moving_steps_ = 0;
};

}  // namespace control
}  // namespace hydrojet
