// Internal to hydrojet_rod: ShootingSolver member templates shared by shooting_solver.cpp and
// multiple_shooting.cpp. Not installed.
#pragma once

#include "hydrojet_control/rod/cvode_integrator.h"
#include "hydrojet_control/rod/shooting_solver.h"
#include "rod_integration.h"

namespace hydrojet {
namespace rod {

template <class Ode>
void ShootingSolver::setup_ode(Ode* ode, const Mat3& R_tip, const Load& load) const {
  const ElasticRod& rod = model_.rod;
  ode->k_diag = rod.stiffness;
  ode->k_inv = rod.stiffness.cwiseInverse();
  ode->u_tilde = rod.precurvature;
  ode->length = rod.length;
  ode->kse_inv = rod.shear_extension_compliance();
  // Tip boundary condition (eq. 16 with eq. 13): n(L) = R(L) f_b + m_t g.
  ode->n_tip = R_tip * load.wrench.force + load.gravity_scale * model_.tip_mass * model_.gravity;
  ode->w_dist = load.gravity_scale * rod.linear_density * model_.gravity;
  ode->dn.setZero();
}

template <class Ode>
IntegrationStats ShootingSolver::Workspace::integrate(const Ode& ode, double s0, double s1, typename Ode::State* y,
                                                      const IntegratorOptions& is) {
  const bool cvode = is.type == IntegratorType::kCvodeAdams || is.type == IntegratorType::kCvodeBdf;
  if (cvode && !cvode_) cvode_.reset(new CvodeWorkspace);
  return internal::integrate_rod(is, cvode ? cvode_.get() : nullptr, ode, s0, s1, y);
}

}  // namespace rod
}  // namespace hydrojet
