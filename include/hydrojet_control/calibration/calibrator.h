// Offline calibration of ζ = [u_x, u_y, E, G, δα, δβ, δγ] (Campisano et al. 2021, §6.2, eq. 27):
// nonlinear least squares (Ceres, Levenberg–Marquardt) on the rotation error between the static
// rod model's tip orientation and the measured one over a set of jet-force combinations.
// ROS-free (Eigen, Ceres, the rod/actuation/config libraries).
//
// Residual of sample i (3 numbers): r_i = log(R_meas,iᵀ R_model(q_i, ζ)), the rotation vector of
// the error in the measured tip frame; |r_i| is the geodesic angle between the two orientations.
// (Eq. 27 as printed minimises Σ⟨h_m, h_i⟩², which is smallest when the quaternions are
// orthogonal, i.e. the orientations 180° apart; see docs/calibration.md.)
//
// Parameters are estimated in internal coordinates x = [u_x, u_y, ln(E/E₀), ln(G/G₀), δα, δβ, δγ]
// (E₀, G₀ the starting moduli): the moduli stay positive and all seven are O(1). Derivatives are
// central differences (absolute step 1e-6) through the shooting solver; every sample keeps its own
// solver, warm-started while only the misalignments move (they change the wrench, not the rod);
// a new u, E or G goes through RodSolver::set_model(), which resets the warm start. The
// covariance is ceres::Covariance (JᵀJ)⁻¹ scaled by the residual variance σ̂² = Σ|r_i|²/(3N − p),
// mapped back to E and G by the delta method.
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

/// Box bounds on ζ (physical units; E and G in Pa, both bounds > 0).
struct Bounds {
  ZetaVector lower, upper;
};
/// Default bounds around a start: u_x, u_y ± 20 1/m; E, G within [start/20, start·20];
/// δα, δβ, δγ ± 0.5 rad around the start.
Bounds default_bounds(const ZetaVector& start);

enum class Loss { kNone, kHuber, kCauchy };

struct CalibrationOptions {
  ParamMask fit = all_params();  ///< parameters to estimate; the others stay at the start
  Loss loss = Loss::kNone;       ///< robust loss on the per-sample angle (Huber / Cauchy)
  double loss_scale = 0.02;      ///< [rad] where the robust loss starts to bend (≈1.1°)
  bool has_bounds = false;       ///< false: default_bounds(start)
  Bounds bounds;
  int max_iterations = 100;  ///< Levenberg–Marquardt iterations
  int num_threads = 1;
  /// A fitted parameter whose standard deviation exceeds its resolution is reported as not
  /// identifiable by the data: u_x, u_y 0.5 1/m (≈2.6° of unloaded tip tilt over 9 cm);
  /// E, G 20 % (relative); δα, δβ, δγ 0.05 rad (≈2.9°).
  ZetaVector resolution = (ZetaVector() << 0.5, 0.5, 0.2, 0.2, 0.05, 0.05, 0.05).finished();
  double max_correlation = 0.98;  ///< |ρ| above this: warn that only a combination is determined
};

struct CalibrationResult {
  bool converged = false;  ///< Ceres converged and every final rod solve converged
  std::string message;     ///< Ceres' termination message or the failure
  ZetaVector start = ZetaVector::Zero();
  ZetaVector zeta = ZetaVector::Zero();  ///< the estimate (= start for parameters not fitted)
  ParamMask fitted{};
  Bounds bounds;
  double start_rms_rad = 0.0;              ///< RMS of the per-sample angle at the start [rad]
  double rms_rad = 0.0;                    ///< RMS of the per-sample angle at the estimate [rad]
  std::vector<double> sample_error_rad;    ///< |r_i| per sample at the estimate [rad]
  std::vector<Eigen::Vector3d> residuals;  ///< r_i per sample [rad]
  double sigma_rad = 0.0;                  ///< σ̂ = sqrt(Σ|r_i|²/(3N − p)), per-axis noise estimate [rad]
  bool covariance_ok = false;
  ZetaVector stddev = ZetaVector::Constant(std::nan(""));  ///< physical units; NaN when unknown/not fitted
  Eigen::Matrix<double, kNumParams, kNumParams> correlation =
      Eigen::Matrix<double, kNumParams, kNumParams>::Constant(std::nan(""));
  ParamMask identifiable{};  ///< fitted and std ≤ resolution (and not in a null space)
  ParamMask at_bound{};
  std::vector<std::string> warnings;
  int iterations = 0;     ///< Levenberg–Marquardt iterations
  int rod_solves = 0;     ///< static rod solves during the fit
  int failed_solves = 0;  ///< of which did not converge
  double time_s = 0.0;    ///< wall time of the fit and the covariance [s]
};

/// Fits ζ to the samples starting from the scene's values. The scene must have a jets section
/// (SceneError("jets") otherwise); the samples are checked with validate_samples (DataError).
/// Throws std::invalid_argument for unusable options (start outside the bounds, bad cross-section).
CalibrationResult calibrate(const config::Scene& scene, const CrossSection& cs, const std::vector<Sample>& samples,
                            const CalibrationOptions& options);

/// The static model's tip orientation (tip in base) for jet forces q [N] in the scene (jet map of
/// eq. 24 with the scene's misalignments). *ok (if given) says whether the rod solve converged.
Eigen::Matrix3d predict_tip_rotation(const config::Scene& scene, const Eigen::Vector3d& q, bool* ok = nullptr);

/// Rotation error r = log(R_measᵀ R_model) [rad] (3-vector; |r| the angle between the two).
Eigen::Vector3d rotation_error(const Eigen::Matrix3d& R_meas, const Eigen::Matrix3d& R_model);

}  // namespace calibration
}  // namespace hydrojet
