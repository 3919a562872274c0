// The probe that measures the first lateral mode on the robot present: once the tip has settled on
// an approached path's first direction (approach.h), and before the path's clock starts, the jets
// add a chirp (identification::chirp, from half to twice the model's mode) that would turn the tip by
// about `amplitude` quasi-statically, along an axis that turns once about the tip's (so that every
// jet takes part), for 2.3 s; the tip's motion against the model's direction at the measured inputs
// is then fitted (identification::fit_mode, the tracker's latency known). The mode's frequency over
// the model's gives the capsule's effective fill (tip_mass_scale), its damping ratio the
// Kelvin–Voigt time; the valves' lags learn from the chirp too (plant_identification.h).
// ROS-free (Eigen, the identification library).
#pragma once

#include <string>
#include <vector>

#include "hydrojet_control/control/task_space.h"
#include "hydrojet_control/identification/mode_fit.h"
#include "hydrojet_control/rod/rod_model.h"

namespace hydrojet {
namespace control {

class ModeProbe {
 public:
  static constexpr double kSeconds = identification::kChirpSeconds + 0.3;  ///< the chirp, then the tip settles
  /// Starts at time t [s] at the held inputs `base` [N], with turns[a] (a = 0..3) the inputs that turn
  /// the tip by amplitude about +x, −x, +y, −y of the tip frame, the tip frame `tip_rotation` (base
  /// frame) and the model's mode there, omega_guess [rad/s]; inputs within [lower, upper] [N].
  void begin(double t, const rod::InputVector& base, const rod::InputVector turns[4], const rod::InputVector& lower,
             const rod::InputVector& upper, const Mat3& tip_rotation, double omega_guess);
  bool active() const { return active_; }
  void cancel() { active_ = false; }
  /// The inputs at time t [s] [N].
  rod::InputVector inputs(double t) const;
  /// One cycle: the model's direction at the measured inputs and the tracker's (unit, base frame).
  void record(const Vec3& model_direction, const Vec3& measured_direction);
  /// The chirp and its settling are over at time t.
  bool done(double t) const { return t - start_ >= kSeconds; }
  /// The record to fit (identification::fit_mode), sampled every dt [s], the tracker `latency` [s]
  /// late; the probe is over.
  identification::ModeRecord finish(double dt, double latency);
  double omega_guess() const { return omega_guess_; }

 private:
  bool active_ = false;
  double start_ = 0.0, omega_guess_ = 0.0;
  rod::InputVector base_, turns_[4], lower_, upper_;
  Mat3 frame_ = Mat3::Identity();
  std::vector<Eigen::Vector2d> model_, measured_;
};

}  // namespace control
}  // namespace hydrojet
