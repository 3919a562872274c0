// rod::RodSolver (rod/rod_solver.h) on general robots: segments, point loads and actuators along the body,
// checked against closed forms of beam theory, against the one-piece solve where both apply (a uniform rod
// with its actuation at the tip), and C^b / J_q against central differences of full solves; its error
// messages, the shipped second robot, stability, and multiple shooting.
#include <gtest/gtest.h>

#include <cmath>

#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"
#include "test_helpers.h"

using namespace hydrojet;
using rod::Mat3;
using rod::Vec3;
using rod::Vec6;

namespace {

rod::RodSegment segment(double length, double EI, double GJ, const Vec3& precurvature = Vec3::Zero(),
                        double density = 0.0) {
  rod::RodSegment s;
  s.length = length;
  s.stiffness = Vec3(EI, EI, GJ);
  s.precurvature = precurvature;
  s.linear_density = density;
  return s;
}

rod::Actuator actuator(double at, const Vec3& direction, const Vec3& position = Vec3::Zero()) {
  rod::Actuator a;
  a.at = at;
  a.direction = direction.normalized();
  a.position = position;
  a.max_force = 1.0;
  return a;
}

rod::InputVector inputs(std::initializer_list<double> q) {
  rod::InputVector v(static_cast<int>(q.size()));
  int i = 0;
  for (double x : q) v[i++] = x;
  return v;
}

/// The tip body twist (v, ω) that takes pose a to pose b, to first order: v = R_aᵀ(p_b − p_a),
/// ω = log(R_aᵀ R_b) (the convention of C^b and J_q).
Vec6 twist(const rod::RodSolution& a, const rod::RodSolution& b) {
  Vec6 t;
  t << a.tip_rotation.transpose() * (b.tip_position - a.tip_position),
      so3::log(a.tip_rotation.transpose() * b.tip_rotation);
  return t;
}

/// ∫₀ˡ exp(s û) e_z ds = l·J_l(l u) e_z, J_l the left Jacobian of SO(3): a constant-curvature arc.
Vec3 arc_chord(const Vec3& u, double l) {
  const Vec3 phi = l * u;
  const double th = phi.norm();
  const Mat3 P = so3::hat(phi);
  Mat3 J = Mat3::Identity();
  if (th > 1e-8) J += (1.0 - std::cos(th)) / (th * th) * P + (th - std::sin(th)) / (th * th * th) * P * P;
  return l * J * Vec3::UnitZ();
}

/// A scene-like model with every kind of station: two segments (the distal precurved, with weight),
/// a follower and a dead point load, a point mass, actuators at the tip and mid-body with moment arms.
rod::RodModel busy_model(rod::RodKind kind) {
  rod::RodModel m;
  m.kind = kind;
  m.segments = {segment(0.05, 1.5e-3, 5.6e-4, Vec3(0.0, 0.0, 0.0), 0.02),
                segment(0.04, 4.0e-4, 1.5e-4, Vec3(0.3, 2.0, 0.0), 0.015)};
  if (kind == rod::RodKind::kCosserat)
    for (auto& s : m.segments) {
      s.shear_stiffness = 40.0;
      s.axial_stiffness = 120.0;
    }
  m.tip_mass = 0.003;
  m.gravity = Vec3(0.0, 3.0, 9.3);
  rod::PointLoad follower;
  follower.at = 0.03;
  follower.force = Vec3(0.01, -0.02, 0.005);
  follower.moment = Vec3(0.0, 0.0, 4e-4);
  rod::PointLoad dead;
  dead.at = 0.05;
  dead.mass = 0.001;
  dead.force = Vec3(0.0, 0.015, 0.0);
  dead.moment = Vec3(2e-4, 0.0, 0.0);
  dead.frame = rod::LoadFrame::kBase;
  m.loads = {follower, dead};
  m.actuators = {actuator(0.09, Vec3(1, 0, 0)), actuator(0.09, Vec3(0, -1, 0), Vec3(0.004, 0, 0)),
                 actuator(0.05, Vec3(1, 0, 0), Vec3(0, 0.005, 0)), actuator(0.07, Vec3(0, 1, 0.2))};
  return m;
}

}  // namespace

