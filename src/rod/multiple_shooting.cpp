// Multiple shooting: where single shooting cannot go (λL > 12), the fallback of RodSolver::solve, or
// forced with ShootingOptions::shooting_segments ≥ 2.
//
// Nodes s_k = k L / M (k = 0..M). Unknowns: the tip frame R_M (ξ, 3) and at every interior node the
// state just above any station there: R_k (η_k), n_k (δn_k, integration frame) and u_k (δu_k).
// Sweep k runs from node k+1 (from the tip for k = M−1) down to s_k; the residuals are
//   c_k = [log(R_kᵀ R⁻(s_k)); (n⁻(s_k) − n_k) / F; h (u⁻(s_k) − u_k)],  k = 1..M−1,
//   r_0 = log R⁻(0)   (h = L / M, F = max EI / L², all in rad),
// with the Jacobian from each sweep's sensitivities (3 directions at the tip, 9 at a node) and the
// node columns in closed form (−J_l⁻¹, −I/F, −h I). The positions decouple, so the tip position is
// −R⁻(0)ᵀ Σ_k Δp_k. Damped Newton (damped_newton.h) on the load path of single shooting
// (load_path.h). The converged tip frame then goes through single shooting's evaluation once (C^b,
// J_q, shape, warm start); at these λL that sweep loses ~e^{λL}·1e-16 of accuracy, and the solution
// says so when it no longer reaches the base. This path allocates (dynamic matrices): a fallback.
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "damped_newton.h"
#include "load_path.h"
#include "rod_integration.h"
#include "sweep.h"

namespace hydrojet {
namespace rod {

using internal::Direction;
using internal::FoldTracker;
using internal::SweepCall;
using internal::SweepState;
using Load = RodSolver::Load;

Load load_between(const Load& from, const Load& to, double t);  // rod_solver.cpp

struct RodSolver::Nodes {
  std::vector<double> s;   ///< s_0 = 0 .. s_M = L
  std::vector<Mat3> R;     ///< frames at the nodes (R[M]: the tip), integration frame
  std::vector<Vec3> n, u;  ///< internal force and curvature at the nodes (interior ones used)
  int segments() const { return static_cast<int>(s.size()) - 1; }
};

namespace {
/// Force scale of the node residuals [N]: max EI / L², the force that bends the stiffest part by ~1 rad.
double node_force_scale(const RodModel& m) {
  double ei = 0.0;
  for (const RodSegment& sg : m.segments) ei = std::max(ei, sg.stiffness.maxCoeff());
  const double L = m.length();
  return ei / (L * L);
}
}  // namespace

struct RodSolver::MsEval {
  Eigen::VectorXd F;
  Eigen::MatrixXd J;
  Eigen::Matrix<double, 3, Eigen::Dynamic> dP_X;  ///< ∂(Σ Δp)/∂X
  Vec3 sum_dp = Vec3::Zero();                     ///< Σ Δp_k = p(0) − p(L), integration frame
  Mat3 R0 = Mat3::Identity();                     ///< R⁻(0)
  double log_det_scale = 0.0;                     ///< log |det| of J's node blocks
  bool ok = false;

  /// Adds the sweep from node k+1 (the tip for k = M−1, with D = 3 directions; else 9) down to s_k:
  /// its Δp, the residual rows of node k (of the base for k = 0) and their columns.
  void add_sweep(const Nodes& x, int k, double Fs, int D, const SweepState<9>& y, const internal::SweepEnd<9>& end);
  /// det ∂r/∂x's sign with J's magnitude relative to its node blocks (fold tracking only).
  double det() const {
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(J);
    double sign = lu.permutationP().determinant(), log_abs = 0.0;
    for (Eigen::Index i = 0; i < J.rows(); ++i) {
      const double d = lu.matrixLU()(i, i);
      if (d == 0.0 || !std::isfinite(d)) return 0.0;
      sign *= d < 0.0 ? -1.0 : 1.0;
      log_abs += std::log(std::abs(d));
    }
    return sign * std::exp(std::clamp(log_abs - log_det_scale, -600.0, 600.0));
  }
};

/// Multiple shooting posed for the load path (load_path.h) and for damped_newton (damped_newton.h):
/// the unknowns are the node values; a step's size is measured in rad (η, δn / F, h δu, as the
/// residuals are scaled).
struct RodSolver::MultipleShooting {
  using Unknowns = Nodes;
  using Load = RodSolver::Load;
  using Point = internal::PathPoint<Nodes, Load>;
  struct Saved {
    RodSolution sol;
    MsEval e;
  };
  using Step = Eigen::VectorXd;
  static constexpr bool kNewtonFromUnloaded = false;

