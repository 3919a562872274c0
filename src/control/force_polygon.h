// The steering plane's reachable polygon (private to src/control/): the zonotope {G q : q_min ≤ q ≤ q_max}
// of a 2×N matrix G (N ≤ 8 inputs), a convex, centrally symmetric polygon with up to 2N edges (a
// hexagon for the HydroJet's three jets and G = A of eq. 24). Every edge is parallel to a generator
// g_i = G_i (q_max,i − q_min,i), so the polygon is the intersection of one slab |n_i·(f − c)| ≤ h_i per
// generator, with n_i ⊥ g_i, c = G (q_min + q_max) / 2 and h_i = Σ_j |n_i·g_j| / 2. Used by the
// reachable-set sweep (ray extents from the rest point). ROS-free (Eigen only).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>

#include "hydrojet_control/control/robot_model.h"

namespace hydrojet {
namespace control {

class ForcePolygon {
 public:
  using Generators = Eigen::Matrix<double, 2, Eigen::Dynamic, 0, 2, kMaxInputs>;

  /// G: 2×N; bounds: N each, q_min ≤ q_max; origin: the point rays start from (inside).
  ForcePolygon(const Generators& G, const InputVector& q_min, const InputVector& q_max, const Eigen::Vector2d& origin)
      : origin_(origin) {
    const int n = static_cast<int>(G.cols());
    center_ = G * (0.5 * (q_min + q_max));
    normal_.setZero(2, n);
    half_width_.setZero(n);
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d g = G.col(i) * (q_max[i] - q_min[i]);
      if (g.norm() > 0.0) normal_.col(i) = Eigen::Vector2d(-g.y(), g.x()) / g.norm();
      for (int j = 0; j < n; ++j)
        half_width_[i] += 0.5 * std::abs(normal_.col(i).dot(G.col(j) * (q_max[j] - q_min[j])));
    }
  }

  /// f inside or on the edge, up to `slack`.
  bool contains(const Eigen::Vector2d& f, double slack = 1e-12) const {
    for (int i = 0; i < normal_.cols(); ++i)
      if (std::abs(normal_.col(i).dot(f - center_)) > half_width_[i] + slack) return false;
    return true;
  }

  /// Distance from the origin to the edge along the unit direction u (0 when the origin is outside
  /// or on the edge).
  double extent(const Eigen::Vector2d& u) const {
    double t = std::numeric_limits<double>::infinity();
    for (int i = 0; i < normal_.cols(); ++i) {
      const double a = normal_.col(i).dot(u), b = normal_.col(i).dot(center_ - origin_);
      if (std::abs(b) > half_width_[i]) return 0.0;  // the origin itself is outside
      if (a > 0.0) t = std::min(t, (half_width_[i] + b) / a);
      if (a < 0.0) t = std::min(t, (b - half_width_[i]) / a);
    }
    return std::isfinite(t) ? std::max(0.0, t) : 0.0;
  }

  const Eigen::Vector2d& origin() const { return origin_; }

 private:
  Eigen::Vector2d origin_, center_;
  Generators normal_;
  InputVector half_width_;
};

}  // namespace control
}  // namespace hydrojet
