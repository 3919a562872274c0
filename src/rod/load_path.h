// Internal to hydrojet_rod: the load path of a static solve — Newton from the start, load
// continuation and fold tracking — written once for single shooting (unknown: the tip orientation
// R(L)) and multiple shooting (unknowns: the node states). Not installed.
//
// A Problem (RodSolver::Shooting, RodSolver::MultipleShooting) provides:
//   Unknowns, Load, Point = PathPoint<Unknowns, Load>, Saved
//   kNewtonFromUnloaded                   Newton straight to the target from the unloaded shape
//   x, det, tip                           the current equilibrium (the result after the ladder)
//   target, sol                           the target load; the solution whose counters grow
//   load_between(from, to, t)             (found by argument lookup) the load a fraction t of the way
//   options(), length(), growth()         ShootingOptions, L, λL of the target load
//   newton(&x, load, &det, &tip)          Newton at one load from x (x updated in place)
//   turned_far(a, b)                      some frame of the unknowns turned by more than max_step
//   save(), restore(saved)                the problem's own state of a direct Newton result
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "hydrojet_control/rod/rod_model.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"
#include "hydrojet_control/rod/stability.h"

namespace hydrojet {
namespace rod {
namespace internal {

/// Continuation steps (fractions of the load change) below which a persisting jump of the solution
/// counts as a snap-through at a fold rather than a step that is too long.
constexpr double kSnapStep = 1.0 / 256.0;
/// λL above which a cold start may reach one of several equilibria (see prefer_load_path()).
constexpr double kSeveralEquilibriaGrowth = 4.0;

/// True when det ∂r/∂x changed sign from `from` to `to` (a zero or non-finite `from` never counts).
inline bool det_sign_changed(double from, double to) {
  return std::isfinite(from) && from != 0.0 && to != 0.0 && (to > 0.0) != (from > 0.0);
}

/// Counts sign changes of det ∂r/∂x between consecutive equilibria of a load path.
struct FoldTracker {
  double det = std::nan("");
  int crossings = 0;
  void start(double d) {
    det = d;
    crossings = 0;
  }
  void note(double d) {
    if (!std::isfinite(d) || d == 0.0) return;
    if (det_sign_changed(det, d)) ++crossings;
    det = d;
  }
  /// A snap-through: counted, and the new branch's det starts a new comparison.
  void snap() {
    ++crossings;
    det = std::nan("");
  }
};

/// Sets the fold report of a solution: the crossings and, when there were any, the warning.
inline void report_folds(const FoldTracker& folds, RodSolution* sol) {
  sol->fold_crossings = folds.crossings;
  if (folds.crossings > 0)
    sol->warning = "the load path crossed a fold or bifurcation " + std::to_string(folds.crossings) +
                   " time(s) (det of the shooting Jacobian changed sign, or the equilibrium snapped through); "
                   "the result may lie on another branch than the start: check stability (stability_eig_min)";
}

/// The cold-solve stability check's indicator: the smallest eigenvalue of the stiffness on the
/// components `checked` of the body compliance C^b (≤ 0: unstable); +inf when no component is
/// checked, NaN when C^b failed (`ok` false). `body_compliance` is called only when needed.
template <class Compliance>
double cold_stability_indicator(const ActuatedSet& checked, Compliance body_compliance) {
  if (std::none_of(checked.begin(), checked.end(), [](bool b) { return b; }))
    return std::numeric_limits<double>::infinity();
  bool ok = false;
  const Mat6 C = body_compliance(&ok);
  return ok ? stability(C, checked).eig_min : std::nan("");
}

/// Adds to sol's warning that its equilibrium is unstable (stability indicator ≤ 0) and that loading
/// from rest with a push found no stable one.
inline void warn_unstable(double indicator, RodSolution* sol) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "unstable equilibrium: stability indicator %.3g <= 0 (the rod cannot hold it; ",
                indicator);
  sol->warning = (sol->warning.empty() ? "" : sol->warning + "; ") + buf +
                 "loading from rest with a push along its softest direction found no stable one)";
}

/// One equilibrium of a load path: the unknowns at `load`, the tip position, det ∂r/∂x.
template <class Unknowns, class Load>
struct PathPoint {
  Unknowns x;
  Load load;
  Vec3 tip;
  double det;
};

/// The load-path Problem of shooting on the tip orientation R(L) (RodSolver::Shooting derives from
/// it): the current equilibrium and Newton's last evaluation
/// `e` (with ok, r, J, R0, p0). Derived provides options(), length(), growth() and
/// newton_at(&R, load, &e), the solver's damped Newton.
template <class Derived, class LoadT, class EvalT>
struct TipOrientationShooting {
  using Unknowns = Mat3;
  using Load = LoadT;
  using Point = PathPoint<Mat3, LoadT>;
  using Saved = EvalT;
  static constexpr bool kNewtonFromUnloaded = true;

  TipOrientationShooting(const LoadT& t, RodSolution* s) : target(t), sol(s) {}

  LoadT target;
  RodSolution* sol;
  Mat3 x = Mat3::Identity();
  double det = 0.0;
  Vec3 tip = Vec3::Zero();
  EvalT e;

