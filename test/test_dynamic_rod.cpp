// Dynamic Cosserat rod (plant/dynamic_rod.h): static limit against the quasi-static Kirchhoff
// RodSolver, free vibration against the cantilever-with-tip-mass estimate, Kelvin–Voigt
// damping, the HydroJet's response to a jet-force step, and input validation.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "hydrojet_control/rod/dynamic_rod.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"

using namespace hydrojet;
using rod::DynamicRod;
using rod::DynamicRodModel;
using rod::Mat3;
using rod::Vec3;

namespace {

constexpr double kL = 0.09, kEI = 6.01e-4, kGJ = 2.23e-4, kTipMass = 0.00258;

/// The HydroJet of Campisano et al. 2021 (Table 1), hanging along +z of the base.
DynamicRodModel hydrojet_parameters() {
  DynamicRodModel p;
  p.rod.segments.resize(1);
  p.rod.segments[0].length = kL;
  p.rod.segments[0].stiffness = Vec3(kEI, kEI, kGJ);
  p.rod.segments[0].precurvature = Vec3(0.034, 0.88, 0.0);
  p.rod.segments[0].linear_density = 0.0;
  p.rod.tip_mass = kTipMass;
  p.rod.gravity = Vec3(0.0, 0.0, 9.81);
  p.kelvin_voigt_time = 0.01;  // light material damping (ζ ≈ 0.15 for the first mode)
  return p;
}

/// Straight rod, no gravity, no damping: the cantilever of the free-vibration tests.
DynamicRodModel straight_undamped(double rho_a, const Vec3& tip_inertia) {
  DynamicRodModel p;
  p.rod.segments.resize(1);
  p.rod.segments[0].length = kL;
  p.rod.segments[0].stiffness = Vec3(kEI, kEI, kGJ);
  p.rod.segments[0].precurvature.setZero();
  p.rod.segments[0].linear_density = rho_a;
  p.rod.tip_mass = kTipMass;
  p.rod.gravity.setZero();
  p.kelvin_voigt_time = 0.0;
  p.tip_inertia = tip_inertia;
  return p;
}

/// Jet map of the paper's eq. (24) with Table 1's misalignments: tip-frame force [N].
Vec3 jet_force(double q1, double q2, double q3) {
  const double p3 = M_PI / 3.0, da = 0.12, db = 0.06, dg = -0.08;
  return Vec3(std::sin(p3 - db) * q1 + std::sin(da) * q2 - std::sin(p3 - dg) * q3,
              std::cos(p3 - db) * q1 - std::cos(da) * q2 + std::cos(p3 - dg) * q3, 0.0);
}

/// Quasi-static Kirchhoff reference (8th-order RK, 16 steps, tight residual).
rod::RodSolution kirchhoff(const rod::RodModel& model, const rod::TipWrench& w) {
  rod::ShootingOptions st;
  st.integrator.type = rod::IntegratorType::kRk8;
  st.integrator.steps = 16;
  st.residual_tolerance = 1e-13;
  rod::RodSolver solver(model, st);
  return solver.solve(w);
}

double rotation_error(const Mat3& a, const Mat3& b) { return so3::log(a.transpose() * b).norm(); }

/// Tolerances of the static limit. The Cosserat rod differs from the Kirchhoff rod by its
/// shear/extension strain |n|/min(GA, EA) over the length L (≈1.4e-7 m for 0.16 N and
/// GA = EA = 1e5 N; the factor 2 covers the force varying along s). The RK4 grid error with the
/// default 21 nodes is ≈1e-7 m and ≈1.1e-6 rad on this strongly bent configuration (measured: it
/// falls 16× per halving of the step, 4th order), so 5e-7 m and 5e-6 rad are used for the grid.
double position_tolerance(const DynamicRodModel& p, double n_max) {
  return 2.0 * p.rod.segments[0].length * n_max / std::min(p.shear_stiffness, p.axial_stiffness) + 5e-7;
}
constexpr double kRotationTolerance = 5e-6;

struct Oscillation {
  std::vector<double> up_crossings;  ///< times [s] of upward zero crossings (interpolated)
  std::vector<double> peaks;         ///< local maxima of the signal
};

/// Vertex value of the parabola through three equally spaced samples (a, b, c), b the largest:
/// removes the sampling error (≈(ωΔt)²/8 relative) from a measured peak.
double parabola_peak(double a, double b, double c) {
  const double curvature = a - 2.0 * b + c;
  return curvature < 0.0 ? b - (c - a) * (c - a) / (8.0 * curvature) : b;
}

/// Steps the rod with zero wrench and records the tip's x coordinate.
Oscillation free_vibration(DynamicRod* rod, double dt, double duration) {
  Oscillation o;
  rod::TipWrench none;
  double x1 = rod->tip_position().x(), x2 = x1, t1 = rod->time();
  const int n = static_cast<int>(std::lround(duration / dt));
  for (int k = 0; k < n; ++k) {
    EXPECT_TRUE(rod->step(none, dt)) << rod->last_error();
    const double x = rod->tip_position().x();
    if (x1 < 0.0 && x >= 0.0) o.up_crossings.push_back(t1 + dt * (-x1) / (x - x1));
    if (x1 > x2 && x1 >= x) o.peaks.push_back(parabola_peak(x2, x1, x));
    x2 = x1;
    x1 = x;
    t1 = rod->time();
  }
  return o;
}

double mean_period(const Oscillation& o) {
  return (o.up_crossings.back() - o.up_crossings.front()) / (o.up_crossings.size() - 1);
}

}  // namespace

