#include "hydrojet_control/rod/shooting_solver.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>

namespace hydrojet {
namespace rod {

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

bool parse_integrator(const std::string& name, IntegratorType* out) {
  for (IntegratorType t : {IntegratorType::kRk4, IntegratorType::kRk8, IntegratorType::kDopri5}) {
    if (name == integrator_name(t)) {
      *out = t;
      return true;
    }
  }
  return false;
}

ShootingSolver::ShootingSolver(const RodModel& model, const ShootingSettings& settings)
    : model_(model), settings_(settings) {}

void ShootingSolver::set_model(const RodModel& model) {
  model_ = model;
  reset();
}

void ShootingSolver::reset() {
  have_solution_ = false;
  R_tip_ = Mat3::Identity();
}

Mat3 ShootingSolver::unloaded_tip_rotation() const {
  // With no load u(s) = ũ solves eq. (14), so the unloaded tip frame is exp(L ũ^).
  return so3::exp(model_.rod.length * model_.rod.precurvature);
}

template <int D>
void ShootingSolver::setup_ode(RodOde<D>* ode, const Mat3& R_tip, const Load& load) const {
  const RodParameters& rod = model_.rod;
  ode->k_diag = rod.stiffness;
  ode->k_inv = rod.stiffness.cwiseInverse();
  ode->u_tilde = rod.precurvature;
  ode->length = rod.length;
  // Tip boundary condition (eq. 16 with eq. 13): n(L) = R(L) f_b + m_t g.
  ode->n_tip = R_tip * load.wrench.force + load.gravity_scale * model_.tip_mass * model_.gravity;
  ode->w_dist = load.gravity_scale * rod.linear_density * model_.gravity;
  ode->dn.setZero();
}

namespace {
template <int D>
void init_tip_state(const RodOde<D>& ode, const Mat3& R_tip, const Vec3& moment,
                    typename RodOde<D>::State* y) {
  y->setZero();
  Eigen::Map<Mat3>(y->data() + 3) = R_tip;
  // eq. (16): u(L) − ũ(L) = K⁻¹ l_b
  y->template segment<3>(12) = ode.u_tilde + ode.k_inv.cwiseProduct(moment);
}
}  // namespace

ShootingSolver::Eval ShootingSolver::evaluate(const Mat3& R_tip, const Load& load, int* rhs) const {
  RodOde<3> ode;
  setup_ode(&ode, R_tip, load);
  RodOde<3>::State y;
  init_tip_state(ode, R_tip, load.wrench.moment, &y);
  for (int i = 0; i < 3; ++i) {
    // Direction x_i: R(L) -> R(L) exp(ε e_i^): η(L) = e_i, and n(L) changes by R(L)(e_i × f_b).
    y[RodOde<3>::kBase + RodOde<3>::kPerDir * i + i] = 1.0;
    ode.dn.col(i) = R_tip * Vec3::Unit(i).cross(load.wrench.force);
  }
  const IntegrationStats st = integrate(settings_.integrator, ode, model_.rod.length, 0.0, y);
  *rhs += st.rhs_evaluations;
  Eval e;
  e.ok = st.ok && y.allFinite();
  if (!e.ok) return e;
  e.R0 = Eigen::Map<const Mat3>(y.data() + 3);
  e.p0 = y.segment<3>(0);
  for (int i = 0; i < 3; ++i) {
    const int o = RodOde<3>::kBase + RodOde<3>::kPerDir * i;
    e.deta0.col(i) = y.segment<3>(o);
    e.dp0.col(i) = y.segment<3>(o + 6);
  }
  // Shooting residual, eq. (15): R(0) = I  <=>  log R(0) = 0.
  e.r = so3::log(so3::orthonormalize(e.R0));
  e.J = so3::right_jacobian_inverse(e.r) * e.deta0;
  e.ok = e.r.allFinite() && e.J.allFinite();
  return e;
}

bool ShootingSolver::newton(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last) const {
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

  Eval e;
  Mat3 R = have_solution_ ? R_tip_ : unloaded_tip_rotation();
  bool ok = newton(&R, target, &sol, &e);

  // Load continuation: from the warm solution if there is one, then from the unloaded shape.
  auto continuation = [&](const Load& from, const Mat3& R_from) {
    Mat3 Rc = R_from;
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
      if (newton(&Rt, l, &sol, &e)) {
        Rc = Rt;
        lambda = ln;
        dl = std::min(2.0 * dl, 0.5);
      } else {
        dl *= 0.5;
      }
    }
    R = Rc;
    return true;
  };
  if (!ok && have_solution_) ok = continuation(load_, R_tip_);
  if (!ok) {
    Load zero;
    zero.gravity_scale = 0.0;
    ok = continuation(zero, unloaded_tip_rotation());
  }

