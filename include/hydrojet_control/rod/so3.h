// SO(3) helpers used by the rod model: hat/vee, exponential and logarithm, the inverse right
// Jacobian, and quaternion output. ROS-free (Eigen only).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace hydrojet {
namespace so3 {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

/// Skew-symmetric matrix û with û v = u × v.
inline Mat3 hat(const Vec3& u) {
  Mat3 m;
  m << 0.0, -u.z(), u.y(), u.z(), 0.0, -u.x(), -u.y(), u.x(), 0.0;
  return m;
}

/// Inverse of hat for a skew-symmetric matrix.
inline Vec3 vee(const Mat3& m) { return Vec3(m(2, 1), m(0, 2), m(1, 0)); }

/// Rodrigues' formula: exp(ŵ) for a rotation vector w [rad].
inline Mat3 exp(const Vec3& w) {
  const double t2 = w.squaredNorm();
  const double t = std::sqrt(t2);
  double a, b;  // sin(t)/t, (1-cos(t))/t^2
  if (t < 1e-4) {
    a = 1.0 - t2 / 6.0;
    b = 0.5 - t2 / 24.0;
  } else {
    a = std::sin(t) / t;
    b = (1.0 - std::cos(t)) / t2;
  }
  const Mat3 W = hat(w);
  return Mat3::Identity() + a * W + b * W * W;
}

/// Rotation vector of R (angle in [0, π]).
inline Vec3 log(const Mat3& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

/// Inverse of the right Jacobian of SO(3): log(R exp(ε̂)) ≈ log(R) + Jr⁻¹(log R) ε.
inline Mat3 right_jacobian_inverse(const Vec3& r) {
  const double t2 = r.squaredNorm();
  const Mat3 W = hat(r);
  double c;  // (1/t² − (1+cos t)/(2 t sin t))
  if (t2 < 1e-8) {
    c = 1.0 / 12.0 + t2 / 720.0;
  } else {
    const double t = std::sqrt(t2);
    c = 1.0 / t2 - (1.0 + std::cos(t)) / (2.0 * t * std::sin(t));
  }
  return Mat3::Identity() + 0.5 * W + c * W * W;
}

/// Right Jacobian of SO(3): exp((r + δ)^) ≈ exp(r̂) exp((Jr(r) δ)^).
inline Mat3 right_jacobian(const Vec3& r) {
  const double t2 = r.squaredNorm();
  const Mat3 W = hat(r);
  double a, b;  // (1 − cos t)/t², (t − sin t)/t³
  if (t2 < 1e-8) {
    a = 0.5 - t2 / 24.0;
    b = 1.0 / 6.0 - t2 / 120.0;
  } else {
    const double t = std::sqrt(t2);
    a = (1.0 - std::cos(t)) / t2;
    b = (t - std::sin(t)) / (t2 * t);
  }
  return Mat3::Identity() - a * W + b * W * W;
}

/// Nearest rotation matrix (polar decomposition through the SVD-free quaternion route).
inline Mat3 orthonormalise(const Mat3& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  return q.toRotationMatrix();
}

/// Unit quaternion [w, x, y, z] with w ≥ 0.
inline Eigen::Vector4d quaternion_wxyz(const Mat3& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  Eigen::Vector4d out(q.w(), q.x(), q.y(), q.z());
  if (out[0] < 0.0) out = -out;
  return out;
}

}  // namespace so3
}  // namespace hydrojet
