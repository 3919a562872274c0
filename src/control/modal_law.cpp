#include "hydrojet_control/control/modal_law.h"

#include <cmath>
#include <unsupported/Eigen/MatrixFunctions>

namespace hydrojet {
namespace control {

void modal_transition(double omega, double zeta, double dt, Eigen::Matrix3d* A, Eigen::Vector3d* B) {
  Eigen::Matrix4d F = Eigen::Matrix4d::Zero();  // (y, v, d, s)
  F(0, 1) = 1.0;
  F(1, 0) = -omega * omega, F(1, 1) = -2.0 * zeta * omega, F(1, 2) = F(1, 3) = omega * omega;
  const Eigen::Matrix4d E = (F * dt).exp();
  *A = E.topLeftCorner<3, 3>();
  *B = E.topRightCorner<3, 1>();
}

void ModalEstimator::start(const Vec3& z, const Vec3& s, double omega, const ModalLawOptions& o) {
  x_.row(0) = z.transpose();
  x_.row(1).setZero();
  x_.row(2) = (z - s).transpose();
  const double sigma = o.tracker_sigma;
  P_ = Eigen::Vector3d(sigma * sigma, std::pow(sigma * omega, 2), 0.03 * 0.03).asDiagonal();
  initialised_ = true;
}

void ModalEstimator::step(const Vec3& s, const Vec3& z, double omega, double zeta, double dt,
                          const ModalLawOptions& o) {
  Eigen::Matrix3d A;
  Eigen::Vector3d B;
  modal_transition(omega, zeta, dt, &A, &B);
  x_ = A * x_ + B * s.transpose();
  P_ = A * P_ * A.transpose();
  P_.diagonal() +=
      Eigen::Vector3d(0.0, o.velocity_noise * o.velocity_noise * dt, o.disturbance_noise * o.disturbance_noise * dt);
  if (!z.allFinite()) return;
  // z = y + noise: H = (1, 0, 0); Joseph form.
  const double R = o.tracker_sigma * o.tracker_sigma;
  const Eigen::Vector3d K = P_.col(0) / (P_(0, 0) + R);
  x_ += K * (z.transpose() - x_.row(0));
  Eigen::Matrix3d IKH = Eigen::Matrix3d::Identity();
  IKH.col(0) -= K;
  P_ = IKH * P_ * IKH.transpose() + R * K * K.transpose();
}

Vec3 modal_shaping(const ReferenceMotion& r, const Vec3& estimated_rate, double omega, double zeta,
                   const ModalLawOptions& o) {
  const double tau = o.actuator_lag;
  return (tau + 2.0 * zeta / omega) * r.rate + (1.0 / (omega * omega) + 2.0 * zeta * tau / omega) * r.accel -
         o.damping_gain * (estimated_rate - r.rate_now) / omega;
}

}  // namespace control
}  // namespace hydrojet
