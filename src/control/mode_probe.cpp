#include "hydrojet_control/control/mode_probe.h"

#include <cmath>

namespace hydrojet {
namespace control {

void ModeProbe::begin(double t, const rod::InputVector& base, const rod::InputVector& plus,
                      const rod::InputVector& minus, const Mat3& tip_rotation, double omega_guess) {
  active_ = true;
  start_ = t;
  base_ = base, plus_ = plus, minus_ = minus;
  frame_ = tip_rotation;
  omega_guess_ = omega_guess;
  model_.clear();
  measured_.clear();
}

rod::InputVector ModeProbe::inputs(double t) const {
  const double c = identification::chirp(t - start_, omega_guess_ / (2.0 * M_PI));
  return c >= 0.0 ? rod::InputVector(base_ + c * (plus_ - base_)) : rod::InputVector(base_ - c * (minus_ - base_));
}

void ModeProbe::record(const Vec3& model_direction, const Vec3& measured_direction) {
  model_.push_back((frame_.transpose() * model_direction).head<2>());
  measured_.push_back((frame_.transpose() * measured_direction).head<2>());
}

identification::ModeFit ModeProbe::fit(double dt, double latency) {
  active_ = false;
  identification::ModeRecord r;
  r.dt = dt;
  r.input = model_;
  r.output = measured_;
  r.delay_samples = static_cast<int>(std::lround(latency / dt));
  return identification::fit_mode(r, omega_guess_);
}

}  // namespace control
}  // namespace hydrojet
