#include "hydrojet_control/control/resolved_rates.h"

#include <Eigen/Cholesky>

#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace control {

Vec3 DirectionPd::correction(const Vec3& observed, const Vec3& desired, double dt, const ControllerOptions& gains) {
  const Vec3 err = rotation_between(observed, desired);  // x_err of eq. (17)
  if (!primed_) {
    prev_error_ = err;
    prev_desired_ = desired;
    primed_ = true;
  }
  const Vec3 x_cntr = gains.kp * dt * err + gains.kd * (err - prev_error_) +
                      gains.feedforward * rotation_between(prev_desired_, desired);
  prev_error_ = err;
  prev_desired_ = desired;
  return x_cntr;
}

Eigen::Vector2d force_change(const Mat3& tip_rotation, const rod::Mat6& body_compliance, const Vec3& x_cntr,
                             double damping) {
  const Vec3 d = tip_rotation.col(2);  // the model's tip direction
  const Eigen::Matrix<double, 3, 2> J_omega = tip_rotation * body_compliance.block<3, 2>(3, 0);
  const Eigen::Matrix<double, 3, 2> M = -so3::hat(d) * J_omega;
  const Vec3 dd = x_cntr.cross(d);
  const Eigen::Matrix2d H = M.transpose() * M + damping * damping * Eigen::Matrix2d::Identity();
  return H.ldlt().solve(M.transpose() * dd);
}

}  // namespace control
}  // namespace hydrojet
