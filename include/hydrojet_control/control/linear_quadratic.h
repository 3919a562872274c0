// Linear-quadratic building blocks of the model-based law: the discrete algebraic Riccati equation
// (LQR gains), and a linear Kalman filter. ROS-free (Eigen only). Dynamic sizes (the models are
// small, 4–12 states); the calls allocate.
//
// DARE:  P = AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q, solved by the structure-preserving doubling
// algorithm (Chu et al. 2004, quadratic convergence):
//   W = I + G_k H_k,  A_{k+1} = A_k W⁻¹ A_k,  G_{k+1} = G_k + A_k W⁻¹ G_k A_kᵀ,
//   H_{k+1} = H_k + A_kᵀ H_k W⁻¹ A_k,  from A_0 = A, G_0 = B R⁻¹ Bᵀ, H_0 = Q;  H_k → P.
// LQR gain: u = −K x with K = (R + BᵀPB)⁻¹ BᵀPA.
//
// Kalman filter (discrete): predict x ← A x + B u, P ← A P Aᵀ + Q; update with z = H x + v,
// v ~ N(0, R): S = H P Hᵀ + R, K = P Hᵀ S⁻¹, x ← x + K (z − H x), P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ
// (Joseph form: P stays symmetric and positive definite in floating point).
#pragma once

#include <Eigen/Core>

namespace hydrojet {
namespace control {

/// P of the DARE for (A, B, Q, R); false when it does not converge (not stabilisable, Q or R not
/// definite enough, a non-finite entry) within `max_iterations` doublings.
bool solve_dare(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& Q, const Eigen::MatrixXd& R,
                Eigen::MatrixXd* P, int max_iterations = 60);

/// K = (R + BᵀPB)⁻¹ BᵀPA.
Eigen::MatrixXd lqr_gain(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& R,
                         const Eigen::MatrixXd& P);

class KalmanFilter {
 public:
  /// Initial estimate x0 with covariance P0.
  void reset(const Eigen::VectorXd& x0, const Eigen::MatrixXd& P0) {
    x_ = x0;
    P_ = P0;
  }
  void predict(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::VectorXd& u, const Eigen::MatrixXd& Q);
  /// False (and no change) when the innovation's covariance is not invertible or z is not finite.
  bool update(const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, const Eigen::VectorXd& z);
  const Eigen::VectorXd& state() const { return x_; }
  const Eigen::MatrixXd& covariance() const { return P_; }

 private:
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
};

}  // namespace control
}  // namespace hydrojet
