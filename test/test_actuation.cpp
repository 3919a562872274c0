// Tests of the actuation library: jet map (eq. 24), thrust (eq. 26), allocation (eq. 20) and the
// per-jet PI flow regulator. Each test compares against an independent truth (explicit geometry,
// hand-computed values, brute-force search, closed-loop simulation of a known plant).
#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "hydrojet_control/actuation/allocation.h"
#include "hydrojet_control/actuation/flow_regulator.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/actuation/thrust.h"

using namespace hydrojet::actuation;
using Eigen::Vector3d;

namespace {
constexpr double kDeg = M_PI / 180.0;
const Vector3d kTable1Misalignment(0.12, 0.06, -0.08);  // (δα, δβ, δγ) [rad]
const Vector3d kTable1QMax(0.243, 0.224, 0.244);        // q_jet max [N]

Vector3d planar_dir(double angle) { return Vector3d(std::cos(angle), std::sin(angle), 0.0); }
}  // namespace

// ------------------------------------------------------------------------------------------------
// Jet map, eq. (24)
// ------------------------------------------------------------------------------------------------

TEST(JetMap, NominalColumnsAreUnitVectors120DegreesApart) {
  const JetMap map;  // zero misalignment
  const Eigen::Matrix<double, 6, 3> W = map.wrench_matrix();
  // Designed directions of the jets in the tip xy-plane: 30°, 270°, 150°.
  const double designed[3] = {30 * kDeg, 270 * kDeg, 150 * kDeg};
  for (int i = 0; i < 3; ++i) {
    const Vector3d f = W.col(i).head<3>();
    EXPECT_NEAR(f.norm(), 1.0, 1e-15);
    EXPECT_LT((f - planar_dir(designed[i])).norm(), 1e-15) << "jet " << i + 1;
    EXPECT_EQ(W.col(i).tail<3>().norm(), 0.0);  // no moment without nozzle offset
    EXPECT_EQ(W(2, i), 0.0);                    // f_z = 0
  }
  // 120° apart: pairwise cosines −1/2; balanced: equal jet forces give zero net force.
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(W.col(i).head<3>().dot(W.col((i + 1) % 3).head<3>()), -0.5, 1e-15);
  EXPECT_LT(map.wrench(Vector3d::Ones()).norm(), 1e-15);
}

TEST(JetMap, MisalignmentRotatesEachColumnAboutTipZ) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-0.3, 0.3);
  std::vector<Vector3d> cases = {kTable1Misalignment};
  for (int k = 0; k < 20; ++k) cases.emplace_back(U(rng), U(rng), U(rng));
  for (const Vector3d& mis : cases) {
    JetGeometry g;
    g.misalignment = mis;
    const JetMap map(g);
    // Jet 1 rotates by +δβ, jet 2 by +δα, jet 3 by −δγ (the signs of eq. 24).
    const double nominal[3] = {30 * kDeg, 270 * kDeg, 150 * kDeg};
    const double rot[3] = {mis(1), mis(0), -mis(2)};
    for (int i = 0; i < 3; ++i) {
      const Vector3d expected = Eigen::AngleAxisd(rot[i], Vector3d::UnitZ()) * planar_dir(nominal[i]);
      EXPECT_LT((map.wrench_matrix().col(i).head<3>() - expected).norm(), 1e-15);
      EXPECT_LT((map.planar().col(i) - expected.head<2>()).norm(), 1e-15);
    }
  }
}

TEST(JetMap, Table1PlanarMatrixMatchesPaperEntries) {
  const JetMap map(hydrojet_geometry());
  const double p3 = M_PI / 3, da = 0.12, db = 0.06, dg = -0.08;
  Eigen::Matrix<double, 2, 3> A;
  A << std::sin(p3 - db), std::sin(da), -std::sin(p3 - dg),  //
      std::cos(p3 - db), -std::cos(da), std::cos(p3 - dg);
  EXPECT_EQ(map.planar(), A);
  // Three jets, two force DoF: A is 2×3 of rank 2, not invertible -> eq. (20) allocation.
  EXPECT_EQ(Eigen::FullPivLU<Eigen::MatrixXd>(A).rank(), 2);
  const Vector3d q(0.1, 0.2, 0.05);
  EXPECT_LT((map.wrench(q).head<2>() - A * q).norm(), 1e-16);
}