TEST(DynamicRodStatic, ResetToStaticMatchesKirchhoffAndStaysPut) {
  const DynamicRodModel p = hydrojet_parameters();
  DynamicRod rod(p);
  ASSERT_TRUE(rod.last_error().empty()) << rod.last_error();
  rod::TipWrench w;
  w.force = jet_force(0.2, 0.05, 0.1);
  w.moment = Vec3(1e-4, -2e-4, 5e-5);
  ASSERT_TRUE(rod.reset_to_static(w)) << rod.last_error();
  const rod::RodSolution ref = kirchhoff(p.rod, w);
  ASSERT_TRUE(ref.converged) << ref.message;
  const double dp = (rod.tip_position() - ref.tip_position).norm();
  const double dr = rotation_error(rod.tip_rotation(), ref.tip_rotation);
  std::printf("[ static ] reset_to_static vs RodSolver: |dp| = %.3e m, |dR| = %.3e rad\n", dp, dr);
  EXPECT_LT(dp, position_tolerance(p, rod.base_force().norm()));
  EXPECT_LT(dr, kRotationTolerance);
  EXPECT_EQ(rod.backbone().size(), static_cast<size_t>(p.nodes));
  EXPECT_NEAR((rod.backbone().back() - rod.tip_position()).norm(), 0.0, 1e-15);
  EXPECT_NEAR(rod.backbone().front().norm(), 0.0, 1e-15);

  // At rest at equilibrium, stepping with the same wrench must not move it.
  const Vec3 p0 = rod.tip_position();
  const Mat3 R0 = rod.tip_rotation();
  for (int k = 0; k < 300; ++k) ASSERT_TRUE(rod.step(w, 0.002)) << rod.last_error();
  EXPECT_NEAR(rod.time(), 0.6, 1e-12);
  EXPECT_LT(rod.tip_velocity().norm(), 1e-9);
  EXPECT_LT(rod.tip_angular_velocity().norm(), 1e-8);
  EXPECT_LT((rod.tip_position() - p0).norm(), 1e-10);
  EXPECT_LT(rotation_error(rod.tip_rotation(), R0), 1e-9);
}

