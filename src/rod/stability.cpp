#include "hydrojet_control/rod/stability.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <limits>

namespace hydrojet {
namespace rod {

StabilityReport stability(const Mat6& C, const ActuatedSet& actuated) {
  using Block = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;
  int idx[6];
  int n = 0;
  for (int i = 0; i < 6; ++i)
    if (actuated[i]) idx[n++] = i;
  StabilityReport rep;
  if (n == 0 || !C.allFinite()) return rep;
  Block Cb(n, n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) Cb(r, c) = C(idx[r], idx[c]);
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

Mat6 hybrid_compliance(const Mat3& R, const Mat6& C) {
  Mat6 out;
  out.topRows<3>() = R * C.topRows<3>();
  out.bottomRows<3>() = R * C.bottomRows<3>();
  return out;
}

}  // namespace rod
}  // namespace hydrojet
