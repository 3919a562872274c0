#include "hydrojet_control/plant/sensors.h"

#include <cmath>

#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace plant {

std::string TrackerNoise::validate() const {
  if (!(position_sigma >= 0)) return "position_sigma: must be >= 0";
  if (!(angle_sigma >= 0)) return "angle_sigma: must be >= 0";
  if (!(position_quantum >= 0)) return "position_quantum: must be >= 0";
  if (!(latency >= 0 && latency < 1.0)) return "latency: must lie in [0, 1) s";
  if (!(dropout_rate >= 0)) return "dropout_rate: must be >= 0";
  if (!(dropout_duration > 0)) return "dropout_duration: must be positive";
  return "";
}

std::string FlowNoise::validate() const {
  if (!(sigma >= 0)) return "sigma: must be >= 0";
  if (!(quantum >= 0)) return "quantum: must be >= 0";
  return "";
}

namespace {
double quantise(double v, double q) { return q > 0.0 ? q * std::round(v / q) : v; }
}  // namespace

SensorPose TrackerModel::corrupt(const SensorPose& p) {
  std::normal_distribution<double> n01(0.0, 1.0);
  SensorPose out;
  for (int i = 0; i < 3; ++i)
    out.position[i] = quantise(p.position[i] + noise_.position_sigma * n01(rng_), noise_.position_quantum);
  const Eigen::Vector3d dtheta(noise_.angle_sigma * n01(rng_), noise_.angle_sigma * n01(rng_),
                               noise_.angle_sigma * n01(rng_));
  out.orientation = Eigen::Quaterniond(p.orientation.toRotationMatrix() * so3::exp(dtheta)).normalized();
  return out;
}

TrackerSample TrackerModel::sample(double t, const SensorPose& tip, const SensorPose& base) {
  const double dt = last_t_ > -1e299 ? t - last_t_ : 0.0;
  last_t_ = t;
  history_.emplace_back(t, std::make_pair(tip, base));
  while (history_.size() > 1 && history_[1].first <= t - noise_.latency + 1e-12) history_.pop_front();
  TrackerSample s;
  // Random dropouts: a Poisson process of rate dropout_rate.
  if (noise_.dropout_rate > 0.0 && dt > 0.0) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    if (t >= dropout_until_ && u(rng_) < 1.0 - std::exp(-noise_.dropout_rate * dt))
      dropout_until_ = t + noise_.dropout_duration;
  }
  if (t < dropout_until_ || (t >= forced_from_ && t < forced_to_)) return s;  // invalid
  const auto& delayed = history_.front();
  s.valid = true;
  s.stamp = delayed.first;
  s.tip = corrupt(delayed.second.first);
  s.base = corrupt(delayed.second.second);
  s.rms_error = noise_.position_sigma;
  return s;
}

Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 8, 1> FlowSensorModel::sample(
    const Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 8, 1>& q) {
  std::normal_distribution<double> n01(0.0, 1.0);
  Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 8, 1> out(q.size());
  for (int i = 0; i < q.size(); ++i) out[i] = std::max(0.0, quantise(q[i] + noise_.sigma * n01(rng_), noise_.quantum));
  return out;
}

}  // namespace plant
}  // namespace hydrojet