TEST(DynamicRodStatic, SettlesToKirchhoffSolutionUnderConstantForce) {
  DynamicRodModel p = hydrojet_parameters();
  p.kelvin_voigt_time = 0.02;  // heavier damping than hydrojet_parameters()' so that it settles in ~2 s
  p.tip_drag = 0.05;
  DynamicRod rod(p);
  ASSERT_TRUE(rod.reset_to_static(rod::TipWrench())) << rod.last_error();
  rod::TipWrench w;
  w.force = jet_force(0.05, 0.2, 0.05);
  const double dt = 0.005;
  int steps = 0;
  while (rod.time() < 4.0) {
    ASSERT_TRUE(rod.step(w, dt)) << rod.last_error();
    ++steps;
  }
  EXPECT_LT(rod.tip_velocity().norm(), 1e-7);
  const rod::RodSolution ref = kirchhoff(p.rod, w);
  ASSERT_TRUE(ref.converged) << ref.message;
  const double dp = (rod.tip_position() - ref.tip_position).norm();
  const double dr = rotation_error(rod.tip_rotation(), ref.tip_rotation);
  std::printf("[ static ] settled after %d steps vs RodSolver: |dp| = %.3e m, |dR| = %.3e rad\n", steps, dp, dr);
  EXPECT_LT(dp, position_tolerance(p, rod.base_force().norm()));
  EXPECT_LT(dr, kRotationTolerance);

  // Tilting the base (gravity 30° off the rod axis) settles to the tilted static solution too.
  const Vec3 g(9.81 * std::sin(M_PI / 6), 0.0, 9.81 * std::cos(M_PI / 6));
  rod.set_gravity(g);
  while (rod.time() < 8.0) ASSERT_TRUE(rod.step(w, dt)) << rod.last_error();
  rod::RodModel tilted = p.rod;
  tilted.gravity = g;
  const rod::RodSolution ref2 = kirchhoff(tilted, w);
  ASSERT_TRUE(ref2.converged);
  EXPECT_LT((rod.tip_position() - ref2.tip_position).norm(), position_tolerance(p, rod.base_force().norm()));
  EXPECT_LT(rotation_error(rod.tip_rotation(), ref2.tip_rotation), kRotationTolerance);
  EXPECT_GT((ref2.tip_position - ref.tip_position).norm(), 1e-3);  // the tilt did matter
}

// A general rod: two segments (the distal one softer and precurved), a point mass and a
// pair of actuators mid-body, actuators at the tip, one with a moment arm. At rest under the inputs
// (reset_to_static) and after settling from a step of them (the jump conditions with their inertia),
// the dynamic rod sits where the static solver (rod::RodSolver) puts it (a second, independent method: its
// stations, pieces and Kirchhoff kinematics), up to shear/extension and the grid.
rod::RodModel two_segment_body() {
  rod::RodModel b;
  b.segments.resize(2);
  b.segments[0].length = 0.05;
  b.segments[0].stiffness = Vec3(1.5e-3, 1.5e-3, 5.6e-4);
  b.segments[0].linear_density = 0.02;
  b.segments[1].length = 0.04;
  b.segments[1].stiffness = Vec3(4e-4, 4e-4, 1.5e-4);
  b.segments[1].precurvature = Vec3(0.0, 2.0, 0.0);
  b.segments[1].linear_density = 0.015;
  rod::PointLoad mid;
  mid.at = 0.05;
  mid.mass = 0.001;
  mid.force = Vec3(0.0, 0.01, 0.0);
  mid.frame = rod::LoadFrame::kBase;
  b.loads = {mid};
  auto actuator = [](double at, const Vec3& p, const Vec3& d) {
    rod::Actuator a;
    a.at = at;
    a.position = p;
    a.direction = d;
    a.max_force = 0.15;
    return a;
  };
  b.actuators = {actuator(0.09, Vec3::Zero(), Vec3::UnitX()), actuator(0.09, Vec3(0.004, 0.0, 0.0), -Vec3::UnitY()),
                 actuator(0.05, Vec3(0.0, 0.005, 0.0), Vec3::UnitX()),
                 actuator(0.05, Vec3(0.005, 0.0, 0.0), Vec3::UnitY())};
  return b;
}