  bool newton(Mat3* R, const LoadT& load, double* d, Vec3* p) {
    if (!static_cast<Derived*>(this)->newton_at(R, load, &e)) return false;
    *d = e.J.determinant();
    *p = -e.R0.transpose() * e.p0;
    return true;
  }
  bool turned_far(const Mat3& a, const Mat3& b) const {
    return so3::log(a.transpose() * b).norm() > static_cast<const Derived*>(this)->options().max_step;
  }
  Saved save() const { return e; }
  void restore(const Saved& direct) {
    e = direct;
    sol->residual = e.r.norm();
    sol->message.clear();
  }
};

/// Two equilibria are "far" apart when a frame turned by more than max_step or the tip moved by more
/// than L/4: more than a load step of a path should do; a jump to another branch or a snap-through.
template <class Problem, class Unknowns>
bool moved_far(const Problem& p, const Unknowns& a, const Vec3& pa, const Unknowns& b, const Vec3& pb) {
  return p.turned_far(a, b) || (pa - pb).norm() > 0.25 * p.length();
}

/// Load continuation from the equilibrium `from` to p.target. The step dl (a fraction of the load
/// change) starts at 1/4, halves when Newton fails or jumps, and doubles up to 1/2 after a success.
/// A step is taken when Newton stays near the previous equilibrium; a larger change is a jump to
/// another branch: the step is halved, and if the jump persists down to kSnapStep the path has
/// reached a fold and snaps through (taken and counted as a fold crossing). Gives up after
/// max_continuation_steps steps (counted in p.sol) or below dl = 1e-6. On success p.x, p.det and
/// p.tip hold the equilibrium at the target load.
template <class Problem>
bool follow_load_path(Problem& p, const typename Problem::Point& from, FoldTracker* folds) {
  typename Problem::Unknowns xc = from.x;
  Vec3 pc = from.tip;
  double lambda = 0.0, dl = 0.25, det = from.det;
  while (lambda < 1.0) {
    if (p.sol->continuation_steps >= p.options().max_continuation_steps || dl < 1e-6) return false;
    const double ln = std::min(1.0, lambda + dl);
    typename Problem::Unknowns xt = xc;
    double d = 0.0;
    Vec3 pt;
    ++p.sol->continuation_steps;
    if (!p.newton(&xt, load_between(from.load, p.target, ln), &d, &pt)) {
      dl *= 0.5;
      continue;
    }
    const bool jump = moved_far(p, xc, pc, xt, pt);
    if (jump && dl > kSnapStep) {
      dl *= 0.5;
      continue;
    }
    if (jump) folds->snap();
    xc = xt;
    pc = pt;
    lambda = ln;
    dl = std::min(2.0 * dl, 0.5);
    if (ln < 1.0) folds->note(d);
    det = d;
  }
  p.x = xc;
  p.det = det;
  p.tip = pc;
  return true;
}

/// Newton from `start` converged to p's current equilibrium. That is the equilibrium connected to
/// the start along the load path unless Newton (a) went across a singular shooting Jacobian (det
/// changed sign), or (b) moved far: a warm start that did (a snap, or another branch), or a cold
/// start of a strongly loaded rod (λL > 4, where several equilibria exist) that did. Then the load
/// path is followed instead (it reports folds and snap-throughs on the way); the direct result is
/// kept only if the path breaks down (Newton fails near a fold): it is where the rod snaps to, and
/// the snap is reported (a det sign change is counted when the caller notes the final det).
template <class Problem>
void prefer_load_path(Problem& p, const typename Problem::Point& start, bool warm, FoldTracker* folds) {
  const bool crossed = det_sign_changed(start.det, p.det);
  const bool far = moved_far(p, start.x, start.tip, p.x, p.tip) && (warm || p.growth() > kSeveralEquilibriaGrowth);
  if (!crossed && !far) return;
  const typename Problem::Saved direct = p.save();  // a failed path leaves x, det and tip as they are
  if (follow_load_path(p, start, folds)) return;
  p.restore(direct);
  folds->start(start.det);
  if (!crossed) ++folds->crossings;
}

/// The load-path part of the robustness ladder: Newton from the start (the warm solution, or the
/// unloaded shape when p allows it; from `guess` instead when given, a predictor's first-order
/// step from the warm solution), preferring the load path when Newton went far or crossed a
/// fold; else load continuation from the warm solution, then from the unloaded shape. True when
/// p.x holds an equilibrium at the target load; *folds counts the folds of the path taken.
template <class Problem>
bool reach_equilibrium(Problem& p, const typename Problem::Point& start, bool warm,
                       const typename Problem::Point& unloaded, FoldTracker* folds,
                       const typename Problem::Unknowns* guess = nullptr) {
  folds->start(start.det);
  p.x = guess ? *guess : start.x;
  bool ok = (warm || Problem::kNewtonFromUnloaded) && p.newton(&p.x, p.target, &p.det, &p.tip);
  if (ok) prefer_load_path(p, start, warm, folds);
  if (!ok && warm) {
    folds->start(start.det);
    ok = follow_load_path(p, start, folds);
  }
  if (!ok) {
    folds->start(unloaded.det);
    ok = follow_load_path(p, unloaded, folds);
  }
  return ok;
}

}  // namespace internal
}  // namespace rod
}  // namespace hydrojet
