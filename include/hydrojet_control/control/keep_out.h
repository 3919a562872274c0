// Keep-out regions: surfaces (a registered stomach model, a plane before a lesion) that the reference
// never takes the capsule into. A direction is allowed when the model puts the capsule (a sphere of
// the robot's tip radius about its tip point) at least `margin` from every region; a target that is
// not is moved to the nearest allowed direction, as the reachable set clips (reachable_set.h). The
// model's tip position per direction comes from the reachable set's sweep (its solves' positions,
// fitted on a grid of the tangent plane at the set's centre), so a check costs an interpolation and a
// distance, never a solve. ROS-free.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "hydrojet_control/control/reachable_set.h"
#include "hydrojet_control/geometry/surface.h"

namespace hydrojet {
namespace control {

/// One region of the controller file's `keep_out` list: a surface whose free side is where the
/// capsule may go, and the margin it keeps from it.
struct KeepOutRegion {
  geometry::Surface surface;
  double margin = 0.002;  ///< [m] (0 ... 0.1)
  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};

class KeepOut {
 public:
  /// The regions over the directions of `set` for a capsule of `tip_radius` [m]. Throws
  /// std::invalid_argument naming the field ("keep_out[1]/normal: ...") when a region is invalid, and
  /// "keep_out: ..." when the regions leave no direction of the set allowed.
  KeepOut(std::vector<KeepOutRegion> regions, double tip_radius, std::shared_ptr<const ReachableSet> set);

  const std::vector<KeepOutRegion>& regions() const { return regions_; }
  /// The set the regions were fitted over.
  const std::shared_ptr<const ReachableSet>& set() const { return set_; }
  double tip_radius() const { return tip_radius_; }
  /// The model's tip position at tip direction d [m], base frame (interpolated from the sweep).
  Vec3 tip_position(const Vec3& d) const;
  /// What the reference keeps beyond each margin [m]: the tip overshoots a reference that stops at an
  /// edge by up to ~2 mm on plants with 20 ms of tracker latency or a light, lightly damped capsule
  /// (docs/contact.md); with this the capsule kept its margin's first 2 mm on every plant measured.
  static constexpr double kTrackingAllowance = 0.001;

  /// The capsule's least distance to a region beyond its margin and kTrackingAllowance at direction d [m] (≥ 0:
  /// allowed; +inf without regions). `offset` [m] is added to the model's tip position: what the tracker has shown the
  /// plant's tip to be off the model's (the controller learns it).
  double clearance(const Vec3& d, const Vec3& offset = Vec3::Zero()) const;
  bool allows(const Vec3& d, const Vec3& offset = Vec3::Zero()) const {
    return regions_.empty() || clearance(d, offset) >= 0.0;
  }
  /// d (normalised) when allowed; else the nearest allowed direction of the set (on the regions' edge),
  /// and the angle between the two in *moved [rad] (0 when allowed). d itself when nothing is allowed
  /// (an offset that large): the caller checks allows() and holds.
  Vec3 clip(const Vec3& d, double* moved = nullptr, const Vec3& offset = Vec3::Zero()) const;

 private:
  using Vec2 = Eigen::Vector2d;
  Vec2 chart(const Vec3& d) const;  ///< tangent-plane coordinates about the set's centre
  Vec3 direction(const Vec2& u) const;
  double clearance_at(const Vec2& u, const Vec3& offset) const;
  double clearance_of(const Vec3& p) const;
  Vec3 position_at(const Vec2& u) const;
  void fit_grid();
  /// From an allowed chart point to the edge toward u (bisection), then (slide) along the edge to
  /// the point nearest u.
  Vec2 edge_toward(const Vec2& allowed, const Vec2& u, const Vec3& offset, bool slide) const;

  std::vector<KeepOutRegion> regions_;
  double tip_radius_ = 0.0;
  std::shared_ptr<const ReachableSet> set_;
  Vec3 center_ = Vec3::UnitZ(), e1_ = Vec3::UnitX(), e2_ = Vec3::UnitY();
  int n_ = 0;          ///< grid nodes per side
  double extent_ = 0;  ///< the grid spans [−extent, extent]² of the chart
  std::vector<Vec3> node_position_;
  std::vector<Eigen::Matrix<double, 3, 2>> node_gradient_;  ///< the fit's slope in the chart [m]
  std::vector<char> node_valid_;                            ///< enough sweep samples about the node for its fit
  std::vector<char> node_in_set_;                           ///< the node's direction lies in the set
  std::vector<double> node_clearance_;                      ///< clearance() at the node with no offset [m]
};

}  // namespace control
}  // namespace hydrojet