TEST(DynamicRodGeneral, RestsAndSettlesWhereTheStaticGeneralSolverPutsIt) {
  DynamicRodModel p;
  p.rod = two_segment_body();
  p.rod.tip_mass = 0.003;
  p.rod.gravity = Vec3(0.0, 0.0, 9.81);
  p.kelvin_voigt_time = 0.02;
  p.tip_drag = 0.05;
  p.nodes = 31;
  DynamicRod rod(p);
  rod::RodModel ref_model = p.rod;
  ref_model.tip_mass = p.rod.tip_mass;
  ref_model.gravity = p.rod.gravity;
  rod::ShootingOptions st;
  st.integrator.type = rod::IntegratorType::kRk8;
  st.integrator.steps = 16;
  st.residual_tolerance = 1e-13;
  rod::RodSolver ref(ref_model, st);
  rod::InputVector q(4);
  q << 0.04, 0.03, 0.05, 0.02;
  ASSERT_TRUE(rod.set_inputs(q));
  ASSERT_TRUE(rod.reset_to_static(rod::TipWrench())) << rod.last_error();
  const rod::RodSolution a = ref.solve(q);
  ASSERT_TRUE(a.converged) << a.message;
  const double tol = position_tolerance(p, rod.base_force().norm());
  std::printf("[ general ] at rest: |dp| = %.2e m, |dR| = %.2e rad (tolerance %.1e m); tip moved %.1f mm by q\n",
              (rod.tip_position() - a.tip_position).norm(), rotation_error(rod.tip_rotation(), a.tip_rotation), tol,
              1e3 * (a.tip_position - ref.solve(rod::InputVector::Zero(4)).tip_position).norm());
  EXPECT_LT((rod.tip_position() - a.tip_position).norm(), tol);
  EXPECT_LT(rotation_error(rod.tip_rotation(), a.tip_rotation), kRotationTolerance);
  // A step of the inputs: the rod moves (inertia of the masses at the nodes) and settles there.
  q << 0.0, 0.06, 0.0, 0.08;
  ASSERT_TRUE(rod.set_inputs(q));
  const double dt = 0.005;
  double peak_speed = 0.0;
  while (rod.time() < 4.0) {
    ASSERT_TRUE(rod.step(rod::TipWrench(), dt)) << rod.last_error();
    peak_speed = std::max(peak_speed, rod.tip_velocity().norm());
  }
  const rod::RodSolution b = ref.solve(q);
  ASSERT_TRUE(b.converged) << b.message;
  std::printf("[ general ] settled: |dp| = %.2e m, |dR| = %.2e rad; peak tip speed %.3f m/s\n",
              (rod.tip_position() - b.tip_position).norm(), rotation_error(rod.tip_rotation(), b.tip_rotation),
              peak_speed);
  EXPECT_GT(peak_speed, 0.01);
  EXPECT_LT(rod.tip_velocity().norm(), 1e-6);
  EXPECT_LT((rod.tip_position() - b.tip_position).norm(), tol);
  EXPECT_LT(rotation_error(rod.tip_rotation(), b.tip_rotation), kRotationTolerance);
  EXPECT_GT((b.tip_position - a.tip_position).norm(), 5e-3) << "the inputs did move the tip";
  // A wrong input count is refused, naming both counts.
  EXPECT_FALSE(rod.set_inputs(rod::InputVector::Zero(3)));
  EXPECT_NE(rod.last_error().find("3 inputs for 4 actuators"), std::string::npos) << rod.last_error();
}

