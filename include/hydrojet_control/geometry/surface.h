// The shapes the tip may meet or must keep out of: planes, spheres, ellipsoids in the base frame. One
// description for the plant's surfaces (plant/environment.h adds their stiffness, damping, friction)
// and the controller's keep-out regions (control/keep_out.h adds a margin). ROS-free (Eigen).
#pragma once

#include <string>

#include <Eigen/Core>

namespace hydrojet {
namespace geometry {

enum class SurfaceType { kPlane, kSphere, kEllipsoid };

struct Surface {
  SurfaceType type = SurfaceType::kPlane;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    ///< a plane's point, a sphere's or ellipsoid's centre [m]
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< a plane's normal, toward the free side (unit)
  /// A sphere's radius (all three), an ellipsoid's semi-axes along the base frame's x, y, z [m].
  Eigen::Vector3d radii = Eigen::Vector3d::Ones();
  bool inside = false;  ///< a sphere or ellipsoid: the free side is inside it (a stomach)
  /// Empty when the shape is valid, else "<field>: <what is wrong>" (point|centre, normal, radius|radii).
  std::string validate_shape() const;
};

/// The nearest point of a surface to p: its signed distance (positive on the free side), the unit
/// normal there toward the free side, and the point itself.
struct SurfacePoint {
  double distance = 0.0;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
};
SurfacePoint nearest_point(const Surface& s, const Eigen::Vector3d& p);

}  // namespace geometry
}  // namespace hydrojet
