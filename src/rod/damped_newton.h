// Internal to hydrojet_rod: the damped Newton iteration of the shooting problems, written once for
// single shooting (unknown: the tip orientation R(L), R(L) ← R(L)·exp(x̂)) and multiple shooting
// (unknowns: the node states). Not installed.
#pragma once

#include <Eigen/LU>
#include <cmath>

#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace rod {
namespace internal {

/// Backtracking halvings of the line search before it gives up.
constexpr int kLineSearchHalvings = 12;

/// Newton with a step cap (options.max_step [rad], in the problem's own measure) and a backtracking
/// line search on the residual norm from *x. The problem P provides, for its unknowns X and its
/// evaluation E:
///   E evaluate(const X&)                        with members ok and a residual
///   double residual(const E&)                   the residual's norm
///   bool step(const E&, Step* dx)               the Newton step; false when the Jacobian is singular
///   double size(const Step&)                    the step's size compared with max_step
///   X moved(const X&, const Step&, double a)    the unknowns moved by a·dx (evaluated as they are)
///   X accepted(X)                               the unknowns of an accepted step, tidied (re-orthonormalised)
/// True when the residual ≤ options.residual_tolerance; *x then holds the root and *last its
/// evaluation. sol gets the iterations, the residual and, on failure, the reason.
template <class P, class X, class E>
bool damped_newton(P& p, const ShootingOptions& options, X* x, RodSolution* sol, E* last) {
  E e = p.evaluate(*x);
  for (int it = 0;; ++it) {
    if (!e.ok) {
      sol->message = "integration failed (non-finite state or step limit)";
      return false;
    }
    sol->residual = p.residual(e);
    if (sol->residual <= options.residual_tolerance) {
      *last = std::move(e);
      return true;
    }
    if (it >= options.max_iterations) {
      sol->message = "Newton iteration limit reached";
      *last = std::move(e);
      return false;
    }
    ++sol->iterations;
    typename P::Step step;
    if (!p.step(e, &step)) {
      sol->message = "singular shooting Jacobian";
      *last = std::move(e);
      return false;
    }
    const double n = p.size(step);
    if (n > options.max_step) step *= options.max_step / n;
    bool accepted = false;
    double alpha = 1.0;
    for (int k = 0; k < kLineSearchHalvings; ++k, alpha *= 0.5) {
      X trial = p.moved(*x, step, alpha);
      E t = p.evaluate(trial);
      if (t.ok && p.residual(t) < (1.0 - 1e-4 * alpha) * sol->residual) {
        *x = p.accepted(std::move(trial));
        e = std::move(t);
        accepted = true;
        break;
      }
    }
    if (!accepted) {
      sol->message = "line search failed (no descent)";
      *last = std::move(e);
      return false;
    }
  }
}

}  // namespace internal
}  // namespace rod
}  // namespace hydrojet
