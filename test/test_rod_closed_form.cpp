// The rod solver against closed-form solutions, the accuracy of its defaults, and its robustness (cold
// starts across the workspace, non-convergence reported).
#include <gtest/gtest.h>

#include <cmath>

#include "hydrojet_control/rod/so3.h"
#include "test_helpers.h"

using namespace hydrojet;
using rod::Mat3;
using rod::Vec3;

namespace {

double rotation_angle_between(const Mat3& A, const Mat3& B) { return so3::log(A.transpose() * B).norm(); }

}  // namespace

// A pure follower moment M about the body x-axis bends the rod into a circular arc of curvature
// κ = M/EI in the base y–z plane: R(L) = Rx(κL), p(L) = (0, (cos κL − 1)/κ, sin κL/κ).
TEST(RodClosedForm, PureTipMomentGivesCircularArc) {
  const double EI = 6.01e-4, L = 0.09;
  for (double bend : {0.3, 1.5, 3.0}) {  // total bend angle κL [rad]
    const double kappa = bend / L, M = kappa * EI;
    rod::RodSolver solver(test::plain_rod(L, EI), test::rk8(32));
    rod::TipWrench w;
    w.moment = Vec3(M, 0, 0);
    const rod::RodSolution sol = solver.solve(w);
    ASSERT_TRUE(sol.converged) << sol.message;
    const Vec3 p_exact(0.0, (std::cos(bend) - 1.0) / kappa, std::sin(bend) / kappa);
    EXPECT_LT((sol.tip_position - p_exact).norm(), 1e-10) << "bend " << bend;
    EXPECT_LT(rotation_angle_between(sol.tip_rotation, so3::exp(Vec3(bend, 0, 0))), 1e-10);
    // Every backbone point lies on the circle of radius 1/κ centred at (0, −1/κ, 0).
    for (const Vec3& p : solver.shape(10)) EXPECT_NEAR((p - Vec3(0, -1.0 / kappa, 0)).norm(), 1.0 / kappa, 1e-10);
  }
}

// With only precurvature the rod takes its unloaded shape: u(s) = ũ, so
// R(L) = exp(Lũ^) and p(L) = [L I + (1 − cos θ)/k² Û + (kL − sin θ)/k³ Û²] e_z with k = |ũ|, θ = kL.
// Solved warm from a heavily loaded state so that Newton has real work to do.
TEST(RodClosedForm, PrecurvatureOnlyGivesUnloadedArc) {
  rod::RodModel m = test::plain_rod();
  m.segments[0].precurvature = Vec3(0.034, 0.88, 0.0) * 10.0;  // a visible bend (0.8 rad)
  rod::RodSolver solver(m, test::rk8(32));
  rod::TipWrench loaded;
  loaded.force = Vec3(0.15, -0.1, 0.0);
  ASSERT_TRUE(solver.solve(loaded).converged);
  const rod::RodSolution sol = solver.solve(rod::TipWrench{});
  ASSERT_TRUE(sol.converged) << sol.message;
  EXPECT_GE(sol.iterations, 2);
  const double L = m.segments[0].length, k = m.segments[0].precurvature.norm(), th = k * L;
  const Mat3 U = so3::hat(m.segments[0].precurvature);
  const Vec3 p_exact =
      (L * Mat3::Identity() + (1 - std::cos(th)) / (k * k) * U + (th - std::sin(th)) / (k * k * k) * U * U) *
      Vec3::UnitZ();
  EXPECT_LT((sol.tip_position - p_exact).norm(), 1e-10);
  EXPECT_LT(rotation_angle_between(sol.tip_rotation, so3::exp(L * m.segments[0].precurvature)), 1e-10);
}