TEST(JetMap, NozzleOffsetAddsMomentRCrossF) {
  JetGeometry g = hydrojet_geometry();
  g.nozzle_offset = 0.012;
  const JetMap map(g);
  const Vector3d r(0, 0, g.nozzle_offset);
  for (int i = 0; i < 3; ++i) {
    const Vector3d f = map.wrench_matrix().col(i).head<3>();
    EXPECT_LT((map.wrench_matrix().col(i).tail<3>() - r.cross(f)).norm(), 1e-17);
  }
}

// ------------------------------------------------------------------------------------------------
// Thrust, eq. (26)
// ------------------------------------------------------------------------------------------------

TEST(Thrust, HandComputedValue) {
  // Q = 1e-5 m^3/s, Table 1 areas, ρ = 998 kg/m^3:
  //   1/A_out − 1/A_in = 2604166.667 − 884955.752 = 1719210.914 [1/m^2]
  //   F = 998 · 1e-10 · 1719210.914 = 0.1715772 N
  const Nozzle n;
  EXPECT_NEAR(force_from_flow(1e-5, n), 0.1715772, 1e-7);
  EXPECT_NEAR(flow_from_force(0.1715772, n), 1e-5, 1e-11);
}

TEST(Thrust, RoundTrip) {
  const Nozzle n;
  for (double F : {1e-6, 1e-3, 0.05, 0.224, 0.243, 0.244, 1.0}) {
    EXPECT_NEAR(force_from_flow(flow_from_force(F, n), n), F, 1e-14 * F) << F;
  }
  for (double Q : {1e-8, 1e-6, 5e-6, 1.19e-5, 3e-5}) {
    EXPECT_NEAR(flow_from_force(force_from_flow(Q, n), n), Q, 1e-14 * Q) << Q;
  }
  // Scaling: thrust is quadratic in flow.
  EXPECT_NEAR(force_from_flow(2e-5, n), 4 * force_from_flow(1e-5, n), 1e-15);
}

TEST(Thrust, NonPositiveInputsGiveZeroAndNaNPropagates) {
  const Nozzle n;
  EXPECT_EQ(force_from_flow(0.0, n), 0.0);
  EXPECT_EQ(force_from_flow(-1e-5, n), 0.0);
  EXPECT_EQ(flow_from_force(0.0, n), 0.0);
  EXPECT_EQ(flow_from_force(-0.1, n), 0.0);
  EXPECT_TRUE(std::isnan(flow_from_force(NAN, n)));
  EXPECT_TRUE(std::isnan(force_from_flow(NAN, n)));
}

TEST(Thrust, ValidationNamesTheBadField) {
  EXPECT_EQ(validate(Nozzle()), "");
  Nozzle n;
  n.inlet_area = 0;
  EXPECT_NE(validate(n).find("inlet_area"), std::string::npos);
  n = Nozzle();
  n.outlet_area = -1e-7;
  EXPECT_NE(validate(n).find("outlet_area"), std::string::npos);
  n = Nozzle();
  n.water_density = NAN;
  EXPECT_NE(validate(n).find("water_density"), std::string::npos);
  n = Nozzle();
  n.outlet_area = n.inlet_area;  // no contraction -> no thrust
  EXPECT_NE(validate(n).find("outlet_area"), std::string::npos);
}

// ------------------------------------------------------------------------------------------------
// Allocation, eq. (20)
// ------------------------------------------------------------------------------------------------

