// C^b from forward-mode sensitivities against central differences of full re-solves, and the
// stability indicators against the Euler column and the HydroJet workspace (paper Figs. 12–13).
#include <gtest/gtest.h>

#include <cmath>

#include "hydrojet_control/rod/so3.h"
#include "hydrojet_control/rod/stability.h"
#include "test_helpers.h"

using namespace hydrojet;
using rod::Mat3;
using rod::Mat6;
using rod::Vec3;

namespace {

// Column i of C^b by central differences: (g⁻¹ ∂g/∂w_i)^∨ with g the tip pose, each side a full
// warm-started BVP solve.
Mat6 finite_difference_compliance(rod::RodSolver& solver, const rod::TipWrench& w) {
  const rod::RodSolution c = solver.solve(w);
  EXPECT_TRUE(c.converged);
  Mat6 C;
  for (int i = 0; i < 6; ++i) {
    const double h = i < 3 ? 1e-5 : 1e-7;  // [N], [N m]
    rod::Vec6 wp = w.stacked(), wm = w.stacked();
    wp[i] += h;
    wm[i] -= h;
    rod::TipWrench a, b;
    a.force = wp.head<3>(), a.moment = wp.tail<3>();
    b.force = wm.head<3>(), b.moment = wm.tail<3>();
    const rod::RodSolution sa = solver.solve(a), sb = solver.solve(b);
    EXPECT_TRUE(sa.converged && sb.converged);
    C.block<3, 1>(0, i) = c.tip_rotation.transpose() * (sa.tip_position - sb.tip_position) / (2 * h);
    C.block<3, 1>(3, i) = (so3::log(c.tip_rotation.transpose() * sa.tip_rotation) -
                           so3::log(c.tip_rotation.transpose() * sb.tip_rotation)) /
                          (2 * h);
  }
  solver.solve(w);
  return C;
}

}  // namespace

TEST(Compliance, MatchesCentralDifferencesOnHydroJet) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    config::Scene sc = test::scene(name);
    sc.solver.residual_tolerance = 1e-14;
    rod::RodSolver solver(test::bare(sc), sc.solver);
    for (const Vec3& f : {Vec3(0, 0, 0), test::jet_force(0.2, 0.05, 0.1), test::jet_force(0.0, 0.22, 0.0)}) {
      rod::TipWrench w;
      w.force = f;
      w.moment = Vec3(1e-4, -2e-4, 5e-5);  // exercise the moment columns away from zero too
      const Mat6 fd = finite_difference_compliance(solver, w);
      ASSERT_TRUE(solver.solve(w).converged);
      const rod::Compliance c = solver.compliance();
      ASSERT_TRUE(c.ok);
      for (int i = 0; i < 6; ++i) {
        const double rel = (c.body.col(i) - fd.col(i)).norm() / fd.col(i).norm();
        EXPECT_LT(rel, 1e-5) << name << " column " << i << "\n" << c.body << "\n\n" << fd;
      }
    }
  }
}

// Under a follower load the compliance is not symmetric (the load is not conservative). The
// force–translation block of a straight, weightless rod, however, is the symmetric beam compliance
// diag(L³/3EI) with coupling L²/2EI to the tip rotation — a closed-form check of the assembly.
TEST(Compliance, StraightRodMatchesBeamTheoryAndFollowerLoadBreaksSymmetry) {
  const double EI = 6.01e-4, GJ = 2.23e-4, L = 0.09;
  rod::RodSolver solver(test::plain_rod(L, EI, GJ), test::rk8(16));
  ASSERT_TRUE(solver.solve(rod::TipWrench{}).converged);
  const Mat6 C = solver.compliance().body;
  EXPECT_NEAR(C(0, 0), L * L * L / (3 * EI), 1e-9);
  EXPECT_NEAR(C(1, 1), L * L * L / (3 * EI), 1e-9);
  EXPECT_NEAR(C(4, 0), L * L / (2 * EI), 1e-9);   // ω_y per f_x
  EXPECT_NEAR(C(3, 1), -L * L / (2 * EI), 1e-9);  // ω_x per f_y
  EXPECT_NEAR(C(5, 5), L / GJ, 1e-9);
  EXPECT_NEAR(C(2, 2), 0.0, 1e-12);  // inextensible

  const config::Scene sc = test::scene("hydrojet_0deg");
  rod::RodSolver hj(test::bare(sc), sc.solver);
  rod::TipWrench w;
  w.force = test::jet_force(0.2, 0.0, 0.1);
  ASSERT_TRUE(hj.solve(w).converged);
  const Mat6 Ch = hj.compliance().body;
  EXPECT_GT((Ch - Ch.transpose()).norm(), 1e-3 * Ch.norm());
}

