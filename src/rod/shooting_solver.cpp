#include "hydrojet_control/rod/shooting_solver.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "hydrojet_control/rod/cvode_integrator.h"
#include "kinsol_workspace.h"
#include "rod_integration.h"
#include "solver_templates.h"

namespace hydrojet {
namespace rod {

using internal::init_tip_state;

const char* integrator_name(IntegratorType t) {
  switch (t) {
    case IntegratorType::kRk4: return "rk4";
    case IntegratorType::kRk8: return "rk8";
    case IntegratorType::kDopri5: return "dopri5";
    case IntegratorType::kCvodeAdams: return "cvode-adams";
    case IntegratorType::kCvodeBdf: return "cvode-bdf";
  }
  return "unknown";
}

const char* integrator_names() { return "rk4, rk8, dopri5, cvode-adams, cvode-bdf"; }

bool parse_integrator(const std::string& name, IntegratorType* out) {
  for (IntegratorType t : {IntegratorType::kRk4, IntegratorType::kRk8, IntegratorType::kDopri5,
                           IntegratorType::kCvodeAdams, IntegratorType::kCvodeBdf}) {
    if (name == integrator_name(t)) {
      *out = t;
      return true;
    }
  }
  return false;
}

ShootingSolver::Scratch::Scratch() = default;
ShootingSolver::Scratch::~Scratch() = default;
CvodeWorkspace& ShootingSolver::Scratch::cvode() {
  if (!cvode_) cvode_.reset(new CvodeWorkspace);
  return *cvode_;
}

ShootingSolver::ShootingSolver(const RodModel& model, const ShootingSettings& settings)
    : model_(model), settings_(settings) {
  select_kernels();
}

void ShootingSolver::set_model(const RodModel& model) {
  model_ = model;
  have_unloaded_det_ = false;
  select_kernels();
  reset();
}

void ShootingSolver::set_settings(const ShootingSettings& settings) {
  settings_ = settings;
  have_unloaded_det_ = false;
  select_kernels();
}

void ShootingSolver::reset() {
  have_solution_ = false;
  multiple_ = false;
  R_tip_ = Mat3::Identity();
  nodes_ = Nodes();
}

const char* ShootingSolver::variant_name() const { return kernels_->name; }

// One compiled right-hand side per combination of terms; the scene's combination is chosen here,
// once, so the integration loop runs without branches on the model's terms.
void ShootingSolver::select_kernels() {
#define HJ_KERNEL(C, W, P, NAME)                                                                      \
  Kernels {                                                                                           \
    &ShootingSolver::evaluate_t<RodTerms<C, W, P>>, &ShootingSolver::compliance_t<RodTerms<C, W, P>>, \
        &ShootingSolver::error_t<RodTerms<C, W, P>>, NAME                                             \
  }
  static const Kernels table[8] = {
      HJ_KERNEL(false, false, false, "kirchhoff"),       HJ_KERNEL(false, false, true, "kirchhoff+precurved"),
      HJ_KERNEL(false, true, false, "kirchhoff+weight"), HJ_KERNEL(false, true, true, "kirchhoff+weight+precurved"),
      HJ_KERNEL(true, false, false, "cosserat"),         HJ_KERNEL(true, false, true, "cosserat+precurved"),
      HJ_KERNEL(true, true, false, "cosserat+weight"),   HJ_KERNEL(true, true, true, "cosserat+weight+precurved"),
  };
  static const Kernels general = HJ_KERNEL(true, true, true, "general");
#undef HJ_KERNEL
  if (!settings_.specialize_model) {
    kernels_ = &general;
    return;
  }
  const RodTermSet t = needed_terms(model_);
  kernels_ = &table[(t.cosserat ? 4 : 0) + (t.distributed_load ? 2 : 0) + (t.precurved ? 1 : 0)];
}

Mat3 ShootingSolver::unloaded_tip_rotation() const {
  // With no load u(s) = ũ solves eq. (14), so the unloaded tip frame is exp(L ũ^).
  return so3::exp(model_.rod.length * model_.rod.precurvature);
}

double ShootingSolver::unloaded_det() const {
  // det ∂r/∂x at the unloaded shape under zero load: where every cold load path starts.
  if (!have_unloaded_det_) {
    Load zero;
    zero.gravity_scale = 0.0;
    int rhs = 0;
    const Eval u = evaluate(unloaded_tip_rotation(), zero, &rhs);
    unloaded_det_ = u.ok ? u.J.determinant() : std::nan("");
    unloaded_tip_ = u.ok ? Vec3(-u.R0.transpose() * u.p0) : Vec3::Zero();
    have_unloaded_det_ = true;
  }
  return unloaded_det_;
}

Vec3 ShootingSolver::unloaded_tip_position() const {
  unloaded_det();
  return unloaded_tip_;
}

double ShootingSolver::growth_estimate(const TipWrench& w) const {
  const RodParameters& rod = model_.rod;
  const double g = model_.gravity.norm();
  const double n = w.force.norm() + model_.tip_mass * g + rod.linear_density * g * rod.length;
  const double ei = std::min(rod.stiffness.x(), rod.stiffness.y());
  return rod.length * std::sqrt(n / ei);
}

bool ShootingSolver::newton(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last) const {
  if (settings_.newton == NewtonBackend::kKinsol) return newton_kinsol(R_tip, load, sol, last);
  Eval e = evaluate(*R_tip, load, &sol->rhs_evaluations);
  for (int it = 0;; ++it) {
    if (!e.ok) {
      sol->message = "integration failed (non-finite state or step limit)";
      return false;
    }
    sol->residual = e.r.norm();
    if (sol->residual <= settings_.residual_tolerance) {
      *last = e;
      return true;
    }
    if (it >= settings_.max_iterations) {
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
    if (n > settings_.max_step) step *= settings_.max_step / n;
    // Backtracking line search on |r|.
    bool accepted = false;
    double alpha = 1.0;
    for (int k = 0; k < 10; ++k, alpha *= 0.5) {
      const Mat3 R_try = *R_tip * so3::exp(alpha * step);
      Eval t = evaluate(R_try, load, &sol->rhs_evaluations);
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

namespace {
/// Continuation steps (fractions of the load change) below which a persisting jump of the solution
/// counts as a snap-through at a fold rather than a step that is too long.
constexpr double kSnapStep = 1.0 / 256.0;

/// Counts a sign change of det ∂r/∂x between consecutive equilibria of a load path.
struct FoldTracker {
  double det = std::nan("");
  int crossings = 0;
  void start(double d) {
    det = d;
    crossings = 0;
  }
  void note(double d) {
    if (!std::isfinite(d) || d == 0.0) return;
    if (std::isfinite(det) && det != 0.0 && (d > 0.0) != (det > 0.0)) ++crossings;
    det = d;
  }
};
}  // namespace

RodSolution ShootingSolver::solve(const TipWrench& wrench) {
  RodSolution sol;
  Load target;
  target.wrench = wrench;
  target.gravity_scale = 1.0;
  if (!wrench.force.allFinite() || !wrench.moment.allFinite()) {
    sol.message = "non-finite tip wrench";
    sol.residual = std::nan("");
    last_ = sol;
    return sol;
  }
  FoldTracker folds;
  auto finish = [&](bool ok, const Eval& e, const Mat3& R) {
    if (e.ok) {
      sol.tip_rotation = so3::orthonormalize(e.R0.transpose() * R);
      sol.tip_position = -e.R0.transpose() * e.p0;
      sol.jacobian_det = e.J.determinant();
    }
    sol.converged = ok && e.ok && std::isfinite(sol.residual) && sol.residual <= settings_.residual_tolerance &&
                    sol.tip_position.allFinite();
    if (sol.converged) {
      folds.note(sol.jacobian_det);
      sol.message.clear();
      have_solution_ = true;
      det_ = sol.jacobian_det;
      tip_pos_ = sol.tip_position;
      multiple_ = false;
      R_tip_ = R;
      load_ = target;
      eval_ = e;
    } else if (sol.message.empty()) {
      sol.message = "did not converge";
    }
  };
  auto report_folds = [&]() {
    sol.fold_crossings = folds.crossings;
    if (folds.crossings > 0)
      sol.warning = "the load path crossed a fold or bifurcation " + std::to_string(folds.crossings) +
                    " time(s) (det of the shooting Jacobian changed sign, or the equilibrium snapped through); "
                    "the result may lie on another branch than the start: check stability (stability_eig_min)";
    last_ = sol;
    return sol;
  };

  const int seg = settings_.shooting_segments;
  // Single shooting loses about λL/ln 10 digits to the growth of its sensitivities; past λL ≈ 12 its
  // Newton iteration and load continuation become unreliable (they drift onto other, better
  // conditioned branches), so the automatic mode goes to multiple shooting directly.
  const bool ill_conditioned = seg == 0 && growth_estimate(wrench) > kSingleShootingGrowthLimit;
  if (seg >= 2 || (seg == 0 && ((multiple_ && have_solution_) || ill_conditioned))) {
    // Multiple shooting: forced, warm from a multiple-shooting solution, or ill-conditioned.
    int M = seg >= 2 ? seg : auto_segments(target);
    if (seg == 0 && multiple_ && have_solution_ && nodes_.segments >= M) M = nodes_.segments;
    const bool ok = ms_solve(target, M, &sol);
    if (ok || seg >= 2) {
      last_ = sol;
      return sol;
    }
    sol = RodSolution();  // fall through to single shooting, then a fresh multiple-shooting attempt
  }

  folds.start(have_solution_ ? det_ : unloaded_det());
  Eval e;
  Mat3 R = have_solution_ ? R_tip_ : unloaded_tip_rotation();
  Load zero;
  zero.gravity_scale = 0.0;

  // Load continuation from `from` (an equilibrium at R_from) to the target load.
  // Tip position of an evaluation (base frame).
  auto tip_of = [](const Eval& x) { return Vec3(-x.R0.transpose() * x.p0); };
  // Two equilibria are "far" apart when the tip turned by more than max_step or moved by more than
  // L/4: more than a load step of a path should do; a jump to another branch or a snap-through.
  const double far_move = 0.25 * model_.rod.length;
  auto far_apart = [&](const Mat3& Ra, const Vec3& pa, const Mat3& Rb, const Vec3& pb) {
    return so3::log(Ra.transpose() * Rb).norm() > settings_.max_step || (pa - pb).norm() > far_move;
  };
  auto continuation = [&](const Load& from, const Mat3& R_from, const Vec3& p_from) {
    Mat3 Rc = R_from;
    Vec3 pc = p_from;
    double lambda = 0.0, dl = 0.25;
    while (lambda < 1.0) {
      if (sol.continuation_steps >= settings_.max_continuation_steps || dl < 1e-6) return false;
      const double ln = std::min(1.0, lambda + dl);
      Load l;
      l.wrench.force = from.wrench.force + ln * (target.wrench.force - from.wrench.force);
      l.wrench.moment = from.wrench.moment + ln * (target.wrench.moment - from.wrench.moment);
      l.gravity_scale = from.gravity_scale + ln * (target.gravity_scale - from.gravity_scale);
      Mat3 Rt = Rc;
      ++sol.continuation_steps;
      // A step is taken when Newton stays near the previous equilibrium (far_apart() false); a
      // larger change is a jump to another branch: the step is halved, and if the jump persists down
      // to a tiny step the path has reached a fold and snaps through (taken and reported as a fold
      // crossing).
      if (newton(&Rt, l, &sol, &e)) {
        const Vec3 pt = tip_of(e);
        const bool jump = far_apart(Rc, pc, Rt, pt);
        if (jump && dl > kSnapStep) {
          dl *= 0.5;
          continue;
        }
        if (jump) {
          ++folds.crossings;
          folds.det = std::nan("");  // a new branch: its det starts a new comparison
        }
        Rc = Rt;
        pc = pt;
        lambda = ln;
        dl = std::min(2.0 * dl, 0.5);
        if (ln < 1.0) folds.note(e.J.determinant());
      } else {
        dl *= 0.5;
      }
    }
    R = Rc;
    return true;
  };

  const Mat3 R_start = R;
  const Vec3 p_start = have_solution_ ? tip_pos_ : unloaded_tip_position();
  bool ok = newton(&R, target, &sol, &e);
  if (ok && e.ok) {
    // The direct Newton result is the equilibrium connected to the start along the load path unless
    // Newton (a) went across a singular shooting Jacobian (det changed sign), or (b) moved far: a
    // warm start whose tip turned by more than max_step or moved by more than L/4 (a snap, or another
    // branch), or a cold start of a strongly loaded rod (λL > 4, where several equilibria exist)
    // that did. Then follow the
    // load path instead (it reports folds and snap-throughs on the way); keep the direct result
    // only if the path fails.
    const double start = folds.det, d = e.J.determinant();
    const bool crossed = std::isfinite(start) && start != 0.0 && d != 0.0 && (d > 0.0) != (start > 0.0);
    const bool far = far_apart(R_start, p_start, R, tip_of(e)) && (have_solution_ || growth_estimate(wrench) > 4.0);
    if (crossed || far) {
      const Mat3 R_direct = R;
      const Eval e_direct = e;
      const bool path = have_solution_ ? continuation(load_, R_tip_, tip_pos_)
                                       : continuation(zero, unloaded_tip_rotation(), unloaded_tip_position());
      if (!path) {
        // The path breaks down (Newton fails near a fold): the far direct result is where the rod
        // snaps to. Keep it, and report the snap (a det sign change is counted by finish()).
        R = R_direct;
        e = e_direct;
        sol.residual = e.r.norm();
        sol.message.clear();
        folds.start(start);
        if (!crossed) ++folds.crossings;
      }
    }
  }
  if (!ok && have_solution_) {
    folds.start(det_);
    ok = continuation(load_, R_tip_, tip_pos_);
  }
  if (!ok) {
    folds.start(unloaded_det());
    ok = continuation(zero, unloaded_tip_rotation(), unloaded_tip_position());
  }
  if (ok && e.ok && settings_.accuracy_tolerance > 0.0 && !is_adaptive(settings_.integrator.type)) {
    // A fixed-step solve is only as good as its steps: estimate the tip error and refuse to call
    // an under-resolved solve converged (no silent inaccuracy under extreme loads). No multiple-
    // shooting fallback here: it would use the same steps.
    sol.error_estimate = (this->*kernels_->error)(R, target, e);
    const double allowed = settings_.accuracy_tolerance * model_.rod.length;
    if (!(sol.error_estimate <= allowed)) {
      sol.message = internal::accuracy_refusal(sol.error_estimate, settings_.integrator.type,
                                               settings_.integrator.steps, 1, allowed);
      sol.residual = e.r.norm();
      sol.tip_rotation = so3::orthonormalize(e.R0.transpose() * R);
      sol.tip_position = -e.R0.transpose() * e.p0;
      sol.jacobian_det = e.J.determinant();
      sol.converged = false;
      return report_folds();
    }
  }
  finish(ok, e, R);
  if (!sol.converged && seg == 0) {
    // Single shooting failed: multiple shooting, which also handles ill-conditioned (long, soft) rods.
    RodSolution ms;
    ms.iterations = sol.iterations;
    ms.continuation_steps = sol.continuation_steps;
    ms.rhs_evaluations = sol.rhs_evaluations;
    if (ms_solve(target, auto_segments(target), &ms)) {
      sol = ms;
      last_ = sol;
      return sol;
    }
    sol.message += "; multiple shooting (" + std::to_string(auto_segments(target)) + " segments): " + ms.message;
  }
  return report_folds();
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
  init_tip_state(ode, R_tip_, load_.wrench.moment, &y);
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
    IntegratorSettings seg = settings_.integrator;
    seg.steps = std::max(1, static_cast<int>(std::ceil(settings_.integrator.steps * (s0 - s1) / L - 1e-9)));
    integrate_ode(ode, s0, s1, &y, seg);
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
