// CVODE / CVODES backend (SUNDIALS 6.4). See include/hydrojet_control/rod/cvode_integrator.h.
#include "hydrojet_control/rod/cvode_integrator.h"

#include <cvodes/cvodes.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace hydrojet {
namespace rod {

namespace {

struct Entry {
  int n = 0;
  int ns = 0;
  bool bdf = false;
  bool analytic_jacobian = false;
  void* mem = nullptr;
  N_Vector y = nullptr;
  N_Vector* yS = nullptr;
  SUNMatrix A = nullptr;
  SUNLinearSolver LS = nullptr;
  SUNNonlinearSolver NLS = nullptr;
  SUNNonlinearSolver NLSsens = nullptr;
  const OdeFunctions* f = nullptr;  ///< the ODE of the integration in progress
};

int rhs_cb(realtype t, N_Vector y, N_Vector ydot, void* ud) {
  const Entry* e = static_cast<const Entry*>(ud);
  e->f->rhs(e->f->ode, t, NV_DATA_S(y), NV_DATA_S(ydot));
  return 0;
}

int jac_cb(realtype t, N_Vector y, N_Vector /*fy*/, SUNMatrix J, void* ud, N_Vector, N_Vector, N_Vector) {
  const Entry* e = static_cast<const Entry*>(ud);
  e->f->jac(e->f->ode, t, NV_DATA_S(y), SM_DATA_D(J));  // dense storage is column-major
  return 0;
}

int sens_cb(int Ns, realtype t, N_Vector y, N_Vector /*ydot*/, N_Vector* yS, N_Vector* ySdot, void* ud, N_Vector,
            N_Vector) {
  const Entry* e = static_cast<const Entry*>(ud);
  for (int i = 0; i < Ns; ++i) e->f->sens_rhs(e->f->ode, t, NV_DATA_S(y), i, NV_DATA_S(yS[i]), NV_DATA_S(ySdot[i]));
  return 0;
}

void silent(int, const char*, const char*, char*, void*) {}

const char* flag_text(int flag) {
  switch (flag) {
    case CV_TOO_MUCH_WORK: return "CVODE: step limit reached (CV_TOO_MUCH_WORK)";
    case CV_TOO_MUCH_ACC: return "CVODE: tolerance too small for machine precision (CV_TOO_MUCH_ACC)";
    case CV_ERR_FAILURE: return "CVODE: repeated error-test failures (CV_ERR_FAILURE)";
    case CV_CONV_FAILURE: return "CVODE: repeated nonlinear-solver failures (CV_CONV_FAILURE)";
    case CV_LSETUP_FAIL: return "CVODE: linear solver setup failed (CV_LSETUP_FAIL)";
    case CV_LSOLVE_FAIL: return "CVODE: linear solve failed (CV_LSOLVE_FAIL)";
    case CV_RHSFUNC_FAIL: return "CVODE: right-hand side failed (CV_RHSFUNC_FAIL)";
    case CV_ILL_INPUT: return "CVODE: illegal input (CV_ILL_INPUT)";
    default: return "CVODE: integration failed";
  }
}

}  // namespace

struct CvodeWorkspace::Impl {
  SUNContext ctx = nullptr;
  std::vector<Entry*> entries;

  Impl() {
    if (SUNContext_Create(nullptr, &ctx) != 0) throw std::runtime_error("SUNContext_Create failed");
  }
  ~Impl() {
    for (Entry* e : entries) {
      if (e->mem) CVodeFree(&e->mem);
      if (e->NLS) SUNNonlinSolFree(e->NLS);
      if (e->NLSsens) SUNNonlinSolFree(e->NLSsens);
      if (e->LS) SUNLinSolFree(e->LS);
      if (e->A) SUNMatDestroy(e->A);
      if (e->yS) N_VDestroyVectorArray(e->yS, e->ns);
      if (e->y) N_VDestroy(e->y);
      delete e;
    }
    SUNContext_Free(&ctx);
  }

