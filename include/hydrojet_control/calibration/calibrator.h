// Offline calibration of ζ (calibration/zeta.h; Campisano et al. 2021, §6.2, eq. 27, and its
// general form for any follower-actuated robot): nonlinear least squares (Ceres,
// Levenberg–Marquardt) on the rotation error between the static rod model's tip orientation and
// the measured one over a set of actuator-input combinations. ROS-free (Eigen, Ceres, the
// rod/actuation/config libraries).
//
// Residual of sample i (3 numbers): r_i = log(R_meas,iᵀ R_model(q_i, ζ)), the rotation vector of
// the error in the measured tip frame; |r_i| is the geodesic angle between the two orientations.
// (Eq. 27 as printed minimises Σ⟨h_m, h_i⟩², which is smallest when the quaternions are
// orthogonal, i.e. the orientations 180° apart; see docs/calibration.md.)
//
// Parameters are estimated in internal coordinates: ln(value/start) for the positive ones (E, G,
// the stiffness scales), the value itself otherwise; all are O(1). Derivatives are central
// differences (absolute step 1e-6) through the rod solver; every sample keeps its own solver,
// warm-started while only the mount rotation moves (it changes the tip wrench, not the rod); a new
// rod goes through RodSolver::set_model(), which resets the warm start. The covariance is
// ceres::Covariance (JᵀJ)⁻¹ scaled by the residual variance σ̂² = Σ|r_i|²/(3N − p), mapped back to
// the positive parameters by the delta method.
//
// Per-segment bending scales that the data cannot tell apart (not identifiable, or correlated
// beyond max_correlation) are replaced by one common scale and the fit is run again; the result
// says so.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hydrojet_control/calibration/samples.h"
#include "hydrojet_control/calibration/zeta.h"
#include "hydrojet_control/config/scene.h"

namespace hydrojet {
namespace calibration {

/// Box bounds on ζ (physical units; both bounds > 0 for a logarithmic parameter).
struct Bounds {
  ZetaVector lower, upper;
};
/// Default bounds around the scene's ζ: precurvatures ± 20 1/m; E, G and the scales within
/// [start/20, start·20]; the mount rotation ± 0.5 rad.
Bounds default_bounds(const Zeta& zeta);

enum class Loss { kNone, kHuber, kCauchy };

/// Per-segment bending scales or one common scale.
enum class BendingScale {
  kAuto,        ///< per segment; one common scale when the data cannot tell the segments apart
  kPerSegment,  ///< as asked, whatever the data say
};

struct CalibrationOptions {
  ParamMask fit;  ///< parameters to estimate (empty: Zeta::default_fit()); the others stay at the start
  BendingScale bending_scale = BendingScale::kAuto;
  Loss loss = Loss::kNone;   ///< robust loss on the per-sample angle (Huber / Cauchy)
  double loss_scale = 0.02;  ///< [rad] where the robust loss starts to bend (≈1.1°)
  bool has_bounds = false;   ///< false: default_bounds(start)
  Bounds bounds;
  int max_iterations = 100;  ///< Levenberg–Marquardt iterations
  int num_threads = 1;
  double max_correlation = 0.98;  ///< |ρ| above this: warn that only a combination is determined
};

struct CalibrationResult {
  bool converged = false;  ///< Ceres converged and every final rod solve converged
  std::string message;     ///< Ceres' termination message or the failure
  ZetaVector start;
  ZetaVector zeta;  ///< the estimate (= start for parameters not fitted)
  ParamMask fitted;
  /// The per-segment bending scales were not identifiable and one common scale was fitted instead.
  bool common_bending_scale = false;
  Bounds bounds;
  double start_rms_rad = 0.0;              ///< RMS of the per-sample angle at the start [rad]
  double rms_rad = 0.0;                    ///< RMS of the per-sample angle at the estimate [rad]
  std::vector<double> sample_error_rad;    ///< |r_i| per sample at the estimate [rad]
  std::vector<Eigen::Vector3d> residuals;  ///< r_i per sample [rad]
  double sigma_rad = 0.0;                  ///< σ̂ = sqrt(Σ|r_i|²/(3N − p)), per-axis noise estimate [rad]
  bool covariance_ok = false;
  ZetaVector stddev;            ///< physical units; NaN when unknown/not fitted
  Eigen::MatrixXd correlation;  ///< NaN when unknown/not fitted
  ParamMask identifiable;       ///< fitted and std ≤ resolution (and not in a null space)
  ParamMask at_bound;
  std::vector<std::string> warnings;
  int iterations = 0;     ///< Levenberg–Marquardt iterations
  int rod_solves = 0;     ///< static rod solves during the fit
  int failed_solves = 0;  ///< of which did not converge
  double time_s = 0.0;    ///< wall time of the fit and the covariance [s]
};

/// Fits ζ to the samples starting from the scene's values (zeta.start()). The samples are checked
/// with validate_samples (DataError). Throws std::invalid_argument for unusable options (a mask of
/// the wrong size, start outside the bounds).
CalibrationResult calibrate(const Zeta& zeta, const std::vector<Sample>& samples, const CalibrationOptions& options);

/// The static model's tip orientation (tip in base) for inputs q in the scene. *ok (if given) says
/// whether the rod solve converged.
Eigen::Matrix3d predict_tip_rotation(const config::Scene& scene, const rod::InputVector& q, bool* ok = nullptr);

/// Rotation error r = log(R_measᵀ R_model) [rad] (3-vector; |r| the angle between the two).
Eigen::Vector3d rotation_error(const Eigen::Matrix3d& R_meas, const Eigen::Matrix3d& R_model);

}  // namespace calibration
}  // namespace hydrojet
