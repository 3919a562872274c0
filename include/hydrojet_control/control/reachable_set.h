// The tip directions the robot can reach: actuator inputs within their bounds and the
// model's equilibrium elastically stable with σ_c (eq. 23) ≥ min_stability_margin and eig_min > 0.
// Computed once per model by a sweep like bench/stability_map.cpp (solve + C^b + stability per point,
// warm-started along a serpentine) over the steering plane: the tip direction's change per input at
// rest maps the input box onto a polygon (for the HydroJet, the lateral tip forces the jets can
// allocate, {A q : 0 ≤ q ≤ q_max} of eq. 24, turned by the rest compliance); rays from the rest point
// to the polygon's edge, two per azimuth bin, force_samples points each, outward and inward in turn,
// each point reached by the smallest bounded inputs that steer there (eq. 20).
// The result is kept as a region of the unit sphere star-shaped about the zero-force direction: the
// largest reachable angle from the centre per azimuth bin. A target outside is moved to the nearest
// direction of the set (clip). ROS-free.
#pragma once

#include <string>
#include <vector>

#include "hydrojet_control/control/robot_model.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

struct ReachableSetOptions {
  double min_stability_margin = 0.5;  ///< σ_c bound [N/m] (the controller passes safety/min_stability_margin)
  int force_samples = 40;             ///< force magnitudes per ray of the sweep (≥ 4)
  int azimuth_bins = 72;              ///< resolution of the boundary about the centre (≥ 8)
  /// Wall time the sweep may take [s] (> 0): a model whose solves do not converge (absurd bounds,
  /// a broken scene) is refused rather than swept for minutes. The HydroJet's takes about 0.1 s.
  double max_time = 10.0;
  std::string validate() const;
};

class ReachableSet {
 public:
  /// Sweeps the inputs of `model` (the HydroJet's jets: bounds [0, max_jet_force]).
  /// @throws std::invalid_argument on bad options, std::runtime_error when the sweep would take longer
  /// than options.max_time (the message says how far it got).
  static ReachableSet compute(const RobotModel& model, const ReachableSetOptions& options);

  /// No stable, converged point was found (then clip() returns the centre).
  bool empty() const { return boundary_.empty(); }
  /// Tip z-axis with the jets off (unit, base frame).
  const Vec3& center() const { return center_; }
  /// Closed loop of unit directions on the edge, counter-clockwise about center() (azimuth_bins points).
  const std::vector<Vec3>& boundary() const { return boundary_; }
  /// The accepted sweep directions (converged, σ_c above the bound).
  const std::vector<Vec3>& samples() const { return samples_; }
  /// The model's tip position at each sample [m], base frame (what keep-out regions are checked on).
  const std::vector<Vec3>& sample_positions() const { return sample_positions_; }
  /// Wall time of compute() [s].
  double compute_time() const { return compute_time_; }

  /// Inside the boundary polyline (great-circle arcs between consecutive boundary points). The
  /// polyline is inscribed: its vertices are reachable samples, and between them it cuts the corners
  /// of the reachable region by at most the chords' sag (≤ 1.5e-2 rad, measured, where the jets'
  /// force polygon has its corners), so it never claims an unreachable direction there.
  bool contains(const Vec3& direction) const;
  /// `direction` (normalised) when inside; else the nearest direction of the set (on its boundary,
  /// geodesic distance), and the angle between the two [rad] in *moved (0 when inside).
  Vec3 clip(const Vec3& direction, double* moved = nullptr) const;

 private:
  /// The polar boundary from samples_ (one vertex per azimuth bin: the sample farthest from the
  /// centre; an empty bin takes the smaller angle of its nearest filled neighbours).
  void build_boundary(int bins);
  /// Geodesic angle from center_ [rad].
  double angle_from_center(const Vec3& d) const { return geodesic_error(center_, d); }
  /// Azimuth about center_, from e1_ towards e2_, in [0, 2π) [rad].
  double azimuth_about_center(const Vec3& d) const;
  /// The direction at `angle` from center_ and `azimuth` about it.
  Vec3 polar_point(double angle, double azimuth) const;
  int bin_of(double azimuth) const;

  Vec3 center_ = Vec3::UnitZ();
  std::vector<Vec3> boundary_;
  std::vector<Vec3> samples_;
  std::vector<Vec3> sample_positions_;
  double compute_time_ = 0.0;
  Vec3 e1_ = Vec3::UnitX(), e2_ = Vec3::UnitY();  ///< orthonormal basis ⊥ center_, e1_ × e2_ = center_
  std::vector<double> max_angle_;                 ///< largest angle from center_ per azimuth bin [rad]
  std::vector<double> vertex_azimuth_;            ///< azimuth of boundary_[b], inside bin b [rad]
};

}  // namespace control
}  // namespace hydrojet