  RodSolver& solver;
  Load target;
  RodSolution* sol;
  int M;
  Nodes x;
  double det = 0.0;
  Vec3 tip = Vec3::Zero();
  MsEval e;                  ///< Newton's last evaluation
  const Load* at = nullptr;  ///< the load of the Newton iteration under way
  Eigen::VectorXd scale;     ///< of a step's parts, to rad

  MultipleShooting(RodSolver& s, const Load& t, RodSolution* out, int segments)
      : solver(s), target(t), sol(out), M(segments) {
    const double L = s.model_.length();
    scale = Eigen::VectorXd::Ones(3 + 9 * (M - 1));
    for (int k = 1; k < M; ++k) {
      const int c = 3 + 9 * (M - 1 - k);
      scale.segment<3>(c + 3).setConstant(1.0 / node_force_scale(s.model_));
      scale.segment<3>(c + 6).setConstant(L / M);
    }
  }

  // load_path.h
  const ShootingOptions& options() const { return solver.options_; }
  double length() const { return solver.model_.length(); }
  double growth() const { return solver.growth_estimate(target.q, target.wrench); }
  bool newton(Nodes* n, const Load& load, double* d, Vec3* p) {
    at = &load;
    if (!internal::damped_newton(*this, options(), n, sol, &e)) return false;
    *d = e.det();
    *p = -e.R0.transpose() * e.sum_dp;
    return true;
  }
  bool turned_far(const Nodes& a, const Nodes& b) const {
    for (int k = 1; k <= M; ++k)
      if (so3::log(a.R[k].transpose() * b.R[k]).norm() > options().max_step) return true;
    return false;
  }
  Saved save() const { return {*sol, e}; }
  void restore(const Saved& direct) {
    *sol = direct.sol;
    e = direct.e;
  }

  // damped_newton.h
  MsEval evaluate(const Nodes& n) {
    MsEval t;
    solver.ms_evaluate(n, *at, &t, &sol->rhs_evaluations);
    return t;
  }
  static double residual(const MsEval& t) { return t.F.norm(); }
  static bool step(const MsEval& t, Step* dx) {
    *dx = -t.J.partialPivLu().solve(t.F);
    return dx->allFinite();
  }
  double size(const Step& dx) const { return dx.cwiseProduct(scale).cwiseAbs().maxCoeff(); }
  static Nodes accepted(Nodes n) { return n; }
  Nodes moved(const Nodes& n, const Step& dX, double a) const {
    Nodes y = n;
    y.R[M] = so3::orthonormalise(n.R[M] * so3::exp(a * dX.head<3>()));
    for (int k = 1; k < M; ++k) {
      const int c = 3 + 9 * (M - 1 - k);
      y.R[k] = so3::orthonormalise(n.R[k] * so3::exp(a * dX.segment<3>(c)));
      y.n[k] = n.n[k] + a * dX.segment<3>(c + 3);
      y.u[k] = n.u[k] + a * dX.segment<3>(c + 6);
    }
    return y;
  }