// Cantilever, force P at a along body x: δ_tip = P a²(3L − a)/(6EI), tip slope P a²/(2EI). The
// linearisation about the straight rod is exactly Euler–Bernoulli, so J_q at q = 0 matches to the
// integration error; a small full solve matches to O((PL²/EI)²).
TEST(RodSolverClosedForm, CantileverWithAForceAtA) {
  const double L = 0.09, EI = 6.01e-4, GJ = 2.23e-4;
  for (double a : {0.02, 0.045, 0.07, 0.09}) {
    rod::RodModel m;
    m.segments = {segment(L, EI, GJ)};
    m.actuators = {actuator(a, Vec3::UnitX())};
    rod::RodSolver solver(m, test::rk8(8));
    ASSERT_TRUE(solver.solve(inputs({0.0})).converged);
    const rod::Compliance c = solver.compliance();
    ASSERT_TRUE(c.ok);
    const double d = a * a * (3 * L - a) / (6 * EI), slope = a * a / (2 * EI);
    EXPECT_NEAR(c.actuation(0, 0), d, 1e-9 * d) << "a = " << a;
    EXPECT_NEAR(c.actuation(4, 0), slope, 1e-9 * slope) << "a = " << a;
    EXPECT_NEAR(c.actuation.col(0).norm(), std::hypot(d, slope), 1e-9 * d);
    const double P = 1e-3;
    const rod::RodSolution s = solver.solve(inputs({P}));
    ASSERT_TRUE(s.converged) << s.message;
    EXPECT_NEAR(s.tip_position.x(), P * d, 1e-3 * P * d) << "a = " << a;
  }
}

// Two segments (EI₁ on [0, a], EI₂ on [a, L]) under a tip force: δ = P[(L³ − b³)/(3EI₁) + b³/(3EI₂)],
// b = L − a (∫ M(s)(L − s)/EI(s) ds with M = P(L − s)).
TEST(RodSolverClosedForm, TwoSegmentCantileverComposite) {
  const double a = 0.05, b = 0.04, L = a + b, EI1 = 1.5e-3, EI2 = 4.0e-4;
  rod::RodModel m;
  m.segments = {segment(a, EI1, 5.6e-4), segment(b, EI2, 1.5e-4)};
  rod::RodSolver solver(m, test::rk8(8));
  ASSERT_TRUE(solver.solve(rod::InputVector(0)).converged);
  const rod::Compliance c = solver.compliance();
  ASSERT_TRUE(c.ok);
  const double d = (L * L * L - b * b * b) / (3 * EI1) + b * b * b / (3 * EI2);
  const double slope = (L * L - b * b) / (2 * EI1) + b * b / (2 * EI2);
  EXPECT_NEAR(c.body(0, 0), d, 1e-9 * d);
  EXPECT_NEAR(c.body(1, 1), d, 1e-9 * d);
  EXPECT_NEAR(c.body(4, 0), slope, 1e-9 * slope);
  // Torsion: L/GJ in series.
  EXPECT_NEAR(c.body(5, 5), a / 5.6e-4 + b / 1.5e-4, 1e-9 * (a / 5.6e-4 + b / 1.5e-4));
}

