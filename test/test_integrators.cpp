// The rod solver's integrators (rod/integrators.h): RK4 and RK8 at their convergence orders, and the
// CVODE integrators (both ways of carrying sensitivities, KINSOL as the Newton iteration, copies).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "hydrojet_control/rod/integrators.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "test_helpers.h"

using namespace hydrojet;
using rod::Mat6;
using rod::Vec3;
using test::angle_between;
using test::force;

namespace {

rod::ShootingOptions with(rod::IntegratorType type, double tol, int steps = 4) {
  rod::ShootingOptions s;
  s.integrator.type = type;
  s.integrator.tolerance = tol;
  s.integrator.steps = steps;
  s.residual_tolerance = 1e-12;
  return s;
}

// Tip position error against a reference solved with RK8 at 256 steps (error ~1e-16).
double tip_error(rod::IntegratorType type, int steps, const rod::RodModel& m, const rod::TipWrench& w,
                 const Vec3& ref) {
  rod::ShootingOptions s = test::rk8(steps, 1e-13);
  s.integrator.type = type;
  rod::RodSolver solver(m, s);
  const rod::RodSolution sol = solver.solve(w);
  EXPECT_TRUE(sol.converged) << sol.message;
  return (sol.tip_position - ref).norm();
}

}  // namespace

// Halving the step divides the global error by 2^p: ~16 for RK4, ~256 for the 8th-order method.
TEST(RodConvergenceOrder, Rk4AndRk8OnHydroJet) {
  const rod::RodModel m = test::bare(test::scene("hydrojet_30deg"));
  rod::TipWrench w;
  w.force = test::jet_force(0.2, 0.05, 0.1);
  rod::RodSolver ref(m, test::rk8(256, 1e-14));
  const rod::RodSolution r = ref.solve(w);
  ASSERT_TRUE(r.converged);
  ASSERT_GT(r.tip_position.head<2>().norm(), 0.02);  // a large deflection, not a near-linear case

  const double e8 = tip_error(rod::IntegratorType::kRk4, 8, m, w, r.tip_position);
  const double e16 = tip_error(rod::IntegratorType::kRk4, 16, m, w, r.tip_position);
  const double e32 = tip_error(rod::IntegratorType::kRk4, 32, m, w, r.tip_position);
  EXPECT_NEAR(e16 / e32, 16.0, 3.0) << e8 << " " << e16 << " " << e32;
  EXPECT_NEAR(e8 / e16, 16.0, 4.0);

  const double f2 = tip_error(rod::IntegratorType::kRk8, 2, m, w, r.tip_position);
  const double f4 = tip_error(rod::IntegratorType::kRk8, 4, m, w, r.tip_position);
  const double f8 = tip_error(rod::IntegratorType::kRk8, 8, m, w, r.tip_position);
  EXPECT_GT(f4 / f8, 256.0 / 2.0) << f2 << " " << f4 << " " << f8;
  EXPECT_LT(f4 / f8, 256.0 * 2.0);
}

// CVODE Adams and BDF (sensitivities in the state, or through CVODES) agree with the RK8 reference
// on the HydroJet, for the solve and for C^b; KINSOL as the Newton iteration finds the same root.
TEST(Cvode, AdamsAndBdfMatchTheReference) {
  const config::Scene sc = test::scene("hydrojet_30deg");
  const rod::TipWrench w = force(test::jet_force(0.2, 0.05, 0.1));
  rod::RodSolver ref(test::bare(sc), test::rk8(128, 1e-13));
  const rod::RodSolution r = ref.solve(w);
  ASSERT_TRUE(r.converged);
  const Mat6 Cref = ref.compliance().body;
  for (rod::IntegratorType t : {rod::IntegratorType::kCvodeAdams, rod::IntegratorType::kCvodeBdf}) {
    for (bool cvodes : {false, true}) {
      rod::ShootingOptions s = with(t, 1e-10);
      s.integrator.cvodes_sensitivities = cvodes;
      rod::RodSolver solver(test::bare(sc), s);
      const std::string what = std::string(rod::integrator_name(t)) + (cvodes ? " (CVODES sensitivities)" : "");
      const rod::RodSolution a = solver.solve(w);
      ASSERT_TRUE(a.converged) << what << ": " << a.message;
      EXPECT_LT((a.tip_position - r.tip_position).norm(), 1e-7) << what;
      EXPECT_LT(angle_between(a.tip_rotation, r.tip_rotation), 1e-6) << what;
      const rod::Compliance C = solver.compliance();
      ASSERT_TRUE(C.ok) << what;
      EXPECT_LT((C.body - Cref).norm(), 1e-5 * Cref.norm()) << what;
      // warm solves along a short path keep converging (CVODE memory reused)
      for (int k = 1; k <= 5; ++k)
        EXPECT_TRUE(solver.solve(force(test::jet_force(0.2 - 0.02 * k, 0.05, 0.1))).converged);
    }
  }
  rod::ShootingOptions k = sc.solver;
  k.newton = rod::NewtonBackend::kKinsol;
  k.residual_tolerance = 1e-12;
  rod::RodSolver kin(test::bare(sc), k);
  rod::ShootingOptions e = sc.solver;
  e.residual_tolerance = 1e-12;
  rod::RodSolver eig(test::bare(sc), e);
  const rod::RodSolution a = kin.solve(w), b = eig.solve(w);
  ASSERT_TRUE(a.converged) << a.message;
  ASSERT_TRUE(b.converged);
  EXPECT_LT((a.tip_position - b.tip_position).norm(), 1e-11);
}

// A copied solver is independent (its CVODE memory is its own) and gives the same answers.
TEST(Cvode, CopiedSolverIsIndependent) {
  const config::Scene sc = test::scene("hydrojet_0deg");
  rod::RodSolver a(test::bare(sc), with(rod::IntegratorType::kCvodeBdf, 1e-9));
  const rod::TipWrench w = force(test::jet_force(0.1, 0.1, 0.0));
  ASSERT_TRUE(a.solve(w).converged);
  rod::RodSolver b = a;
  const rod::RodSolution sa = a.solve(w), sb = b.solve(w);
  ASSERT_TRUE(sa.converged && sb.converged);
  EXPECT_LT((sa.tip_position - sb.tip_position).norm(), 1e-14);
}
