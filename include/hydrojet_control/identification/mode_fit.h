// The first lateral mode's frequency and damping from a record of the tip's motion, fitted with Ceres
// (output error: the model simulated against the whole record, so the tracker's noise does not bias
// it). Per lateral component c of the tip direction (two, in a frame fixed for the record):
//   ÿ_c = ω² (g_c s_c + b_c − y_c) − 2ζω ẏ_c
// with s the model's quasi-static direction at the measured actuator inputs (held between samples),
// g_c its gain and b_c its offset (the model's error), from an unknown start (y_c, ẏ_c). With no
// input (s ≡ 0: a free vibration) g is not fitted. The identification of a rig's first day
// (`identify`), the controller's probe and the simulated plant's truth all use it. ROS-free (Eigen, Ceres).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace hydrojet {
namespace identification {

struct ModeRecord {
  double dt = 0.01;                     ///< sample period [s]
  std::vector<Eigen::Vector2d> input;   ///< s at each sample (empty or all zero: a free vibration)
  std::vector<Eigen::Vector2d> output;  ///< y at each sample: the state delay_samples earlier (a tracker's latency)
  int delay_samples = 0;
};

struct ModeFit {
  bool ok = false;
  std::string error;                               ///< why not
  double omega = 0.0;                              ///< ω [rad/s]
  double zeta = 0.0;                               ///< ζ [-]
  Eigen::Vector2d gain = Eigen::Vector2d::Ones();  ///< g_c (1 for a free vibration)
  double rms_residual = 0.0;                       ///< [same unit as y]
  double hz() const { return omega / (2.0 * M_PI); }
};

/// The probe's excitation at time t [s] from its start, for a mode guessed at guess_hz: a logarithmic
/// chirp from half to twice the guess over kChirpSeconds, of unit amplitude, faded in and out.
constexpr double kChirpSeconds = 2.0;
double chirp(double t, double guess_hz);

/// Fits ω and ζ (starting from several ω about omega_guess [rad/s]); ok when the fit converged to
/// a mode inside (0.1, 10) omega_guess and ζ < 1.5 that explains at least a quarter of the
/// record's motion (variance). Samples ≥ 20.
ModeFit fit_mode(const ModeRecord& record, double omega_guess, double zeta_guess = 0.2);

/// One fit of a probe's size on a known mode (3.5 Hz, ζ 0.2), for a process to page Ceres in before
/// its loop needs it; true when the fit recovers that mode within 1 %.
bool warm_up();

}  // namespace identification
}  // namespace hydrojet
