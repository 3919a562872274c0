// Multiple shooting for the rod BVP (the fallback of ShootingSolver::solve, or forced with
// ShootingSettings::shooting_segments ≥ 2).
//
// Nodes s_k = k L / M, k = 0..M. Unknowns X = [ξ_M (3); (η_k, δu_k) for k = M−1 down to 1]: the tip
// orientation R_M·exp(ξ̂) and the node states R_k·exp(η̂_k), u_k + δu_k. Segment k runs from node
// k+1 down to node k, starting at (p = 0, R_{k+1}, u_{k+1}) (the tip segment at u(L) = ũ + K⁻¹ l_b)
// with n(s) from the tip orientation R_M, as in single shooting. Residuals (all in rad):
//   c_k = [log(R_kᵀ R⁻(s_k)); h (u⁻(s_k) − u_k)],  k = 1..M−1,  h = L / M;
//   r_0 = log R⁻(0) (the base condition).
// The Jacobian comes from forward sensitivities per segment (9 directions: ξ_M, η_{k+1}, δu_{k+1}),
// the node columns in closed form (−J_l⁻¹(c_k), −h I). Damped Newton on ‖F‖ with load
// continuation, as in single shooting. The positions decouple (n(s) is closed form), so the tip
// position is −R⁻(0)ᵀ Σ_k Δp_k. C^b follows from the implicit-function theorem on F(X, w) = 0 with
// 6 more directions per segment. This path allocates (Eigen dynamic matrices): it is a fallback.
// One variant (the general Cosserat form) serves every model here.
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "hydrojet_control/rod/shooting_solver.h"
#include "rod_integration.h"
#include "solver_templates.h"