  if (e.ok) {
    sol.tip_rotation = so3::orthonormalize(e.R0.transpose() * R);
    sol.tip_position = -e.R0.transpose() * e.p0;
    sol.jacobian_det = e.J.determinant();
  }
  sol.converged = ok && e.ok && std::isfinite(sol.residual) &&
                  sol.residual <= settings_.residual_tolerance && sol.tip_position.allFinite();
  if (sol.converged) {
    sol.message.clear();
    have_solution_ = true;
    R_tip_ = R;
    load_ = target;
    eval_ = e;
  } else if (sol.message.empty()) {
    sol.message = "did not converge";
  }
  last_ = sol;
  return sol;
}

Compliance ShootingSolver::compliance() {
  Compliance c;
  if (!have_solution_) return c;
  RodOde<6> ode;
  setup_ode(&ode, R_tip_, load_);
  RodOde<6>::State y;
  init_tip_state(ode, R_tip_, load_.wrench.moment, &y);
  for (int i = 0; i < 3; ++i) {
    // Direction f_b,i: n(L) changes by R(L) e_i.
    ode.dn.col(i) = R_tip_.col(i);
    // Direction l_b,i: u(L) changes by K⁻¹ e_i.
    y[RodOde<6>::kBase + RodOde<6>::kPerDir * (3 + i) + 3 + i] = ode.k_inv[i];
  }
  const IntegrationStats st = integrate(settings_.integrator, ode, model_.rod.length, 0.0, y);
  if (!st.ok || !y.allFinite()) return c;
  Eigen::Matrix<double, 3, 6> eta_w, dp_w;
  for (int d = 0; d < 6; ++d) {
    const int o = RodOde<6>::kBase + RodOde<6>::kPerDir * d;
    eta_w.col(d) = y.segment<3>(o);
    dp_w.col(d) = y.segment<3>(o + 6);
  }
  // Implicit function theorem on r(x, w) = 0: dx/dw = −(∂r/∂x)⁻¹ ∂r/∂w.
  const Eigen::Matrix<double, 3, 6> dr_dw = so3::right_jacobian_inverse(eval_.r) * eta_w;
  const Eigen::Matrix<double, 3, 6> dx_dw = -eval_.J.partialPivLu().solve(dr_dw);
  const Eigen::Matrix<double, 3, 6> dp0 = eval_.dp0 * dx_dw + dp_w;
  // Tip pose in the base frame: R_T = R(0)ᵀ R(L), p_T = −R(0)ᵀ p(0). Along the solution R(0) stays
  // I, so the body twist is ω = dx/dw and v = R_Tᵀ dp_T = −R(L)ᵀ dp(0).
  c.body.topRows<3>() = -R_tip_.transpose() * dp0;
  c.body.bottomRows<3>() = dx_dw;
  c.ok = c.body.allFinite();
  return c;
}

std::vector<Vec3> ShootingSolver::shape(int segments) const {
  std::vector<Vec3> pts;
  if (!have_solution_ || segments < 1) return pts;
  RodOde<0> ode;
  setup_ode(&ode, R_tip_, load_);
  RodOde<0>::State y;
  init_tip_state(ode, R_tip_, load_.wrench.moment, &y);
  IntegratorSettings seg = settings_.integrator;
  seg.steps = std::max(1, (settings_.integrator.steps + segments - 1) / segments);
  const double L = model_.rod.length;
  std::vector<Vec3> from_tip{Vec3::Zero()};
  for (int k = 0; k < segments; ++k) {
    const double s0 = L * (1.0 - double(k) / segments);
    const double s1 = L * (1.0 - double(k + 1) / segments);
    integrate(seg, ode, s0, s1, y);
    from_tip.push_back(y.segment<3>(0));
  }
  const Mat3 R0 = Eigen::Map<const Mat3>(y.data() + 3);
  const Vec3 p0 = y.segment<3>(0);
  for (auto it = from_tip.rbegin(); it != from_tip.rend(); ++it) pts.push_back(R0.transpose() * (*it - p0));
  return pts;
}

}  // namespace rod
}  // namespace hydrojet
