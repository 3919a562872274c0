#include "hydrojet_control/rod/stability.h"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <cmath>
#include <limits>

namespace hydrojet {
namespace rod {

namespace {

using Block = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;

/// σ_c and the eigenvalue indicator of one compliance block (eqs. 21–23).
StabilityReport block_report(const Block& Cb) {
  StabilityReport rep;
  const int n = static_cast<int>(Cb.rows());
  // eq. (21)–(22): S = (C^b)^† = V Σ^† Uᵀ.
  Eigen::JacobiSVD<Block> svd(Cb, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const auto& sv = svd.singularValues();
  const double tol = sv(0) * n * std::numeric_limits<double>::epsilon();
  Block sinv = Block::Zero(n, n);
  for (int i = 0; i < n; ++i)
    if (sv(i) > tol) sinv(i, i) = 1.0 / sv(i);
  const Block S = svd.matrixV() * sinv * svd.matrixU().transpose();
  // eq. (23): σ_c = min diag(Σ^†) = 1/σ_max(C^b_block).
  rep.margin = sv(0) > 0.0 ? 1.0 / sv(0) : 0.0;
  Eigen::EigenSolver<Block> es(S, false);
  rep.eig_min = es.eigenvalues().real().minCoeff();
  rep.ok = std::isfinite(rep.margin) && std::isfinite(rep.eig_min);
  return rep;
}

}  // namespace

StabilityReport stability(const Mat6& C, const ActuatedSet& actuated) {
  int idx[6];
  int n = 0;
  for (int i = 0; i < 6; ++i)
    if (actuated[i]) idx[n++] = i;
  if (n == 0 || !C.allFinite()) return StabilityReport();
  Block Cb(n, n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) Cb(r, c) = C(idx[r], idx[c]);
  return block_report(Cb);
}

StabilityReport stability(const Mat6& C, const Eigen::Ref<const Eigen::Matrix<double, 6, Eigen::Dynamic>>& wrenches,
                          double arm) {
  if (wrenches.cols() == 0 || !C.allFinite() || !wrenches.allFinite() || !(arm > 0.0)) return StabilityReport();
  // Moments as forces at the arm: wrench (f, m/arm), twist (v, ω·arm), so C̃ = D C D, D = diag(1, arm).
  Vec6 D;
  D << 1.0, 1.0, 1.0, arm, arm, arm;
  const Mat6 Cs = D.asDiagonal() * C * D.asDiagonal();
  const Eigen::Matrix<double, 6, Eigen::Dynamic> Ws = D.cwiseInverse().asDiagonal() * wrenches;
  // U: an orthonormal basis of the span of the actuators' tip wrenches (rank by the SVD).
  Eigen::JacobiSVD<Eigen::Matrix<double, 6, Eigen::Dynamic>> svd(Ws, Eigen::ComputeThinU);
  const auto& sv = svd.singularValues();
  if (!(sv(0) > 0.0)) return StabilityReport();
  int r = 0;
  while (r < sv.size() && sv(r) > 1e-9 * sv(0)) ++r;
  const Eigen::Matrix<double, 6, Eigen::Dynamic> U = svd.matrixU().leftCols(r);
  return block_report(Block(U.transpose() * Cs * U));
}

Vec6 softest_wrench_direction(const Mat6& C, const ActuatedSet& a) {
  int idx[6], n = 0;
  for (int i = 0; i < 6; ++i)
    if (a[i]) idx[n++] = i;
  if (n == 0 || !C.allFinite()) return Vec6::Constant(std::nan(""));
  Eigen::MatrixXd block(n, n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) block(r, c) = C(idx[r], idx[c]);
  const Eigen::MatrixXd S = block.completeOrthogonalDecomposition().pseudoInverse();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (S + S.transpose()));
  if (es.info() != Eigen::Success) return Vec6::Constant(std::nan(""));
  Vec6 d = Vec6::Zero();
  for (int k = 0; k < n; ++k) d[idx[k]] = es.eigenvectors()(k, 0);
  return d;
}

Eigen::Matrix<double, 6, Eigen::Dynamic> equivalent_tip_wrenches(
    const Mat6& C, const Eigen::Ref<const Eigen::Matrix<double, 6, Eigen::Dynamic>>& actuation_jacobian) {
  // Pseudo-inverse with singular values below 1e-9 σ_max dropped (the inextensible rod's axial
  // directions): a twist the actuators cannot make must not become a huge wrench.
  Eigen::JacobiSVD<Mat6> svd(C, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const auto& sv = svd.singularValues();
  Vec6 inv = Vec6::Zero();
  for (int i = 0; i < 6; ++i)
    if (sv(i) > 1e-9 * sv(0)) inv(i) = 1.0 / sv(i);
  return svd.matrixV() * inv.asDiagonal() * svd.matrixU().transpose() * actuation_jacobian;
}

Mat6 hybrid_compliance(const Mat3& R, const Mat6& C) {
  Mat6 out;
  out.topRows<3>() = R * C.topRows<3>();
  out.bottomRows<3>() = R * C.bottomRows<3>();
  return out;
}

}  // namespace rod
}  // namespace hydrojet