// Precurved unloaded segments are piecewise arcs: tip frame Π exp(l_k ũ_k), tip position the chain of
// the arcs' chords, and the shape passes through each segment's end.
TEST(RodSolverClosedForm, PrecurvedSegmentsArePiecewiseArcs) {
  rod::RodModel m;
  m.segments = {segment(0.03, 1e-3, 4e-4, Vec3(0.0, 4.0, 0.0)), segment(0.025, 5e-4, 2e-4, Vec3(-6.0, 0.0, 3.0)),
                segment(0.035, 8e-4, 3e-4, Vec3(2.0, 5.0, -1.0))};
  rod::RodSolver solver(m, test::rk8(12));
  const rod::RodSolution s = solver.solve(rod::InputVector(0));
  ASSERT_TRUE(s.converged) << s.message;
  Mat3 R = Mat3::Identity();
  Vec3 p = Vec3::Zero();
  std::vector<Vec3> ends{p};
  for (const auto& g : m.segments) {
    p += R * arc_chord(g.precurvature, g.length);
    R = R * so3::exp(g.length * g.precurvature);
    ends.push_back(p);
  }
  EXPECT_LT((s.tip_position - p).norm(), 1e-10);
  EXPECT_LT(so3::log(s.tip_rotation.transpose() * R).norm(), 1e-10);
  // Shape at the segment ends (0, 0.03, 0.055, 0.09 m are points of a 90-point shape at 1 mm).
  const std::vector<Vec3> shape = solver.shape(90);
  ASSERT_EQ(shape.size(), 91u);
  EXPECT_LT((shape[0] - ends[0]).norm(), 1e-12);
  EXPECT_LT((shape[30] - ends[1]).norm(), 1e-10);
  EXPECT_LT((shape[55] - ends[2]).norm(), 1e-10);
  EXPECT_LT((shape[90] - ends[3]).norm(), 1e-10);
  Mat3 Rs;
  Vec3 ps;
  ASSERT_TRUE(solver.frame_at(0.055, &Rs, &ps));
  EXPECT_LT((ps - ends[2]).norm(), 1e-10);
}

// Two identical segments are one rod; actuators at the tip are the tip follower wrench B q: the cut rod
// (two pieces, a station between them) gives the one-piece solution, C^b, and J_q = C^b B. Kirchhoff
// and Cosserat, with weight and precurvature.
TEST(RodSolverEquivalence, IdenticalSegmentsAndTipActuatorsAreTheUniformRod) {
  for (rod::RodKind kind : {rod::RodKind::kKirchhoff, rod::RodKind::kCosserat}) {
    rod::RodModel u;
    u.segments.resize(1);
    u.segments[0].length = 0.09;
    u.segments[0].stiffness = Vec3(6.01e-4, 7.2e-4, 2.23e-4);
    u.segments[0].precurvature = Vec3(0.034, 0.88, 0.1);
    u.segments[0].linear_density = 0.03;
    u.kind = kind;
    u.segments[0].shear_stiffness = 40.0;
    u.segments[0].axial_stiffness = 150.0;
    u.tip_mass = 0.00258;
    u.gravity = Vec3(0.0, 4.9, 8.5);
    rod::RodModel g = u;
    rod::RodSegment half = g.segments[0];
    half.length = 0.045;
    g.segments = {half, half};
    g.actuators = {actuator(0.09, Vec3(1, 0, 0)), actuator(0.09, Vec3(-0.5, 0.8, 0.1), Vec3(0, 0, 0.003)),
                   actuator(0.09, Vec3(0, -1, 0), Vec3(0.004, 0, 0))};
    const rod::InputVector q = inputs({0.12, 0.05, 0.09});
    Eigen::Matrix<double, 6, 3> B;
    for (int j = 0; j < 3; ++j) B.col(j) = g.actuators[j].unit_wrench();
    const Vec6 w = B * q;
    rod::RodSolver ref(u, test::rk8(8));
    rod::TipWrench tw;
    tw.force = w.head<3>();
    tw.moment = w.tail<3>();
    const rod::RodSolution a = ref.solve(tw);
    rod::RodSolver gen(g, test::rk8(8));
    const rod::RodSolution b = gen.solve(q);
    ASSERT_TRUE(a.converged && b.converged) << a.message << " / " << b.message;
    EXPECT_LT((a.tip_position - b.tip_position).norm(), 1e-11);
    EXPECT_LT(so3::log(a.tip_rotation.transpose() * b.tip_rotation).norm(), 1e-10);
    const rod::Compliance ca = ref.compliance();
    const rod::Compliance cb = gen.compliance();
    ASSERT_TRUE(ca.ok && cb.ok);
    EXPECT_LT((ca.body - cb.body).norm(), 1e-8 * ca.body.norm());
    EXPECT_LT((cb.actuation - ca.body * B).norm(), 1e-8 * (ca.body * B).norm());
  }
}

