// Eq. (20) over N actuators: the active-set solver against an independent exact solver
// (enumeration of all 3^N active sets, each a QR least-squares solve) on random cases for N = 3…8,
// against the 27-set solver of allocation.h for N = 3, and its errors.
#include <gtest/gtest.h>

#include <Eigen/QR>
#include <cmath>
#include <limits>
#include <random>

#include "hydrojet_control/actuation/allocation.h"
#include "hydrojet_control/actuation/bounded_allocation.h"

using namespace hydrojet::actuation;

namespace {

/// The exact minimum of eq. (20) by enumeration: every input free, at its lower or at its upper bound
/// (3^N sets); the free ones solve min ‖[A_F; √λ I] q_F − [w − A_B q_B; 0]‖² by column-pivoting QR;
/// infeasible or rank-deficient sets are dropped (a basic optimum always exists). Returns the objective.
double enumerated_minimum(const Eigen::MatrixXd& A, const Eigen::VectorXd& w, const Eigen::VectorXd& lo,
                          const Eigen::VectorXd& hi, double lambda) {
  const int m = static_cast<int>(A.rows()), n = static_cast<int>(A.cols());
  int sets = 1;
  for (int i = 0; i < n; ++i) sets *= 3;
  double best = std::numeric_limits<double>::infinity();
  for (int code = 0; code < sets; ++code) {
    Eigen::VectorXd q = Eigen::VectorXd::Zero(n);
    std::vector<int> free;
    for (int i = 0, c = code; i < n; ++i, c /= 3) {
      if (c % 3 == 0)
        free.push_back(i);
      else
        q[i] = c % 3 == 1 ? lo[i] : hi[i];
    }
    const int nf = static_cast<int>(free.size());
    if (nf > 0) {
      Eigen::MatrixXd M = Eigen::MatrixXd::Zero(m + nf, nf);
      Eigen::VectorXd b = Eigen::VectorXd::Zero(m + nf);
      b.head(m) = w - A * q;
      for (int k = 0; k < nf; ++k) {
        M.col(k).head(m) = A.col(free[k]);
        M(m + k, k) = std::sqrt(lambda);
      }
      const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(M);
      if (qr.rank() < nf) continue;
      const Eigen::VectorXd x = qr.solve(b);
      bool feasible = true;
      for (int k = 0; k < nf; ++k) {
        const int i = free[k];
        feasible = feasible && x[k] >= lo[i] - 1e-12 && x[k] <= hi[i] + 1e-12;
        q[i] = std::min(std::max(x[k], lo[i]), hi[i]);
      }
      if (!feasible) continue;
    }
    best = std::min(best, (A * q - w).squaredNorm() + lambda * q.squaredNorm());
  }
  return best;
}

}  // namespace

// Random problems: 1–6 actuated rows, N = 3…8 inputs, bounds with and without reversible inputs,
// targets inside and far outside the reachable set, λ ∈ {0, 1e-6, 1e-2}. The active-set objective
// equals the enumerated minimum within 1e-12 (and is feasible).
TEST(BoundedAllocation, MatchesEnumerationOnRandomCasesForThreeToEightInputs) {
  std::mt19937 rng(20261125);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> rows(1, 6);
  int cases = 0;
  for (int n = 3; n <= 8; ++n) {
    const int count = n <= 6 ? 60 : 15;
    for (int c = 0; c < count; ++c, ++cases) {
      const int m = rows(rng);
      InputMatrix A(m, n);
      for (int i = 0; i < m; ++i)
        for (int j = 0; j < n; ++j) A(i, j) = u(rng);
      InputVector lo(n), hi(n);
      for (int j = 0; j < n; ++j) {
        lo[j] = c % 3 == 0 ? -0.1 * std::abs(u(rng)) : 0.0;  // some inputs reversible
        hi[j] = 0.05 + 0.2 * std::abs(u(rng));
      }
      AllocVector w(m);
      for (int i = 0; i < m; ++i) w[i] = (c % 2 ? 0.1 : 0.6) * u(rng);  // inside and beyond reach
      const double lambda = c % 4 == 0 ? 0.0 : (c % 4 == 1 ? 1e-6 : 1e-2);
      const BoundedAllocationResult r = allocate_bounded(A, w, lo, hi, lambda);
      ASSERT_TRUE(r.ok) << r.message;
      EXPECT_TRUE((r.q.array() >= lo.array()).all() && (r.q.array() <= hi.array()).all());
      const double ours = bounded_allocation_objective(A, w, r.q, lambda);
      const double exact = enumerated_minimum(A, w, lo, hi, lambda);
      EXPECT_NEAR(ours, exact, 1e-12) << "n = " << n << ", m = " << m << ", lambda = " << lambda;
      // Warm-started from a random feasible point: the same minimum.
      InputVector s(n);
      for (int j = 0; j < n; ++j) s[j] = lo[j] + (hi[j] - lo[j]) * 0.5 * (1.0 + u(rng));
      const BoundedAllocationResult warm = allocate_bounded(A, w, lo, hi, lambda, 1e-9, &s);
      ASSERT_TRUE(warm.ok);
      EXPECT_NEAR(bounded_allocation_objective(A, w, warm.q, lambda), exact, 1e-12);
    }
  }
  EXPECT_GE(cases, 200);
}