namespace {

/// KKT conditions of the box-constrained convex QP at q: gradient of the objective
/// g = 2(Aᵀ(Aq − w) + λq) vanishes on free coordinates, is ≥ 0 at a lower bound and ≤ 0 at an upper.
void expect_kkt(const AllocMatrix& A, const AllocVector& w, const Vector3d& lo, const Vector3d& hi, double lambda,
                const Vector3d& q, double tol) {
  const Vector3d g = 2.0 * (A.transpose() * (A * q - w) + lambda * q);
  for (int i = 0; i < 3; ++i) {
    const double bt = 1e-12 * std::max({1.0, std::abs(lo(i)), std::abs(hi(i))});
    ASSERT_GE(q(i), lo(i) - bt);
    ASSERT_LE(q(i), hi(i) + bt);
    const bool at_lo = q(i) <= lo(i) + bt, at_hi = q(i) >= hi(i) - bt;
    if (at_lo && at_hi) continue;
    if (at_lo)
      EXPECT_GE(g(i), -tol) << "coordinate " << i;
    else if (at_hi)
      EXPECT_LE(g(i), tol) << "coordinate " << i;
    else
      EXPECT_NEAR(g(i), 0.0, tol) << "coordinate " << i;
  }
}

/// Brute force: best point of an n³ grid over the box, then cyclic coordinate descent with exact
/// clamped 1-D minimisation (converges to the minimum value of a convex box-constrained quadratic).
/// Returns the best objective; `grid_best` gets the best grid objective (≥ the true minimum).
double brute_force(const AllocMatrix& A, const AllocVector& w, const Vector3d& lo, const Vector3d& hi, double lambda,
                   int n, double* grid_best) {
  Vector3d best_q = lo;
  double best = allocation_objective(A, w, lo, lambda);
  Vector3d q;
  for (int i = 0; i < n; ++i) {
    q(0) = lo(0) + (hi(0) - lo(0)) * i / (n - 1);
    for (int j = 0; j < n; ++j) {
      q(1) = lo(1) + (hi(1) - lo(1)) * j / (n - 1);
      for (int k = 0; k < n; ++k) {
        q(2) = lo(2) + (hi(2) - lo(2)) * k / (n - 1);
        const double f = allocation_objective(A, w, q, lambda);
        if (f < best) best = f, best_q = q;
      }
    }
  }
  *grid_best = best;
  // Local refinement: coordinate descent, f along e_i is a 1-D quadratic a t² + ... .
  q = best_q;
  for (int sweep = 0; sweep < 20000; ++sweep) {
    for (int i = 0; i < 3; ++i) {
      const double a = A.col(i).squaredNorm() + lambda;
      if (a <= 0.0) continue;
      const double grad = A.col(i).dot(A * q - w) + lambda * q(i);
      q(i) = std::min(std::max(q(i) - grad / a, lo(i)), hi(i));
    }
  }
  return std::min(best, allocation_objective(A, w, q, lambda));
}

}  // namespace

