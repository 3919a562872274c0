// Internal to hydrojet_rod: integrating a RodOde with any integrator (Eigen Runge–Kutta methods or
// CVODE(S)), for the sweeps of single and multiple shooting. Not installed.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <string>
#include <Eigen/Dense>

#include "hydrojet_control/rod/cvode_integrator.h"
#include "hydrojet_control/rod/integrators.h"
#include "hydrojet_control/rod/rod_model.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace rod {
namespace internal {

/// Why a fixed-step solve is refused by the accuracy check (ShootingOptions::accuracy_tolerance).
inline std::string accuracy_refusal(double estimate, IntegratorType type, int steps, int segments, double allowed) {
  const std::string how = std::string(integrator_name(type)) + " with " + std::to_string(steps) + " steps" +
                          (segments > 1 ? " over " + std::to_string(segments) + " segments" : "");
  char buf[200];
  if (std::isfinite(estimate))
    std::snprintf(buf, sizeof buf, "estimated tip error %.2g m of %s exceeds accuracy_tolerance*L = %.2g m", estimate,
                  how.c_str(), allowed);
  else
    std::snprintf(buf, sizeof buf, "tip error of %s cannot be estimated (the half-step integration diverged)",
                  how.c_str());
  return std::string(buf) + ": use more steps or an adaptive integrator";
}

/// Copies the fixed parameters of one RodOde into another (of any D / variant).
template <class A, class B>
void copy_parameters(const A& a, B* b) {
  b->k_diag = a.k_diag;
  b->k_inv = a.k_inv;
  b->u_tilde = a.u_tilde;
  b->n_tip = a.n_tip;
  b->w_dist = a.w_dist;
  b->length = a.length;
  b->kse_inv = a.kse_inv;
}

/// ∂f/∂y of the base 15-number state by exact Jacobian–vector products, column-major into J
/// (leading dimension ld).
template <class Ode>
void base_jacobian(const Ode& ode, double s, const double* yp, double* J, int ld) {
  using B = Eigen::Matrix<double, 15, 1>;
  const B y = Eigen::Map<const B>(yp);
  B e, out;
  for (int j = 0; j < 15; ++j) {
    e.setZero();
    e[j] = 1.0;
    ode.jvp(s, y, e, Vec3::Zero(), out);
    for (int i = 0; i < 15; ++i) J[j * ld + i] = out[i];
  }
}

/// Block-diagonal Jacobian of the augmented state [y, directions] for CVODE's BDF Newton
/// iteration: the exact base block and, per direction, the exact 9×9 block of the (linear)
/// sensitivity equations. The coupling of the sensitivities to the base state is left out.
template <class Ode>
void augmented_jacobian(const void* o, double s, const double* yp, double* J) {
  const Ode& ode = *static_cast<const Ode*>(o);
  constexpr int n = Ode::kSize;
  Eigen::Map<Eigen::MatrixXd> Jm(J, n, n);
  Jm.setZero();
  base_jacobian(ode, s, yp, J, n);
  if constexpr (Ode::kDirections > 0) {
    RodOde<1, typename Ode::Terms> one;  // its δn stays zero: the linear part only
    copy_parameters(ode, &one);
    one.dn.setZero();
    typename RodOde<1, typename Ode::Terms>::State z, dz;
    z.template head<15>() = Eigen::Map<const Eigen::Matrix<double, 15, 1>>(yp);
    Eigen::Matrix<double, 9, 9> S;
    for (int j = 0; j < 9; ++j) {
      z.template tail<9>().setZero();
      z[15 + j] = 1.0;
      one(s, z, dz);
      S.col(j) = dz.template tail<9>();
    }
    for (int d = 0; d < Ode::kDirections; ++d) Jm.template block<9, 9>(15 + 9 * d, 15 + 9 * d) = S;
  }
}

/// CVODE on the augmented state.
template <class Ode>
IntegrationStats cvode_augmented(CvodeWorkspace& ws, const IntegratorOptions& is, const Ode& ode, double s0, double s1,
                                 typename Ode::State* y) {
  OdeFunctions f = ode_functions(ode);
  if (is.type == IntegratorType::kCvodeBdf) f.jac = &augmented_jacobian<Ode>;
  return ws.integrate(is, f, s0, s1, y->data());
}

/// CVODES forward sensitivities: the base state (15) plus D sensitivity vectors in plain state
/// coordinates (δp, δR, δu); converted from and to the [η, δu, δp] layout of RodOde.
template <class Ode>
struct SensitivityProblem {
  static constexpr int D = Ode::kDirections;
  using Base = RodOde<0, typename Ode::Terms>;
  using B = Eigen::Matrix<double, 15, 1>;
  Base base;
  Eigen::Matrix<double, 3, D> dn = Eigen::Matrix<double, 3, D>::Zero();

