#include "hydrojet_control/control/plant_identification.h"

#include <algorithm>
#include <cmath>

#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {

std::string IdentificationOptions::validate() const {
  return util::check_range("probe_amplitude", probe_amplitude, 0.002, 0.2);
}

void LatencyEstimator::add(double now, double stamp) {
  const double delay = now - stamp;
  if (!std::isfinite(delay) || delay < 0.0) return;
  delays_[next_] = delay;
  next_ = (next_ + 1) % kWindow;
  count_ = std::min(count_ + 1, kWindow);
}

double LatencyEstimator::latency() const {
  if (count_ == 0) return 0.0;
  std::array<double, kWindow> d = delays_;
  std::nth_element(d.begin(), d.begin() + count_ / 2, d.begin() + count_);
  return d[count_ / 2];
}

namespace {
constexpr double kForgetting =
    0.99995;  // per step: a memory of ~20000 steps (200 s at 100 Hz): a valve does not change
constexpr double kMovingFraction = 0.005;
constexpr double kPrior = 1e4;  // the prior's variance: weak (a stronger one pulls a slow valve's τ to the prior)
}  // namespace

ValveLagEstimator::ValveLagEstimator(double prior_lag, double max_flow) : prior_lag_(prior_lag), scale_(max_flow) {
  reset();
}

void ValveLagEstimator::reset() {
  const double a = std::exp(-dt_ / prior_lag_);
  for (Fit& f : fits_) {
    f.theta(0) = a;
    for (int j = 0; j < kKnots; ++j) f.theta(j + 1) = (1.0 - a) * std::pow(kKnotDuty[j], 0.8);
    f.P = Mat::Identity() * kPrior;
    f.effective = 0.0;
    f.error = 0.0;
    f.simulated = 0.0;
  }
  best_ = 0;
  moving_steps_ = 0;
}

void ValveLagEstimator::add(double previous_flow, double duty, double flow, double dt) {
  if (!(std::isfinite(previous_flow) && std::isfinite(duty) && std::isfinite(flow) && dt > 0.0)) return;
  if (std::abs(dt - dt_) > 0.01 * dt_) {  // a new sampling period: start again at it
    dt_ = dt;
    reset();
  }
  const double y = flow / scale_;
  for (int p = 0; p < kPlays; ++p) {
    Fit& f = fits_[p];
    const double half = 0.005 * p, d = std::clamp(duty, 0.0, 1.0);
    if (d > f.effective + half) f.effective = d - half;
    if (d < f.effective - half) f.effective = d + half;
    Vec phi = Vec::Zero();
    phi(0) = previous_flow / scale_;
    const int j = static_cast<int>(std::upper_bound(kKnotDuty, kKnotDuty + kKnots - 1, f.effective) - kKnotDuty) - 1;
    const double x = (f.effective - kKnotDuty[j]) / (kKnotDuty[j + 1] - kKnotDuty[j]);
    phi(j + 1) = 1.0 - x;
    phi(j + 2) = x;
    // Instrumental variables: the regressor f[k] carries the sensor's noise, which the equation's
    // error f[k+1] − a f[k] shares (least squares would bias a low, τ short); the fit's own
    // noise-free simulation of the flow does not, and follows f[k] closely.
    Vec z = phi;
    z(0) = f.simulated;
    const double e = y - phi.dot(f.theta);
    f.error = kForgetting * f.error + (1.0 - kForgetting) * e * e;
    const Vec Pz = f.P * z;
    const Eigen::Matrix<double, 1, kKnots + 1> phiP = phi.transpose() * f.P;
    const Vec k = Pz / (kForgetting + phiP.dot(z));
    f.theta += k * e;
    f.P = (f.P - k * phiP) / kForgetting;
    phi(0) = f.simulated;
    f.simulated = std::max(0.0, phi.dot(f.theta));
    if (const double trace = std::abs(f.P.trace()); trace > kPrior * (kKnots + 1)) f.P *= kPrior * (kKnots + 1) / trace;
  }
  for (int p = 0; p < kPlays; ++p)
    if (fits_[p].error < fits_[best_].error) best_ = p;
  if (std::abs(flow - previous_flow) > kMovingFraction * scale_) ++moving_steps_;
}

namespace {
/// τ of a and its standard deviation for a's variance.
double lag_of(double a, double dt) { return -dt / std::log(std::clamp(a, 1e-3, 0.999)); }
}  // namespace

bool ValveLagEstimator::identified() const {
  if (moving_steps_ < 50) return false;
  const Fit& f = fits_[best_];
  const double a = std::clamp(f.theta(0), 1e-3, 0.999), log_a = std::log(a);
  const double sd_a = std::sqrt(std::max(0.0, f.P(0, 0) * f.error));
  const double sd_tau = dt_ / (a * log_a * log_a) * sd_a;
  return sd_tau <= 0.1 * lag_of(a, dt_);
}

double ValveLagEstimator::time_constant() const {
  return identified() ? lag_of(fits_[best_].theta(0), dt_) : prior_lag_;
}

}  // namespace control
}  // namespace hydrojet