// The jets scene: its three actuators (built from the `jets` section) give the solution of the jet
// map's tip force (eq. 24) on the uniform solver.
TEST(RodSolverEquivalence, JetsSceneIsItsThreeActuators) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const config::Scene sc = test::scene(name);
    ASSERT_EQ(sc.rod.actuators.size(), 3u);
    rod::RodSolver ref(test::bare(sc), sc.solver);
    rod::RodSolver gen(sc.rod, sc.solver);
    for (const Vec3& jets : {Vec3(0.2, 0.05, 0.0), Vec3(0.0, 0.15, 0.21), Vec3(0.1, 0.1, 0.1)}) {
      rod::TipWrench w;
      w.force = test::jet_force(jets[0], jets[1], jets[2]);
      const rod::RodSolution a = ref.solve(w);
      const rod::RodSolution b = gen.solve(inputs({jets[0], jets[1], jets[2]}));
      ASSERT_TRUE(a.converged && b.converged) << name;
      EXPECT_LT((a.tip_position - b.tip_position).norm(), 1e-11) << name;
      EXPECT_LT(so3::log(a.tip_rotation.transpose() * b.tip_rotation).norm(), 1e-10) << name;
    }
  }
}

// C^b and J_q from the sensitivities against central differences of full solves, on a model with
// every kind of station (follower and dead loads, point mass, segment change, actuators with moment
// arms mid-body and at the tip), Kirchhoff and Cosserat.
TEST(RodSolverSensitivities, ComplianceAndActuationJacobianMatchCentralDifferences) {
  for (rod::RodKind kind : {rod::RodKind::kKirchhoff, rod::RodKind::kCosserat}) {
    const rod::RodModel m = busy_model(kind);
    rod::ShootingOptions opt = test::rk8(16, 1e-13);
    rod::RodSolver solver(m, opt);
    const rod::InputVector q = inputs({0.06, 0.03, 0.05, 0.04});
    const rod::RodSolution s0 = solver.solve(q);
    ASSERT_TRUE(s0.converged) << s0.message;
    const rod::Compliance c = solver.compliance();
    ASSERT_TRUE(c.ok);
    const double h = 1e-5;
    rod::RodSolver probe(m, opt);
    for (int j = 0; j < 4; ++j) {
      rod::InputVector qp = q, qm = q;
      qp[j] += h;
      qm[j] -= h;
      probe.solve(q);
      const rod::RodSolution sp = probe.solve(qp);
      probe.solve(q);
      const rod::RodSolution sm = probe.solve(qm);
      ASSERT_TRUE(sp.converged && sm.converged);
      const Vec6 fd = (twist(s0, sp) - twist(s0, sm)) / (2 * h);
      EXPECT_LT((fd - c.actuation.col(j)).norm(), 1e-5 * c.actuation.col(j).norm()) << "actuator " << j;
    }
    for (int i = 0; i < 6; ++i) {
      rod::TipWrench wp, wm;
      const double hi = i < 3 ? h : h * 0.01;
      (i < 3 ? wp.force : wp.moment)[i % 3] = hi;
      (i < 3 ? wm.force : wm.moment)[i % 3] = -hi;
      probe.solve(q);
      const rod::RodSolution sp = probe.solve(q, wp);
      probe.solve(q);
      const rod::RodSolution sm = probe.solve(q, wm);
      ASSERT_TRUE(sp.converged && sm.converged);
      const Vec6 fd = (twist(s0, sp) - twist(s0, sm)) / (2 * hi);
      EXPECT_LT((fd - c.body.col(i)).norm(), 1e-5 * c.body.col(i).norm()) << "wrench component " << i;
    }
  }
}

// A dead moment M at a on a straight rod bends only [0, a] (m(s) = M there, 0 beyond): tip slope
// M a/EI, tip deflection M a(2L − a)/(2EI) (small M: linear).
TEST(RodSolverClosedForm, PointMomentAtABendsOnlyTheProximalPart) {
  const double L = 0.09, EI = 6.01e-4, a = 0.04, M = 1e-6;
  rod::RodModel m;
  m.segments = {segment(L, EI, 2.23e-4)};
  rod::PointLoad l;
  l.at = a;
  l.moment = Vec3(0.0, M, 0.0);
  l.frame = rod::LoadFrame::kBase;
  m.loads = {l};
  rod::RodSolver solver(m, test::rk8(8));
  const rod::RodSolution s = solver.solve(rod::InputVector(0));
  ASSERT_TRUE(s.converged) << s.message;
  const double slope = M * a / EI, d = M * a * (2 * L - a) / (2 * EI);
  EXPECT_NEAR(so3::log(s.tip_rotation).y(), slope, 1e-6 * slope);
  EXPECT_NEAR(s.tip_position.x(), d, 1e-5 * d);
}

