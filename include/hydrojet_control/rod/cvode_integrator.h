// CVODE / CVODES (SUNDIALS 6.4) as an integrator backend for the rod ODE.
//   - cvode-adams: variable-order Adams–Moulton with fixed-point iteration (non-stiff problems);
//   - cvode-bdf:   variable-order BDF with Newton iteration and a dense direct linear solver on the
//                  analytic Jacobian (stiff problems).
// Two ways to carry the forward-mode sensitivities the shooting solver needs:
//   - augmented: the sensitivity equations are part of the ODE state (as for the Runge–Kutta
//                methods); BDF gets a block-diagonal analytic Jacobian (the state block and one
//                sensitivity block per direction; the coupling blocks are left out, which only makes
//                CVODE's modified Newton iteration a little less exact);
//   - cvodes:      CVODES forward sensitivity analysis (staggered corrector, sensitivities in the
//                  error test) on the 15-number base state with analytic sensitivity right-hand sides.
// The solver memory is created once per (size, directions, method) and re-initialised per
// integration (CVodeReInit), so steady-state solves do not allocate.
// SUNDIALS types do not leak out of this header. ROS-free.
#pragma once

#include <memory>

#include "hydrojet_control/rod/integrators.h"

namespace hydrojet {
namespace rod {

/// An ODE y' = f(s, y) of size n handed to CVODE through plain function pointers (type-erased so
/// that one compiled backend serves every RodOde variant).
struct OdeFunctions {
  const void* ode = nullptr;  ///< passed back to every callback
  int n = 0;
  void (*rhs)(const void* ode, double s, const double* y, double* dy) = nullptr;
  /// Dense n×n Jacobian ∂f/∂y, column-major (only BDF uses it); null: CVODE's difference quotients.
  void (*jac)(const void* ode, double s, const double* y, double* J) = nullptr;
  /// Forward sensitivities (CVODES): ns directions of n numbers each; d(ys_i)/ds = sens_rhs(i).
  int ns = 0;
  void (*sens_rhs)(const void* ode, double s, const double* y, int i, const double* ys, double* dys) = nullptr;
};

/// Owns the CVODE memories (one SUNContext per workspace). Not thread-safe; not copyable (a copy of
/// the owner makes a new, empty workspace).
class CvodeWorkspace {
 public:
  CvodeWorkspace();
  ~CvodeWorkspace();
  CvodeWorkspace(const CvodeWorkspace&) = delete;
  CvodeWorkspace& operator=(const CvodeWorkspace&) = delete;

  /// Integrates from s0 to s1 (either direction) with settings.type kCvodeAdams or kCvodeBdf,
  /// relative and absolute tolerance settings.tolerance, at most settings.max_steps steps.
  /// y (n numbers) is advanced in place; with f.ns > 0, ys (n·ns numbers, direction-major) too.
  /// rhs_evaluations counts calls of f (sensitivity right-hand sides are counted in
  /// sensitivity_evaluations). ok = false on any CVODE failure (the reason in *error if given).
  IntegrationStats integrate(const IntegratorOptions& settings, const OdeFunctions& f, double s0, double s1, double* y,
                             double* ys = nullptr, const char** error = nullptr);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Wraps an ODE functor with operator()(s, State y, State& dy) (and, for BDF, a Jacobian) for CVODE.
template <class Ode>
OdeFunctions ode_functions(const Ode& ode) {
  OdeFunctions f;
  f.ode = &ode;
  f.n = Ode::kSize;
  f.rhs = [](const void* o, double s, const double* y, double* dy) {
    const Ode& ode = *static_cast<const Ode*>(o);
    typename Ode::State ys = Eigen::Map<const typename Ode::State>(y), d;
    ode(s, ys, d);
    Eigen::Map<typename Ode::State> out(dy);
    out = d;
  };
  return f;
}

}  // namespace rod
}  // namespace hydrojet