// Small free vibration of a straight cantilever with a tip mass (no gravity, no damping).
// Estimate: T = 2π sqrt((m_t + 33/140 ρA L) L³/(3EI)) (Rayleigh). Shifts from it:
//  - the tip's rotational inertia adds J_t θ'² ≈ J_t (3/(2L))² to the effective mass
//    (θ = 3δ/(2L) at the tip of a cantilever under a tip force): +0.43 % for the default J_t;
//  - BDF-α's phase error at ω Δt = 0.03 (Δt = 1 ms ≈ T/200): ≈ +0.02 % (measured);
//  - geometric nonlinearity at δ/L ≈ 1 %: O(1e-4); grid error: negligible for the tip-mass mode.
// Tolerances: 0.3 % without J_t, 1 % with the default J_t against the uncorrected estimate.
TEST(DynamicRodVibration, PeriodMatchesCantileverWithTipMass) {
  const double rho_a = 1e-3;  // exercises the 33/140 ρA L term (0.8 % of m_t)
  const double T_est = 2.0 * M_PI * std::sqrt((kTipMass + 33.0 / 140.0 * rho_a * kL) * kL * kL * kL / (3.0 * kEI));
  for (const Vec3& Jt : {Vec3(0, 0, 0), DynamicRodModel().tip_inertia}) {
    DynamicRod rod(straight_undamped(rho_a, Jt));
    rod::TipWrench push;
    push.force = Vec3(2.5e-3, 0.0, 0.0);  // ≈1 mm static tip deflection
    ASSERT_TRUE(rod.reset_to_static(push)) << rod.last_error();
    const double x0 = rod.tip_position().x();
    EXPECT_NEAR(x0, 2.5e-3 * kL * kL * kL / (3.0 * kEI), 2e-6);  // linear beam theory
    const double dt = 1e-3;
    const Oscillation o = free_vibration(&rod, dt, 4.3 * T_est);
    ASSERT_GE(o.up_crossings.size(), 4u);
    ASSERT_GE(o.peaks.size(), 3u);
    const double T = mean_period(o);
    const double T_corr = T_est * std::sqrt(1.0 + Jt.x() * 2.25 / (kL * kL) / (kTipMass + 33.0 / 140.0 * rho_a * kL));
    std::printf(
        "[ period ] J_t = %.0e: T = %.5f s, estimate %.5f s (%+.3f %%), with J_t correction "
        "%.5f s (%+.3f %%)\n",
        Jt.x(), T, T_est, 100.0 * (T / T_est - 1.0), T_corr, 100.0 * (T / T_corr - 1.0));
    EXPECT_NEAR(T / T_est, 1.0, Jt.x() == 0.0 ? 3e-3 : 1e-2);
    EXPECT_NEAR(T / T_corr, 1.0, 3e-3);
    // No growth (BDF-α dissipates only at high frequency): peaks never increase, and little decays.
    // (The higher modes excited by the release ride on the signal at the 1e-5 level.)
    for (size_t i = 1; i < o.peaks.size(); ++i) EXPECT_LE(o.peaks[i], o.peaks[i - 1] * (1.0 + 2e-5));
    EXPECT_LE(o.peaks.back(), o.peaks.front());
    EXPECT_GT(o.peaks.back(), 0.995 * x0);
    EXPECT_LT(o.peaks.front(), x0 * (1.0 + 1e-5));
    std::printf("[ period ] peaks / x0: first %.6f, last %.6f (%zu periods)\n", o.peaks.front() / x0,
                o.peaks.back() / x0, o.peaks.size());
  }
}

// Varying Δt between steps (θ-method steps): still stable, same period within 1 %.
TEST(DynamicRodVibration, VariableTimeStepIsStable) {
  DynamicRod rod(straight_undamped(0.0, Vec3::Zero()));
  rod::TipWrench push;
  push.force = Vec3(2.5e-3, 0.0, 0.0);
  ASSERT_TRUE(rod.reset_to_static(push));
  const double x0 = rod.tip_position().x();
  std::vector<double> up, peaks;
  double x1 = x0, x2 = x0, t1 = 0.0;
  for (int k = 0; rod.time() < 0.9; ++k) {
    const double dt = (k % 3 == 0) ? 1.5e-3 : 1e-3;
    ASSERT_TRUE(rod.step(rod::TipWrench(), dt)) << rod.last_error();
    const double x = rod.tip_position().x();
    if (x1 < 0.0 && x >= 0.0) up.push_back(t1 + dt * (-x1) / (x - x1));
    if (x1 > x2 && x1 >= x) peaks.push_back(x1);  // unequal spacing: raw samples
    x2 = x1, x1 = x, t1 = rod.time();
  }
  const double T_est = 2.0 * M_PI * std::sqrt(kTipMass * kL * kL * kL / (3.0 * kEI));
  ASSERT_GE(up.size(), 3u);
  EXPECT_NEAR((up.back() - up.front()) / (up.size() - 1) / T_est, 1.0, 1e-2);
  // Sampled peaks (jitter ≈ (ωΔt)²/8 ≈ 2e-4): no growth beyond that, and not over-damped.
  for (size_t i = 1; i < peaks.size(); ++i) EXPECT_LE(peaks[i], peaks[i - 1] * (1.0 + 5e-4));
  EXPECT_LE(peaks.back(), x0);
  EXPECT_GT(peaks.back(), 0.5 * x0);
}