TEST(Allocation, MatchesBruteForceAndSatisfiesKkt) {
  std::mt19937 rng(2021);
  std::uniform_real_distribution<double> U(-1.0, 1.0), U01(0.0, 1.0);

  struct Case {
    AllocMatrix A;
    Vector3d lo, hi;
  };
  std::vector<Case> cases;
  // HydroJet: Table 1 misalignments, jets in [0, q_max], planar A (2×3) and full 6×3 with offset.
  cases.push_back({JetMap(hydrojet_geometry()).planar(), Vector3d::Zero(), kTable1QMax});
  JetGeometry g = hydrojet_geometry();
  g.nozzle_offset = 0.01;
  cases.push_back({JetMap(g).wrench_matrix(), Vector3d::Zero(), kTable1QMax});
  // Random A with 1..6 rows (rank-deficient for rows < 3) and random boxes.
  for (int k = 0; k < 18; ++k) {
    const int rows = 1 + k % 6;
    AllocMatrix A(rows, 3);
    for (int r = 0; r < rows; ++r)
      for (int c = 0; c < 3; ++c) A(r, c) = U(rng);
    Vector3d lo, hi;
    for (int i = 0; i < 3; ++i) lo(i) = U(rng), hi(i) = lo(i) + 0.1 + 1.5 * U01(rng);
    cases.push_back({A, lo, hi});
  }
  // Exactly dependent columns (rank 2 with 6 rows): exercises the λ = 0 rank-deficient sets.
  for (int k = 0; k < 2; ++k) {
    AllocMatrix A(6, 3);
    for (int r = 0; r < 6; ++r) A(r, 0) = U(rng), A(r, 1) = U(rng), A(r, 2) = -0.5 * A(r, 0);
    cases.push_back({A, Vector3d(-0.2, -0.5, 0.0), Vector3d(0.8, 0.5, 1.0)});
  }

  int n_cases = 0, n_reachable = 0, n_unreachable = 0;
  for (const Case& c : cases) {
    const Eigen::Index m = c.A.rows();
    for (int variant = 0; variant < 2; ++variant) {
      // variant 0: w = A q for a feasible q (reachable); 1: far outside the reachable set.
      Vector3d qf;
      for (int i = 0; i < 3; ++i) qf(i) = c.lo(i) + (c.hi(i) - c.lo(i)) * U01(rng);
      AllocVector w = c.A * qf;
      if (variant == 1) {
        AllocVector d(m);
        for (int r = 0; r < m; ++r) d(r) = U(rng);
        w += 5.0 * (c.A.norm() + 1.0) * d;
      }
      for (double lambda : {0.0, 1e-3, 1.0}) {
        SCOPED_TRACE(testing::Message() << "case " << n_cases << " rows " << m << " variant " << variant << " lambda "
                                        << lambda);
        const AllocationResult r = allocate(c.A, w, c.lo, c.hi, lambda);
        ASSERT_TRUE(r.ok) << r.message;
        const double f = allocation_objective(c.A, w, r.q, lambda);
        double grid_best = 0.0;
        const double bf = brute_force(c.A, w, c.lo, c.hi, lambda, 41, &grid_best);
        // Exact ≤ refined brute force (+ rounding), and equal to it: coordinate descent on a
        // convex box QP converges linearly, and 20000 sweeps from the best grid point leave only
        // rounding (observed ≤ 1e-13 absolute, ~1e-16 relative); 1e-10 relative leaves margin
        // for slowly converging, ill-conditioned random A.
        EXPECT_LE(f, bf + 1e-12 * std::max(1.0, bf));
        EXPECT_NEAR(f, bf, 1e-10 * std::max(1.0, bf));
        // No feasible grid sample beats the exact solution (≤ the best one ⇔ ≤ every one).
        EXPECT_LE(f, grid_best + 1e-12 * std::max(1.0, grid_best));
        expect_kkt(c.A, w, c.lo, c.hi, lambda, r.q, 1e-9 * std::max(1.0, w.norm()));
        EXPECT_NEAR(r.residual_norm, (c.A * r.q - w).norm(), 1e-15);
        if (variant == 0) {
          EXPECT_TRUE(r.reachable);  // λ-independent
          ++n_reachable;
        } else if (!r.reachable) {
          ++n_unreachable;
        }
        ++n_cases;
      }
    }
  }
  EXPECT_EQ(n_cases, 132);
  EXPECT_GT(n_unreachable, 40);
  EXPECT_EQ(n_reachable, 66);  // most "far outside" targets are out of reach
}

TEST(Allocation, HydroJetFineGridBruteForce) {
  // 81³ grid plus refinement for the paper's A and bounds.
  const AllocMatrix A = JetMap(hydrojet_geometry()).planar();
  const Vector3d lo = Vector3d::Zero();
  for (const Eigen::Vector2d& w2 :
       {Eigen::Vector2d(0.05, -0.1), Eigen::Vector2d(0.3, 0.4), Eigen::Vector2d(-0.12, 0.02)}) {
    const AllocVector w = w2;
    for (double lambda : {0.0, 1e-3, 1.0}) {
      const AllocationResult r = allocate(A, w, lo, kTable1QMax, lambda);
      ASSERT_TRUE(r.ok);
      const double f = allocation_objective(A, w, r.q, lambda);
      double grid_best = 0.0;
      const double bf = brute_force(A, w, lo, kTable1QMax, lambda, 81, &grid_best);
      EXPECT_LE(f, grid_best + 1e-12);
      EXPECT_NEAR(f, bf, 1e-12);
      expect_kkt(A, w, lo, kTable1QMax, lambda, r.q, 1e-10);
    }
  }
}

TEST(Allocation, ReachableForceIsReproducedExactlyWithZeroLambda) {
  const AllocMatrix A = JetMap(hydrojet_geometry()).planar();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U01(0.0, 1.0);
  for (int k = 0; k < 200; ++k) {
    const Vector3d qf(kTable1QMax(0) * U01(rng), kTable1QMax(1) * U01(rng), kTable1QMax(2) * U01(rng));
    const AllocVector w = A * qf;
    const AllocationResult r = allocate(A, w, Vector3d::Zero(), kTable1QMax, 0.0);
    ASSERT_TRUE(r.ok);
    EXPECT_TRUE(r.reachable);
    EXPECT_LT((A * r.q - w).norm(), 1e-9);
    EXPECT_LT(r.residual_norm, 1e-9);
  }
}

