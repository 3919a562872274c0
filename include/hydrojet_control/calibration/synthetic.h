// Synthetic calibration data from the static model at a known scene (its ζ is the truth): random
// actuator-input combinations, model tip orientations, Gaussian orientation noise. For tests, benchmarks
// and dry runs (calibrate --synthesize). ROS-free.
#pragma once

#include <cmath>
#include <vector>

#include <Eigen/Core>

#include "hydrojet_control/calibration/samples.h"
#include "hydrojet_control/config/scene.h"

namespace hydrojet {
namespace calibration {

struct SyntheticOptions {
  int samples = 40;
  double noise_rad = 0.5 * M_PI / 180.0;  ///< σ per axis of the orientation noise [rad]
  double max_force_fraction = 0.9;        ///< q_i uniform in fraction·[min_force_i, max_force_i]
  unsigned seed = 1;
};

/// Random inputs q (per actuator uniform in fraction·[min_force_i, max_force_i] of the scene) and
/// the scene's static tip orientation for each, rotated by exp(n̂), n ~ N(0, σ² I₃) in the tip frame.
/// Deterministic for a seed. Throws std::runtime_error if a rod solve does not converge.
std::vector<Sample> synthesise(const config::Scene& truth, const SyntheticOptions& options);

}  // namespace calibration
}  // namespace hydrojet
