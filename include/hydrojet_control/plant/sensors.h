// The simulated plant's sensors: a two-sensor 6-DoF EM tracker (tip and base, like the NDI Aurora)
// and three flow sensors, each with noise, quantisation, latency and dropouts (all configurable; off
// for accuracy runs, on for fault tests). Deterministic for a seed. ROS-free (Eigen only).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <deque>
#include <random>
#include <string>

namespace hydrojet {
namespace plant {

/// A pose of a sensor in the tracker frame.
struct SensorPose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< [m]
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

struct TrackerSample {
  bool valid = false;  ///< false during a dropout (the driver would report "missing")
  double stamp = 0.0;  ///< time the pose was measured [s] (sample time minus latency)
  SensorPose tip, base;
  double rms_error = 0.0;  ///< the tracker's own fit RMS [m]
};

struct TrackerNoise {
  double position_sigma = 0.5e-3;         ///< per axis [m] (Aurora ~0.5 mm)
  double angle_sigma = 0.3 * M_PI / 180;  ///< per axis [rad] (Aurora ~0.3°)
  double position_quantum = 1e-5;         ///< [m] (the BX float32 mm output resolves ~1e-5 m)
  double latency = 0.0;                   ///< [s], a multiple of the sample period
  double dropout_rate = 0.0;              ///< dropouts started per second [1/s]
  double dropout_duration = 0.05;         ///< [s]
  std::string validate() const;
};

struct FlowNoise {
  double sigma = 5e-8;        ///< [m^3/s] (~3 mL/min)
  double quantum = 1.667e-9;  ///< [m^3/s] (0.1 mL/min display resolution)
  std::string validate() const;
};

/// Samples the tracker: true poses in, noisy, quantised, delayed poses out.
class TrackerModel {
 public:
  TrackerModel(const TrackerNoise& noise, unsigned seed) : noise_(noise), rng_(seed) {}
  /// Records the true sensor poses at time t and returns what the tracker reports at t.
  TrackerSample sample(double t, const SensorPose& tip, const SensorPose& base);
  /// Fault injection: no samples for [t0, t0 + duration).
  void force_dropout(double t0, double duration) { forced_from_ = t0, forced_to_ = t0 + duration; }

 private:
  SensorPose corrupt(const SensorPose& p);
  TrackerNoise noise_;
  std::mt19937 rng_;
  std::deque<std::pair<double, std::pair<SensorPose, SensorPose>>> history_;
  double dropout_until_ = -1.0;
  double forced_from_ = 1e300, forced_to_ = -1e300;
  double last_t_ = -1e300;
};

/// Samples the three flow sensors.
class FlowSensorModel {
 public:
  FlowSensorModel(const FlowNoise& noise, unsigned seed) : noise_(noise), rng_(seed) {}
  /// One reading per channel [m^3/s] (noise, quantisation, never negative).
  Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 8, 1> sample(
      const Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 8, 1>& true_flow);

 private:
  FlowNoise noise_;
  std::mt19937 rng_;
};

}  // namespace plant
}  // namespace hydrojet
