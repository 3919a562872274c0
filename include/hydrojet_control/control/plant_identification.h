// What the controller measures of the plant it has, online and in closed loop, instead of assuming
// it: the tracker's latency (its stamps), each jet's flow-loop lag (commanded duty against measured
// flow), and the first lateral mode's frequency and damping (the tip's motion against the model's
// quasi-static direction). The modal law uses them (modal_law.h); the experiment reports them
// (`identified`). ROS-free (Eigen).
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hydrojet_control/control/task_space.h"

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
  // What the modal law takes from them.
  bool mode_identified = false;    ///< the probe's fit holds (else: the first guess)
  std::string mode_error;          ///< why the probe's fit did not hold (empty: it did, or no probe yet)
  double tip_mass_scale = 0.0;     ///< the capsule's effective fill: the model's mode equals the one measured [-]
  double damping_time = 0.0;       ///< τ_kv = 2ζ/ω [s]
  bool valves_identified = false;  ///< every jet's lag has enough data
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

/// A valve's lag τ from its duty u and measured flow f, sampled every dt: recursive least squares on
///   f[k+1] = a f[k] + g(e[k]),  a = exp(−dt/τ),
/// with g the valve's unknown static curve as piecewise-linear over the duty (kKnots hat functions),
/// so that neither its exponent nor its dead zone biases a, and e the duty past the valve's play (a
/// backlash of unknown width: one estimator per width of kPlays, the one that predicts best wins).
/// Instrumental variables (the fit's simulated flow for f[k]) keep the flow sensor's noise from biasing τ.
class ValveLagEstimator {
 public:
  /// g on these duties: closer at small openings, where dead zones put the curve's kink.
  static constexpr int kKnots = 14;
  static constexpr double kKnotDuty[kKnots] = {0.0,  0.02, 0.04, 0.06, 0.08, 0.1,  0.13,
                                               0.17, 0.22, 0.3,  0.4,  0.55, 0.75, 1.0};
  static constexpr int kPlays = 5;  ///< play widths 0, 0.01, ..., 0.04 [duty]
  /// prior_lag [s]: the estimate until the data say otherwise; max_flow [m^3/s]: the flows' scale.
  ValveLagEstimator(double prior_lag = 0.04, double max_flow = 1.6e-5);
  void reset();
  /// Flow `flow` [m^3/s] measured dt [s] after the duty `duty` was commanded at flow `previous_flow`.
  void add(double previous_flow, double duty, double flow, double dt);
  /// τ [s]: the fit's once identified(), the prior's until then.
  double time_constant() const;
  double play() const { return best_ * 0.01; }  ///< the play's width that predicts best [duty]
  /// Enough data: 50 steps where the flow moved by at least 0.5 % of max_flow, and τ's standard
  /// deviation (from the fit's covariance and its prediction errors) within 10 % of τ.
  bool identified() const;

 private:
  using Vec = Eigen::Matrix<double, kKnots + 1, 1>;
  using Mat = Eigen::Matrix<double, kKnots + 1, kKnots + 1>;
  struct Fit {
    Vec theta;  ///< (a, g at the knots / scale)
    Mat P;
    double effective = 0.0;  ///< the duty past the play
    double error = 0.0;      ///< forgotten mean square of the prediction errors
    double simulated = 0.0;  ///< the fit's own simulation of f (normalised): the instrument
  };
  double prior_lag_, scale_;
  std::array<Fit, kPlays> fits_;
  int best_ = 0;
  double dt_ = 0.01;
  int moving_steps_ = 0;
};

}  // namespace control
}  // namespace hydrojet
