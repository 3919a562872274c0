// Internal to hydrojet_rod: the damped Newton iteration on the tip orientation R(L) (the shooting
// unknown x of eq. 15, R(L) ← R(L)·exp(x̂)), written once for ShootingSolver and GeneralRodSolver.
// Not installed.
#pragma once

#include <Eigen/LU>
#include <cmath>

#include "hydrojet_control/rod/shooting_solver.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace rod {
namespace internal {

/// Newton with a step cap (options.max_step [rad]) and a backtracking line search on |r| from
/// *R_tip. `evaluate(R)` returns an evaluation with members ok, r (residual log R(0)) and J (∂r/∂x).
/// True when |r| ≤ options.residual_tolerance; *R_tip then holds the root and *last its evaluation.
/// sol gets the iterations, the residual and, on failure, the reason.
template <class Eval, class Evaluate>
bool damped_newton(Evaluate&& evaluate, const ShootingOptions& options, Mat3* R_tip, RodSolution* sol, Eval* last) {
  Eval e = evaluate(*R_tip);
  for (int it = 0;; ++it) {
    if (!e.ok) {
      sol->message = "integration failed (non-finite state or step limit)";
      return false;
    }
    sol->residual = e.r.norm();
    if (sol->residual <= options.residual_tolerance) {
      *last = e;
      return true;
    }
    if (it >= options.max_iterations) {
      sol->message = "Newton iteration limit reached";
      *last = e;
      return false;
    }
    ++sol->iterations;
    Eigen::PartialPivLU<Mat3> lu(e.J);
    Vec3 step = -lu.solve(e.r);
    if (!step.allFinite() || std::abs(e.J.determinant()) < 1e-300) {
      sol->message = "singular shooting Jacobian";
      *last = e;
      return false;
    }
    const double n = step.norm();
    if (n > options.max_step) step *= options.max_step / n;
    bool accepted = false;
    double alpha = 1.0;
    for (int k = 0; k < 10; ++k, alpha *= 0.5) {
      const Mat3 R_try = *R_tip * so3::exp(alpha * step);
      Eval t = evaluate(R_try);
      if (t.ok && t.r.norm() < (1.0 - 1e-4 * alpha) * sol->residual) {
        *R_tip = so3::orthonormalize(R_try);
        e = t;
        accepted = true;
        break;
      }
    }
    if (!accepted) {
      sol->message = "line search failed (no descent)";
      *last = e;
      return false;
    }
  }
}

}  // namespace internal
}  // namespace rod
}  // namespace hydrojet
