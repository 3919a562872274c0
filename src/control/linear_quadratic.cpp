#include "hydrojet_control/control/linear_quadratic.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>

namespace hydrojet {
namespace control {

bool solve_dare(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& Q, const Eigen::MatrixXd& R,
                Eigen::MatrixXd* P, int max_iterations) {
  const Eigen::Index n = A.rows();
  if (A.cols() != n || B.rows() != n || Q.rows() != n || Q.cols() != n || R.rows() != B.cols() || R.cols() != B.cols())
    return false;
  const Eigen::LLT<Eigen::MatrixXd> r(R);  // fails unless R is positive definite
  if (r.info() != Eigen::Success) return false;
  Eigen::MatrixXd Ak = A, Gk = B * r.solve(B.transpose()), Hk = Q;
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  for (int k = 0; k < max_iterations; ++k) {
    const Eigen::PartialPivLU<Eigen::MatrixXd> W(I + Gk * Hk);
    const Eigen::MatrixXd WA = W.solve(Ak), WG = W.solve(Gk);
    const Eigen::MatrixXd H_next = Hk + Ak.transpose() * Hk * WA;
    Gk = Gk + Ak * WG * Ak.transpose();
    Ak = Ak * WA;
    // Max norms: a diverging H (not stabilisable) overflows them to inf, which then fails the test.
    const double change = (H_next - Hk).cwiseAbs().maxCoeff();
    Hk = 0.5 * (H_next + H_next.transpose());
    if (!Hk.allFinite()) return false;
    if (change <= 1e-13 * std::max(1.0, Hk.cwiseAbs().maxCoeff())) {
      *P = Hk;
      return true;
    }
  }
  return false;
}

Eigen::MatrixXd lqr_gain(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& R,
                         const Eigen::MatrixXd& P) {
  const Eigen::MatrixXd BtP = B.transpose() * P;
  return (R + BtP * B).ldlt().solve(BtP * A);
}

void KalmanFilter::predict(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::VectorXd& u,
                           const Eigen::MatrixXd& Q) {
  x_ = A * x_ + (B.cols() > 0 ? Eigen::VectorXd(B * u) : Eigen::VectorXd::Zero(x_.size()));
  P_ = A * P_ * A.transpose() + Q;
  P_ = 0.5 * (P_ + P_.transpose());
}

bool KalmanFilter::update(const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, const Eigen::VectorXd& z) {
  if (!z.allFinite()) return false;
  const Eigen::MatrixXd S = H * P_ * H.transpose() + R;
  const Eigen::LDLT<Eigen::MatrixXd> s(S);
  if (s.info() != Eigen::Success || !s.isPositive()) return false;
  const Eigen::MatrixXd K = s.solve(H * P_).transpose();  // P Hᵀ S⁻¹ (S, P symmetric)
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(P_.rows(), P_.cols()) - K * H;
  x_ += K * (z - H * x_);
  P_ = IKH * P_ * IKH.transpose() + K * R * K.transpose();
  return true;
}

}  // namespace control
}  // namespace hydrojet
