// The shooting Newton iteration through SUNDIALS KINSOL (NewtonBackend::kKinsol), kept for the
// comparison in docs/work_precision.md: the unknown is x ∈ R³ with R(L) = R_ref·exp(x̂), the
// residual log R(0), the Jacobian (∂r/∂η)·J_r(x) from the same forward sensitivities.
#include <kinsol/kinsol.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <cmath>
#include <stdexcept>

#include "hydrojet_control/rod/rod_solver.h"
#include "kinsol_workspace.h"

namespace hydrojet {
namespace rod {

struct KinsolWorkspace::Impl {
  SUNContext ctx = nullptr;
  void* mem = nullptr;
  N_Vector u = nullptr, scale = nullptr;
  SUNMatrix A = nullptr;
  SUNLinearSolver LS = nullptr;
  Func f = nullptr;
  Jac j = nullptr;
  void* data = nullptr;
};

namespace {
int kin_func(N_Vector u, N_Vector fval, void* ud) {
  auto* im = static_cast<KinsolWorkspace::Impl*>(ud);
  return im->f(NV_DATA_S(u), NV_DATA_S(fval), im->data);
}
int kin_jac(N_Vector u, N_Vector, SUNMatrix J, void* ud, N_Vector, N_Vector) {
  auto* im = static_cast<KinsolWorkspace::Impl*>(ud);
  return im->j(NV_DATA_S(u), SM_DATA_D(J), im->data);
}
void kin_silent(int, const char*, const char*, char*, void*) {}
}  // namespace

KinsolWorkspace::KinsolWorkspace() : impl_(new Impl) {
  Impl& m = *impl_;
  if (SUNContext_Create(nullptr, &m.ctx) != 0) throw std::runtime_error("SUNContext_Create failed");
  m.u = N_VNew_Serial(3, m.ctx);
  m.scale = N_VNew_Serial(3, m.ctx);
  N_VConst(0.0, m.u);
  N_VConst(1.0, m.scale);
  m.mem = KINCreate(m.ctx);
  m.A = SUNDenseMatrix(3, 3, m.ctx);
  m.LS = SUNLinSol_Dense(m.u, m.A, m.ctx);
  const bool ok = m.mem && KINInit(m.mem, kin_func, m.u) == KIN_SUCCESS &&
                  KINSetUserData(m.mem, impl_) == KIN_SUCCESS &&
                  KINSetErrHandlerFn(m.mem, kin_silent, nullptr) == KIN_SUCCESS &&
                  KINSetLinearSolver(m.mem, m.LS, m.A) == KIN_SUCCESS && KINSetJacFn(m.mem, kin_jac) == KIN_SUCCESS &&
                  KINSetMaxSetupCalls(m.mem, 1) == KIN_SUCCESS && KINSetScaledStepTol(m.mem, 1e-15) == KIN_SUCCESS;
  if (!ok) throw std::runtime_error("KINSOL set-up failed");
}

KinsolWorkspace::~KinsolWorkspace() {
  Impl& m = *impl_;
  KINFree(&m.mem);
  SUNLinSolFree(m.LS);
  SUNMatDestroy(m.A);
  N_VDestroy(m.u);
  N_VDestroy(m.scale);
  SUNContext_Free(&m.ctx);
  delete impl_;
}

int KinsolWorkspace::solve(Func f, Jac j, void* data, double* x, double fnorm_tol, int max_iters, double max_step,
                           long* iters, long* fevals) {
  Impl& m = *impl_;
  m.f = f;
  m.j = j;
  m.data = data;
  for (int i = 0; i < 3; ++i) NV_Ith_S(m.u, i) = x[i];
  KINSetFuncNormTol(m.mem, fnorm_tol);
  KINSetNumMaxIters(m.mem, max_iters);
  KINSetMaxNewtonStep(m.mem, max_step);
  const int flag = KINSol(m.mem, m.u, KIN_LINESEARCH, m.scale, m.scale);
  for (int i = 0; i < 3; ++i) x[i] = NV_Ith_S(m.u, i);
  KINGetNumNonlinSolvIters(m.mem, iters);
  KINGetNumFuncEvals(m.mem, fevals);
  return flag;
}

KinsolWorkspace& RodSolver::Workspace::kinsol() {
  if (!kinsol_) kinsol_.reset(new KinsolWorkspace);
  return *kinsol_;
}

bool RodSolver::newton_kinsol(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last) {
  struct Ctx {
    RodSolver* s = nullptr;
    const Load* load = nullptr;
    Mat3 R_ref;
    Vec3 x = Vec3::Constant(std::nan(""));
    Eval e;
    int rhs = 0;
    const Eval& at(const double* xp) {
      const Vec3 xn(xp[0], xp[1], xp[2]);
      if (xn != x) {
        e = s->evaluate(R_ref * so3::exp(xn), *load, &rhs);
        x = xn;
      }
      return e;
    }
  } c;
  c.s = this;
  c.load = &load;
  c.R_ref = *R_tip;
  auto f = [](const double* x, double* fv, void* d) -> int {
    const Eval& e = static_cast<Ctx*>(d)->at(x);
    if (!e.ok) return 1;
    for (int i = 0; i < 3; ++i) fv[i] = e.r[i];
    return 0;
  };
  auto j = [](const double* x, double* J, void* d) -> int {
    const Eval& e = static_cast<Ctx*>(d)->at(x);
    if (!e.ok) return 1;
    Eigen::Map<Mat3> Jm(J);
    Jm = e.J * so3::right_jacobian(Vec3(x[0], x[1], x[2]));
    return 0;
  };
  double x[3] = {0.0, 0.0, 0.0};
  long iters = 0, fevals = 0;
  // KINSOL's test is on the max-norm; |r| ≤ tol in the 2-norm is checked below.
  const int flag = workspace_.kinsol().solve(f, j, &c, x, options_.residual_tolerance / std::sqrt(3.0),
                                             options_.max_iterations, options_.max_step, &iters, &fevals);
  sol->iterations += static_cast<int>(iters);
  const Eval& e = c.at(x);
  sol->rhs_evaluations += c.rhs;
  if (!e.ok) {
    sol->message = "integration failed (non-finite state or step limit)";
    return false;
  }
  *last = e;
  *R_tip = so3::orthonormalise(c.R_ref * so3::exp(Vec3(x[0], x[1], x[2])));
  sol->residual = e.r.norm();
  if (sol->residual <= options_.residual_tolerance) return true;
  sol->message =
      flag >= 0 ? "KINSOL stopped above the residual tolerance" : "KINSOL failed (flag " + std::to_string(flag) + ")";
  return false;
}

}  // namespace rod
}  // namespace hydrojet