TEST(Allocation, OutOfReachForceIsFlagged) {
  const AllocMatrix A = JetMap(hydrojet_geometry()).planar();
  // 1 N is beyond what three jets of ≤ 0.244 N can produce in any direction.
  for (double angle = 0; angle < 2 * M_PI; angle += 0.3) {
    const AllocVector w = Eigen::Vector2d(std::cos(angle), std::sin(angle));
    for (double lambda : {0.0, 1.0}) {
      const AllocationResult r = allocate(A, w, Vector3d::Zero(), kTable1QMax, lambda);
      ASSERT_TRUE(r.ok);
      EXPECT_FALSE(r.reachable);
      EXPECT_GT(r.residual_norm, 0.2);
    }
  }
  // With λ = 1 a reachable force is still "reachable" although the returned q trades residual.
  const AllocVector w = A * Vector3d(0.1, 0.0, 0.05);
  const AllocationResult r = allocate(A, w, Vector3d::Zero(), kTable1QMax, 1.0);
  EXPECT_TRUE(r.reachable);
  EXPECT_GT(r.residual_norm, 1e-3);
}

TEST(Allocation, ZeroLambdaTiesGoToLeastEffort) {
  // Nominal geometry: A (1,1,1)ᵀ = 0, so w = A (0.1, 0.05, 0) is produced by (0.1+t, 0.05+t, t),
  // t ∈ [0, 0.1]; the smallest ‖q‖ on that segment is at t = 0.
  const AllocMatrix A = JetMap().planar();
  const AllocVector w = A * Vector3d(0.1, 0.05, 0.0);
  const AllocationResult r = allocate(A, w, Vector3d::Zero(), Vector3d::Constant(0.2), 0.0);
  ASSERT_TRUE(r.ok);
  EXPECT_LT((r.q - Vector3d(0.1, 0.05, 0.0)).norm(), 1e-12);
}

TEST(Allocation, NonFiniteOrInvalidInputTurnsJetsOff) {
  const AllocMatrix A = JetMap(hydrojet_geometry()).planar();
  const AllocVector w = Eigen::Vector2d(0.05, 0.02);
  const Vector3d lo = Vector3d::Zero(), hi = kTable1QMax;
  auto expect_fail = [](const AllocationResult& r, const std::string& name) {
    EXPECT_FALSE(r.ok);
    EXPECT_FALSE(r.reachable);
    EXPECT_EQ(r.q, Vector3d::Zero());
    EXPECT_TRUE(std::isnan(r.residual_norm));
    EXPECT_NE(r.message.find(name), std::string::npos) << r.message;
  };
  AllocMatrix An = A;
  An(1, 2) = NAN;
  expect_fail(allocate(An, w, lo, hi, 1.0), "A");
  AllocVector wn = w;
  wn(0) = NAN;
  expect_fail(allocate(A, wn, lo, hi, 1.0), "w_des");
  expect_fail(allocate(A, w, Vector3d(0, NAN, 0), hi, 1.0), "q_min");
  expect_fail(allocate(A, w, lo, Vector3d(INFINITY, 1, 1), 1.0), "q_max");
  expect_fail(allocate(A, w, lo, hi, NAN), "lambda");
  expect_fail(allocate(A, w, lo, hi, -1.0), "lambda");
  expect_fail(allocate(A, w, hi, lo, 0.0), "q_min");
  expect_fail(allocate(A, AllocVector::Zero(3), lo, hi, 0.0), "w_des");
}

#ifdef EIGEN_RUNTIME_NO_MALLOC
TEST(Allocation, NoHeapAllocation) {
  const AllocMatrix A = JetMap(hydrojet_geometry()).wrench_matrix();
  const AllocVector w = A * Vector3d(0.1, 0.2, 0.05);
  Eigen::internal::set_is_malloc_allowed(false);
  const AllocationResult r = allocate(A, w, Vector3d::Zero(), kTable1QMax, 1e-3);
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_TRUE(r.ok);
}
#endif