TEST(RodSolverErrors, BadModelsAndInputsAreNamed) {
  rod::RodModel m;
  m.segments = {segment(0.09, 6e-4, 2e-4)};
  m.actuators = {actuator(0.09, Vec3::UnitX())};
  rod::RodModel bad = m;
  bad.segments[0].length = -1.0;
  try {
    rod::RodSolver s(bad, test::rk8(4));
    FAIL() << "a negative length must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("segments[0].length"), std::string::npos) << e.what();
  }
  bad = m;
  bad.actuators[0].at = 0.2;
  EXPECT_NE(bad.validate().find("actuators[0].at"), std::string::npos);
  bad = m;
  bad.actuators[0].direction = Vec3(1.0, 0.1, 0.0);
  EXPECT_NE(bad.validate().find("actuators[0].direction"), std::string::npos);
  rod::RodSolver solver(m, test::rk8(4));
  const rod::RodSolution wrong = solver.solve(inputs({0.1, 0.2}));
  EXPECT_FALSE(wrong.converged);
  EXPECT_NE(wrong.message.find("expected 1 actuator input"), std::string::npos) << wrong.message;
  const rod::RodSolution nan = solver.solve(inputs({std::nan("")}));
  EXPECT_FALSE(nan.converged);
  EXPECT_NE(nan.message.find("non-finite"), std::string::npos);
  EXPECT_FALSE(solver.compliance().ok);  // nothing converged yet
}

// The shipped second robot solves at its full inputs, cold and warm, within the accuracy contract
// (1e-6 m against a 64-step reference).
TEST(RodSolverScenes, TwoSegmentThrustersSolvesWithinTheAccuracyContract) {
  const config::Scene sc = test::scene("two_segment_thrusters");
  rod::RodSolver solver(sc.rod, sc.solver);
  rod::ShootingOptions fine = sc.solver;
  fine.integrator.steps = 64;
  rod::RodSolver ref(sc.rod, fine);
  const int N = static_cast<int>(sc.rod.actuators.size());
  for (int k = 0; k < 6; ++k) {
    rod::InputVector q(N);
    for (int j = 0; j < N; ++j) q[j] = sc.rod.actuators[j].max_force * (0.5 + 0.5 * std::sin(1.3 * k + 2.1 * j));
    const rod::RodSolution s = solver.solve(q), r = ref.solve(q);
    ASSERT_TRUE(s.converged && r.converged) << s.message << " / " << r.message;
    EXPECT_LT((s.tip_position - r.tip_position).norm(), 1e-6) << k;
  }
}

// Stability for a general actuator set (the block of C^b on the span of the actuators' equivalent tip
// wrenches) reduces to today's {f_x, f_y} block on the HydroJet: its jets span exactly that plane.
// For actuators along the body the equivalent tip wrenches (C^b)^† J_q move the tip as they do.
TEST(RodSolverStability, ReducesToTheLateralForceBlockOnTheHydroJet) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    const config::Scene sc = test::scene(name);
    rod::RodSolver gen(sc.rod, sc.solver);
    for (const Vec3& jets : {Vec3(0.2, 0.05, 0.0), Vec3(0.0, 0.15, 0.21), Vec3(0.02, 0.01, 0.03)}) {
      ASSERT_TRUE(gen.solve(inputs({jets[0], jets[1], jets[2]})).converged);
      const rod::Compliance c = gen.compliance();
      ASSERT_TRUE(c.ok);
      const rod::StabilityReport today = rod::stability(c.body, rod::lateral_force_actuation());
      const rod::StabilityReport general = rod::stability(c.body, rod::equivalent_tip_wrenches(c.body, c.actuation));
      ASSERT_TRUE(today.ok && general.ok);
      EXPECT_NEAR(general.margin, today.margin, 1e-9 * today.margin) << name;
      EXPECT_NEAR(general.eig_min, today.eig_min, 1e-9 * std::abs(today.eig_min)) << name;
    }
  }
  const config::Scene sc = test::scene("two_segment_thrusters");
  rod::RodSolver gen(sc.rod, sc.solver);
  ASSERT_TRUE(gen.solve(rod::InputVector::Constant(6, 0.03)).converged);
  const rod::Compliance c = gen.compliance();
  ASSERT_TRUE(c.ok);
  const Eigen::Matrix<double, 6, Eigen::Dynamic> W = rod::equivalent_tip_wrenches(c.body, c.actuation);
  EXPECT_LT((c.body * W - c.actuation).norm(), 1e-6 * c.actuation.norm());
  const rod::StabilityReport st = rod::stability(c.body, W);
  ASSERT_TRUE(st.ok);
  EXPECT_GT(st.eig_min, 0.0);  // a moderate load on a cantilever: stable
}

