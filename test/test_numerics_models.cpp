// The numerics of the rod solver beyond the Kirchhoff/RK8 default: the Cosserat model (closed
// forms, the Kirchhoff limit, its compliance), the scene-specialised right-hand sides against the
// general one, and multiple shooting against single shooting.
#include <gtest/gtest.h>

#include <cmath>

#include "hydrojet_control/rod/so3.h"
#include "hydrojet_control/rod/stability.h"
#include "test_helpers.h"

using namespace hydrojet;
using rod::Mat6;
using rod::Vec3;
using test::angle_between;
using test::force;

namespace {

rod::RodModel cosserat(rod::RodModel m, double GA, double EA) {
  m.kind = rod::RodKind::kCosserat;
  m.segments[0].shear_stiffness = GA;
  m.segments[0].axial_stiffness = EA;
  return m;
}

}  // namespace

// Straight, weightless Cosserat rod. An axial follower force F stretches it by F L / EA; a small
// lateral force deflects it by F L³/(3EI) + F L/GA (Timoshenko cantilever).
TEST(Cosserat, StraightRodMatchesExtensionAndTimoshenko) {
  const double EI = 6.01e-4, L = 0.09, GA = 0.4, EA = 1.3;  // soft-silicone ratios (EA/EI ≈ 2e3 m⁻²)
  rod::RodSolver solver(cosserat(test::plain_rod(L, EI), GA, EA), test::rk8(32));
  const rod::RodSolution ax = solver.solve(force(Vec3(0, 0, 0.13)));
  ASSERT_TRUE(ax.converged) << ax.message;
  EXPECT_NEAR(ax.tip_position.z(), L * (1.0 + 0.13 / EA), 1e-12);
  EXPECT_NEAR(ax.tip_position.head<2>().norm(), 0.0, 1e-12);

  const double F = 1e-5 * EI / (L * L);
  const rod::RodSolution lat = solver.solve(force(Vec3(F, 0, 0)));
  ASSERT_TRUE(lat.converged) << lat.message;
  const double delta = F * L * L * L / (3 * EI) + F * L / GA;
  EXPECT_NEAR(lat.tip_position.x(), delta, 1e-4 * delta);
  // C^b of the straight rod: v_x per f_x = L³/3EI + L/GA, v_z per f_z = L/EA.
  ASSERT_TRUE(solver.solve(rod::TipWrench{}).converged);
  const rod::Compliance C = solver.compliance();
  ASSERT_TRUE(C.ok);
  EXPECT_NEAR(C.body(0, 0), L * L * L / (3 * EI) + L / GA, 1e-9);
  EXPECT_NEAR(C.body(2, 2), L / EA, 1e-9);
}

// As EA, GA → ∞ the Cosserat solution tends to the Kirchhoff one, the gap shrinking like 1/EA.
TEST(Cosserat, ConvergesToKirchhoffAsStiffnessGrows) {
  const config::Scene sc = test::scene("hydrojet_30deg");
  const rod::TipWrench w = force(test::jet_force(0.2, 0.05, 0.1));
  rod::RodSolver kirchhoff(test::bare(sc), test::rk8(32));
  const rod::RodSolution k = kirchhoff.solve(w);
  ASSERT_TRUE(k.converged);
  double last = 1.0;
  for (double EA : {1e1, 1e2, 1e3, 1e4, 1e5, 1e6}) {
    rod::RodSolver c(cosserat(test::bare(sc), EA, EA), test::rk8(32));
    const rod::RodSolution s = c.solve(w);
    ASSERT_TRUE(s.converged) << "EA " << EA << ": " << s.message;
    const double gap = (s.tip_position - k.tip_position).norm();
    EXPECT_LT(gap, sc.rod.segments[0].length * 0.3 / EA) << "EA " << EA;  // ≤ L·max|n| / EA
    if (EA > 1e1) {
      EXPECT_NEAR(last / gap, 10.0, 1.0) << "EA " << EA;  // first order in 1/EA
    }
    last = gap;
  }
  rod::RodSolver stiff(cosserat(test::bare(sc), 1e12, 1e12), test::rk8(32));
  EXPECT_LT((stiff.solve(w).tip_position - k.tip_position).norm(), 1e-12);
}