  static void rhs(const void* o, double s, const double* y, double* dy) {
    const auto& p = *static_cast<const SensitivityProblem*>(o);
    typename Base::State ys = Eigen::Map<const B>(y), d;
    p.base(s, ys, d);
    Eigen::Map<B> out(dy);
    out = d;
  }
  static void jac(const void* o, double s, const double* y, double* J) {
    base_jacobian(static_cast<const SensitivityProblem*>(o)->base, s, y, J, 15);
  }
  static void sens(const void* o, double s, const double* y, int i, const double* ys, double* dys) {
    const auto& p = *static_cast<const SensitivityProblem*>(o);
    p.base.jvp(s, Eigen::Map<const B>(y), Eigen::Map<const B>(ys), p.dn.col(i), Eigen::Map<B>(dys));
  }
};

template <class Ode>
IntegrationStats cvodes_sensitivities(CvodeWorkspace& ws, const IntegratorOptions& is, const Ode& ode, double s0,
                                      double s1, typename Ode::State* y) {
  constexpr int D = Ode::kDirections;
  SensitivityProblem<Ode> p;
  copy_parameters(ode, &p.base);
  p.dn = ode.dn;
  Eigen::Matrix<double, 15, 1> yb = y->template head<15>();
  Eigen::Matrix<double, 15, D> ys;
  const Eigen::Map<const Mat3> R(yb.data() + 3);
  for (int d = 0; d < D; ++d) {
    const int o = 15 + 9 * d;
    const Vec3 eta = y->template segment<3>(o);
    ys.col(d).template segment<3>(0) = y->template segment<3>(o + 6);
    const Mat3 dR = R * so3::hat(eta);
    for (int c = 0; c < 3; ++c) ys.col(d).template segment<3>(3 + 3 * c) = dR.col(c);
    ys.col(d).template segment<3>(12) = y->template segment<3>(o + 3);
  }
  OdeFunctions f;
  f.ode = &p;
  f.n = 15;
  f.rhs = &SensitivityProblem<Ode>::rhs;
  if (is.type == IntegratorType::kCvodeBdf) f.jac = &SensitivityProblem<Ode>::jac;
  f.ns = D;
  f.sens_rhs = &SensitivityProblem<Ode>::sens;
  const IntegrationStats st = ws.integrate(is, f, s0, s1, yb.data(), ys.data());
  if (!st.ok) return st;
  y->template head<15>() = yb;
  const Eigen::Map<const Mat3> R0(yb.data() + 3);
  for (int d = 0; d < D; ++d) {
    const int o = 15 + 9 * d;
    const Mat3 A = R0.transpose() * Eigen::Map<const Mat3>(ys.col(d).data() + 3);
    y->template segment<3>(o) = 0.5 * Vec3(A(2, 1) - A(1, 2), A(0, 2) - A(2, 0), A(1, 0) - A(0, 1));
    y->template segment<3>(o + 3) = ys.col(d).template segment<3>(12);
    y->template segment<3>(o + 6) = ys.col(d).template segment<3>(0);
  }
  return st;
}

/// Integrates any RodOde with the integrator of `is`.
template <class Ode>
IntegrationStats integrate_rod(const IntegratorOptions& is, CvodeWorkspace* ws, const Ode& ode, double s0, double s1,
                               typename Ode::State* y) {
  switch (is.type) {
    case IntegratorType::kRk4:
    case IntegratorType::kRk8:
    case IntegratorType::kDopri5: return integrate(is, ode, s0, s1, *y);
    case IntegratorType::kCvodeAdams:
    case IntegratorType::kCvodeBdf:
      if constexpr (Ode::kDirections > 0) {
        if (is.cvodes_sensitivities) return cvodes_sensitivities(*ws, is, ode, s0, s1, y);
      }
      return cvode_augmented(*ws, is, ode, s0, s1, y);
  }
  IntegrationStats st;
  st.ok = false;
  return st;
}

}  // namespace internal
}  // namespace rod
}  // namespace hydrojet
