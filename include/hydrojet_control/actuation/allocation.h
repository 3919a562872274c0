// Jet-force allocation, Campisano et al. 2021, §4, eq. (20) (the "RedundancyOpt" branch of
// Algorithm 1). ROS-free (Eigen only).
//
//   minimise   ‖A q − w_des‖² + λ ‖q‖²     subject to   q_min ≤ q ≤ q_max
//
// The paper writes the target as w_a + ẇ^b (eq. 19) and uses λ = 1; here the caller forms w_des and
// chooses λ ≥ 0. The paper's upper bound is strict (q < q_max); here the box is closed.
//
// Solved EXACTLY (up to rounding) by active-set enumeration: with three variables every candidate
// active set — each q_i free, at its lower bound or at its upper bound, 3³ = 27 sets — is tried; the
// free variables solve the reduced regularised least-squares problem
//   min ‖A_F q_F − (w_des − A_B q_B)‖² + λ‖q_F‖²
// (column-pivoting Householder QR of the stacked [A_F; √λ I], which is well conditioned for λ > 0),
// infeasible candidates are dropped and the feasible one with the lowest objective wins. The
// problem is convex and the optimum's own active set is among the 27, so this is the global
// minimum. λ = 0 with rank-deficient A (e.g. HydroJet's 2×3, or 3 free jets with 2 rows): the
// optimum need not be unique, but a "basic" optimum — free columns of A independent — always
// exists, so sets with dependent free columns are skipped. Ties within 1e-12·‖w_des‖² are broken
// towards the smaller ‖q‖ (less jet effort) among the candidates.
// No heap allocation: all matrices have fixed maximum sizes.
#pragma once

#include <string>

#include <Eigen/Core>

namespace hydrojet {
namespace actuation {

/// Actuation matrix: 1..6 wrench rows (e.g. JetMap::planar() or rows of JetMap::wrench_matrix()),
/// one column per jet [N or N m per N of jet force].
using AllocMatrix = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::ColMajor, 6, 3>;
/// Wrench with the same rows as AllocMatrix [N, N m].
using AllocVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 6, 1>;

struct AllocationResult {
  /// Jet forces [N]; the exact minimiser of eq. (20). Zeros (jets off) when !ok.
  Eigen::Vector3d q = Eigen::Vector3d::Zero();
  /// ‖A q − w_des‖ of the returned q [N, N m]; NaN when !ok.
  double residual_norm = 0.0;
  /// True iff w_des lies in the reachable set {A q : q_min ≤ q ≤ q_max}, up to
  ///   min_{q in box} ‖A q − w_des‖ ≤ tolerance · max(1, ‖w_des‖).
  /// Independent of λ: with λ > 0 the returned q trades residual for a smaller ‖q‖, so its
  /// residual_norm may exceed the tolerance even when reachable is true (then the λ = 0 problem is
  /// solved as well to decide). With λ = 0, reachable ⇔ residual_norm ≤ tolerance·max(1,‖w_des‖).
  bool reachable = false;
  /// False on invalid input (non-finite values, size mismatch, q_min > q_max, λ < 0); then q = 0.
  bool ok = false;
  /// Empty when ok, else names the offending argument.
  std::string message;
};

/// Solves eq. (20) exactly. A: 1..6 rows × 3; w_des: A.rows() entries; q_min ≤ q_max [N];
/// lambda ≥ 0 [1, relative to A's units]; tolerance ≥ 0: relative reachability tolerance (see
/// AllocationResult::reachable).
AllocationResult allocate(const AllocMatrix& A, const AllocVector& w_des, const Eigen::Vector3d& q_min,
                          const Eigen::Vector3d& q_max, double lambda, double tolerance = 1e-9);

/// Objective of eq. (20): ‖A q − w_des‖² + λ‖q‖².
double allocation_objective(const AllocMatrix& A, const AllocVector& w_des, const Eigen::Vector3d& q, double lambda);

}  // namespace actuation
}  // namespace hydrojet
