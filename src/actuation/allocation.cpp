#include "hydrojet_control/actuation/allocation.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/QR>

namespace hydrojet {
namespace actuation {

namespace {

using StackedMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, 9, 3>;
using StackedVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 9, 1>;

struct Candidate {
  Eigen::Vector3d q = Eigen::Vector3d::Zero();
  double cost = std::numeric_limits<double>::infinity();
};

/// Exact minimiser of eq. (20) over the box by enumeration of the 27 active sets.
Candidate solve_box(const AllocMatrix& A, const AllocVector& w, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                    double lambda) {
  const Eigen::Index m = A.rows();
  const double sqrt_lambda = std::sqrt(lambda);
  const double tie = 1e-12 * w.squaredNorm();
  Candidate best;
  for (int code = 0; code < 27; ++code) {
    int state[3];  // 0 free, 1 at lower bound, 2 at upper bound
    int free_idx[3];
    int nf = 0;
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    for (int i = 0, c = code; i < 3; ++i, c /= 3) {
      state[i] = c % 3;
      if (state[i] == 0)
        free_idx[nf++] = i;
      else
        q(i) = state[i] == 1 ? lo(i) : hi(i);
    }
    if (nf > 0) {
      // Reduced problem: min ‖[A_F; √λ I] q_F − [w − A_B q_B; 0]‖².
      StackedMatrix M = StackedMatrix::Zero(m + nf, nf);
      StackedVector b = StackedVector::Zero(m + nf);
      b.head(m) = w - A * q;  // q holds only the bound entries here
      for (int k = 0; k < nf; ++k) {
        M.col(k).head(m) = A.col(free_idx[k]);
        M(m + k, k) = sqrt_lambda;
      }
      const Eigen::ColPivHouseholderQR<StackedMatrix> qr(M);
      // Rank deficient (only possible for λ = 0): skip. A convex quadratic with λ = 0 always has a
      // "basic" optimum whose free columns are independent (move along a null direction of A_F,
      // which leaves the objective unchanged, until one more bound becomes active), so no optimum
      // is lost; the solution set of a deficient A_F is covered by sets with more bounds.
      if (qr.rank() < nf) continue;
      const StackedVector x = qr.solve(b);
      bool feasible = true;
      for (int k = 0; k < nf && feasible; ++k) {
        const int i = free_idx[k];
        const double slack = 1e-12 * std::max({std::abs(lo(i)), std::abs(hi(i)), 1e-300});
        feasible = std::isfinite(x(k)) && x(k) >= lo(i) - slack && x(k) <= hi(i) + slack;
        q(i) = std::min(std::max(x(k), lo(i)), hi(i));
      }
      if (!feasible) continue;
    }
    const double cost = allocation_objective(A, w, q, lambda);
    if (cost < best.cost - tie || (cost <= best.cost + tie && q.squaredNorm() < best.q.squaredNorm())) {
      best.q = q;
      best.cost = cost;
    }
  }
  return best;
}

AllocationResult failure(const std::string& message) {
  AllocationResult r;
  r.residual_norm = std::numeric_limits<double>::quiet_NaN();
  r.message = message;
  return r;
}

}  // namespace

double allocation_objective(const AllocMatrix& A, const AllocVector& w_des, const Eigen::Vector3d& q, double lambda) {
  return (A * q - w_des).squaredNorm() + lambda * q.squaredNorm();  // eq. (20)
}

AllocationResult allocate(const AllocMatrix& A, const AllocVector& w_des, const Eigen::Vector3d& q_min,
                          const Eigen::Vector3d& q_max, double lambda, double tolerance) {
  if (A.rows() < 1) return failure("A: needs 1..6 rows");
  if (w_des.rows() != A.rows()) return failure("w_des: size must equal A.rows()");
  if (!A.allFinite()) return failure("A: non-finite entry");
  if (!w_des.allFinite()) return failure("w_des: non-finite entry");
  if (!q_min.allFinite()) return failure("q_min: non-finite entry");
  if (!q_max.allFinite()) return failure("q_max: non-finite entry");
  if (!(q_min.array() <= q_max.array()).all()) return failure("q_min/q_max: q_min > q_max");
  if (!std::isfinite(lambda) || lambda < 0.0) return failure("lambda: must be finite and >= 0");
  if (!std::isfinite(tolerance) || tolerance < 0.0) return failure("tolerance: must be finite and >= 0");

  const Candidate best = solve_box(A, w_des, q_min, q_max, lambda);
  AllocationResult r;
  r.ok = true;
  r.q = best.q;
  r.residual_norm = (A * r.q - w_des).norm();
  const double reach_residual =
      lambda == 0.0 ? r.residual_norm : (A * solve_box(A, w_des, q_min, q_max, 0.0).q - w_des).norm();
  r.reachable = reach_residual <= tolerance * std::max(1.0, w_des.norm());
  return r;
}

}  // namespace actuation
}  // namespace hydrojet