// Kelvin–Voigt damping B = τ K gives the tip-mass mode a damping ratio ζ ≈ τ ω / 2, so the peaks
// decay as exp(−ζ ω t): faster with larger τ. Checked against that estimate within 5 % in the
// logarithmic decrement (BDF-α adds ~1e-4 per period; the rod's higher modes shift ω slightly;
// measured agreement ≈ 0.1 %).
TEST(DynamicRodDamping, KelvinVoigtDecayGrowsWithRetardationTime) {
  const double w1 = 2.0 * M_PI / (2.0 * M_PI * std::sqrt(kTipMass * kL * kL * kL / (3.0 * kEI)));
  double previous_decrement = 0.0;
  for (double tau : {0.002, 0.005}) {
    DynamicRodModel p = straight_undamped(0.0, Vec3::Zero());
    p.kelvin_voigt_time = tau;
    DynamicRod rod(p);
    rod::TipWrench push;
    push.force = Vec3(2.5e-3, 0.0, 0.0);
    ASSERT_TRUE(rod.reset_to_static(push));
    const Oscillation o = free_vibration(&rod, 1e-3, 0.85);
    ASSERT_GE(o.peaks.size(), 3u);
    for (size_t i = 1; i < o.peaks.size(); ++i) EXPECT_LT(o.peaks[i], o.peaks[i - 1]);
    const double decrement = std::log(o.peaks.front() / o.peaks.back()) / (o.peaks.size() - 1);
    const double zeta = tau * w1 / 2.0;
    const double expected = 2.0 * M_PI * zeta / std::sqrt(1.0 - zeta * zeta);
    std::printf("[ damping] tau = %.3f s: log decrement %.4f per period, estimate %.4f\n", tau, decrement, expected);
    EXPECT_NEAR(decrement / expected, 1.0, 0.05);
    EXPECT_GT(decrement, previous_decrement);
    previous_decrement = decrement;
  }
}

// A step of the jet force: the HydroJet's tip overshoots, oscillates and settles to the static
// solution (default damping: τ_kv = 0.01 s).
TEST(DynamicRodHydroJet, JetForceStepOvershootsAndSettles) {
  const DynamicRodModel p = hydrojet_parameters();
  DynamicRod rod(p);
  ASSERT_TRUE(rod.reset_to_static(rod::TipWrench())) << rod.last_error();
  const Vec3 p0 = rod.tip_position();
  rod::TipWrench w;
  w.force = jet_force(0.2, 0.05, 0.1);
  DynamicRod target(p);
  ASSERT_TRUE(target.reset_to_static(w));
  const Vec3 pf = target.tip_position();
  const Vec3 e = (pf - p0).normalized();
  const double travel = (pf - p0).norm();
  ASSERT_GT(travel, 0.01);

  double max_progress = 0.0, min_after_peak = 1e9;
  bool peaked = false;
  const double dt = 0.005;
  while (rod.time() < 6.0) {
    ASSERT_TRUE(rod.step(w, dt)) << rod.last_error();
    const double progress = (rod.tip_position() - p0).dot(e) / travel;
    if (progress > max_progress) max_progress = progress;
    if (progress > 1.0) peaked = true;
    if (peaked) min_after_peak = std::min(min_after_peak, progress);
  }
  std::printf("[hydrojet] travel %.4f m, overshoot %.1f %%, undershoot after the peak to %.1f %%\n", travel,
              100.0 * (max_progress - 1.0), 100.0 * min_after_peak);
  EXPECT_GT(max_progress, 1.2);     // overshoot
  EXPECT_LT(min_after_peak, 0.95);  // and swings back: an oscillation
  EXPECT_LT(rod.tip_velocity().norm(), 1e-6);
  EXPECT_LT((rod.tip_position() - pf).norm(), 1e-7);
  const rod::RodSolution ref = kirchhoff(p.rod, w);
  ASSERT_TRUE(ref.converged);
  EXPECT_LT((rod.tip_position() - ref.tip_position).norm(), position_tolerance(p, rod.base_force().norm()));
  EXPECT_LT(rotation_error(rod.tip_rotation(), ref.tip_rotation), kRotationTolerance);
}