// ------------------------------------------------------------------------------------------------
// Flow regulator
// ------------------------------------------------------------------------------------------------

namespace {

/// First-order valve/line plant: Q' = (G u − Q)/τ, integrated exactly over dt with u held.
struct FirstOrderPlant {
  double gain = 2e-5;  ///< G: flow at full duty [m^3/s]
  double tau = 0.05;   ///< lag [s]
  double Q = 0.0;      ///< flow [m^3/s]
  double step(double u, double dt) {
    Q += (1.0 - std::exp(-dt / tau)) * (gain * u - Q);
    return Q;
  }
};

FlowRegulatorOptions test_gains() {
  FlowRegulatorOptions p;
  p.kp = 2.5e4;  // loop gain kp·G = 0.5
  p.ki = 5e5;    // ki·G = 10 /s
  return p;
}

}  // namespace

TEST(FlowRegulator, StepConvergesWithZeroSteadyStateError) {
  const double dt = 0.01;  // 100 Hz, as the paper's flow sensors
  for (double ff : {0.0, 1.0 / 2e-5, 1.0 / 3e-5 /* mismatched feedforward */}) {
    FlowRegulatorOptions p = test_gains();
    p.feedforward = ff;
    FlowRegulator reg(p);
    FirstOrderPlant plant;
    const double sp = 1.2e-5;
    for (int k = 0; k < 1000; ++k) plant.step(reg.update(sp, plant.Q, dt), dt);
    EXPECT_NEAR(plant.Q, sp, 1e-9 * sp) << "ff " << ff;
    EXPECT_NEAR(reg.output(), sp / plant.gain, 1e-8);  // duty that holds the setpoint
    EXPECT_TRUE(reg.ok());
    EXPECT_FALSE(reg.saturated());
  }
}

// The flow lead: with lead_time = the valve's time constant and the exact feedforward (no PI), the
// first-order valve meets a ramp of desired flow on time; without the lead it lags by τ·slope (the
// closed form of a first-order lag's ramp response, reached after t ≫ τ). The PI alone removes the
// lag only after its integrator has caught up (half of it at worst with the test gains); the lead
// with the PI keeps it small throughout.
TEST(FlowRegulator, LeadTimeCancelsAFirstOrderValveLagOnARamp) {
  const double dt = 0.001, slope = 2e-5;  // [s], [m^3/s per s]: 0 to 1e-5 in 0.5 s
  FirstOrderPlant valve;
  valve.tau = 0.04;
  struct Lag {
    double last, worst;  // desired − measured flow at the end and its largest magnitude [m^3/s]
  };
  auto ramp = [&](double lead, double kp, double ki) {
    FlowRegulatorOptions p;
    p.feedforward = 1.0 / valve.gain;
    p.kp = kp;
    p.ki = ki;
    p.lead_time = lead;
    FlowRegulator reg(p);
    FirstOrderPlant v = valve;
    Lag lag{0.0, 0.0};
    for (int k = 1; k <= 500; ++k) {
      const double q_des = slope * k * dt;
      v.step(reg.update(q_des, v.Q, dt), dt);
      lag.last = q_des - v.Q;
      lag.worst = std::max(lag.worst, std::abs(lag.last));
    }
    return lag;
  };
  const double lag = valve.tau * slope;                    // 8e-7 m^3/s
  EXPECT_NEAR(ramp(0.0, 0.0, 0.0).last, lag, 0.03 * lag);  // τ·slope (1 − e^{−12.5})
  EXPECT_LT(ramp(valve.tau, 0.0, 0.0).worst, 0.05 * lag);  // the rate is a backward difference
  const FlowRegulatorOptions g = test_gains();
  EXPECT_GT(ramp(0.0, g.kp, g.ki).worst, 0.3 * lag);
  EXPECT_LT(ramp(valve.tau, g.kp, g.ki).worst, 0.05 * lag);
  // Out of range: a lead over 1 s or not finite is refused by name.
  FlowRegulatorOptions bad;
  bad.lead_time = 2.0;
  EXPECT_NE(validate(bad).find("lead_time"), std::string::npos);
  bad.lead_time = std::nan("");
  EXPECT_NE(validate(bad).find("lead_time"), std::string::npos);
}

