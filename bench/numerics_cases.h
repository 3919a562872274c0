// Scenes and load cases of the numerics study, shared by the work-precision driver, the stability
// map and the extreme-case tests (test/test_numerics_extreme.cpp), so that docs/work_precision.md,
// docs/stability.md and the tests talk about the same problems.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace numerics {

using rod::Mat3;
using rod::Vec3;

inline config::Scene scene(const std::string& name) {
  return config::load_scene(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/" + name + ".yaml");
}

/// The rod of a scene without its actuators: loaded by a tip wrench only.
inline rod::RodModel bare(const config::Scene& s) { return s.rod.without_actuators(); }

/// q_max [N] of a HydroJet scene's three jets.
inline Vec3 jet_max_force(const config::Scene& s) { return control::jet_max_force(s.rod); }

/// Jet map of eq. (24) with Table 1's misalignments: tip-frame force from three jet forces [N].
inline Vec3 jet_force(double q1, double q2, double q3) {
  const double p3 = M_PI / 3.0, da = 0.12, db = 0.06, dg = -0.08;
  return Vec3(std::sin(p3 - db) * q1 + std::sin(da) * q2 - std::sin(p3 - dg) * q3,
              std::cos(p3 - db) * q1 - std::cos(da) * q2 + std::cos(p3 - dg) * q3, 0.0);
}

/// The HydroJet's largest single-jet force: jet 1 at q_max,1 = 0.243 N (|f| = 0.243 N).
inline Vec3 max_jet(double scale = 1.0) { return jet_force(0.243 * scale, 0.0, 0.0); }
/// Mid jet force: jets 1 and 2 at half their maximum.
inline Vec3 mid_jet(double scale = 1.0) { return jet_force(0.1215 * scale, 0.112 * scale, 0.0); }

struct Case {
  std::string name;
  std::string description;
  rod::RodModel model;
  rod::TipWrench wrench;
  rod::ActuatedSet actuated = rod::lateral_force_actuation();
  /// Shooting segments for the reference solves (1: single shooting is well conditioned here).
  int reference_segments = 1;
  /// Tip accuracy asked of the solver under test [m] (1e-6 m for the 9 cm HydroJet, ∝ L).
  double tolerance = 1e-6;
};

inline rod::RodModel to_cosserat(rod::RodModel m, double GA, double EA) {
  m.kind = rod::RodKind::kCosserat;
  for (rod::RodSegment& sg : m.segments) {
    sg.shear_stiffness = GA;
    sg.axial_stiffness = EA;
  }
  return m;
}

inline Case make_case(const std::string& name, const std::string& description, const rod::RodModel& m,
                      const Vec3& force, int ref_segments = 1) {
  Case c;
  c.name = name;
  c.description = description;
  c.model = m;
  c.wrench.force = force;
  c.reference_segments = ref_segments;
  c.tolerance = 1e-6 * m.length() / 0.09;
  return c;
}

/// The scenes of docs/work_precision.md.
inline std::vector<Case> work_precision_cases() {
  const rod::RodModel hj0 = bare(scene("hydrojet_0deg")), hj30 = bare(scene("hydrojet_30deg"));
  rod::RodModel soft_long = hj30;
  soft_long.segments[0].length *= 5.0;
  soft_long.segments[0].stiffness *= 0.2;
  return {
      make_case("hj0_mid", "HydroJet 0°, jets 1+2 at half force", hj0, mid_jet()),
      make_case("hj0_max", "HydroJet 0°, jet 1 at full force (0.243 N)", hj0, max_jet()),
      make_case("hj30_mid", "HydroJet 30°, jets 1+2 at half force", hj30, mid_jet()),
      make_case("hj30_max", "HydroJet 30°, jet 1 at full force", hj30, max_jet()),
      make_case("hj30_3x", "HydroJet 30°, 3× the full jet force (bends past 2π)", hj30, max_jet(3.0)),
      make_case("cosserat_shear_stiff", "HydroJet 30° as a Cosserat rod, EA = GA = 1e8·EI",
                to_cosserat(hj30, 6.01e4, 6.01e4), max_jet()),
      make_case("cosserat_silicone", "HydroJet 30° as a Cosserat rod, silicone EA = 1.3 N, GA = 0.4 N",
                to_cosserat(hj30, 0.4, 1.3), max_jet()),
      make_case("soft_long", "L × 5, EI × 0.2 (a very soft long rod), mid jet force", soft_long, mid_jet(), 8),
  };
}

/// The stiff and extreme cases of docs/stability.md.
inline std::vector<Case> extreme_cases() {
  const rod::RodModel hj30 = bare(scene("hydrojet_30deg"));
  std::vector<Case> v;
  rod::RodModel soft = hj30, stiff = hj30, tilted = hj30, longr = hj30;
  soft.segments[0].stiffness *= 1e-3;
  stiff.segments[0].stiffness *= 1e3;
  tilted.gravity = Vec3(0.0, 9.81, 0.0);  // base turned 90° about x: gravity across the rod
  tilted.tip_mass *= 10.0;
  longr.segments[0].length *= 10.0;
  v.push_back(
      make_case("very_soft", "EI, GJ × 1e-3, jet force × 1e-3 (same shape scale as gravity)", soft, mid_jet(1e-3), 16));
  v.push_back(make_case("very_soft_full_jets", "EI, GJ × 1e-3 under the full mid jet force (FL²/EI ≈ 2500)", soft,
                        mid_jet(), 48));
  v.push_back(make_case("very_stiff", "EI, GJ × 1e3, full jet force", stiff, max_jet()));
  v.push_back(make_case("cosserat_shear_stiff", "Cosserat, EA = GA = 1e8·EI (EA/EI = 1e8 m⁻²)",
                        to_cosserat(hj30, 6.01e4, 6.01e4), max_jet()));
  v.push_back(make_case("cosserat_silicone", "Cosserat, EA = 1.3 N, GA = 0.4 N (silicone bellows)",
                        to_cosserat(hj30, 0.4, 1.3), max_jet()));
  v.push_back(make_case("follower_1x", "follower force 1× the full jet force", hj30, max_jet(1.0)));
  v.push_back(make_case("follower_3x", "follower force 3× (bends past 2π)", hj30, max_jet(3.0)));
  v.push_back(make_case("follower_10x", "follower force 10×", hj30, max_jet(10.0)));
  v.push_back(make_case("gravity_dominated", "base tilted 90°, tip mass × 10, full jet force", tilted, max_jet()));
  v.push_back(make_case("long_rod", "L × 10, mid jet force", longr, mid_jet(), 16));
  v.push_back(make_case("long_rod_gravity", "L × 10, gravity only", longr, Vec3::Zero(), 16));
  return v;
}

/// The actuation grid of the stability map (paper §7.8, Figs. 12–13: 3000 jet-force combinations
/// with q < q_max): q1 in 20, q2 in 15, q3 in 10 equal steps over [0, q_max), ordered as a
/// serpentine (boustrophedon) so that consecutive points are neighbours and warm starts stay short.
inline std::vector<Vec3> stability_grid(const Vec3& qmax = Vec3(0.243, 0.224, 0.244)) {
  const int n1 = 20, n2 = 15, n3 = 10;
  std::vector<Vec3> q;
  q.reserve(n1 * n2 * n3);
  for (int k = 0; k < n3; ++k)
    for (int jj = 0; jj < n2; ++jj) {
      const int j = k % 2 == 0 ? jj : n2 - 1 - jj;
      for (int ii = 0; ii < n1; ++ii) {
        const int i = (k * n2 + jj) % 2 == 0 ? ii : n1 - 1 - ii;
        q.emplace_back(qmax[0] * i / n1, qmax[1] * j / n2, qmax[2] * k / n3);
      }
    }
  return q;
}

/// A reference solution: two different methods (RK8 with many steps, DOPRI5 at 1e-12, both with
/// residual 1e-13), cold with load continuation; `agreement` is their tip distance [m].
struct Reference {
  bool ok = false;
  Vec3 position = Vec3::Zero();
  Mat3 rotation = Mat3::Identity();
  rod::Mat6 compliance = rod::Mat6::Zero();
  double agreement = NAN;        ///< |p_rk8 − p_dopri5| [m]
  double angle_agreement = NAN;  ///< rotation angle between them [rad]
  std::string message;
};

inline rod::ShootingOptions reference_settings(const Case& c, bool rk8) {
  rod::ShootingOptions s;
  s.integrator.type = rk8 ? rod::IntegratorType::kRk8 : rod::IntegratorType::kDopri5;
  s.integrator.steps = 256 * std::max(1, c.reference_segments);
  s.integrator.tolerance = 1e-12;
  s.residual_tolerance = 1e-12;
  s.max_iterations = 50;
  s.max_continuation_steps = 2000;
  s.shooting_segments = c.reference_segments > 1 ? c.reference_segments : 1;
  return s;
}

inline Reference reference(const Case& c) {
  Reference r;
  rod::RodSolver a(c.model, reference_settings(c, true)), b(c.model, reference_settings(c, false));
  const rod::RodSolution sa = a.solve(c.wrench), sb = b.solve(c.wrench);
  if (!sa.converged || !sb.converged) {
    r.message = "reference did not converge: rk8 " + (sa.converged ? std::string("ok") : sa.message) + ", dopri5 " +
                (sb.converged ? std::string("ok") : sb.message);
    return r;
  }
  r.position = sa.tip_position;
  r.rotation = sa.tip_rotation;
  r.agreement = (sa.tip_position - sb.tip_position).norm();
  r.angle_agreement = so3::log(sa.tip_rotation.transpose() * sb.tip_rotation).norm();
  const rod::Compliance C = a.compliance();
  r.compliance = C.body;
  r.ok = C.ok && r.agreement <= 1e-10 * std::max(1.0, c.model.length() / 0.09);
  if (!r.ok) r.message = "references disagree by " + std::to_string(r.agreement) + " m";
  return r;
}

}  // namespace numerics
}  // namespace hydrojet
