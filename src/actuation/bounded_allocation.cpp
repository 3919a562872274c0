#include "hydrojet_control/actuation/bounded_allocation.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>

namespace hydrojet {
namespace actuation {

namespace {

using Hessian = InputHessian;

/// Where an input is in the working set.
enum Bound : int { kFree = 0, kLower = -1, kUpper = 1 };

BoundedAllocationResult failure(int n, const std::string& message) {
  BoundedAllocationResult r;
  r.q = InputVector::Zero(n);
  r.residual_norm = std::numeric_limits<double>::quiet_NaN();
  r.message = message;
  return r;
}

std::string check_inputs(const InputMatrix& A, const AllocVector& w, const InputVector& lo, const InputVector& hi,
                         double lambda, double tolerance, const InputVector* start) {
  const Eigen::Index n = A.cols();
  if (A.rows() < 1 || n < 1) return "A: needs 1..6 rows and 1..8 columns";
  if (w.rows() != A.rows()) return "w_des: size must equal A.rows()";
  if (lo.size() != n || hi.size() != n) return "q_min/q_max: one bound per column of A";
  if (start && start->size() != n) return "start: one entry per column of A";
  if (!A.allFinite()) return "A: non-finite entry";
  if (!w.allFinite()) return "w_des: non-finite entry";
  if (!lo.allFinite() || !hi.allFinite()) return "q_min/q_max: non-finite entry";
  if (!(lo.array() <= hi.array()).all()) return "q_min/q_max: q_min > q_max";
  if (start && !start->allFinite()) return "start: non-finite entry";
  if (!std::isfinite(lambda) || lambda < 0.0) return "lambda: must be finite and >= 0";
  if (!std::isfinite(tolerance) || tolerance < 0.0) return "tolerance: must be finite and >= 0";
  return "";
}

/// The Newton step to the minimum on the face of the free inputs: H_FF p_F = −grad_F, p = 0 elsewhere.
bool face_step(const Hessian& H, const InputVector& grad, const int* free_idx, int nf, InputVector* p) {
  Hessian Hf(nf, nf);
  InputVector rhs(nf);
  for (int a = 0; a < nf; ++a) {
    rhs[a] = -grad[free_idx[a]];
    for (int b = 0; b < nf; ++b) Hf(a, b) = H(free_idx[a], free_idx[b]);
  }
  const Eigen::LLT<Hessian> llt(Hf);
  if (llt.info() != Eigen::Success) return false;
  const InputVector pf = llt.solve(rhs);
  *p = InputVector::Zero(grad.size());
  for (int a = 0; a < nf; ++a) (*p)[free_idx[a]] = pf[a];
  return p->allFinite();
}

/// The primal active-set iteration on min ½qᵀHq − gᵀq over the box; false when it did not finish.
bool active_set(const Hessian& H, const InputVector& g, const InputVector& lo, const InputVector& hi, InputVector* q,
                int* iterations) {
  const int n = static_cast<int>(g.size());
  int state[kMaxInputs];
  for (int i = 0; i < n; ++i) state[i] = (*q)[i] <= lo[i] ? kLower : ((*q)[i] >= hi[i] ? kUpper : kFree);
  const double scale = H.cwiseAbs().maxCoeff() * std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff()) +
                       g.cwiseAbs().maxCoeff() + 1e-300;
  // at_minimum: q minimises the objective on the current face (after a full step to it, or when the
  // face has no free input); then the multipliers decide, without recomputing a step from rounding
  // noise (which a nearly singular H_FF would amplify).
  bool at_minimum = false;
  for (*iterations = 0; *iterations < 20 * n + 20; ++*iterations) {
    const InputVector grad = H * *q - g;
    int free_idx[kMaxInputs], nf = 0;
    for (int i = 0; i < n; ++i)
      if (state[i] == kFree) free_idx[nf++] = i;
    if (!at_minimum && nf > 0) {
      InputVector p;
      if (!face_step(H, grad, free_idx, nf, &p)) return false;
      // Step toward the face minimum, stopping at the first bound in the way.
      double alpha = 1.0;
      int block = -1;
      for (int a = 0; a < nf; ++a) {
        const int i = free_idx[a];
        const double to = p[i] < 0.0 ? (lo[i] - (*q)[i]) / p[i] : (p[i] > 0.0 ? (hi[i] - (*q)[i]) / p[i] : 2.0);
        if (to < alpha) alpha = std::max(0.0, to), block = i;
      }
      *q = (*q + alpha * p).cwiseMax(lo).cwiseMin(hi);
      if (block >= 0) {
        state[block] = p[block] < 0.0 ? kLower : kUpper;
        (*q)[block] = state[block] == kLower ? lo[block] : hi[block];
      }
      at_minimum = block < 0;
      continue;
    }
    // At the minimum on this face: release the bound whose multiplier is most negative.
    int worst = -1;
    double worst_mu = -1e-14 * scale;
    for (int i = 0; i < n; ++i) {
      if (state[i] == kFree || lo[i] == hi[i]) continue;
      const double mu = state[i] == kLower ? grad[i] : -grad[i];
      if (mu < worst_mu) worst_mu = mu, worst = i;
    }
    if (worst < 0) return true;  // KKT: every multiplier ≥ 0
    state[worst] = kFree;
    at_minimum = false;
  }
  return false;
}

/// min over the box of eq. (20) with the given λ (made definite as the header says); false on failure.
bool minimise(const InputMatrix& A, const AllocVector& w, const InputVector& lo, const InputVector& hi, double lambda,
              const InputVector& start, InputVector* q, int* iterations) {
  const Eigen::Index n = A.cols();
  const double floor = 1e-12 * A.squaredNorm() / static_cast<double>(n) + 1e-300;
  Hessian H = A.transpose() * A;
  H.diagonal().array() += std::max(lambda, floor);
  const InputVector g = A.transpose() * w;
  *q = start.cwiseMax(lo).cwiseMin(hi);
  return active_set(H, g, lo, hi, q, iterations);
}

}  // namespace

BoxQpResult minimise_box_qp(const InputHessian& H, const InputVector& g, const InputVector& q_min,
                            const InputVector& q_max, const InputVector* start) {
  BoxQpResult r;
  const Eigen::Index n = g.size();
  r.q = InputVector::Zero(n);
  if (n < 1 || H.rows() != n || H.cols() != n)
    r.message = "H: must be N x N with N = g.size() in 1..8";
  else if (q_min.size() != n || q_max.size() != n)
    r.message = "q_min/q_max: one bound per entry of g";
  else if (start && start->size() != n)
    r.message = "start: one entry per entry of g";
  else if (!H.allFinite() || !g.allFinite())
    r.message = "H/g: non-finite entry";
  else if (!q_min.allFinite() || !q_max.allFinite())
    r.message = "q_min/q_max: non-finite entry";
  else if (!(q_min.array() <= q_max.array()).all())
    r.message = "q_min/q_max: q_min > q_max";
  else if (start && !start->allFinite())
    r.message = "start: non-finite entry";
  if (!r.message.empty()) return r;
  InputVector q = (start ? *start : InputVector::Zero(n)).cwiseMax(q_min).cwiseMin(q_max);
  if (!active_set(H, g, q_min, q_max, &q, &r.iterations)) {
    r.message = "the active-set iteration did not finish (iteration limit or H not positive definite)";
    return r;
  }
  r.q = q;
  r.ok = true;
  return r;
}

double bounded_allocation_objective(const InputMatrix& A, const AllocVector& w_des, const InputVector& q,
                                    double lambda) {
  return (A * q - w_des).squaredNorm() + lambda * q.squaredNorm();  // eq. (20)
}

BoundedAllocationResult allocate_bounded(const InputMatrix& A, const AllocVector& w_des, const InputVector& q_min,
                                         const InputVector& q_max, double lambda, double tolerance,
                                         const InputVector* start) {
  const int n = static_cast<int>(std::max<Eigen::Index>(A.cols(), 0));
  const std::string bad = check_inputs(A, w_des, q_min, q_max, lambda, tolerance, start);
  if (!bad.empty()) return failure(n, bad);
  BoundedAllocationResult r;
  const InputVector from = start ? *start : InputVector::Zero(n);
  if (!minimise(A, w_des, q_min, q_max, lambda, from, &r.q, &r.iterations))
    return failure(n, "the active-set iteration did not finish (iteration limit or indefinite reduced Hessian)");
  r.ok = true;
  r.residual_norm = (A * r.q - w_des).norm();
  double reach = r.residual_norm;
  if (lambda > 0.0) {
    InputVector q0;
    int it = 0;
    reach = minimise(A, w_des, q_min, q_max, 0.0, r.q, &q0, &it) ? (A * q0 - w_des).norm() : r.residual_norm;
  }
  r.reachable = reach <= tolerance * std::max(1.0, w_des.norm());
  return r;
}

}  // namespace actuation
}  // namespace hydrojet
