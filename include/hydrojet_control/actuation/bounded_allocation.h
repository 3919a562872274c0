// Eq. (20) for any actuator set: N ≤ 8 inputs with lower and upper bounds, any set of
// actuated wrench components (1..6 rows). ROS-free (Eigen only).
//
//   minimise   ‖A q − w_des‖² + λ ‖q‖²     subject to   q_min ≤ q ≤ q_max
//
// Solved exactly (up to rounding) by a primal active-set method for the box-constrained convex QP
// (Nocedal & Wright, Numerical Optimization, §16.5): from a feasible start, solve the equality
// problem on the free inputs (Cholesky of H_FF, H = AᵀA + λI), step to it or to the first bound in
// the way, and when the step is zero release the bound with the most negative multiplier; optimal
// when every multiplier is ≥ 0 (the KKT conditions). The 27-set enumeration of allocation.h does the
// same for three inputs but grows as 3^N; this one takes a few iterations for any N (warm-started
// from the last solution, one or two). λ = 0 with a rank-deficient A (more inputs than actuated
// components): the optimum is not unique, and H is made definite with λ_min = 1e-12·tr(AᵀA)/N, which
// picks the smaller-norm optimum and changes the objective by less than λ_min‖q‖².
// No heap allocation: fixed maximum sizes.
#pragma once

#include <Eigen/Core>
#include <string>

#include "hydrojet_control/actuation/allocation.h"
#include "hydrojet_control/rod/rod_model.h"

namespace hydrojet {
namespace actuation {

using rod::kMaxInputs;
/// Actuation matrix: 1..6 wrench rows × 1..8 inputs.
using InputMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, 6, kMaxInputs>;
using rod::InputVector;

struct BoundedAllocationResult {
  InputVector q;               ///< the minimiser of eq. (20); zeros when !ok
  double residual_norm = 0.0;  ///< ‖A q − w_des‖; NaN when !ok
  /// As AllocationResult::reachable: min over the box of ‖A q − w_des‖ ≤ tolerance·max(1, ‖w_des‖),
  /// independent of λ.
  bool reachable = false;
  bool ok = false;      ///< false on invalid input or when the iteration did not finish (then q = 0)
  int iterations = 0;   ///< active-set iterations
  std::string message;  ///< empty when ok, else names the argument or the failure
};

/// Solves eq. (20) exactly for N inputs. A: 1..6 rows × N columns; w_des: A.rows(); q_min ≤ q_max (N
/// each, finite); λ ≥ 0; `start` (optional, N entries): a warm start, clamped into the box.
BoundedAllocationResult allocate_bounded(const InputMatrix& A, const AllocVector& w_des, const InputVector& q_min,
                                         const InputVector& q_max, double lambda, double tolerance = 1e-9,
                                         const InputVector* start = nullptr);

/// Symmetric N×N matrix of a box-constrained QP.
using InputHessian = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, kMaxInputs, kMaxInputs>;

struct BoxQpResult {
  InputVector q;        ///< the minimiser; zeros when !ok
  bool ok = false;      ///< false on invalid input or when the iteration did not finish
  int iterations = 0;   ///< active-set iterations
  std::string message;  ///< empty when ok, else names the argument or the failure
};

/// The problem under eq. (20) in its general form: minimise ½ qᵀ H q − gᵀ q over q_min ≤ q ≤ q_max,
/// H symmetric positive definite (N ≤ 8), by the same active-set iteration; `start` as above. The
/// controller's step on the actuation Jacobian (resolved_rates.h) is one.
BoxQpResult minimise_box_qp(const InputHessian& H, const InputVector& g, const InputVector& q_min,
                            const InputVector& q_max, const InputVector* start = nullptr);

/// Objective of eq. (20) for N inputs: ‖A q − w_des‖² + λ‖q‖².
double bounded_allocation_objective(const InputMatrix& A, const AllocVector& w_des, const InputVector& q,
                                    double lambda);

}  // namespace actuation
}  // namespace hydrojet
