// Shared fixtures for the rod tests: the scenes shipped in config/scenes and small helpers.
#pragma once

#include <string>

#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace test {

inline config::Scene scene(const std::string& name) {
  return config::load_scene(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/" + name + ".yaml");
}

/// Jet map of eq. (24) with Table 1's misalignments: tip-frame force from three jet forces [N].
inline rod::Vec3 jet_force(double q1, double q2, double q3, double da = 0.12, double db = 0.06, double dg = -0.08) {
  const double p3 = M_PI / 3.0;
  return rod::Vec3(std::sin(p3 - db) * q1 + std::sin(da) * q2 - std::sin(p3 - dg) * q3,
                   std::cos(p3 - db) * q1 - std::cos(da) * q2 + std::cos(p3 - dg) * q3, 0.0);
}

/// The rod of a scene without its actuators: loaded by a tip wrench only.
inline rod::RodModel bare(const config::Scene& s) { return s.rod.without_actuators(); }

/// q_max [N] of a HydroJet scene's three jets.
inline rod::Vec3 jet_max_force(const config::Scene& s) { return control::jet_max_force(s.rod); }

/// A straight, unloaded, isotropic rod with no gravity (for closed-form checks).
inline rod::RodModel plain_rod(double L = 0.09, double EI = 6.01e-4, double GJ = 2.23e-4) {
  rod::RodModel m;
  m.segments.resize(1);
  m.segments[0].length = L;
  m.segments[0].stiffness = rod::Vec3(EI, EI, GJ);
  m.segments[0].precurvature.setZero();
  m.tip_mass = 0.0;
  m.gravity.setZero();
  return m;
}

inline rod::ShootingOptions rk8(int steps, double residual_tol = 1e-12) {
  rod::ShootingOptions s;
  s.integrator.type = rod::IntegratorType::kRk8;
  s.integrator.steps = steps;
  s.residual_tolerance = residual_tol;
  return s;
}

/// The angle [rad] of the rotation from A to B.
inline double angle_between(const rod::Mat3& A, const rod::Mat3& B) { return so3::log(A.transpose() * B).norm(); }

/// A tip wrench of a force alone.
inline rod::TipWrench force(const rod::Vec3& f) {
  rod::TipWrench w;
  w.force = f;
  return w;
}

}  // namespace test
}  // namespace hydrojet
