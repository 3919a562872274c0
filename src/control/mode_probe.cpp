#include "hydrojet_control/control/mode_probe.h"

#include <cmath>

namespace hydrojet {
namespace control {

void ModeProbe::begin(double t, const rod::InputVector& base, const rod::InputVector turns[4],
                      const rod::InputVector& lower, const rod::InputVector& upper, const Mat3& tip_rotation,
                      double omega_guess) {
  active_ = true;
  start_ = t;
  base_ = base, lower_ = lower, upper_ = upper;
  for (int a = 0; a < 4; ++a) turns_[a] = turns[a];
  frame_ = tip_rotation;
  omega_guess_ = omega_guess;
  model_.clear();
  measured_.clear();
}

// The chirp along an axis that turns once over it: the turns about x and y superposed (each with the
// inputs of its sign), within the bounds.
rod::InputVector ModeProbe::inputs(double t) const {
  const double c = identification::chirp(t - start_, omega_guess_ / (2.0 * M_PI));
  const double psi = 2.0 * M_PI * (t - start_) / identification::kChirpSeconds;
  const double x = c * std::cos(psi), y = c * std::sin(psi);
  rod::InputVector q =
      base_ + std::abs(x) * (turns_[x >= 0.0 ? 0 : 1] - base_) + std::abs(y) * (turns_[y >= 0.0 ? 2 : 3] - base_);
  return q.cwiseMax(lower_).cwiseMin(upper_);
}

void ModeProbe::record(const Vec3& model_direction, const Vec3& measured_direction) {
  model_.push_back((frame_.transpose() * model_direction).head<2>());
  measured_.push_back((frame_.transpose() * measured_direction).head<2>());
}

identification::ModeRecord ModeProbe::finish(double dt, double latency) {
  active_ = false;
  identification::ModeRecord r;
  r.dt = dt;
  r.input = model_;
  r.output = measured_;
  r.delay_samples = static_cast<int>(std::lround(latency / dt));
  return r;
}

}  // namespace control
}  // namespace hydrojet