  Entry* get(int n, int ns, bool bdf, bool analytic_jacobian, double s0) {
    for (Entry* e : entries)
      if (e->n == n && e->ns == ns && e->bdf == bdf && e->analytic_jacobian == analytic_jacobian) return e;
    Entry* e = new Entry;
    entries.push_back(e);
    e->n = n;
    e->ns = ns;
    e->bdf = bdf;
    e->analytic_jacobian = analytic_jacobian;
    e->y = N_VNew_Serial(n, ctx);
    N_VConst(0.0, e->y);
    N_VEnableFusedOps_Serial(e->y, SUNTRUE);  // fused linear combinations (clones inherit)
    e->mem = CVodeCreate(bdf ? CV_BDF : CV_ADAMS, ctx);
    bool ok = e->mem && CVodeInit(e->mem, rhs_cb, s0, e->y) == CV_SUCCESS &&
              CVodeSetUserData(e->mem, e) == CV_SUCCESS &&
              CVodeSetErrHandlerFn(e->mem, silent, nullptr) == CV_SUCCESS &&
              CVodeSStolerances(e->mem, 1e-6, 1e-6) == CV_SUCCESS;
    if (ok && bdf) {
      e->A = SUNDenseMatrix(n, n, ctx);
      e->LS = SUNLinSol_Dense(e->y, e->A, ctx);
      ok = CVodeSetLinearSolver(e->mem, e->LS, e->A) == CV_SUCCESS;
      if (ok && analytic_jacobian) ok = CVodeSetJacFn(e->mem, jac_cb) == CV_SUCCESS;
    } else if (ok) {
      e->NLS = SUNNonlinSol_FixedPoint(e->y, 0, ctx);
      ok = CVodeSetNonlinearSolver(e->mem, e->NLS) == CV_SUCCESS;
    }
    if (ok && ns > 0) {
      e->yS = N_VCloneVectorArray(ns, e->y);
      for (int i = 0; i < ns; ++i) N_VConst(0.0, e->yS[i]);
      ok = CVodeSensInit(e->mem, ns, CV_STAGGERED, sens_cb, e->yS) == CV_SUCCESS &&
           CVodeSetSensErrCon(e->mem, SUNTRUE) == CV_SUCCESS && CVodeSensEEtolerances(e->mem) == CV_SUCCESS;
      if (ok && !bdf) {
        e->NLSsens = SUNNonlinSol_FixedPointSens(ns, e->y, 0, ctx);
        ok = CVodeSetNonlinearSolverSensStg(e->mem, e->NLSsens) == CV_SUCCESS;
      }
    }
    if (!ok) throw std::runtime_error("CVODE set-up failed");
    return e;
  }
};

CvodeWorkspace::CvodeWorkspace() : impl_(new Impl) {}
CvodeWorkspace::~CvodeWorkspace() = default;

IntegrationStats CvodeWorkspace::integrate(const IntegratorOptions& st, const OdeFunctions& f, double s0, double s1,
                                           double* y, double* ys, const char** error) {
  IntegrationStats out;
  out.ok = false;
  const bool bdf = st.type == IntegratorType::kCvodeBdf;
  if ((st.type != IntegratorType::kCvodeAdams && !bdf) || f.n <= 0 || !f.rhs || (f.ns > 0 && (!f.sens_rhs || !ys))) {
    if (error) *error = "CVODE: bad call";
    return out;
  }
  Entry* e = impl_->get(f.n, f.ns, bdf, bdf && f.jac != nullptr, s0);
  e->f = &f;
  std::copy(y, y + f.n, NV_DATA_S(e->y));
  int flag = CVodeReInit(e->mem, s0, e->y);
  if (flag == CV_SUCCESS) flag = CVodeSStolerances(e->mem, st.tolerance, st.tolerance);
  if (flag == CV_SUCCESS) flag = CVodeSetMaxNumSteps(e->mem, st.max_steps);
  if (flag == CV_SUCCESS) flag = CVodeSetStopTime(e->mem, s1);
  if (flag == CV_SUCCESS && f.ns > 0) {
    for (int i = 0; i < f.ns; ++i) std::copy(ys + i * f.n, ys + (i + 1) * f.n, NV_DATA_S(e->yS[i]));
    flag = CVodeSensReInit(e->mem, CV_STAGGERED, e->yS);
    if (flag == CV_SUCCESS) flag = CVodeSensEEtolerances(e->mem);
  }
  realtype t = s0;
  if (flag == CV_SUCCESS) flag = CVode(e->mem, s1, e->y, &t, CV_NORMAL);
  if (flag >= 0 && f.ns > 0) flag = CVodeGetSens(e->mem, &t, e->yS);
  long nfe = 0, nst = 0, netf = 0, nje = 0, nfS = 0;
  CVodeGetNumRhsEvals(e->mem, &nfe);
  CVodeGetNumSteps(e->mem, &nst);
  CVodeGetNumErrTestFails(e->mem, &netf);
  if (bdf) CVodeGetNumJacEvals(e->mem, &nje);
  if (f.ns > 0) {
    long nfeS = 0;
    CVodeGetSensNumRhsEvals(e->mem, &nfS);
    CVodeGetNumRhsEvalsSens(e->mem, &nfeS);  // f calls made for the sensitivities (DQ only)
    nfe += nfeS;
  }
  out.rhs_evaluations = static_cast<int>(nfe);
  out.sensitivity_evaluations = static_cast<int>(nfS);
  out.steps = static_cast<int>(nst);
  out.rejected_steps = static_cast<int>(netf);
  out.jacobian_evaluations = static_cast<int>(nje);
  e->f = nullptr;
  if (flag < 0) {
    if (error) *error = flag_text(flag);
    return out;
  }
  std::copy(NV_DATA_S(e->y), NV_DATA_S(e->y) + f.n, y);
  bool finite = std::all_of(y, y + f.n, [](double v) { return std::isfinite(v); });
  if (f.ns > 0) {
    for (int i = 0; i < f.ns; ++i) std::copy(NV_DATA_S(e->yS[i]), NV_DATA_S(e->yS[i]) + f.n, ys + i * f.n);
    finite = finite && std::all_of(ys, ys + f.n * f.ns, [](double v) { return std::isfinite(v); });
  }
  out.ok = finite && std::abs(t - s1) <= 1e-12 * std::max(1.0, std::abs(s1 - s0));
  if (!out.ok && error) *error = "CVODE: non-finite state";
  return out;
}

}  // namespace rod
}  // namespace hydrojet
