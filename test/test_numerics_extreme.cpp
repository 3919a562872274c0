// Stiff and extreme cases (docs/stability.md): every case either meets the reference accuracy or
// returns converged = false with a reason — no silent failures. The reference of each case is two
// different methods at tolerance ≤ 1e-12 that must agree to ≤ 1e-10 m (bench/numerics_cases.h).
// The solvers under test run with their default robustness ladder (Newton → continuation →
// multiple shooting) and the default accuracy check of fixed-step methods.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "../bench/numerics_cases.h"
#include "hydrojet_control/rod/stability.h"
#include "test_helpers.h"

using namespace hydrojet;
using numerics::Case;
using rod::IntegratorType;
using rod::Vec3;

namespace {

const Case& find_case(const std::string& name) {
  static const std::vector<Case> cases = [] {
    std::vector<Case> v = numerics::extreme_cases();
    for (const Case& c : numerics::work_precision_cases()) v.push_back(c);
    return v;
  }();
  for (const Case& c : cases)
    if (c.name == name) return c;
  throw std::runtime_error("no case " + name);
}

struct Config {
  const char* name;
  IntegratorType type;
  int steps;
  double tol;
};

/// The integrators every case is tried with (tolerances at which 1e-6·L is reachable).
const Config kConfigs[] = {
    {"rk8 (4 steps, the default)", IntegratorType::kRk8, 4, 0.0},
    {"rk8 (32 steps)", IntegratorType::kRk8, 32, 0.0},
    {"dopri5 (1e-10)", IntegratorType::kDopri5, 0, 1e-10},
    {"cvode-adams (1e-10)", IntegratorType::kCvodeAdams, 0, 1e-10},
    {"cvode-bdf (1e-10)", IntegratorType::kCvodeBdf, 0, 1e-10},
};

/// Solves the case cold with each configuration: converged within tolerance of the reference, or
/// not converged with a message. Returns how many configurations converged.
int check_case(const std::string& name, bool cvode = true) {
  const Case& c = find_case(name);
  const numerics::Reference ref = numerics::reference(c);
  EXPECT_TRUE(ref.ok) << name << ": " << ref.message;
  if (!ref.ok) return 0;
  EXPECT_LE(ref.agreement, 1e-10 * std::max(1.0, c.model.segments[0].length / 0.09)) << name;
  int converged = 0;
  for (const Config& k : kConfigs) {
    if (!cvode && (k.type == IntegratorType::kCvodeAdams || k.type == IntegratorType::kCvodeBdf)) continue;
    rod::ShootingOptions s;
    s.integrator.type = k.type;
    if (k.steps) s.integrator.steps = k.steps;
    if (k.tol > 0.0) s.integrator.tolerance = k.tol;
    rod::RodSolver solver(c.model, s);
    const rod::RodSolution sol = solver.solve(c.wrench);
    if (!sol.converged) {
      EXPECT_FALSE(sol.message.empty()) << name << " / " << k.name << ": not converged without a reason";
      continue;
    }
    ++converged;
    const double err = (sol.tip_position - ref.position).norm();
    EXPECT_LE(err, c.tolerance) << name << " / " << k.name << ": converged but " << err
                                << " m from the reference (silent failure); segments " << sol.segments;
    EXPECT_TRUE(sol.message.empty());
  }
  return converged;
}

}  // namespace

TEST(Extreme, VerySoftRod) { EXPECT_GE(check_case("very_soft"), 1); }
TEST(Extreme, VeryStiffRod) { EXPECT_EQ(check_case("very_stiff"), 5); }
TEST(Extreme, ShearStiffCosserat) { EXPECT_EQ(check_case("cosserat_shear_stiff"), 5); }
TEST(Extreme, SiliconeCosserat) { EXPECT_GE(check_case("cosserat_silicone"), 4); }
TEST(Extreme, FollowerForce1x) { EXPECT_EQ(check_case("follower_1x"), 5); }
TEST(Extreme, FollowerForce3x) { EXPECT_GE(check_case("follower_3x"), 4); }
TEST(Extreme, FollowerForce10x) { EXPECT_GE(check_case("follower_10x"), 4); }
TEST(Extreme, GravityDominatedTiltedBaseHeavyTip) { EXPECT_EQ(check_case("gravity_dominated"), 5); }
TEST(Extreme, LongRodNeedsMultipleShooting) { EXPECT_GE(check_case("long_rod", false), 2); }
TEST(Extreme, LongRodUnderGravityOnly) { EXPECT_GE(check_case("long_rod_gravity", false), 2); }
TEST(Extreme, SoftLongRod) { EXPECT_GE(check_case("soft_long", false), 2); }