// Euler column: a straight upright rod (gravity along −z of the base) with a tip weight P. Its
// lateral tip compliance is (tan kL − kL)/(kP), k = √(P/EI); it diverges at P_cr = π²EI/(4L²)
// and turns negative beyond. The eigenvalue indicator must be > 0 below P_cr and ≤ 0 above it.
TEST(Stability, EulerColumnBucklesAtCriticalLoad) {
  const double EI = 6.01e-4, L = 0.09, g = 9.81;
  const double Pcr = M_PI * M_PI * EI / (4 * L * L);
  for (double ratio : {0.3, 0.8, 0.97, 1.03, 1.5}) {
    rod::RodModel m = test::plain_rod(L, EI);
    m.gravity = Vec3(0, 0, -g);
    m.tip_mass = ratio * Pcr / g;
    // The straight branch is the one with the closed form: past P_cr a cold solve would otherwise
    // leave it for the buckled one (Extreme.ColdSolvePastBucklingReachesTheBuckledBranch).
    rod::ShootingOptions options = test::rk8(16);
    options.cold_stability_check.fill(false);
    rod::RodSolver solver(m, options);
    const rod::RodSolution sol = solver.solve(rod::TipWrench{});
    ASSERT_TRUE(sol.converged);
    const rod::Compliance c = solver.compliance();
    ASSERT_TRUE(c.ok);
    const double P = ratio * Pcr, k = std::sqrt(P / EI);
    const double exact = (std::tan(k * L) - k * L) / (k * P);
    EXPECT_NEAR(c.body(0, 0), exact, 1e-7 * std::abs(exact)) << "P/Pcr = " << ratio;
    const rod::StabilityReport st = rod::stability(c.body, rod::lateral_force_actuation());
    ASSERT_TRUE(st.ok);
    if (ratio < 1.0) {
      EXPECT_GT(st.eig_min, 0.0) << "P/Pcr = " << ratio;
    } else {
      EXPECT_LE(st.eig_min, 0.0) << "P/Pcr = " << ratio;
    }
    EXPECT_GT(st.margin, 0.0);
  }
}

// Paper Figs. 12–13: the eigenvalue indicator stays positive over the HydroJet actuation space, at
// both base angles.
TEST(Stability, HydroJetWorkspaceIsStableAtBothBaseAngles) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const config::Scene sc = test::scene(name);
    rod::RodSolver solver(test::bare(sc), sc.solver);
    double lowest = 1e300;
    const double qmax[3] = {0.243, 0.224, 0.244};
    const int n = 7;
    for (int a = 0; a < n; ++a)
      for (int b = 0; b < n; ++b)
        for (int c = 0; c < n; ++c) {
          rod::TipWrench w;
          w.force = test::jet_force(qmax[0] * a / (n - 1), qmax[1] * b / (n - 1), qmax[2] * c / (n - 1));
          ASSERT_TRUE(solver.solve(w).converged);
          const rod::Compliance C = solver.compliance();
          ASSERT_TRUE(C.ok);
          const rod::StabilityReport st = rod::stability(C.body, sc.actuated);
          ASSERT_TRUE(st.ok);
          lowest = std::min(lowest, st.eig_min);
        }
    EXPECT_GT(lowest, 0.0) << name;
  }
}