// N = 3: the same minimiser as the 27-set solver of allocation.h (unique for λ > 0), and the same
// reachability verdict.
TEST(BoundedAllocation, ThreeInputsAgreeWithTheTwentySevenSetSolver) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int c = 0; c < 100; ++c) {
    const int m = 1 + c % 3;
    AllocMatrix A3(m, 3);
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < 3; ++j) A3(i, j) = u(rng);
    AllocVector w(m);
    for (int i = 0; i < m; ++i) w[i] = 0.3 * u(rng);
    const Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi(0.243, 0.224, 0.244);
    const double lambda = 1e-3;
    const AllocationResult a = allocate(A3, w, lo, hi, lambda);
    const BoundedAllocationResult b = allocate_bounded(InputMatrix(A3), w, InputVector(lo), InputVector(hi), lambda);
    ASSERT_TRUE(a.ok && b.ok);
    EXPECT_LT((a.q - Eigen::Vector3d(b.q)).norm(), 1e-9) << c;
    EXPECT_EQ(a.reachable, b.reachable) << c;
  }
}

TEST(BoundedAllocation, BadInputIsNamedAndGivesZeros) {
  InputMatrix A = InputMatrix::Identity(2, 4);
  AllocVector w = AllocVector::Constant(2, 0.1);
  const InputVector lo = InputVector::Zero(4), hi = InputVector::Constant(4, 0.2);
  struct Case {
    InputMatrix A;
    AllocVector w;
    InputVector lo, hi;
    double lambda;
    const char* names;
  };
  InputMatrix nanA = A;
  nanA(0, 0) = NAN;
  const Case cases[] = {{nanA, w, lo, hi, 0.0, "A:"},
                        {A, AllocVector::Constant(3, 0.1), lo, hi, 0.0, "w_des:"},
                        {A, w, InputVector::Zero(3), hi, 0.0, "q_min/q_max:"},
                        {A, w, InputVector::Constant(4, 0.3), hi, 0.0, "q_min > q_max"},
                        {A, w, lo, hi, -1.0, "lambda:"}};
  for (const Case& c : cases) {
    const BoundedAllocationResult r = allocate_bounded(c.A, c.w, c.lo, c.hi, c.lambda);
    EXPECT_FALSE(r.ok);
    EXPECT_NE(r.message.find(c.names), std::string::npos) << r.message;
    EXPECT_TRUE(r.q.isZero()) << r.q.transpose();
  }
  // A target beyond reach is not an error: the closest reachable wrench, reachable = false.
  const BoundedAllocationResult far = allocate_bounded(A, AllocVector::Constant(2, 1.0), lo, hi, 0.0);
  ASSERT_TRUE(far.ok);
  EXPECT_FALSE(far.reachable);
  EXPECT_NEAR(far.q[0], 0.2, 1e-12);
  EXPECT_NEAR(far.q[1], 0.2, 1e-12);
}