// A small lateral tip force on a straight cantilever: δ = FL³/(3EI), tip slope FL²/(2EI)
// (Euler–Bernoulli). With FL²/EI = 1e-4 the geometric nonlinearity is O(1e-4) relative.
TEST(RodClosedForm, SmallTipForceMatchesLinearBeam) {
  const double EI = 6.01e-4, L = 0.09;
  const double F = 1e-4 * EI / (L * L);
  rod::RodSolver solver(test::plain_rod(L, EI), test::rk8(16, 1e-14));
  for (int axis : {0, 1}) {
    rod::TipWrench w;
    w.force[axis] = F;
    const rod::RodSolution sol = solver.solve(w);
    ASSERT_TRUE(sol.converged) << sol.message;
    const double delta = F * L * L * L / (3 * EI);
    EXPECT_NEAR(sol.tip_position[axis], delta, 1e-3 * delta);
    EXPECT_NEAR(sol.tip_position[1 - axis], 0.0, 1e-12);
    const double slope = F * L * L / (2 * EI);
    EXPECT_NEAR(so3::log(sol.tip_rotation).norm(), slope, 1e-3 * slope);
  }
}

// The defaults (RK8, 4 steps) put the tip within 1e-6 m of the exact solution on both HydroJet
// scenes, across the jet-force range. "Exact" is established by two different methods (RK8 with
// 256 steps and adaptive DOPRI5 at 1e-13) that must agree to 1e-10 m first.
TEST(RodAccuracy, DefaultsWithinOneMicronOnHydroJetScenes) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const config::Scene sc = test::scene(name);
    rod::RodSolver def(test::bare(sc), sc.solver);
    rod::RodSolver ref8(test::bare(sc), test::rk8(256, 1e-13));
    rod::ShootingOptions d5 = test::rk8(1, 1e-13);
    d5.integrator.type = rod::IntegratorType::kDopri5;
    d5.integrator.tolerance = 1e-13;
    rod::RodSolver ref5(test::bare(sc), d5);
    for (double q1 : {0.0, 0.243})
      for (double q2 : {0.0, 0.112, 0.224})
        for (double q3 : {0.0, 0.244}) {
          rod::TipWrench w;
          w.force = test::jet_force(q1, q2, q3);
          const rod::RodSolution a = ref8.solve(w), b = ref5.solve(w), s = def.solve(w);
          ASSERT_TRUE(a.converged && b.converged && s.converged) << name;
          ASSERT_LT((a.tip_position - b.tip_position).norm(), 1e-10) << name;
          EXPECT_LT((s.tip_position - a.tip_position).norm(), 1e-6) << name << " q=" << q1 << "," << q2 << "," << q3;
        }
  }
}

// Cold starts (no warm start) converge across the HydroJet actuation range, and report it honestly.
TEST(RodRobustness, ColdStartsConvergeAcrossWorkspace) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const config::Scene sc = test::scene(name);
    rod::RodSolver solver(test::bare(sc), sc.solver);
    for (double q1 = 0; q1 <= 0.2431; q1 += 0.0810)
      for (double q2 = 0; q2 <= 0.2241; q2 += 0.0747)
        for (double q3 = 0; q3 <= 0.2441; q3 += 0.0813) {
          solver.reset();
          rod::TipWrench w;
          w.force = test::jet_force(q1, q2, q3);
          const rod::RodSolution s = solver.solve(w);
          EXPECT_TRUE(s.converged) << name << " " << s.message;
          EXPECT_LE(s.residual, sc.solver.residual_tolerance);
        }
  }
}

// A solve that cannot converge says so: a NaN wrench, and an iteration budget too small to finish.
TEST(RodRobustness, NonConvergenceIsReported) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  rod::RodSolver solver(test::bare(sc), sc.solver);
  rod::TipWrench bad;
  bad.force = Vec3(std::nan(""), 0, 0);
  const rod::RodSolution s = solver.solve(bad);
  EXPECT_FALSE(s.converged);
  EXPECT_FALSE(s.message.empty());

  rod::ShootingOptions tight = sc.solver;
  tight.max_iterations = 1;
  tight.max_continuation_steps = 0;
  rod::RodSolver limited(test::bare(sc), tight);
  rod::TipWrench big;
  big.force = test::jet_force(0.243, 0.0, 0.0);
  const rod::RodSolution t = limited.solve(big);
  EXPECT_FALSE(t.converged);
  EXPECT_GT(t.residual, tight.residual_tolerance);
  EXPECT_FALSE(limited.has_solution());
}