// Long rods converge from cold starts across the actuation space scaled to 10 %: single shooting
// fails on some of these (an ill-conditioned e^{λL} Jacobian), multiple shooting takes over. (At the
// full jet force the 0.9 m rod, FL²/EI ≈ 400, has folds and unstable equilibria along the load
// path: docs/stability.md.)
TEST(Extreme, LongRodColdStartsAcrossWorkspace) {
  rod::RodModel m = numerics::bare(numerics::scene("hydrojet_30deg"));
  m.segments[0].length *= 10.0;
  rod::ShootingOptions s;
  s.integrator.steps = 64;
  rod::RodSolver solver(m, s);
  int multiple = 0;
  for (double q1 : {0.0, 0.012, 0.0243})
    for (double q3 : {0.0, 0.0122, 0.0244}) {
      solver.reset();
      rod::TipWrench w;
      w.force = numerics::jet_force(q1, 0.0112, q3);
      const rod::RodSolution sol = solver.solve(w);
      EXPECT_TRUE(sol.converged) << q1 << " " << q3 << ": " << sol.message;
      multiple += sol.segments > 1;
    }
  RecordProperty("multiple_shooting_solves", multiple);
}

// Near elastic instability: an Euler column loaded towards P_cr. The eigenvalue indicator goes to
// zero (reported, positive below P_cr). Past P_cr of the weaker direction (EIx < EIy, so one
// bending direction buckles first) the straight equilibrium is unstable: the shooting Jacobian has
// changed sign against the unloaded rod (a crossing the solver reports with a warning) and the
// indicator is non-positive. (The solver's cold-start stability check is off here: this is the raw
// straight branch; ColdSolvePastBucklingReachesTheBuckledBranch has it on.)
TEST(Extreme, NearInstabilityIsDetectedAndReported) {
  const double EI = 6.01e-4, L = 0.09, g = 9.81;
  const double Pcr = M_PI * M_PI * EI / (4 * L * L);  // of the weaker direction
  rod::RodModel m = test::plain_rod(L, EI);
  m.segments[0].stiffness.y() = 1.2 * EI;
  m.gravity = Vec3(0, 0, -g);
  rod::ShootingOptions options = test::rk8(16);
  options.cold_stability_check.fill(false);
  rod::RodSolver solver(m, options);
  double last_eig = 1e300;
  for (double ratio : {0.5, 0.8, 0.9, 0.95, 0.99}) {
    m.tip_mass = ratio * Pcr / g;
    solver.set_model(m);
    const rod::RodSolution s = solver.solve(rod::TipWrench{});
    ASSERT_TRUE(s.converged) << ratio;
    EXPECT_EQ(s.fold_crossings, 0) << ratio;
    EXPECT_TRUE(s.warning.empty()) << ratio;
    const rod::StabilityReport st = rod::stability(solver.compliance().body, rod::lateral_force_actuation());
    ASSERT_TRUE(st.ok);
    EXPECT_GT(st.eig_min, 0.0) << ratio;
    EXPECT_LT(st.eig_min, last_eig) << ratio;  // decreasing towards the critical load
    last_eig = st.eig_min;
  }
  // Lateral tip stiffness of the column: k(P) = kP/(tan kL − kL) → 0 as P → P_cr.
  const double k99 = std::sqrt(0.99 * Pcr / EI);
  EXPECT_NEAR(last_eig, k99 * 0.99 * Pcr / (std::tan(k99 * L) - k99 * L), 1e-3 * last_eig);
  for (double ratio : {1.05, 1.15}) {
    m.tip_mass = ratio * Pcr / g;
    solver.set_model(m);
    const rod::RodSolution s = solver.solve(rod::TipWrench{});
    ASSERT_TRUE(s.converged) << ratio;
    const rod::StabilityReport st = rod::stability(solver.compliance().body, rod::lateral_force_actuation());
    EXPECT_LE(st.eig_min, 0.0) << ratio;
    EXPECT_LT(s.jacobian_det, 0.0) << ratio;
    EXPECT_EQ(s.fold_crossings, 1) << ratio;
    EXPECT_NE(s.warning.find("fold or bifurcation"), std::string::npos) << s.warning;
  }
}

/// The tip angle α of the clamped-free elastica under a dead end load P = ratio·P_cr (Euler's
/// buckled branch): P/P_cr = (2 K(k)/π)², k = sin(α/2), K the complete elliptic integral of the
/// first kind (bisection on k).
double elastica_tip_angle(double ratio) {
  double lo = 0.0, hi = 1.0 - 1e-15;
  for (int i = 0; i < 200; ++i) {
    const double k = 0.5 * (lo + hi), r = std::pow(2.0 * std::comp_ellint_1(k) / M_PI, 2);
    (r < ratio ? lo : hi) = k;
  }
  return 2.0 * std::asin(0.5 * (lo + hi));
}

