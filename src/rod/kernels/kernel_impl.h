// Internal to hydrojet_rod: the hot kernels of single shooting (one integration with the 3 Newton
// directions; one with the 6 compliance directions; the Richardson error estimate), templated on
// the model's terms (RodTerms: Kirchhoff or Cosserat, with or without distributed weight, straight
// or precurved).
//
// Why the variants exist: the right-hand side of eq. (14) is compiled once per combination of
// terms, and the scene's combination is chosen once per model (kernel_table.cpp), so the
// integration loop runs without branches on terms the scene does not have. Why one translation
// unit per variant (kernel_*.cpp, which only instantiate): with all of them in one, GCC's
// inlining budget ran out and the hot loop became 2× slower. Not installed.
#pragma once

#include "../solver_templates.h"

namespace hydrojet {
namespace rod {

using internal::init_tip_state;

template <class T>
ShootingSolver::Eval ShootingSolver::evaluate_t(const Mat3& R_tip, const Load& load, int* rhs) {
  using Ode = RodOde<3, T>;
  Ode ode;
  setup_ode(&ode, R_tip, load);
  typename Ode::State y;
  init_tip_state(ode, R_tip, load.wrench.moment, &y);
  for (int i = 0; i < 3; ++i) {
    // Direction x_i: R(L) -> R(L) exp(ε e_i^): η(L) = e_i, and n(L) changes by R(L)(e_i × f_b).
    y[Ode::kBase + Ode::kPerDir * i + i] = 1.0;
    ode.dn.col(i) = R_tip * Vec3::Unit(i).cross(load.wrench.force);
  }
  const IntegrationStats st = workspace_.integrate(ode, model_.rod.length, 0.0, &y, settings_.integrator);
  *rhs += st.rhs_evaluations;
  Eval e;
  e.ok = st.ok && y.allFinite();
  if (!e.ok) return e;
  e.R0 = Eigen::Map<const Mat3>(y.data() + 3);
  e.p0 = y.template segment<3>(0);
  for (int i = 0; i < 3; ++i) {
    const int o = Ode::kBase + Ode::kPerDir * i;
    e.deta0.col(i) = y.template segment<3>(o);
    e.dp0.col(i) = y.template segment<3>(o + 6);
  }
  // Shooting residual, eq. (15): R(0) = I  <=>  log R(0) = 0.
  e.r = so3::log(so3::orthonormalize(e.R0));
  e.J = so3::right_jacobian_inverse(e.r) * e.deta0;
  e.ok = e.r.allFinite() && e.J.allFinite();
  return e;
}

template <class T>
bool ShootingSolver::compliance_t(Mat6* C) {
  // Directions 0–2: f_b,i (n(L) changes by R(L) e_i); 3–5: l_b,i (u(L) changes by K⁻¹ e_i, no δn).
  using Ode = RodOde<6, T>;
  Ode ode;
  setup_ode(&ode, R_tip_, load_);
  typename Ode::State y;
  init_tip_state(ode, R_tip_, load_.wrench.moment, &y);
  for (int i = 0; i < 3; ++i) {
    ode.dn.col(i) = R_tip_.col(i);
    y[Ode::kBase + Ode::kPerDir * (3 + i) + 3 + i] = ode.k_inv[i];
  }
  const IntegrationStats st = workspace_.integrate(ode, model_.rod.length, 0.0, &y, settings_.integrator);
  if (!st.ok || !y.allFinite()) return false;
  Eigen::Matrix<double, 3, 6> eta_w, dp_w;
  for (int d = 0; d < 6; ++d) {
    const int o = Ode::kBase + Ode::kPerDir * d;
    eta_w.col(d) = y.template segment<3>(o);
    dp_w.col(d) = y.template segment<3>(o + 6);
  }
  // Implicit function theorem on r(x, w) = 0: dx/dw = −(∂r/∂x)⁻¹ ∂r/∂w.
  const Eigen::Matrix<double, 3, 6> dr_dw = so3::right_jacobian_inverse(eval_.r) * eta_w;
  const Eigen::Matrix<double, 3, 6> dx_dw = -eval_.J.partialPivLu().solve(dr_dw);
  const Eigen::Matrix<double, 3, 6> dp0 = eval_.dp0 * dx_dw + dp_w;
  // Tip pose in the base frame: R_T = R(0)ᵀ R(L), p_T = −R(0)ᵀ p(0). Along the solution R(0) stays
  // I, so the body twist is ω = dx/dw and v = R_Tᵀ dp_T = −R(L)ᵀ dp(0).
  C->topRows<3>() = -R_tip_.transpose() * dp0;
  C->bottomRows<3>() = dx_dw;
  return C->allFinite();
}

template <class T>
double ShootingSolver::error_t(const Mat3& R_tip, const Load& load, const Eval& e) {
  // Richardson estimate of the discretisation error of the converged N-step solve: integrate the
  // state alone with N/2 steps (or 2N when N is odd), compare R(0), p(0), and carry the difference
  // through the shooting problem: the exact integrator would leave the residual δr ≈ f·log(R0ᵀR0'),
  // which Newton removes with δx = −J⁻¹δr, moving the tip by δp ≈ f·(p0' − p0) + ∂p0/∂x·δx.
  const IntegratorOptions& is = settings_.integrator;
  const int N = is.steps;
  const double q = is.type == IntegratorType::kRk4 ? 16.0 : 256.0;  // 2^order
  IntegratorOptions other = is;
  double f;
  if (N % 2 == 0) {
    other.steps = N / 2;
    f = -1.0 / (q - 1.0);  // exact − fine ≈ (fine − coarse)/(2^p − 1)
  } else {
    other.steps = 2 * N;
    f = q / (q - 1.0);  // exact − coarse ≈ (fine − coarse)·2^p/(2^p − 1)
  }
  using Ode = RodOde<0, T>;
  Ode ode;
  setup_ode(&ode, R_tip, load);
  typename Ode::State y;
  init_tip_state(ode, R_tip, load.wrench.moment, &y);
  const IntegrationStats st = workspace_.integrate(ode, model_.rod.length, 0.0, &y, other);
  if (!st.ok || !y.allFinite()) return std::numeric_limits<double>::infinity();
  const Mat3 R0o = Eigen::Map<const Mat3>(y.data() + 3);
  const Vec3 dr = f * so3::log(so3::orthonormalize(e.R0.transpose() * R0o));
  const Vec3 dp = f * (y.template segment<3>(0) - e.p0);
  const Vec3 dx = -e.J.partialPivLu().solve(dr);
  return (dp + e.dp0 * dx).norm();
}

}  // namespace rod
}  // namespace hydrojet

/// Explicit instantiation of one variant's kernels (in a kernel_*.cpp).
#define HYDROJET_ROD_KERNELS(C, W, P)                                                                          \
  namespace hydrojet {                                                                                         \
  namespace rod {                                                                                              \
  template ShootingSolver::Eval ShootingSolver::evaluate_t<RodTerms<C, W, P>>(const Mat3&, const Load&, int*); \
  template bool ShootingSolver::compliance_t<RodTerms<C, W, P>>(Mat6*);                                        \
  template double ShootingSolver::error_t<RodTerms<C, W, P>>(const Mat3&, const Load&, const Eval&);           \
  }                                                                                                            \
  }
