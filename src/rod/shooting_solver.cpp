#include "hydrojet_control/rod/shooting_solver.h"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "hydrojet_control/rod/cvode_integrator.h"
#include "damped_newton.h"
#include "kinsol_workspace.h"
#include "load_path.h"
#include "rod_integration.h"
#include "solver_templates.h"

namespace hydrojet {
namespace rod {

using internal::FoldTracker;

ShootingSolver::Workspace::Workspace() = default;
ShootingSolver::Workspace::~Workspace() = default;

ShootingSolver::ShootingSolver(const RodModel& model, const ShootingOptions& settings)
    : model_(model), settings_(settings) {
  select_kernels();
  update_unloaded_shape();
}

void ShootingSolver::set_model(const RodModel& model) {
  model_ = model;
  select_kernels();
  update_unloaded_shape();
  reset();
}

void ShootingSolver::set_settings(const ShootingOptions& settings) {
  settings_ = settings;
  select_kernels();
  update_unloaded_shape();
}

void ShootingSolver::reset() {
  have_solution_ = false;
  multiple_ = false;
  R_tip_ = Mat3::Identity();
  nodes_ = Nodes();
}

void ShootingSolver::update_unloaded_shape() {
  // With no load u(s) = ũ solves eq. (14), so the unloaded tip frame is exp(L ũ^).
  unloaded_.tip_rotation = so3::exp(model_.rod.length * model_.rod.precurvature);
  int rhs = 0;
  const Eval u = evaluate(unloaded_.tip_rotation, Load::none(), &rhs);
  unloaded_.det = u.ok ? u.J.determinant() : std::nan("");
  unloaded_.tip_position = u.ok ? Vec3(-u.R0.transpose() * u.p0) : Vec3::Zero();
}

double ShootingSolver::growth_estimate(const TipWrench& w) const {
  const ElasticRod& rod = model_.rod;
  const double g = model_.gravity.norm();
  const double n = w.force.norm() + model_.tip_mass * g + rod.linear_density * g * rod.length;
  const double ei = std::min(rod.stiffness.x(), rod.stiffness.y());
  return rod.length * std::sqrt(n / ei);
}

bool ShootingSolver::newton(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last) {
  if (settings_.newton == NewtonBackend::kKinsol) return newton_kinsol(R_tip, load, sol, last);
  return internal::damped_newton([&](const Mat3& R) { return evaluate(R, load, &sol->rhs_evaluations); }, settings_,
                                 R_tip, sol, last);
}

/// Single shooting on the load path (load_path.h): the unknown is the tip orientation R(L) (the x
/// of eq. 15); Newton's last evaluation `e` describes the equilibrium reached.
struct ShootingSolver::SingleShooting : internal::TipOrientationShooting<SingleShooting, Load, Eval> {
  SingleShooting(ShootingSolver& s, const Load& t, RodSolution* out) : TipOrientationShooting(t, out), solver(s) {}

  ShootingSolver& solver;

  const ShootingOptions& options() const { return solver.settings_; }
  double length() const { return solver.model_.rod.length; }
  double growth() const { return solver.growth_estimate(target.wrench); }
  bool newton_at(Mat3* R, const Load& load, Eval* last) { return solver.newton(R, load, sol, last); }