namespace hydrojet {
namespace rod {

struct ShootingSolver::MsEval {
  Eigen::VectorXd F;
  Eigen::MatrixXd J;
  Eigen::MatrixXd Fw;                             ///< ∂F/∂w (compliance only)
  Eigen::Matrix<double, 3, Eigen::Dynamic> dP_X;  ///< ∂(Σ Δp)/∂X (compliance only)
  Eigen::Matrix<double, 3, 6> dP_w;               ///< ∂(Σ Δp)/∂w (compliance only)
  Mat3 R0 = Mat3::Identity();                     ///< R⁻(0)
  Vec3 sum_dp = Vec3::Zero();                     ///< Σ Δp_k = p(0) − p(L), integration frame
  double det_scale = 1.0;                         ///< det of the node block of J (J's det / this = det ∂r/∂x)
  bool ok = false;
};

int ShootingSolver::auto_segments(const Load& load) const {
  // Pieces of growth exp(λL/M) ≈ e² each; at least 4 (the fallback also helps with nonlinearity).
  const double g = growth_estimate(load.wrench);
  return std::clamp(static_cast<int>(std::ceil(g / 2.0)), 4, 64);
}

ShootingSolver::Nodes ShootingSolver::ms_unloaded_nodes(int M) const {
  Nodes x;
  x.segments = M;
  x.R.resize(M + 1);
  x.u.assign(M + 1, model_.rod.precurvature);
  for (int k = 0; k <= M; ++k) x.R[k] = so3::exp(model_.rod.length * k / M * model_.rod.precurvature);
  return x;
}

ShootingSolver::Nodes ShootingSolver::ms_nodes_from_tip(const Mat3& R_tip, const Load& load, int M) const {
  using Ode = RodOde<0, CosseratGeneral>;
  Ode ode;
  setup_ode(&ode, R_tip, load);
  Ode::State y;
  internal::init_tip_state(ode, R_tip, load.wrench.moment, &y);
  Nodes x;
  x.segments = M;
  x.R.resize(M + 1);
  x.u.resize(M + 1);
  x.R[M] = R_tip;
  x.u[M] = y.segment<3>(12);
  const double L = model_.rod.length;
  IntegratorSettings is = settings_.integrator;
  is.steps = std::max(1, (settings_.integrator.steps + M - 1) / M);
  for (int k = M - 1; k >= 0; --k) {
    integrate_ode(ode, L * (k + 1) / M, L * k / M, &y, is);
    x.R[k] = so3::orthonormalize(Eigen::Map<const Mat3>(y.data() + 3));
    x.u[k] = y.segment<3>(12);
  }
  return x;
}

ShootingSolver::Nodes ShootingSolver::ms_resample(const Nodes& x, const Load& load, int M) const {
  // Node values at s_j = j L / M from a multiple-shooting solution on other nodes: integrate each old
  // segment from its upper node down to the new nodes inside it.
  using Ode = RodOde<0, CosseratGeneral>;
  const int Mo = x.segments;
  const double L = model_.rod.length;
  Ode ode;
  setup_ode(&ode, x.R[Mo], load);
  Nodes y;
  y.segments = M;
  y.R.resize(M + 1);
  y.u.resize(M + 1);
  y.R[M] = x.R[Mo];
  y.u[M] = ode.u_tilde + ode.k_inv.cwiseProduct(load.wrench.moment);
  IntegratorSettings is = settings_.integrator;
  for (int j = M - 1; j >= 1; --j) {
    const double sj = L * j / M;
    const int k = std::min(Mo - 1, static_cast<int>(std::floor(sj / L * Mo)));  // old segment [s_k, s_k+1]
    Ode::State st;
    internal::init_tip_state(ode, x.R[k + 1], load.wrench.moment, &st);
    if (k + 1 < Mo) st.segment<3>(12) = x.u[k + 1];
    const double s0 = L * (k + 1) / Mo;
    is.steps = std::max(1, static_cast<int>(std::ceil(settings_.integrator.steps * (s0 - sj) / L - 1e-9)));
    integrate_ode(ode, s0, sj, &st, is);
    y.R[j] = so3::orthonormalize(Eigen::Map<const Mat3>(st.data() + 3));
    y.u[j] = st.segment<3>(12);
  }
  y.R[0] = Mat3::Identity();
  y.u[0] = y.u[1];
  return y;
}

template <bool kWithWrench>
bool ShootingSolver::ms_assemble(const Nodes& x, const Load& load, MsEval* e, int* rhs, int steps_per_segment) const {
  // Direction layout per segment. Newton: ξ 0–2, η 3–5, δu 6–8. Compliance: ξ 0–2, f_b 3–5,
  // η 6–8, δu 9–11, l_b 12–14 (only ξ and f_b carry a δn).
  constexpr int D = kWithWrench ? 15 : 9;
  constexpr int kEta = kWithWrench ? 6 : 3, kDu = kWithWrench ? 9 : 6, kF = 3, kL = 12;
  using Ode = RodOde<D, CosseratGeneral>;
  const int M = x.segments;
  const int N = 6 * (M - 1) + 3;
  const double L = model_.rod.length, h = L / M;
  e->F.setZero(N);
  e->J.setZero(N, N);
  if (kWithWrench) {
    e->Fw.setZero(N, 6);
    e->dP_X.setZero(3, N);
    e->dP_w.setZero();
  }
  e->sum_dp.setZero();
  e->det_scale = 1.0;
  e->ok = false;
  IntegratorSettings is = settings_.integrator;
  is.steps = steps_per_segment > 0 ? steps_per_segment : std::max(1, (settings_.integrator.steps + M - 1) / M);
  const Mat3& RM = x.R[M];
  auto node_col = [M](int k) { return 3 + 6 * (M - 1 - k); };

  Ode ode;
  setup_ode(&ode, RM, load);
  for (int i = 0; i < 3; ++i) {
    ode.dn.col(i) = RM * Vec3::Unit(i).cross(load.wrench.force);
    if (kWithWrench) ode.dn.col(kF + i) = RM.col(i);
  }
  typename Ode::State y;
  for (int k = M - 1; k >= 0; --k) {
    const bool tip = k + 1 == M;
    y.setZero();
    Eigen::Map<Mat3>(y.data() + 3) = x.R[k + 1];
    y.template segment<3>(12) = tip ? Vec3(ode.u_tilde + ode.k_inv.cwiseProduct(load.wrench.moment)) : x.u[k + 1];
    for (int i = 0; i < 3; ++i) {
      if (tip) {
        y[Ode::kBase + Ode::kPerDir * i + i] = 1.0;  // ξ_M also rotates the tip segment's start
        if (kWithWrench) y[Ode::kBase + Ode::kPerDir * (kL + i) + 3 + i] = ode.k_inv[i];
      } else {
        y[Ode::kBase + Ode::kPerDir * (kEta + i) + i] = 1.0;
        y[Ode::kBase + Ode::kPerDir * (kDu + i) + 3 + i] = 1.0;
      }
    }
    const IntegrationStats st = integrate_ode(ode, L * (k + 1) / M, L * k / M, &y, is);
    *rhs += st.rhs_evaluations;
    if (!st.ok || !y.allFinite()) return false;
    const Mat3 Rm = Eigen::Map<const Mat3>(y.data() + 3);
    const Vec3 um = y.template segment<3>(12);
    e->sum_dp += y.template segment<3>(0);
    auto eta = [&](int d) { return Vec3(y.template segment<3>(Ode::kBase + Ode::kPerDir * d)); };
    auto du = [&](int d) { return Vec3(y.template segment<3>(Ode::kBase + Ode::kPerDir * d + 3)); };
    auto dp = [&](int d) { return Vec3(y.template segment<3>(Ode::kBase + Ode::kPerDir * d + 6)); };
    const int row = 6 * (M - 1 - k);  // for k = 0 this is the base row block 6(M−1)
    Vec3 r;
    Mat3 Jri;
    if (k >= 1) {
      r = so3::log(so3::orthonormalize(x.R[k].transpose() * Rm));
      Jri = so3::right_jacobian_inverse(r);
      e->F.template segment<3>(row) = r;
      e->F.template segment<3>(row + 3) = h * (um - x.u[k]);
      const int c = node_col(k);
      const Mat3 Jli = so3::right_jacobian_inverse(-r);
      e->J.template block<3, 3>(row, c) = -Jli;
      e->J.template block<3, 3>(row + 3, c + 3) = -h * Mat3::Identity();
      e->det_scale *= Jli.determinant() * h * h * h;
    } else {
      r = so3::log(so3::orthonormalize(Rm));
      Jri = so3::right_jacobian_inverse(r);
      e->F.template segment<3>(row) = r;
      e->R0 = Rm;
    }
    // Columns of the segment's start unknowns (and of the wrench).
    auto put = [&](int d, int col, bool wrench) {
      Eigen::MatrixXd& A = wrench ? e->Fw : e->J;
      A.template block<3, 1>(row, col) += Jri * eta(d);
      if (k >= 1) A.template block<3, 1>(row + 3, col) += h * du(d);
      if (kWithWrench) {
        if (wrench) {
          e->dP_w.col(col) += dp(d);
        } else {
          e->dP_X.col(col) += dp(d);
        }
      }
    };
    for (int i = 0; i < 3; ++i) {
      put(i, i, false);
      if (!tip) {
        put(kEta + i, node_col(k + 1) + i, false);
        put(kDu + i, node_col(k + 1) + 3 + i, false);
      }
      if (kWithWrench) {
        put(kF + i, i, true);
        if (tip) put(kL + i, 3 + i, true);
      }
    }
  }
  e->ok = e->F.allFinite() && e->J.allFinite();
  return e->ok;
}

bool ShootingSolver::ms_newton(Nodes* x, const Load& load, RodSolution* sol, double* det) const {
  const int M = x->segments;
  const double h = model_.rod.length / M;
  MsEval e;
  if (!ms_assemble<false>(*x, load, &e, &sol->rhs_evaluations)) {
    sol->message = "integration failed (non-finite state or step limit)";
    return false;
  }
  auto apply = [&](const Nodes& from, const Eigen::VectorXd& step, double alpha) {
    Nodes t = from;
    t.R[M] = so3::orthonormalize(from.R[M] * so3::exp(alpha * step.head<3>()));
    for (int k = 1; k < M; ++k) {
      const int c = 3 + 6 * (M - 1 - k);
      t.R[k] = so3::orthonormalize(from.R[k] * so3::exp(alpha * step.segment<3>(c)));
      t.u[k] = from.u[k] + alpha * step.segment<3>(c + 3);
    }
    return t;
  };
  for (int it = 0;; ++it) {
    sol->residual = e.F.norm();
    if (sol->residual <= settings_.residual_tolerance) {
      const Eigen::PartialPivLU<Eigen::MatrixXd> lu(e.J);
      *det = lu.determinant() / e.det_scale;
      sol->tip_rotation = so3::orthonormalize(e.R0.transpose() * x->R[M]);
      sol->tip_position = -e.R0.transpose() * e.sum_dp;
      return true;
    }
    if (it >= settings_.max_iterations) {
      sol->message = "Newton iteration limit reached";
      return false;
    }
    ++sol->iterations;
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(e.J);
    Eigen::VectorXd step = -lu.solve(e.F);
    if (!step.allFinite()) {
      sol->message = "singular multiple-shooting Jacobian";
      return false;
    }
    // Cap every rotation part at max_step [rad] and every curvature part at max_step / h.
    double worst = step.head<3>().norm();
    for (int k = 1; k < M; ++k) {
      const int c = 3 + 6 * (M - 1 - k);
      worst = std::max({worst, step.segment<3>(c).norm(), h * step.segment<3>(c + 3).norm()});
    }
    if (worst > settings_.max_step) step *= settings_.max_step / worst;
    bool accepted = false;
    double alpha = 1.0;
    for (int k = 0; k < 12; ++k, alpha *= 0.5) {
      const Nodes t = apply(*x, step, alpha);
      MsEval et;
      if (ms_assemble<false>(t, load, &et, &sol->rhs_evaluations) &&
          et.F.norm() < (1.0 - 1e-4 * alpha) * sol->residual) {
        *x = t;
        e = std::move(et);
        accepted = true;
        break;
      }
    }
    if (!accepted) {
      sol->message = "line search failed (no descent)";
      return false;
    }
  }
}

double ShootingSolver::ms_error_estimate(const Nodes& x, const Load& load) const {
  // The Richardson estimate of error_t() for multiple shooting: every segment once more with half
  // (or twice) its steps; the change of the residuals F and of Σ Δp goes through the Jacobian.
  const int M = x.segments;
  const int n = std::max(1, (settings_.integrator.steps + M - 1) / M);
  const double q = settings_.integrator.type == IntegratorType::kRk4 ? 16.0 : 256.0;
  const int other = n % 2 == 0 ? n / 2 : 2 * n;
  const double f = n % 2 == 0 ? -1.0 / (q - 1.0) : q / (q - 1.0);
  MsEval fine, coarse;
  int rhs = 0;
  if (!ms_assemble<true>(x, load, &fine, &rhs) || !ms_assemble<false>(x, load, &coarse, &rhs, other))
    return std::numeric_limits<double>::infinity();
  const Eigen::VectorXd dF = f * (coarse.F - fine.F);
  const Eigen::VectorXd dX = -Eigen::PartialPivLU<Eigen::MatrixXd>(fine.J).solve(dF);
  const Vec3 dsum = f * (coarse.sum_dp - fine.sum_dp) + fine.dP_X * dX;
  return dsum.norm();
}

bool ShootingSolver::ms_solve(const Load& target, int M, RodSolution* sol) {
  sol->segments = M;
  Load zero;
  zero.gravity_scale = 0.0;
  // Start: the stored solution (multiple or single shooting) at its load, else the unloaded shape.
  Nodes start;
  Load from = zero;
  bool warm = false;
  if (have_solution_) {
    start = !multiple_             ? ms_nodes_from_tip(R_tip_, load_, M)
            : nodes_.segments == M ? nodes_
                                   : ms_resample(nodes_, load_, M);
    from = load_;
    warm = start.R.size() == static_cast<size_t>(M + 1);
    for (const Mat3& R : start.R) warm = warm && R.allFinite();
  }
  if (!warm) start = ms_unloaded_nodes(M);
  const Vec3 p_from = warm ? tip_pos_ : unloaded_tip_position();
  double det_prev = warm ? det_ : unloaded_det();
  int crossings = 0;
  auto note = [&](double d) {
    if (!std::isfinite(d) || d == 0.0) return;
    if (std::isfinite(det_prev) && det_prev != 0.0 && (d > 0.0) != (det_prev > 0.0)) ++crossings;
    det_prev = d;
  };

  Nodes x = start;
  double det = 0.0;
  bool ok = warm && ms_newton(&x, target, sol, &det);
  auto continuation = [&](const Load& l0, const Nodes& x0, const Vec3& p0) {
    Nodes xc = x0;
    Vec3 pc = p0;
    double lambda = 0.0, dl = 0.25;
    while (lambda < 1.0) {
      if (sol->continuation_steps >= settings_.max_continuation_steps || dl < 1e-6) return false;
      const double ln = std::min(1.0, lambda + dl);
      Load l;
      l.wrench.force = l0.wrench.force + ln * (target.wrench.force - l0.wrench.force);
      l.wrench.moment = l0.wrench.moment + ln * (target.wrench.moment - l0.wrench.moment);
      l.gravity_scale = l0.gravity_scale + ln * (target.gravity_scale - l0.gravity_scale);
      Nodes xt = xc;
      ++sol->continuation_steps;
      double d = 0.0;
      // Taken only if no node orientation moved by more than max_step and the tip by no more than
      // L/4 (else: a branch jump, or a snap-through at a fold).
      auto near = [&] {
        for (int k = 1; k <= M; ++k)
          if (so3::log(xc.R[k].transpose() * xt.R[k]).norm() > settings_.max_step) return false;
        return (sol->tip_position - pc).norm() <= 0.25 * model_.rod.length;
      };
      if (ms_newton(&xt, l, sol, &d)) {
        const bool jump = !near();
        if (jump && dl > 1.0 / 256.0) {  // see kSnapStep in shooting_solver.cpp
          dl *= 0.5;
          continue;
        }
        if (jump) {
          ++crossings;  // snap-through at a fold
          det_prev = std::nan("");
        }
        xc = xt;
        pc = sol->tip_position;
        lambda = ln;
        dl = std::min(2.0 * dl, 0.5);
        if (ln < 1.0) note(d);
        det = d;
      } else {
        dl *= 0.5;
      }
    }
    x = xc;
    return true;
  };
  bool far = false;
  if (ok) {
    for (int k = 1; k <= M; ++k) far = far || so3::log(start.R[k].transpose() * x.R[k]).norm() > settings_.max_step;
    far = far || (sol->tip_position - p_from).norm() > 0.25 * model_.rod.length;
  }
  if (ok && (far || (std::isfinite(det_prev) && det_prev != 0.0 && det != 0.0 && (det > 0.0) != (det_prev > 0.0)))) {
    // Newton crossed a singular Jacobian or moved far (a snap, or another branch): prefer the
    // equilibrium reached along the load path, as single shooting does.
    const Nodes x_direct = x;
    const double det_direct = det;
    const RodSolution s_direct = *sol;
    if (!continuation(from, start, p_from)) {
      // The path breaks down at a fold: keep the far direct result (the snap) and report it.
      const bool crossed =
          std::isfinite(det_) && det_ != 0.0 && det_direct != 0.0 && (det_direct > 0.0) != (det_ > 0.0);
      x = x_direct;
      det = det_direct;
      *sol = s_direct;
      det_prev = det_;
      crossings = crossed ? 0 : 1;  // a sign change is counted by note() below
    }
  }
  if (!ok && warm) {
    det_prev = det_;
    crossings = 0;
    ok = continuation(from, start, p_from);
  }
  if (!ok) {
    det_prev = unloaded_det();
    crossings = 0;
    ok = continuation(zero, ms_unloaded_nodes(M), unloaded_tip_position());
  }
  sol->converged = ok && std::isfinite(sol->residual) && sol->residual <= settings_.residual_tolerance &&
                   sol->tip_position.allFinite();
  if (!sol->converged) {
    if (sol->message.empty()) sol->message = "did not converge";
    return false;
  }
  if (settings_.accuracy_tolerance > 0.0 && !is_adaptive(settings_.integrator.type)) {
    sol->error_estimate = ms_error_estimate(x, target);
    const double allowed = settings_.accuracy_tolerance * model_.rod.length;
    if (!(sol->error_estimate <= allowed)) {
      sol->message = internal::accuracy_refusal(sol->error_estimate, settings_.integrator.type,
                                                settings_.integrator.steps, M, allowed);
      sol->converged = false;
      return false;
    }
  }
  note(det);
  sol->jacobian_det = det;
  sol->message.clear();
  sol->fold_crossings = crossings;
  if (crossings > 0)
    sol->warning = "the load path crossed a fold or bifurcation " + std::to_string(crossings) +
                   " time(s) (det of the shooting Jacobian changed sign, or the equilibrium snapped through); "
                   "the result may lie on another branch than the start: check stability (stability_eig_min)";
  have_solution_ = true;
  multiple_ = true;
  nodes_ = x;
  R_tip_ = x.R[M];
  tip_pos_ = sol->tip_position;
  load_ = target;
  det_ = det;
  return true;
}

bool ShootingSolver::ms_compliance(Mat6* C) const {
  MsEval e;
  int rhs = 0;
  if (!ms_assemble<true>(nodes_, load_, &e, &rhs)) return false;
  const Eigen::PartialPivLU<Eigen::MatrixXd> lu(e.J);
  const Eigen::MatrixXd dX_dw = -lu.solve(e.Fw);
  const Eigen::Matrix<double, 3, 6> dsum = e.dP_X * dX_dw + e.dP_w;
  const Mat3& RM = nodes_.R[nodes_.segments];
  // ω = dξ_M/dw; p_T = −R(0)ᵀ Σ Δp with R(0) = I along the solution: v = R_Mᵀ δp_T = −R_Mᵀ δΣ.
  C->topRows<3>() = -RM.transpose() * dsum;
  C->bottomRows<3>() = dX_dw.topRows<3>();
  return C->allFinite();
}

}  // namespace rod
}  // namespace hydrojet