  /// A load-path point at the node values `n` under `load` (its det and tip from one evaluation).
  bool point(const Nodes& n, const Load& load, Point* out) {
    MsEval t;
    if (!solver.ms_evaluate(n, load, &t, &sol->rhs_evaluations)) return false;
    *out = Point{n, load, Vec3(-t.R0.transpose() * t.sum_dp), t.det()};
    return true;
  }
};

// Pieces of growth exp(λL/M) ≈ e² each; at least 4 (the fallback also helps with nonlinearity).
int RodSolver::auto_segments(const Load& load) const {
  return std::clamp(static_cast<int>(std::ceil(growth_estimate(load.q, load.wrench) / 2.0)), 4, 64);
}

// The nodes of a single sweep from R_tip under `load` (exact for the unloaded shape).
bool RodSolver::ms_nodes(const Mat3& R_tip, const Load& load, int M, Nodes* x) {
  const double L = model_.length();
  x->s.resize(M + 1);
  for (int k = 0; k <= M; ++k) x->s[k] = L * k / M;
  internal::Recorder rec;
  for (int k = M - 1; k >= 1; --k) rec.at.push_back(x->s[k]);
  SweepState<0> y;
  SweepCall<0> c(load, options_.integrator, workspace_.cvode(options_.integrator.type), &y);
  c.R_tip = R_tip;
  c.rec = &rec;
  if (!kernels_->run<0>(*this, c) || static_cast<int>(rec.R.size()) != M - 1) return false;
  x->R.assign(M + 1, Mat3::Identity());
  x->n.assign(M + 1, Vec3::Zero());
  x->u.assign(M + 1, Vec3::Zero());
  x->R[M] = R_tip;
  for (int j = 0; j < M - 1; ++j) {
    const int k = M - 1 - j;
    x->R[k] = so3::orthonormalise(rec.R[j]);
    x->n[k] = rec.n[j];
    x->u[k] = rec.u[j];
  }
  return true;
}

void RodSolver::MsEval::add_sweep(const Nodes& x, int k, double Fs, int D, const SweepState<9>& y,
                                  const internal::SweepEnd<9>& end) {
  using O9 = RodOde<9, CosseratGeneral>;
  const int M = x.segments();
  const double h = (x.s[M] - x.s[0]) / M;
  const auto col = [M](int j) { return 3 + 9 * (M - 1 - j); };  // node j's unknowns (j = 1..M−1)
  const auto eta = [&y](int d) { return Vec3(y.segment<3>(O9::kBase + O9::kPerDir * d)); };
  sum_dp += y.segment<3>(0);
  const Mat3 Rm = Eigen::Map<const Mat3>(y.data() + 3);
  const int c0 = k == M - 1 ? 0 : col(k + 1);
  for (int d = 0; d < D; ++d) dP_X.col(c0 + d) += y.segment<3>(O9::kBase + O9::kPerDir * d + 6);
  if (k == 0) {
    const int row = 9 * (M - 1);
    const Vec3 r = so3::log(so3::orthonormalise(Rm));
    F.segment<3>(row) = r;
    const Mat3 Jri = so3::right_jacobian_inverse(r);
    for (int d = 0; d < D; ++d) J.block<3, 1>(row, c0 + d) = Jri * eta(d);
    R0 = Rm;
    return;
  }
  const int row = 9 * (M - 1 - k);
  const Vec3 r = so3::log(so3::orthonormalise(x.R[k].transpose() * Rm));
  F.segment<3>(row) = r;
  F.segment<3>(row + 3) = (end.n - x.n[k]) / Fs;
  F.segment<3>(row + 6) = h * (y.segment<3>(12) - x.u[k]);
  const Mat3 Jri = so3::right_jacobian_inverse(r);
  for (int d = 0; d < D; ++d) {
    J.block<3, 1>(row, c0 + d) = Jri * eta(d);
    J.block<3, 1>(row + 3, c0 + d) = end.dn.col(d) / Fs;
    J.block<3, 1>(row + 6, c0 + d) = h * y.segment<3>(O9::kBase + O9::kPerDir * d + 3);
  }
  const Mat3 node = -so3::right_jacobian_inverse(-r);
  J.block<3, 3>(row, col(k)) = node;
  J.block<3, 3>(row + 3, col(k) + 3) = -Mat3::Identity() / Fs;
  J.block<3, 3>(row + 6, col(k) + 6) = -h * Mat3::Identity();
  log_det_scale += std::log(std::abs(node.determinant())) + 3.0 * std::log(h / Fs);
}

// F, J, Σ Δp and its derivative, R⁻(0) at the node values x; every piece with step_multiplier times
// its steps (the Richardson estimate's second integration).
bool RodSolver::ms_evaluate(const Nodes& x, const Load& load, MsEval* e, int* rhs, int step_multiplier) {
  const int M = x.segments(), N = 3 + 9 * (M - 1);
  const double Fs = node_force_scale(model_);
  e->F.setZero(N);
  e->J.setZero(N, N);
  e->dP_X.setZero(3, N);
  e->sum_dp.setZero();
  e->log_det_scale = 0.0;
  e->ok = false;
  Direction dirs[9];
  for (int i = 0; i < 3; ++i) {
    dirs[i].eta_tip = Vec3::Unit(i);
    dirs[3 + i].dn0 = Vec3::Unit(i);
    dirs[6 + i].du0 = Vec3::Unit(i);
  }
  for (int k = M - 1; k >= 0; --k) {
    const int D = k == M - 1 ? 3 : 9;
    SweepState<9> y;
    internal::SweepEnd<9> end;
    bool ok;
    if (D == 3) {
      SweepState<3> y3;
      internal::SweepEnd<3> end3;
      SweepCall<3> c(load, options_.integrator, workspace_.cvode(options_.integrator.type), &y3);
      c.R_tip = x.R[M];
      c.dirs = dirs;
      c.s_end = x.s[k];
      c.to = &end3;
      c.step_multiplier = step_multiplier;
      ok = kernels_->run<3>(*this, c);
      *rhs += c.rhs;
      y.setZero();
      y.head<RodOde<3, CosseratGeneral>::kSize>() = y3;
      end.n = end3.n;
      end.dn.leftCols<3>() = end3.dn;
    } else {
      const internal::SweepStart from{x.s[k + 1], x.R[k + 1], x.u[k + 1], x.n[k + 1]};
      SweepCall<9> c(load, options_.integrator, workspace_.cvode(options_.integrator.type), &y);
      c.dirs = dirs;
      c.from = &from;
      c.s_end = x.s[k];
      c.to = &end;
      c.step_multiplier = step_multiplier;
      ok = kernels_->run<9>(*this, c);
      *rhs += c.rhs;
    }
    if (!ok || !y.allFinite()) return false;
    e->add_sweep(x, k, Fs, D, y, end);
  }
  e->ok = e->F.allFinite() && e->J.allFinite();
  return e->ok;
}

// The Richardson estimate of error_estimate() for multiple shooting: every piece once more with twice
// its steps; the change of the residuals F and of Σ Δp goes through the Jacobian.
double RodSolver::ms_error_estimate(const Nodes& x, const Load& load) {
  const double q = options_.integrator.type == IntegratorType::kRk4 ? 16.0 : 256.0;
  const double f = q / (q - 1.0);  // exact − coarse ≈ (fine − coarse)·2^p/(2^p − 1)
  MsEval coarse, fine;
  int rhs = 0;
  if (!ms_evaluate(x, load, &coarse, &rhs) || !ms_evaluate(x, load, &fine, &rhs, 2))
    return std::numeric_limits<double>::infinity();
  const Eigen::VectorXd dF = f * (fine.F - coarse.F);
  const Eigen::VectorXd dX = -coarse.J.partialPivLu().solve(dF);
  return (f * (fine.sum_dp - coarse.sum_dp) + coarse.dP_X * dX).norm();
}

// Multiple shooting to `target` with M segments: Newton from the warm solution's nodes, else along
// the load path from the unloaded shape (load_path.h). On success the tip frame goes through single
// shooting's evaluation (C^b, J_q, shape, warm start).
bool RodSolver::ms_solve(const Load& target, int M, RodSolution* sol) {
  sol->segments = M;
  MultipleShooting ms{*this, target, sol, M};
  Nodes rest_nodes;
  MultipleShooting::Point unloaded, start;
  if (!ms_nodes(unloaded_tip_, no_load(), M, &rest_nodes) || !ms.point(rest_nodes, no_load(), &unloaded)) {
    sol->message = "multiple shooting: the unloaded shape failed to integrate";
    return false;
  }
  Nodes warm_nodes;
  const bool warm = have_solution_ && ms_nodes(R_tip_, load_, M, &warm_nodes) && ms.point(warm_nodes, load_, &start);
  FoldTracker folds;
  bool ok = internal::reach_equilibrium(ms, warm ? start : unloaded, warm, unloaded, &folds);
  if (ok && accuracy_check_applies()) {
    sol->error_estimate = ms_error_estimate(ms.x, target);
    if (!accurate_enough(sol, M)) return false;
  }
  if (!ok) {
    if (sol->message.empty()) sol->message = "did not converge";
    sol->message = "multiple shooting (" + std::to_string(M) + " segments): " + sol->message;
    return false;
  }
  folds.note(ms.det);
  // The tip frame through single shooting's evaluation (C^b, J_q, shape, warm start); the pose and
  // the residual are multiple shooting's own.
  const Mat3 R_tip = ms.x.R[M];
  const Eval single = evaluate(R_tip, target, &sol->rhs_evaluations);
  if (!single.ok) {
    sol->message = "multiple shooting converged, but one sweep from its tip frame failed to integrate";
    return false;
  }
  sol->converged = true;
  sol->message.clear();
  sol->tip_rotation = so3::orthonormalise(ms.e.R0.transpose() * R_tip);
  sol->tip_position = -ms.e.R0.transpose() * ms.e.sum_dp;
  sol->jacobian_det = ms.det;
  internal::report_folds(folds, sol);
  if (single.r.norm() > 1e-6)
    sol->warning += std::string(sol->warning.empty() ? "" : "; ") +
                    "multiple shooting at λL = " + std::to_string(growth_estimate(target.q, target.wrench)) +
                    ": C^b, J_q and the shape come from one sweep from the tip, which reaches the base only to " +
                    std::to_string(single.r.norm()) + " rad";
  commit(R_tip, target, single, *sol);
  return true;
}

}  // namespace rod
}  // namespace hydrojet