  /// Newton from the warm solution (or the unloaded shape) → load continuation from the warm
  /// solution → from the unloaded shape.
  bool reach_equilibrium(FoldTracker* folds) {
    const ShootingSolver& s = solver;
    const Point unloaded{s.unloaded_.tip_rotation, Load::none(), s.unloaded_.tip_position, s.unloaded_.det};
    const Point start = s.have_solution_ ? Point{s.R_tip_, s.load_, s.tip_pos_, s.det_} : unloaded;
    return internal::reach_equilibrium(*this, start, s.have_solution_, unloaded, folds);
  }
  /// The tip pose and det ∂r/∂x of the last evaluation.
  void describe_tip() {
    if (!e.ok) return;
    sol->tip_rotation = so3::orthonormalize(e.R0.transpose() * x);
    sol->tip_position = -e.R0.transpose() * e.p0;
    sol->jacobian_det = e.J.determinant();
  }
  /// The accuracy check of a fixed-step solve (Richardson estimate of the compiled variant).
  bool accurate_enough() {
    if (!solver.accuracy_check_applies()) return true;
    sol->error_estimate = (solver.*solver.kernels_->error)(x, target, e);
    return solver.accurate_enough(sol, 1);
  }
  /// Convergence test; a converged equilibrium ends the load path (its det noted) and becomes the
  /// warm start.
  void finish(bool ok, FoldTracker* folds) {
    sol->converged = solver.converged(ok && e.ok, *sol);
    if (!sol->converged) {
      if (sol->message.empty()) sol->message = "did not converge";
      return;
    }
    folds->note(sol->jacobian_det);
    sol->message.clear();
    solver.commit_single(x, target, e, *sol);
  }
};

RodSolution ShootingSolver::solve(const TipWrench& wrench) {
  if (!wrench.force.allFinite() || !wrench.moment.allFinite()) return remember(non_finite_wrench());
  const Load target{wrench, 1.0};
  // Multiple shooting first when forced, warm from a multiple-shooting solution, or ill-conditioned.
  if (multiple_shooting_first(wrench)) {
    RodSolution ms;
    if (ms_solve(target, first_segments(target), &ms) || settings_.shooting_segments >= 2) return remember(ms);
  }
  // Single shooting: Newton from the warm solution → load continuation from the warm solution →
  // from the unloaded shape.
  RodSolution sol;
  FoldTracker folds;
  SingleShooting single{*this, target, &sol};
  const bool cold = !have_solution_;
  const bool ok = single.reach_equilibrium(&folds);
  single.describe_tip();
  // Accuracy check. A refused solve gets no multiple-shooting retry: it would use the same steps.
  if (ok && !single.accurate_enough()) return remember(report_folds(folds, &sol));
  single.finish(ok, &folds);
  // Multiple shooting when single shooting failed (automatic mode).
  if (!sol.converged && settings_.shooting_segments == 0 && fall_back_to_multiple(target, &sol)) return remember(sol);
  report_folds(folds, &sol);
  if (cold && sol.converged) load_from_rest_if_unstable(target, &sol);
  return remember(sol);
}

// The smallest eigenvalue of the stiffness on settings_.cold_stability_check at the stored
// solution (≤ 0: unstable); +inf when no component is checked, NaN when C^b fails.
double ShootingSolver::stability_indicator() {
  return internal::cold_stability_indicator(settings_.cold_stability_check, [this](bool* ok) {
    const Compliance c = compliance();
    *ok = c.ok;
    return c.body;
  });
}

// A cold direct Newton may land on an equilibrium the rod cannot hold (the straight branch of a
// column loaded past buckling, perfect or nearly so). Then the rod is loaded from rest with a small
// push along its softest direction (the stiffness's eigenvector of the negative eigenvalue), which
// bends it onto the stable branch, and the push is taken away along the load path. An unstable
// result of both is kept and reported.
void ShootingSolver::load_from_rest_if_unstable(const Load& target, RodSolution* sol) {
  const double direct = stability_indicator();
  if (!(direct <= 0.0)) return;
  const Mat3 R_tip = R_tip_;  // the direct solution, committed: restored if the path does no better
  const Eval eval = eval_;
  Vec6 push = softest_push(compliance().body, target);
  // Toward the rod's own imperfection (the unloaded tip's side), where a real column buckles.
  if ((R_tip_ * push.head<3>()).dot(unloaded_.tip_position) < 0.0) push = -push;
  const RodSolution kept = *sol;
  RodSolution path;
  FoldTracker folds;
  if (push.allFinite() && push.norm() > 0.0) {
    Load pushed = target;
    pushed.wrench.force += push.head<3>();
    pushed.wrench.moment += push.tail<3>();
    SingleShooting to_pushed{*this, pushed, &path}, back{*this, target, &path};
    folds.start(unloaded_.det);
    const SingleShooting::Point rest{unloaded_.tip_rotation, Load::none(), unloaded_.tip_position, unloaded_.det};
    if (internal::follow_load_path(to_pushed, rest, &folds) &&
        internal::follow_load_path(back, {to_pushed.x, pushed, to_pushed.tip, to_pushed.det}, &folds)) {
      back.describe_tip();
      if (back.accurate_enough()) back.finish(true, &folds);
    }
  }
  if (path.converged && stability_indicator() > 0.0) {
    path.iterations += kept.iterations;
    path.rhs_evaluations += kept.rhs_evaluations;
    *sol = report_folds(folds, &path);
    return;
  }
  commit_single(R_tip, target, eval, kept);
  *sol = kept;
  internal::warn_unstable(direct, sol);
}

// A body wrench along the softest direction of the checked components at the stored solution: the
// eigenvector of the symmetric part of the stiffness S = (C^b block)⁻¹ with the smallest (most
// negative) eigenvalue — the mode the rod buckles in first (for a column, about its weaker axis) —
// scaled to a tenth of the load (tip force and weights; moments by the length).
Vec6 ShootingSolver::softest_push(const Mat6& C, const Load& target) const {
  const double L = model_.rod.length;
  const double load = target.wrench.force.norm() + target.wrench.moment.norm() / L +
                      (model_.tip_mass + model_.rod.linear_density * L) * model_.gravity.norm();
  Vec6 push = 0.1 * std::max(load, 1e-6) * softest_wrench_direction(C, settings_.cold_stability_check);
  push.tail<3>() *= L;
  return push;
}

RodSolution ShootingSolver::remember(const RodSolution& sol) {
  last_ = sol;
  return sol;
}

RodSolution ShootingSolver::non_finite_wrench() {
  RodSolution sol;
  sol.message = "non-finite tip wrench";
  sol.residual = std::nan("");
  return sol;
}

bool ShootingSolver::multiple_shooting_first(const TipWrench& wrench) const {
  const int seg = settings_.shooting_segments;
  // Single shooting loses about λL/ln 10 digits to the growth of its sensitivities; past λL ≈ 12 its
  // Newton iteration and load continuation become unreliable (they drift onto other, better
  // conditioned branches), so the automatic mode goes to multiple shooting directly.
  const bool ill_conditioned = seg == 0 && growth_estimate(wrench) > kSingleShootingGrowthLimit;
  return seg >= 2 || (seg == 0 && ((multiple_ && have_solution_) || ill_conditioned));
}

int ShootingSolver::first_segments(const Load& target) const {
  const int seg = settings_.shooting_segments;
  const int M = seg >= 2 ? seg : auto_segments(target);
  // Warm from a multiple-shooting solution: keep its finer nodes.
  return seg == 0 && multiple_ && have_solution_ && nodes_.segments >= M ? nodes_.segments : M;
}

bool ShootingSolver::fall_back_to_multiple(const Load& target, RodSolution* sol) {
  RodSolution ms;
  ms.iterations = sol->iterations;
  ms.continuation_steps = sol->continuation_steps;
  ms.rhs_evaluations = sol->rhs_evaluations;
  if (ms_solve(target, auto_segments(target), &ms)) {
    *sol = ms;
    return true;
  }
  sol->message += "; multiple shooting (" + std::to_string(auto_segments(target)) + " segments): " + ms.message;
  return false;
}

bool ShootingSolver::accuracy_check_applies() const {
  return settings_.accuracy_tolerance > 0.0 && !is_adaptive(settings_.integrator.type);
}

bool ShootingSolver::accurate_enough(RodSolution* sol, int segments) const {
  // A fixed-step solve is only as good as its steps: refuse to call an under-resolved solve
  // converged (no silent inaccuracy under extreme loads).
  const double allowed = settings_.accuracy_tolerance * model_.rod.length;
  if (sol->error_estimate <= allowed) return true;
  sol->message = internal::accuracy_refusal(sol->error_estimate, settings_.integrator.type, settings_.integrator.steps,
                                            segments, allowed);
  sol->converged = false;
  return false;
}

bool ShootingSolver::converged(bool ok, const RodSolution& sol) const {
  return ok && std::isfinite(sol.residual) && sol.residual <= settings_.residual_tolerance &&
         sol.tip_position.allFinite();
}

const RodSolution& ShootingSolver::report_folds(const FoldTracker& folds, RodSolution* sol) {
  internal::report_folds(folds, sol);
  return *sol;
}

void ShootingSolver::commit_single(const Mat3& R_tip, const Load& load, const Eval& e, const RodSolution& sol) {
  have_solution_ = true;
  multiple_ = false;
  R_tip_ = R_tip;
  load_ = load;
  eval_ = e;
  det_ = sol.jacobian_det;
  tip_pos_ = sol.tip_position;
}

Compliance ShootingSolver::compliance() {
  Compliance c;
  if (!have_solution_) return c;
  c.ok = multiple_ ? ms_compliance(&c.body) : (this->*kernels_->compliance)(&c.body);
  return c;
}

std::vector<Vec3> ShootingSolver::shape(int segments) const {
  std::vector<Vec3> pts;
  if (!have_solution_ || segments < 1) return pts;
  using Ode = RodOde<0, CosseratGeneral>;
  Ode ode;
  setup_ode(&ode, R_tip_, load_);
  Ode::State y;
  internal::init_tip_state(ode, R_tip_, load_.wrench.moment, &y);
  const double L = model_.rod.length;
  // Break points: the output points and, for a multiple-shooting solution, the nodes, where the
  // integration restarts from the node's (R, u) (p carries on).
  std::vector<double> br;
  for (int k = 0; k <= segments; ++k) br.push_back(L * (1.0 - double(k) / segments));
  const int M = multiple_ ? nodes_.segments : 1;
  for (int k = 1; k < M; ++k) br.push_back(L * k / M);
  std::sort(br.begin(), br.end(), std::greater<double>());
  br.erase(std::unique(br.begin(), br.end(), [L](double a, double b) { return std::abs(a - b) <= 1e-14 * L; }),
           br.end());
  Workspace ws;  // shape() is const: its own integrator memory
  std::vector<Vec3> from_tip{Vec3::Zero()};
  for (size_t i = 0; i + 1 < br.size(); ++i) {
    const double s0 = br[i], s1 = br[i + 1];
    if (multiple_) {
      const int k = static_cast<int>(std::lround(s0 / L * M));
      if (k < M && std::abs(s0 - L * k / M) <= 1e-12 * L) {
        Eigen::Map<Mat3>(y.data() + 3) = nodes_.R[k];
        y.segment<3>(12) = nodes_.u[k];
      }
    }
    IntegratorOptions seg = settings_.integrator;
    seg.steps = std::max(1, static_cast<int>(std::ceil(settings_.integrator.steps * (s0 - s1) / L - 1e-9)));
    ws.integrate(ode, s0, s1, &y, seg);
    // keep only the requested output points
    const double f = (L - s1) / L * segments;
    if (std::abs(f - std::round(f)) <= 1e-9) from_tip.push_back(y.segment<3>(0));
  }
  const Mat3 R0 = Eigen::Map<const Mat3>(y.data() + 3);
  const Vec3 p0 = y.segment<3>(0);
  for (auto it = from_tip.rbegin(); it != from_tip.rend(); ++it) pts.push_back(R0.transpose() * (*it - p0));
  return pts;
}

}  // namespace rod
}  // namespace hydrojet