// A cold solve past buckling (tip weight 1.1 and 1.5 P_cr, column upright, EIy = 1.2 EIx) lands by
// Newton on the straight, unstable branch; the solver loads the rod from rest with a push along
// its softest direction instead and returns the buckled branch: stable, no warning, and its tip
// angle is the elastica's. A slightly precurved (imperfect) column ends on the same side as its
// imperfection. (A direct Newton or a load path that crosses the bifurcation along the straight
// branch both end there: the check follows every cold solve.)
TEST(Extreme, ColdSolvePastBucklingReachesTheBuckledBranch) {
  const double EI = 6.01e-4, L = 0.09, g = 9.81;
  const double Pcr = M_PI * M_PI * EI / (4 * L * L);
  for (double ratio : {1.1, 1.5}) {
    for (double imperfection : {0.0, 0.05}) {
      rod::RodModel m = test::plain_rod(L, EI);
      m.segments[0].stiffness.y() = 1.2 * EI;
      m.segments[0].precurvature.x() = imperfection;  // bends about x (the weaker axis): toward −y
      m.gravity = Vec3(0, 0, -g);
      m.tip_mass = ratio * Pcr / g;
      rod::RodSolver solver(m, test::rk8(32));
      const rod::RodSolution s = solver.solve(rod::TipWrench{});
      ASSERT_TRUE(s.converged) << ratio << ": " << s.message;
      EXPECT_TRUE(s.warning.empty()) << s.warning;
      const rod::StabilityReport st = rod::stability(solver.compliance().body, rod::lateral_force_actuation());
      EXPECT_GT(st.eig_min, 0.0) << ratio;
      const double angle = std::acos(std::min(1.0, s.tip_rotation(2, 2)));
      if (imperfection == 0.0) {
        EXPECT_NEAR(angle, elastica_tip_angle(ratio), 1e-6) << ratio;
      } else {
        EXPECT_NEAR(angle, elastica_tip_angle(ratio), 0.1 * elastica_tip_angle(ratio)) << ratio;
        EXPECT_LT(s.tip_position.y(), 0.0) << ratio;  // on the imperfection's side
      }
      EXPECT_LT(std::abs(s.tip_position.x()), 1e-9) << ratio;  // buckled about the weaker axis (x)
    }
  }
}

// Where no stable equilibrium exists (a compressive follower force of 10 P_cr on a straight rod:
// Beck's column has no bent equilibria), the cold solve keeps the straight one and warns.
TEST(Extreme, ColdSolveWithNoStableEquilibriumWarns) {
  const double EI = 6.01e-4, L = 0.09;
  rod::RodModel m = test::plain_rod(L, EI);
  m.segments[0].stiffness.y() = 1.2 * EI;
  rod::RodSolver solver(m, test::rk8(16));
  rod::TipWrench w;
  w.force.z() = -10.0 * M_PI * M_PI * EI / (4 * L * L);
  const rod::RodSolution s = solver.solve(w);
  ASSERT_TRUE(s.converged) << s.message;
  EXPECT_LT((s.tip_position - Vec3(0, 0, L)).norm(), 1e-9);
  EXPECT_NE(s.warning.find("unstable equilibrium"), std::string::npos) << s.warning;
  EXPECT_LE(rod::stability(solver.compliance().body, rod::lateral_force_actuation()).eig_min, 0.0);
}

// Cold starts (no warm start) across the HydroJet workspace converge wherever the reference does.
TEST(Extreme, ColdStartsAcrossHydroJetWorkspace) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const config::Scene sc = numerics::scene(name);
    rod::RodSolver solver(test::bare(sc), sc.solver);
    Case c;
    c.model = test::bare(sc);
    for (double q1 = 0; q1 <= 0.2431; q1 += 0.0486)
      for (double q2 = 0; q2 <= 0.2241; q2 += 0.0448)
        for (double q3 = 0; q3 <= 0.2441; q3 += 0.0488) {
          solver.reset();
          c.wrench.force = numerics::jet_force(q1, q2, q3);
          const rod::RodSolution s = solver.solve(c.wrench);
          if (!s.converged) {
            const numerics::Reference ref = numerics::reference(c);
            EXPECT_FALSE(ref.ok) << name << " q = " << q1 << " " << q2 << " " << q3 << ": " << s.message;
          }
        }
  }
}

// A fixed-step solve that is too coarse for its load says so instead of returning a wrong shape.
TEST(Extreme, UnderResolvedFixedStepSolveIsRefused) {
  const Case& c = find_case("follower_10x");
  rod::ShootingOptions s;  // rk8, 4 steps: ~4e-5 m off at 10× the jet force
  rod::RodSolver solver(c.model, s);
  const rod::RodSolution sol = solver.solve(c.wrench);
  EXPECT_FALSE(sol.converged);
  EXPECT_NE(sol.message.find("estimated tip error"), std::string::npos) << sol.message;
  EXPECT_GT(sol.error_estimate, 1e-5 * c.model.segments[0].length);
  s.integrator.steps = 16;
  rod::RodSolver finer(c.model, s);
  const rod::RodSolution ok = finer.solve(c.wrench);
  ASSERT_TRUE(ok.converged) << ok.message;
  EXPECT_LT(ok.error_estimate, 1e-8);
}