// The play's inverse: a linear valve (no lag) whose opening moves only when the duty leaves a band of
// width p about it (the plant's hysteresis, written out here) follows a desired flow that turns back
// and forth exactly under the feedforward alone when the regulator inverts p; without, its opening
// trails the duty by p/2 (p/2·Q_max of flow, the band's closed form); inverting 0.8 p leaves 0.2 of
// that. A play outside [0, 0.5) or not finite is taken as none.
TEST(FlowRegulator, InvertingTheValvesPlayRemovesItsBand) {
  const double q_max = 1.6e-5, p = 0.03, dt = 0.01;
  auto worst = [&](double inverted) {
    FlowRegulatorOptions o;
    o.feedforward = 1.0 / q_max;
    FlowRegulator reg(o);
    reg.set_play(inverted);
    double opening = 0.0, most = 0.0;
    for (int k = 0; k < 400; ++k) {
      const double q = q_max * (0.4 + 0.2 * std::sin(2.0 * M_PI * 0.7 * k * dt));
      const double duty = reg.update(q, q, dt);
      if (duty > opening + 0.5 * p) opening = duty - 0.5 * p;
      if (duty < opening - 0.5 * p) opening = duty + 0.5 * p;
      if (k >= 100) most = std::max(most, std::abs(q_max * opening - q));
    }
    return most;
  };
  EXPECT_NEAR(worst(0.0), 0.5 * p * q_max, 0.01 * p * q_max);
  EXPECT_LT(worst(p), 1e-12 * q_max);
  EXPECT_NEAR(worst(0.8 * p), 0.1 * p * q_max, 0.01 * p * q_max);
  FlowRegulator reg;
  for (const double bad : {-0.01, 0.5, std::nan(""), HUGE_VAL}) {
    reg.set_play(bad);
    EXPECT_EQ(reg.play(), 0.0) << bad;
  }
}

// The valve curve's inverse: for a valve whose steady flow is Q_max d^γ (the plant's valves without
// dead zone or hysteresis), the feedforward alone (no PI) gives the duty that delivers q exactly; γ = 1
// is the linear feedforward k_ff q.
TEST(FlowRegulator, FeedforwardInvertsTheValveCurve) {
  const double q_max = 1.6e-5;
  for (const double gamma : {0.8, 1.0, 1.3}) {
    FlowRegulatorOptions p;
    p.feedforward = 1.0 / q_max;
    p.valve_exponent = gamma;
    for (const double q : {1e-8, 2e-7, 3e-6, 8e-6, 1.5e-5}) {
      FlowRegulator reg(p);
      const double d = reg.update(q, q, 0.01);
      EXPECT_NEAR(q_max * std::pow(d, gamma) / q, 1.0, 1e-12) << gamma << " " << q;
      if (gamma == 1.0) EXPECT_EQ(d, p.feedforward * q);
    }
    FlowRegulator reg(p);
    EXPECT_EQ(reg.update(0.0, 0.0, 0.01), 0.0);  // no flow wanted: shut
  }
  FlowRegulatorOptions bad;
  for (const double gamma : {0.0, 20.0, std::nan("")}) {
    bad.valve_exponent = gamma;
    EXPECT_NE(validate(bad).find("valve_exponent"), std::string::npos) << gamma;
  }
}