// Body mass (ρA > 0, body weight in the statics too) and all drag terms: the step response still
// settles to the static solution, with less overshoot than without drag.
TEST(DynamicRodHydroJet, DragAndBodyMassReduceOvershootAndSettle) {
  rod::TipWrench w;
  w.force = jet_force(0.1, 0.05, 0.0);  // ≈0.09 N: well below the flutter threshold (header)
  double overshoot[2];
  for (int with_drag = 0; with_drag < 2; ++with_drag) {
    DynamicRodModel p = hydrojet_parameters();
    p.rod.segments[0].linear_density = 5e-3;
    p.rotational_inertia_per_length = 1e-8;
    if (with_drag) {
      p.linear_drag = 0.2;
      p.quadratic_drag = 0.5;
      p.tip_drag = 0.02;
      p.tip_quadratic_drag = 0.05;
      p.tip_angular_drag = 1e-5;
    }
    DynamicRod rod(p);
    ASSERT_TRUE(rod.last_error().empty()) << rod.last_error();
    const Vec3 p0 = rod.tip_position();
    DynamicRod target(p);
    ASSERT_TRUE(target.reset_to_static(w));
    const Vec3 pf = target.tip_position();
    const Vec3 e = (pf - p0).normalized();
    double max_progress = 0.0;
    while (rod.time() < 5.0) {
      ASSERT_TRUE(rod.step(w, 0.005)) << rod.last_error();
      max_progress = std::max(max_progress, (rod.tip_position() - p0).dot(e) / (pf - p0).norm());
    }
    overshoot[with_drag] = max_progress - 1.0;
    EXPECT_LT((rod.tip_position() - pf).norm(), 1e-6);
    const rod::RodSolution ref = kirchhoff(p.rod, w);
    ASSERT_TRUE(ref.converged);
    EXPECT_LT((rod.tip_position() - ref.tip_position).norm(), position_tolerance(p, rod.base_force().norm()));
  }
  std::printf("[  drag  ] overshoot without drag %.1f %%, with drag %.1f %%\n", 100 * overshoot[0], 100 * overshoot[1]);
  EXPECT_GT(overshoot[0], 0.1);
  EXPECT_LT(overshoot[1], 0.7 * overshoot[0]);
}

TEST(DynamicRodInput, RejectsNonFiniteWrenchAndBadStep) {
  DynamicRod rod(hydrojet_parameters());
  rod::TipWrench w;
  w.force = jet_force(0.1, 0.1, 0.1);
  for (int k = 0; k < 5; ++k) ASSERT_TRUE(rod.step(w, 0.005));
  const Vec3 p = rod.tip_position();
  const double t = rod.time();

  rod::TipWrench bad = w;
  bad.force.y() = std::nan("");
  EXPECT_FALSE(rod.step(bad, 0.005));
  EXPECT_NE(rod.last_error().find("force"), std::string::npos) << rod.last_error();
  bad = w;
  bad.moment.z() = INFINITY;
  EXPECT_FALSE(rod.step(bad, 0.005));
  EXPECT_NE(rod.last_error().find("moment"), std::string::npos) << rod.last_error();
  EXPECT_FALSE(rod.reset_to_static(bad));
  EXPECT_NE(rod.last_error().find("moment"), std::string::npos) << rod.last_error();
  EXPECT_FALSE(rod.step(w, 0.0));
  EXPECT_NE(rod.last_error().find("dt"), std::string::npos) << rod.last_error();
  EXPECT_FALSE(rod.step(w, std::nan("")));
  rod.set_gravity(Vec3(0, std::nan(""), 9.81));
  EXPECT_NE(rod.last_error().find("gravity"), std::string::npos) << rod.last_error();
  EXPECT_TRUE(rod.gravity().allFinite());
  // The state is unchanged by the rejected calls.
  EXPECT_EQ(rod.time(), t);
  EXPECT_EQ((rod.tip_position() - p).norm(), 0.0);
  EXPECT_TRUE(rod.step(w, 0.005)) << rod.last_error();
  EXPECT_TRUE(rod.last_error().empty());
}

