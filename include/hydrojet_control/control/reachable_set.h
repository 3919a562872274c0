// The tip directions the robot can reach (issue 13): jet forces within their bounds and the model's
// equilibrium elastically stable with σ_c (eq. 23) ≥ min_stability_margin. Computed once per model by
// a force-space sweep (like bench/stability_map.cpp: solve + C^b + stability per point, warm-started
// along a serpentine), kept as a region of the unit sphere star-shaped about the zero-force
// direction: the largest reachable angle from the centre per azimuth bin. A target outside is moved
// to the nearest direction of the set (clip). ROS-free.
#pragma once

#include <string>
#include <vector>

#include "hydrojet_control/control/robot_model.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

struct ReachableSetOptions {
  double min_stability_margin = 0.5;  ///< σ_c bound [N/m] (the controller passes safety/min_stability_margin)
  int force_samples = 40;             ///< samples per axis of the force-space sweep (≥ 4)
  int azimuth_bins = 72;              ///< resolution of the boundary about the centre (≥ 8)
  std::string validate() const;
};

class ReachableSet {
 public:
  /// Sweeps the jet forces of `model` (bounds [0, max_jet_force] per jet).
  static ReachableSet compute(const RobotModel& model, const ReachableSetOptions& options);

  /// No stable, converged point was found (then clip() returns the centre).
  bool empty() const { return boundary_.empty(); }
  /// Tip z-axis with the jets off (unit, base frame).
  const Vec3& center() const { return center_; }
  /// Closed loop of unit directions on the edge, counter-clockwise about center() (azimuth_bins points).
  const std::vector<Vec3>& boundary() const { return boundary_; }
  /// The accepted sweep directions (converged, σ_c above the bound).
  const std::vector<Vec3>& samples() const { return samples_; }
  /// Wall time of compute() [s].
  double compute_time() const { return compute_time_; }

  bool contains(const Vec3& direction) const;
  /// `direction` itself when inside; else the nearest direction of the set (on its boundary), and the
  /// angle between the two [rad] in *moved (0 when inside).
  Vec3 clip(const Vec3& direction, double* moved = nullptr) const;

 private:
  Vec3 center_ = Vec3::UnitZ();
  std::vector<Vec3> boundary_;
  std::vector<Vec3> samples_;
  double compute_time_ = 0.0;
  // Polar description about center_ (private helpers in reachable_set.cpp).
  Vec3 e1_ = Vec3::UnitX(), e2_ = Vec3::UnitY();  ///< orthonormal basis ⊥ center_
  std::vector<double> max_angle_;                 ///< largest angle from center_ per azimuth bin [rad]
};

}  // namespace control
}  // namespace hydrojet