// A column past buckling (tip weight 1.1 P_cr, upright, EIy = 1.2 EIx) cut into two identical
// segments: a cold solve leaves the straight, unstable branch (which it reaches with the check off)
// for the buckled one, as RodSolver does on the same rod: the same deflection about the weaker
// axis, stable.
TEST(RodSolverStability, ColdSolvePastBucklingReachesTheBuckledBranchAsTheUniformRod) {
  const double EI = 6.01e-4, L = 0.09, g = 9.81;
  const double Pcr = M_PI * M_PI * EI / (4 * L * L);
  rod::RodModel u = test::plain_rod(L, EI);
  u.segments[0].stiffness.y() = 1.2 * EI;
  u.gravity = Vec3(0, 0, -g);
  u.tip_mass = 1.1 * Pcr / g;
  rod::RodModel m = u;
  rod::RodSegment half = m.segments[0];
  half.length = L / 2;
  m.segments = {half, half};
  const rod::ShootingOptions opt = test::rk8(16);
  rod::RodSolver uniform(u, opt);
  rod::RodSolver general(m, opt);
  const rod::RodSolution a = uniform.solve(rod::TipWrench());
  const rod::RodSolution b = general.solve(rod::InputVector(0));
  ASSERT_TRUE(a.converged && b.converged) << a.message << " / " << b.message;
  EXPECT_TRUE(b.warning.find("unstable") == std::string::npos) << b.warning;
  EXPECT_GT(std::abs(b.tip_position.y()), 0.01);  // buckled, about the weaker (x) axis
  EXPECT_LT(std::abs(b.tip_position.x()), 1e-9);
  EXPECT_NEAR(std::abs(b.tip_position.y()), std::abs(a.tip_position.y()), 1e-9);
  EXPECT_NEAR(b.tip_position.z(), a.tip_position.z(), 1e-9);
  const rod::Compliance c = general.compliance();
  ASSERT_TRUE(c.ok);
  EXPECT_GT(rod::stability(c.body, rod::lateral_force_actuation()).eig_min, 0.0);
  // With the check off the cold solve stays on the straight branch, which is unstable.
  rod::ShootingOptions off = opt;
  off.cold_stability_check.fill(false);
  rod::RodSolver straight(m, off);
  const rod::RodSolution s = straight.solve(rod::InputVector(0));
  ASSERT_TRUE(s.converged);
  EXPECT_LT(std::hypot(s.tip_position.x(), s.tip_position.y()), 1e-9);
  EXPECT_LE(rod::stability(straight.compliance().body, rod::lateral_force_actuation()).eig_min, 0.0);
}