TEST(DynamicRodInput, RejectsInvalidParametersNamingThem) {
  struct Case {
    const char* name;
    void (*edit)(DynamicRodModel*);
  };
  const Case cases[] = {
      {"shear_stiffness", [](DynamicRodModel* p) { p->shear_stiffness = -1.0; }},
      {"axial_stiffness", [](DynamicRodModel* p) { p->axial_stiffness = 0.0; }},
      {"kelvin_voigt_time", [](DynamicRodModel* p) { p->kelvin_voigt_time = std::nan(""); }},
      {"linear_drag", [](DynamicRodModel* p) { p->linear_drag = -0.1; }},
      {"tip_drag", [](DynamicRodModel* p) { p->tip_drag = -1.0; }},
      {"tip_angular_drag", [](DynamicRodModel* p) { p->tip_angular_drag = INFINITY; }},
      {"tip_inertia", [](DynamicRodModel* p) { p->tip_inertia.y() = -1e-8; }},
      {"rotational_inertia_per_length", [](DynamicRodModel* p) { p->rotational_inertia_per_length = -1.0; }},
      {"nodes", [](DynamicRodModel* p) { p->nodes = 1; }},
      {"max_substep_halvings", [](DynamicRodModel* p) { p->max_substep_halvings = -1; }},
      {"tolerance", [](DynamicRodModel* p) { p->tolerance = 0.0; }},
      {"alpha", [](DynamicRodModel* p) { p->alpha = 0.3; }},
      {"rod.segments[0].length", [](DynamicRodModel* p) { p->rod.segments[0].length = 0.0; }},
      {"rod.segments[0].stiffness", [](DynamicRodModel* p) { p->rod.segments[0].stiffness.z() = 0.0; }},
      {"rod.segments[0].linear_density", [](DynamicRodModel* p) { p->rod.segments[0].linear_density = -1e-3; }},
      {"rod.tip_mass", [](DynamicRodModel* p) { p->rod.tip_mass = std::nan(""); }},
      {"rod.gravity", [](DynamicRodModel* p) { p->rod.gravity.x() = std::nan(""); }},
  };
  EXPECT_TRUE(hydrojet_parameters().validate().empty());
  for (const Case& c : cases) {
    DynamicRodModel p = hydrojet_parameters();
    c.edit(&p);
    const std::string err = p.validate();
    EXPECT_EQ(err.rfind(c.name, 0), 0u) << c.name << ": " << err;
    try {
      DynamicRod rod(p);
      ADD_FAILURE() << "constructor accepted an invalid " << c.name;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(c.name), std::string::npos) << e.what();
    }
  }
}

// Not an assertion: prints the cost per time step for the HydroJet under a jet-force step (the
// hardest phase: large, fast motion) at the two time steps of interest.
TEST(DynamicRodPerformance, MicrosecondsPerStep) {
  for (double dt : {0.01, 0.002}) {
    DynamicRod rod(hydrojet_parameters());
    rod::TipWrench w;
    w.force = jet_force(0.2, 0.05, 0.1);
    int steps = 0, iterations = 0, passes = 0;
    const auto t0 = std::chrono::steady_clock::now();
    while (rod.time() < 2.0) {
      ASSERT_TRUE(rod.step(w, dt)) << rod.last_error();
      ++steps;
      iterations += rod.last_iterations();
      passes += rod.last_evaluations();
    }
    const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() / steps;
    std::printf(
        "[  perf  ] dt = %.3f s: %.1f us/step (%.2f Newton iterations, %.2f shooting passes "
        "per step; 600 s of simulation: %.1f s)\n",
        dt, us, double(iterations) / steps, double(passes) / steps, us * 1e-6 * 600.0 / dt);
  }
}
