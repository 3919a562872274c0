// The lateral tip forces the jets can produce (private to src/control/): the zonotope
// {A q : 0 ≤ q ≤ q_max} of eq. (24)'s 2×3 matrix A, a convex, centrally symmetric polygon (a hexagon
// for three jets). Every edge is parallel to a generator g_i = A_i q_max,i, so the polygon is the
// intersection of one slab |n_i·(f − c)| ≤ h_i per generator, with n_i ⊥ g_i, c = Σ g_i / 2 and
// h_i = Σ_j |n_i·g_j| / 2. Used by the reachable-set sweep (ray extents) and the look-at solver
// (keeping its force allocatable). ROS-free (Eigen only).
#pragma once

#include <Eigen/Core>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "hydrojet_control/actuation/jet_map.h"

namespace hydrojet {
namespace control {

class ForcePolygon {
 public:
  ForcePolygon(const Eigen::Matrix<double, 2, 3>& A, const Eigen::Vector3d& q_max) {
    center_.setZero();
    for (int i = 0; i < 3; ++i) center_ += 0.5 * A.col(i) * q_max[i];
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector2d g = A.col(i) * q_max[i];
      normal_.col(i) =
          g.norm() > 0.0 ? Eigen::Vector2d(Eigen::Vector2d(-g.y(), g.x()) / g.norm()) : Eigen::Vector2d::Zero();
      half_width_[i] = 0.0;
      for (int j = 0; j < 3; ++j) half_width_[i] += 0.5 * std::abs(normal_.col(i).dot(A.col(j) * q_max[j]));
    }
  }

  /// f inside or on the edge, up to `slack` [N].
  bool contains(const Eigen::Vector2d& f, double slack = 1e-12) const {
    for (int i = 0; i < 3; ++i)
      if (std::abs(normal_.col(i).dot(f - center_)) > half_width_[i] + slack) return false;
    return true;
  }

  /// f itself when inside, else the edge point on the segment from the origin to f (the origin
  /// must be inside).
  Eigen::Vector2d clamp(const Eigen::Vector2d& f) const {
    const double n = f.norm();
    if (contains(f) || !(n > 0.0)) return f;
    return f * std::min(1.0, extent(f / n) / n);
  }

  /// How far f lies inside the nearest edge [N] (≤ 0: on the edge or outside).
  double edge_gap(const Eigen::Vector2d& f) const {
    double gap = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 3; ++i) gap = std::min(gap, half_width_[i] - std::abs(normal_.col(i).dot(f - center_)));
    return gap;
  }

  /// Distance [N] from the origin to the edge along the unit direction u (0 when the origin is
  /// outside or on the edge).
  double extent(const Eigen::Vector2d& u) const {
    double t = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 3; ++i) {
      const double a = normal_.col(i).dot(u), b = normal_.col(i).dot(center_);
      if (std::abs(b) > half_width_[i]) return 0.0;  // the origin itself is outside
      if (a > 0.0) t = std::min(t, (half_width_[i] + b) / a);
      if (a < 0.0) t = std::min(t, (b - half_width_[i]) / a);
    }
    return std::isfinite(t) ? std::max(0.0, t) : 0.0;
  }

 private:
  Eigen::Vector2d center_;
  Eigen::Matrix<double, 2, 3> normal_;
  Eigen::Vector3d half_width_;
};

/// The tip body wrench per lateral tip force (6×2): every row of the jet map's wrench matrix is a
/// combination of the two rows of A (f_z = 0, the moments (d e_z) × f), so the wrench of any jet
/// forces q depends on A q only: w = W A^T (A A^T)^{-1} (A q).
inline Eigen::Matrix<double, 6, 2> wrench_per_force(const actuation::JetMap& jets) {
  const Eigen::Matrix<double, 2, 3>& A = jets.planar();
  return jets.wrench_matrix() * A.transpose() * (A * A.transpose()).inverse();
}

}  // namespace control
}  // namespace hydrojet
