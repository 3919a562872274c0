// Internal to hydrojet_rod: KINSOL memory for the 3-unknown shooting problem
// (ShootingOptions::newton = NewtonBackend::kKinsol). Not installed.
#pragma once

namespace hydrojet {
namespace rod {

class KinsolWorkspace {
 public:
  /// Residual and Jacobian callbacks on x ∈ R³ (return 0 on success, > 0 recoverable failure).
  using Func = int (*)(const double* x, double* f, void* data);
  using Jac = int (*)(const double* x, double* J /*3×3 column-major*/, void* data);

  KinsolWorkspace();
  ~KinsolWorkspace();
  KinsolWorkspace(const KinsolWorkspace&) = delete;
  KinsolWorkspace& operator=(const KinsolWorkspace&) = delete;

  /// Runs KINSOL (line search, exact Newton: a Jacobian every iteration) from x. Returns the
  /// KINSOL flag (≥ 0 success); iterations and function evaluations in *iters, *fevals.
  int solve(Func f, Jac j, void* data, double* x, double fnorm_tol, int max_iters, double max_step, long* iters,
            long* fevals);

  struct Impl;  // SUNDIALS handles (kinsol_newton.cpp)

 private:
  Impl* impl_;
};

}  // namespace rod
}  // namespace hydrojet
