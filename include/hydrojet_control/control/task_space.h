// The HydroJet's task space (paper §5, Fig. 7): the tip direction, two DoF (ϑ, φ).
//   ϑ: bend angle between the base z-axis and the tip z-axis [rad], in [0, π]
//   φ: azimuth of the tip z-axis about the base z-axis, measured from the base x-axis [rad]
// The tip z-axis in base coordinates is d(ϑ, φ) = (sin ϑ cos φ, sin ϑ sin φ, cos ϑ).
// φ is undefined at ϑ = 0, so the controller works with the unit vector d, never with raw angles.
// ROS-free (Eigen only).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace hydrojet {
namespace control {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

/// Tip z-axis (unit) in the base frame for bend angle ϑ and azimuth φ [rad].
inline Vec3 direction(double theta, double phi) {
  return Vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
}

/// The unit vector along v, without overflow or underflow on the way: v is scaled by its largest
/// component first, so (1e308, 1e308, 1e308) is a direction like any other, not an infinity that
/// normalises to zero. False (unit untouched) when v is not finite or is zero.
inline bool unit_direction(const Vec3& v, Vec3* unit) {
  if (!v.allFinite()) return false;
  const double scale = v.cwiseAbs().maxCoeff();
  if (!(scale > 0.0)) return false;
  const Vec3 u = (v / scale).normalized();
  if (!u.allFinite()) return false;
  *unit = u;
  return true;
}

/// Bend angle ϑ [rad] of a unit tip direction d.
inline double bend_angle(const Vec3& d) { return std::atan2(d.head<2>().norm(), d.z()); }

/// Azimuth φ [rad] in (−π, π] of a unit tip direction; 0 when ϑ = 0 (undefined there).
inline double azimuth(const Vec3& d) { return d.head<2>().norm() > 0.0 ? std::atan2(d.y(), d.x()) : 0.0; }

/// Rotation vector [rad] (base frame) of the shortest rotation taking unit vector a onto unit
/// vector b: axis a × b, angle ∠(a, b). Perpendicular to both; well defined except for b = −a.
inline Vec3 rotation_between(const Vec3& a, const Vec3& b) {
  const Vec3 c = a.cross(b);
  const double s = c.norm(), cth = a.dot(b);
  const double angle = std::atan2(s, cth);
  if (s < 1e-12) {
    if (cth > 0.0) return Vec3::Zero();
    // Antipodal: any axis perpendicular to a.
    Vec3 axis = a.cross(Vec3::UnitX());
    if (axis.norm() < 1e-6) axis = a.cross(Vec3::UnitY());
    return angle * axis.normalized();
  }
  return angle * c / s;
}

/// Primary error metric: the geodesic angle [rad] between desired and measured tip z-axes.
inline double geodesic_error(const Vec3& desired, const Vec3& measured) {
  return std::atan2(desired.cross(measured).norm(), desired.dot(measured));
}

/// The paper's metric (§7.3, §7.5): desired and measured directions are converted to pitch and yaw
/// (Euler angles of the tip z-axis: pitch = rotation about base y, yaw = about base x) and the
/// Euclidean norm of their difference is taken.
inline Eigen::Vector2d pitch_yaw(const Vec3& d) {
  // d = Ry(pitch) Rx(yaw) e_z = (cos(yaw) sin(pitch), −sin(yaw), cos(yaw) cos(pitch))
  return Eigen::Vector2d(std::atan2(d.x(), d.z()), std::asin(std::max(-1.0, std::min(1.0, -d.y()))));
}
inline double pitch_yaw_error(const Vec3& desired, const Vec3& measured) {
  return (pitch_yaw(desired) - pitch_yaw(measured)).norm();
}

/// The spiral of §7.1, eq. (28): ϑ and φ linear in time. The printed rates (0.1, 0.8 rad/s)
/// contradict the stated end point (ϑ = 1.04 rad, φ = 14 rad after 600 s); the defaults reach the
/// end point over 600 s. All parameters configurable.
struct SpiralPath {
  double theta_start = 0.0;  ///< [rad]
  double phi_start = 0.0;    ///< [rad]
  double theta_end = 1.04;   ///< [rad]
  double phi_end = 14.0;     ///< [rad]
  double duration = 600.0;   ///< [s]

  double theta_rate() const { return (theta_end - theta_start) / duration; }  ///< ς [rad/s]
  double phi_rate() const { return (phi_end - phi_start) / duration; }        ///< ε [rad/s]
  /// Desired (ϑ, φ) at time t [s] since the path started; held at the end point after `duration`.
  Eigen::Vector2d angles(double t) const {
    const double tc = std::max(0.0, std::min(t, duration));
    return Eigen::Vector2d(theta_start + theta_rate() * tc, phi_start + phi_rate() * tc);
  }
  Vec3 direction_at(double t) const {
    const auto a = angles(t);
    return direction(a[0], a[1]);
  }
  bool finished(double t) const { return t >= duration; }
};

}  // namespace control
}  // namespace hydrojet