TEST(FlowRegulator, AntiWindupBoundsOvershootAfterSaturation) {
  const double dt = 0.01;
  struct Run {
    double time_above = 0.0;  // time after the step with Q > 1.05·setpoint [s]
    double max_integrator_saturated = 0.0;
  };
  // One regulator step: (setpoint, measured) -> duty, and its integrator after the step.
  using Step = std::function<double(double, double)>;
  auto run = [&](const Step& step, const std::function<double()>& integrator) {
    FirstOrderPlant plant;
    Run out;
    // 5 s at an unreachable setpoint (needs duty 2): the valve saturates at 1.
    for (int k = 0; k < 500; ++k) {
      plant.step(step(4e-5, plant.Q), dt);
      if (k > 100) out.max_integrator_saturated = std::max(out.max_integrator_saturated, integrator());
    }
    EXPECT_NEAR(plant.Q, 2e-5, 1e-12);
    // Then a reachable setpoint.
    const double sp = 1e-5;
    for (int k = 0; k < 3000; ++k) {
      plant.step(step(sp, plant.Q), dt);
      if (plant.Q > 1.05 * sp) out.time_above += dt;
    }
    EXPECT_NEAR(plant.Q, sp, 1e-9 * sp);  // both recover eventually
    return out;
  };
  FlowRegulator reg(test_gains());
  int n = 0;
  const Run aw = run(
      [&](double sp, double q) {
        const double u = reg.update(sp, q, dt);
        if (++n > 101 && n <= 500) EXPECT_TRUE(reg.saturated()) << n;  // the unreachable setpoint
        return u;
      },
      [&] { return reg.integrator(); });
  // The reference without anti-windup: the same PI with its integrator unbounded.
  const FlowRegulatorOptions g = test_gains();
  double integral = 0.0;
  const Run plain = run(
      [&](double sp, double q) {
        const double e = sp - q;
        integral += g.ki * e * dt;
        return std::clamp(g.kp * e + integral, g.output_min, g.output_max);
      },
      [&] { return integral; });
  // With anti-windup the integrator stays ≤ the duty range and the flow leaves the saturated
  // value within a few plant time constants; without it, I ≈ ki·e·t ≈ 100 keeps the valve open
  // for seconds.
  EXPECT_LE(aw.max_integrator_saturated, 1.0);
  EXPECT_GT(plain.max_integrator_saturated, 50.0);
  EXPECT_LT(aw.time_above, 0.3);
  EXPECT_GT(plain.time_above, 3.0);
}

TEST(FlowRegulator, LowerLimitDoesNotWindUp) {
  FlowRegulator reg(test_gains());
  // Measured flow above a zero setpoint for a long time (e.g. a leaking valve): command stays 0
  // and the integrator does not go negative without bound.
  for (int k = 0; k < 1000; ++k) EXPECT_EQ(reg.update(0.0, 1e-5, 0.01), 0.0);
  EXPECT_GE(reg.integrator(), 0.0);
}

TEST(FlowRegulator, NonFiniteInputOrBadDtGivesZeroCommand) {
  FlowRegulator reg(test_gains());
  FirstOrderPlant plant;
  for (int k = 0; k < 100; ++k) plant.step(reg.update(1e-5, plant.Q, 0.01), 0.01);
  ASSERT_GT(reg.output(), 0.0);
  const double integrator = reg.integrator();
  struct Bad {
    double q_des, q_meas, dt;
    const char* what;
  };
  for (const Bad& b :
       {Bad{1e-5, NAN, 0.01, "measured"}, Bad{1e-5, INFINITY, 0.01, "measured"}, Bad{NAN, 1e-5, 0.01, "desired"},
        Bad{1e-5, 1e-5, 0.0, "dt"}, Bad{1e-5, 1e-5, -0.01, "dt"}, Bad{1e-5, 1e-5, NAN, "dt"}}) {
    EXPECT_EQ(reg.update(b.q_des, b.q_meas, b.dt), 0.0);
    EXPECT_EQ(reg.output(), 0.0);
    EXPECT_FALSE(reg.ok());
    EXPECT_NE(reg.error().find(b.what), std::string::npos) << reg.error();
    EXPECT_EQ(reg.integrator(), integrator);  // state frozen
  }
  EXPECT_GT(reg.update(1e-5, plant.Q, 0.01), 0.0);
  EXPECT_TRUE(reg.ok());
  reg.reset();
  EXPECT_EQ(reg.integrator(), 0.0);
  EXPECT_EQ(reg.output(), 0.0);
}

TEST(FlowRegulator, InvalidParametersThrow) {
  FlowRegulatorOptions p = test_gains();
  p.ki = -1;
  EXPECT_NE(validate(p).find("ki"), std::string::npos);
  EXPECT_THROW(FlowRegulator{p}, std::invalid_argument);
  p = test_gains();
  p.output_max = 1.5;
  EXPECT_NE(validate(p).find("output_max"), std::string::npos);
  p = test_gains();
  p.output_min = 0.6, p.output_max = 0.4;
  EXPECT_NE(validate(p).find("output_min"), std::string::npos);
}