// Multiple shooting (beyond single shooting's reach, λL > 12): a long soft rod as two identical
// segments under a large tip follower force from actuators is the uniform rod under that force (nodes
// and a station that do not coincide against nodes alone). Then forced multiple shooting on the busy
// model equals
// single shooting there, and a load with mid-body actuators at λL ≈ 20 converges with 8 and 16
// segments to the same equilibrium.
TEST(RodSolverMultipleShooting, BeyondSingleShootingAsTheUniformRodsMultipleShooting) {
  rod::RodModel u;
  u.segments.resize(1);
  u.segments[0].length = 0.3;
  u.segments[0].stiffness = Vec3(2e-4, 2.4e-4, 1.5e-4);
  u.segments[0].precurvature = Vec3(0.2, 1.0, 0.0);
  u.gravity = Vec3(0.0, 2.0, 9.6);
  u.tip_mass = 0.002;
  rod::RodModel g = u;
  rod::RodSegment half = g.segments[0];
  half.length = 0.15;
  g.segments = {half, half};
  g.actuators = {actuator(0.3, Vec3(1, 0, 0)), actuator(0.3, Vec3(0, 1, 0), Vec3(0.003, 0, 0))};
  const rod::InputVector q = inputs({0.4, 0.25});
  rod::RodSolver gen(g, test::rk8(64));
  ASSERT_GT(gen.growth_estimate(q, rod::TipWrench()), 12.0) << "the case must be beyond single shooting";
  const rod::RodSolution b = gen.solve(q);
  ASSERT_TRUE(b.converged) << b.message;
  EXPECT_GE(b.segments, 4);
  rod::RodSolver ref(u, test::rk8(64));
  rod::TipWrench tw;
  tw.force = Vec3(0.4, 0.25, 0.0);
  tw.moment = Vec3(0.003, 0.0, 0.0).cross(Vec3(0, 1, 0)) * 0.25;
  const rod::RodSolution a = ref.solve(tw);
  ASSERT_TRUE(a.converged) << a.message;
  std::printf("λL = %.1f: general %d segments, uniform %d; |dp| = %.2e m, |dR| = %.2e rad\n",
              gen.growth_estimate(q, rod::TipWrench()), b.segments, a.segments,
              (a.tip_position - b.tip_position).norm(), so3::log(a.tip_rotation.transpose() * b.tip_rotation).norm());
  EXPECT_LT((a.tip_position - b.tip_position).norm(), 1e-8);
  EXPECT_LT(so3::log(a.tip_rotation.transpose() * b.tip_rotation).norm(), 1e-7);
  // C^b and J_q at the multiple-shooting solution: as the uniform rod's (J_q = C^b B).
  const rod::Compliance ca = ref.compliance();
  const rod::Compliance cb = gen.compliance();
  ASSERT_TRUE(ca.ok && cb.ok);
  EXPECT_LT((ca.body - cb.body).norm(), 1e-5 * ca.body.norm());
}

TEST(RodSolverMultipleShooting, ForcedEqualsSingleShootingAndSegmentCountsAgree) {
  const rod::RodModel m = busy_model(rod::RodKind::kKirchhoff);
  const rod::InputVector q = inputs({0.05, 0.03, 0.04, 0.02});
  rod::RodSolver single(m, test::rk8(8));
  rod::ShootingOptions forced = test::rk8(8);
  forced.shooting_segments = 6;
  rod::RodSolver ms(m, forced);
  const rod::RodSolution a = single.solve(q), b = ms.solve(q);
  ASSERT_TRUE(a.converged && b.converged) << a.message << " / " << b.message;
  EXPECT_EQ(b.segments, 6);
  EXPECT_LT((a.tip_position - b.tip_position).norm(), 1e-10);
  EXPECT_LT(so3::log(a.tip_rotation.transpose() * b.tip_rotation).norm(), 1e-9);
  // The busy model softened ten times and loaded: λL ≈ 20; 8 and 16 segments, one equilibrium.
  rod::RodModel soft = m;
  for (auto& s : soft.segments) s.stiffness /= 10.0;
  const rod::InputVector big = inputs({0.3, 0.2, 0.3, 0.2});
  rod::ShootingOptions o8 = test::rk8(16), o16 = test::rk8(16);
  o8.shooting_segments = 8;
  o16.shooting_segments = 16;
  rod::RodSolver s8(soft, o8), s16(soft, o16);
  const rod::RodSolution c = s8.solve(big), d = s16.solve(big);
  std::printf("soft busy model: λL = %.1f\n", s8.growth_estimate(big, rod::TipWrench()));
  ASSERT_TRUE(c.converged && d.converged) << c.message << " / " << d.message;
  // Steps in proportion to each piece's length, at least one: 8 and 16 pieces integrate differently.
  EXPECT_LT((c.tip_position - d.tip_position).norm(), 1e-7);
  EXPECT_GT((c.tip_position - a.tip_position).norm(), 1e-2) << "a large deflection";
}