// C^b of a soft Cosserat rod from sensitivities against central differences of full solves.
TEST(Cosserat, ComplianceMatchesCentralDifferences) {
  config::Scene sc = test::scene("hydrojet_0deg");
  rod::RodSolver solver(cosserat(test::bare(sc), 0.4, 1.3), test::rk8(16, 1e-14));
  rod::TipWrench w = force(test::jet_force(0.1, 0.05, 0.0));
  w.moment = Vec3(1e-4, -2e-4, 5e-5);
  ASSERT_TRUE(solver.solve(w).converged);
  const rod::Compliance C = solver.compliance();
  ASSERT_TRUE(C.ok);
  const rod::RodSolution c = solver.solve(w);
  for (int i = 0; i < 6; ++i) {
    const double h = i < 3 ? 1e-5 : 1e-7;
    rod::TipWrench a = w, b = w;
    (i < 3 ? a.force[i] : a.moment[i - 3]) += h;
    (i < 3 ? b.force[i] : b.moment[i - 3]) -= h;
    const rod::RodSolution sa = solver.solve(a), sb = solver.solve(b);
    ASSERT_TRUE(sa.converged && sb.converged);
    rod::Vec6 col;
    col.head<3>() = c.tip_rotation.transpose() * (sa.tip_position - sb.tip_position) / (2 * h);
    col.tail<3>() = (so3::log(c.tip_rotation.transpose() * sa.tip_rotation) -
                     so3::log(c.tip_rotation.transpose() * sb.tip_rotation)) /
                    (2 * h);
    EXPECT_LT((C.body.col(i) - col).norm(), 1e-5 * col.norm()) << "column " << i;
  }
}

// The right-hand side compiled for the scene's terms gives the same numbers as the general one.
TEST(Specialisation, VariantsMatchTheGeneralRightHandSide) {
  config::Scene hj = test::scene("hydrojet_30deg");
  rod::RodModel weight = test::bare(hj);
  weight.segments[0].linear_density = 0.02;
  weight.segments[0].stiffness.x() *= 1.3;
  rod::RodModel straight = test::plain_rod();
  straight.gravity = Vec3(0, 9.81, 0);
  straight.tip_mass = 0.003;
  struct Case {
    rod::RodModel m;
    const char* variant;
  } cases[] = {{test::bare(hj), "kirchhoff+precurved"},
               {weight, "kirchhoff+weight+precurved"},
               {straight, "kirchhoff"},
               {cosserat(test::bare(hj), 2.0, 5.0), "cosserat+precurved"},
               {cosserat(weight, 2.0, 5.0), "cosserat+weight+precurved"}};
  for (const Case& c : cases) {
    rod::ShootingOptions s = test::rk8(8);
    rod::RodSolver special(c.m, s);
    s.specialise_model = false;
    rod::RodSolver general(c.m, s);
    EXPECT_STREQ(special.variant_name(), c.variant);
    EXPECT_STREQ(general.variant_name(), "general");
    const rod::TipWrench w = force(test::jet_force(0.2, 0.0, 0.1));
    const rod::RodSolution a = special.solve(w), b = general.solve(w);
    ASSERT_TRUE(a.converged && b.converged) << c.variant;
    EXPECT_LT((a.tip_position - b.tip_position).norm(), 1e-13) << c.variant;
    EXPECT_LT((special.compliance().body - general.compliance().body).norm(), 1e-10 * general.compliance().body.norm())
        << c.variant;
  }
}

// Multiple shooting (forced) finds the single-shooting solution, shape and compliance.
TEST(MultipleShooting, AgreesWithSingleShooting) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const config::Scene sc = test::scene(name);
    rod::RodSolver single(test::bare(sc), test::rk8(16, 1e-12));
    rod::ShootingOptions ms = test::rk8(16, 1e-12);
    ms.shooting_segments = 4;
    rod::RodSolver multi(test::bare(sc), ms);
    for (const Vec3& f : {Vec3(0, 0, 0), test::jet_force(0.243, 0.0, 0.1), test::jet_force(0.0, 0.224, 0.0)}) {
      rod::TipWrench w = force(f);
      w.moment = Vec3(2e-4, 0, -1e-4);
      const rod::RodSolution a = single.solve(w), b = multi.solve(w);
      ASSERT_TRUE(a.converged && b.converged) << name << " " << b.message;
      EXPECT_EQ(b.segments, 4);
      EXPECT_LT((a.tip_position - b.tip_position).norm(), 1e-10) << name;
      EXPECT_LT(angle_between(a.tip_rotation, b.tip_rotation), 1e-10) << name;
      EXPECT_NEAR(a.jacobian_det, b.jacobian_det, 1e-6 * std::abs(a.jacobian_det)) << name;
      const Mat6 Ca = single.compliance().body, Cb = multi.compliance().body;
      EXPECT_LT((Ca - Cb).norm(), 1e-8 * Ca.norm()) << name;
      const auto pa = single.shape(8), pb = multi.shape(8);
      ASSERT_EQ(pa.size(), pb.size());
      for (size_t i = 0; i < pa.size(); ++i) EXPECT_LT((pa[i] - pb[i]).norm(), 1e-10);
    }
  }
}
