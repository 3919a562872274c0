// The rod's lowest lateral modes (control/modal_model.h) against independent truths: the closed form
// of a cantilever with a tip mass (and Rayleigh's 33/140 of its own mass), and the free vibration of
// the plant's dynamic Cosserat rod (rod/dynamic_rod.h) about a loaded, precurved equilibrium.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "hydrojet_control/control/modal_model.h"
#include "hydrojet_control/rod/dynamic_rod.h"
#include "test_helpers.h"

namespace {

using namespace hydrojet;
using rod::Vec3;

rod::ShootingOptions accurate() {
  rod::ShootingOptions o;
  o.integrator.type = rod::IntegratorType::kRk8;
  o.integrator.steps = 16;
  o.residual_tolerance = 1e-13;
  return o;
}

TEST(ModalModel, CantileverWithTipMassMatchesTheClosedForm) {
  const double L = 0.09, EI = 6e-4, mt = 0.0077;
  for (const double rho_a : {0.0, 0.02}) {
    rod::RodModel m;
    m.segments.resize(1);
    m.segments[0].length = L;
    m.segments[0].stiffness = Vec3(EI, EI, 4e-4);
    m.segments[0].linear_density = rho_a;
    m.tip_mass = mt;
    const control::ModalModel mm =
        control::lateral_modes(rod::RodSolver(m, accurate()), rod::InputVector(0), rod::TipWrench());
    ASSERT_TRUE(mm.ok) << mm.error;
    // Rayleigh with the static shape: k = 3EI/L³, m = m_t + 33/140 ρA L (exact for ρA = 0).
    const double w = std::sqrt(3 * EI / (L * L * L) / (mt + 33.0 / 140.0 * rho_a * L));
    EXPECT_NEAR(mm.frequency[0] / w, 1.0, 1e-5) << rho_a;
    EXPECT_NEAR(mm.frequency[1] / w, 1.0, 1e-5) << rho_a;  // round: both lateral modes alike
    EXPECT_NEAR(mm.stiffness(0, 0), 3 * EI / (L * L * L), 1e-6 * 3 * EI / (L * L * L));
    // The tip turns by 3/(2L) per unit of tip displacement (a tip-loaded cantilever), x about −y.
    EXPECT_NEAR(mm.rotation(1, 0), 1.5 / L, 1e-5 / L);
    EXPECT_NEAR(mm.rotation(0, 1), -1.5 / L, 1e-5 / L);
  }
}

/// The overload from a known C^b (the controller's cycle) gives the solver's modes when the body's
/// mass is all at its tip, and refuses a body with mass of its own.
TEST(ModalModel, FromTheCyclesComplianceMatchesTheSolvesModes) {
  const rod::RodModel m = test::scene("hydrojet_30deg").rod;
  ASSERT_FALSE(control::has_body_mass(m));
  control::ModalOptions o;
  o.tip_mass_scale = 3.0;
  const rod::InputVector q = rod::InputVector::Constant(m.input_count(), 0.01);
  const control::ModalModel a = control::lateral_modes(rod::RodSolver(m, accurate()), q, rod::TipWrench(), o);
  rod::RodSolver s(m, accurate());
  ASSERT_TRUE(s.solve(q, rod::TipWrench()).converged);
  const rod::Compliance c = s.compliance();
  ASSERT_TRUE(c.ok);
  const control::ModalModel b = control::lateral_modes(m, c.body, o);
  ASSERT_TRUE(a.ok && b.ok) << a.error << b.error;
  EXPECT_NEAR(b.frequency[0] / a.frequency[0], 1.0, 1e-12);
  EXPECT_NEAR(b.frequency[1] / a.frequency[1], 1.0, 1e-12);
  EXPECT_LT((b.rotation - a.rotation).norm(), 1e-12 * a.rotation.norm());

  rod::RodModel massive = m;
  massive.segments[0].linear_density = 0.01;
  const control::ModalModel refused = control::lateral_modes(massive, c.body, o);
  EXPECT_FALSE(refused.ok);
  EXPECT_NE(refused.error.find("mass of its own"), std::string::npos) << refused.error;
}

/// The dynamic rod released from a static push along mode 1: the period of its tip's motion along
/// that mode's displacement, from upward zero crossings over about four periods.
double released_frequency(const rod::DynamicRodModel& p, const control::ModalModel& mm, const Vec3& tip_dir_base,
                          double push) {
  rod::DynamicRod rod(p);
  EXPECT_TRUE(rod.last_error().empty()) << rod.last_error();
  const Vec3 p_eq = rod.tip_position();  // at rest, unloaded (the constructor's equilibrium)
  rod::TipWrench w;
  const Eigen::Vector2d f = mm.stiffness * mm.modes.col(0);  // the static force that bends along mode 1
  w.force.head<2>() = push * f / f.norm();
  EXPECT_TRUE(rod.reset_to_static(w)) << rod.last_error();
  const double T_est = 2 * M_PI / mm.frequency[0], dt = T_est / 200;
  std::vector<double> up;
  double x1 = (rod.tip_position() - p_eq).dot(tip_dir_base), t1 = 0.0;
  for (int k = 0; k < static_cast<int>(4.5 * T_est / dt); ++k) {
    EXPECT_TRUE(rod.step(rod::TipWrench(), dt)) << rod.last_error();
    const double x = (rod.tip_position() - p_eq).dot(tip_dir_base);
    if (x1 < 0.0 && x >= 0.0) up.push_back(t1 + dt * (-x1) / (x - x1));
    x1 = x, t1 = rod.time();
  }
  EXPECT_GE(up.size(), 3u);
  return up.size() < 2 ? 0.0 : 2 * M_PI * (up.size() - 1) / (up.back() - up.front());
}

/// Both shipped robots, undamped, with the scene's gravity and precurvature: the reduced model's
/// first frequency against the dynamic rod's own: within 0.2 % (measured 0.02 %, 0.02 %, 0.07 %; the
/// released rod's period is resolved to about 1e-4: crossings interpolated at T/200, Till's α-method at
/// (ωΔt)² ≈ 1e-3).
TEST(ModalModel, FirstModeMatchesTheDynamicRodsFreeVibration) {
  struct Case {
    const char* scene;
    double tip_mass_scale;
  } cases[] = {{"hydrojet_0deg", 3.0}, {"hydrojet_30deg", 1.0}, {"two_segment_thrusters", 1.0}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.scene);
    rod::DynamicRodModel p;
    p.rod = test::scene(c.scene).rod;
    p.rod.tip_mass *= c.tip_mass_scale;
    p.kelvin_voigt_time = 0.0;
    // Till's α = −0.2 damps only the high frequencies: (ωΔt)² ≈ 1e-3 of the mode per period at 200 steps.
    p.tip_inertia = Vec3(8e-8, 8e-8, 6e-8);
    control::ModalOptions o;
    o.tip_inertia = p.tip_inertia;
    const rod::RodSolver solver(p.rod, accurate());
    const control::ModalModel mm =
        control::lateral_modes(solver, rod::InputVector::Zero(p.rod.input_count()), rod::TipWrench(), o);
    ASSERT_TRUE(mm.ok) << mm.error;
    rod::RodSolver eq = solver;
    const rod::RodSolution sol = eq.solve(rod::InputVector::Zero(p.rod.input_count()));
    ASSERT_TRUE(sol.converged);
    Vec3 along = Vec3::Zero();
    along.head<2>() = mm.modes.col(0);
    const Vec3 dir = (sol.tip_rotation * along).normalized();
    const double w_dyn = released_frequency(p, mm, dir, 1e-3 * mm.stiffness.norm());  // ≈1 mm
    std::printf("%-22s first mode: reduced %.3f Hz, dynamic rod %.3f Hz (%+.2f %%); second %.3f Hz\n", c.scene,
                mm.frequency[0] / (2 * M_PI), w_dyn / (2 * M_PI), 100 * (mm.frequency[0] / w_dyn - 1),
                mm.frequency[1] / (2 * M_PI));
    EXPECT_NEAR(mm.frequency[0] / w_dyn, 1.0, 2e-3);
  }
}

}  // namespace
