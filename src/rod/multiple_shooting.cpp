// Multiple shooting for the rod BVP (the fallback of ShootingSolver::solve, or forced with
// ShootingOptions::shooting_segments ≥ 2).
//
// Nodes s_k = k L / M, k = 0..M. Unknowns X = [ξ_M (3); (η_k, δu_k) for k = M−1 down to 1]: the tip
// orientation R_M·exp(ξ̂) and the node states R_k·exp(η̂_k), u_k + δu_k. Segment k runs from node
// k+1 down to node k, starting at (p = 0, R_{k+1}, u_{k+1}) (the tip segment at u(L) = ũ + K⁻¹ l_b)
// with n(s) from the tip orientation R_M, as in single shooting. Residuals (all in rad):
//   c_k = [log(R_kᵀ R⁻(s_k)); h (u⁻(s_k) − u_k)],  k = 1..M−1,  h = L / M;
//   r_0 = log R⁻(0) (the base condition).
// The Jacobian comes from forward sensitivities per segment (9 directions: ξ_M, η_{k+1}, δu_{k+1}),
// the node columns in closed form (−J_l⁻¹(c_k), −h I). Damped Newton on ‖F‖ on the load path of
// single shooting (load_path.h). The positions decouple (n(s) is closed form), so the tip
// position is −R⁻(0)ᵀ Σ_k Δp_k. C^b follows from the implicit-function theorem on F(X, w) = 0 with
// 6 more directions per segment. This path allocates (Eigen dynamic matrices): it is a fallback.
// One variant (the general Cosserat form) serves every model here.
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "hydrojet_control/rod/shooting_solver.h"
#include "load_path.h"
#include "rod_integration.h"
#include "solver_templates.h"

namespace hydrojet {
namespace rod {

using internal::FoldTracker;

struct ShootingSolver::MsEval {
  Eigen::VectorXd F;
  Eigen::MatrixXd J;
  Eigen::MatrixXd Fw;                             ///< ∂F/∂w (compliance only)
  Eigen::Matrix<double, 3, Eigen::Dynamic> dP_X;  ///< ∂(Σ Δp)/∂X (compliance only)
  Eigen::Matrix<double, 3, 6> dP_w;               ///< ∂(Σ Δp)/∂w (compliance only)
  Mat3 R0 = Mat3::Identity();                     ///< R⁻(0)
  Vec3 sum_dp = Vec3::Zero();                     ///< Σ Δp_k = p(0) − p(L), integration frame
  double det_scale = 1.0;                         ///< det of the node block of J (J's det / this = det ∂r/∂x)
  bool ok = false;

  /// Zero F and J for M segments (and the compliance blocks with_wrench).
  void reset(int M, bool with_wrench) {
    const int N = 6 * (M - 1) + 3;
    F.setZero(N);
    J.setZero(N, N);
    if (with_wrench) {
      Fw.setZero(N, 6);
      dP_X.setZero(3, N);
      dP_w.setZero();
    }
    sum_dp.setZero();
    det_scale = 1.0;
    ok = false;
  }
  /// Columns of node k's unknowns (η_k, δu_k) in X; also the row of c_k's δu part.
  static int node_col(int M, int k) { return 3 + 6 * (M - 1 - k); }
  /// Adds segment k (integrated from node k+1 down to s_k, end state y): its residual rows and
  /// their columns.
  template <class Dir, class Ode>
  void add_segment(const Nodes& x, int k, double h, const typename Ode::State& y) {
    const int M = x.segments;
    const bool tip = k + 1 == M;
    const int row = 6 * (M - 1 - k);  // for k = 0 this is the base row block 6(M−1)
    sum_dp += y.template segment<3>(0);
    const Mat3 Jri = add_residual(x, k, row, h, Eigen::Map<const Mat3>(y.data() + 3), Vec3(y.template segment<3>(12)));
    auto column = [&](int d, int col, bool wrench) {
      const Eigen::Matrix<double, 9, 1> s = y.template segment<9>(Ode::kBase + Ode::kPerDir * d);
      add_column(k, row, h, Jri, s, col, wrench, Dir::kWithWrench);
    };
    for (int i = 0; i < 3; ++i) {
      column(i, i, false);
      if (!tip) {
        column(Dir::kEta + i, node_col(M, k + 1) + i, false);
        column(Dir::kDu + i, node_col(M, k + 1) + 3 + i, false);
      }
      if (Dir::kWithWrench) {
        column(Dir::kF + i, i, true);
        if (tip) column(Dir::kL + i, 3 + i, true);
      }
    }
  }
  /// Residual rows of segment k at s_k (from `row`): for k ≥ 1 node k's continuity c_k and its node
  /// columns, for k = 0 the base condition r_0. Returns J_r⁻¹ of the rotation residual.
  Mat3 add_residual(const Nodes& x, int k, int row, double h, const Mat3& Rm, const Vec3& um) {
    if (k == 0) {
      const Vec3 r = so3::log(so3::orthonormalize(Rm));
      F.segment<3>(row) = r;
      R0 = Rm;
      return so3::right_jacobian_inverse(r);
    }
    const Vec3 r = so3::log(so3::orthonormalize(x.R[k].transpose() * Rm));
    F.segment<3>(row) = r;
    F.segment<3>(row + 3) = h * (um - x.u[k]);
    const Mat3 Jli = so3::right_jacobian_inverse(-r);
    const int c = node_col(x.segments, k);
    J.block<3, 3>(row, c) = -Jli;
    J.block<3, 3>(row + 3, c + 3) = -h * Mat3::Identity();
    det_scale *= Jli.determinant() * h * h * h;
    return so3::right_jacobian_inverse(r);
  }
  /// Adds the change of segment k's rows along one start direction (η, δu, δp at s_k in s) to
  /// column `col` of J, or of Fw for a wrench direction.
  void add_column(int k, int row, double h, const Mat3& Jri, const Eigen::Matrix<double, 9, 1>& s, int col, bool wrench,
                  bool with_wrench) {
    Eigen::MatrixXd& A = wrench ? Fw : J;
    A.block<3, 1>(row, col) += Jri * s.head<3>();
    if (k >= 1) A.block<3, 1>(row + 3, col) += h * s.segment<3>(3);
    if (!with_wrench) return;
    if (wrench) {
      dP_w.col(col) += s.tail<3>();
    } else {
      dP_X.col(col) += s.tail<3>();
    }
  }
};

/// Multiple shooting on the load path (load_path.h): the unknowns are the node states. A cold
/// start takes the load path from the unloaded shape directly.
struct ShootingSolver::MultipleShooting {
  using Unknowns = Nodes;
  using Load = ShootingSolver::Load;
  using Point = internal::PathPoint<Nodes, Load>;
  using Saved = RodSolution;
  static constexpr bool kNewtonFromUnloaded = false;

  ShootingSolver& solver;
  Load target;
  RodSolution* sol;
  Nodes x;
  double det = 0.0;
  Vec3 tip = Vec3::Zero();

  const ShootingOptions& options() const { return solver.settings_; }
  double length() const { return solver.model_.rod.length; }
  double growth() const { return solver.growth_estimate(target.wrench); }
  bool newton(Nodes* n, const Load& load, double* d, Vec3* p) {
    if (!solver.ms_newton(n, load, sol, d)) return false;
    *p = sol->tip_position;
    return true;
  }
  bool turned_far(const Nodes& a, const Nodes& b) const {
    for (int k = 1; k <= a.segments; ++k)
      if (so3::log(a.R[k].transpose() * b.R[k]).norm() > options().max_step) return true;
    return false;
  }
  Saved save() const { return *sol; }
  void restore(const Saved& direct) { *sol = direct; }

  /// Newton from the stored solution (on M segments; multiple or single shooting) → load
  /// continuation from it → from the unloaded shape.
  bool reach_equilibrium(int M, FoldTracker* folds) {
    ShootingSolver& s = solver;
    const Point unloaded{s.ms_unloaded_nodes(M), Load::none(), s.unloaded_.tip_position, s.unloaded_.det};
    Point start{Nodes(), s.load_, s.tip_pos_, s.det_};
    bool warm = false;
    if (s.have_solution_) {
      start.x = s.ms_stored_nodes(M);
      warm = start.x.R.size() == static_cast<size_t>(M + 1);
      for (const Mat3& R : start.x.R) warm = warm && R.allFinite();
    }
    return internal::reach_equilibrium(*this, warm ? start : unloaded, warm, unloaded, folds);
  }
};

namespace {
/// Direction layout of one segment's sensitivities. Newton: ξ 0–2, η 3–5, δu 6–8. Compliance: ξ 0–2,
/// f_b 3–5, η 6–8, δu 9–11, l_b 12–14 (only ξ and f_b carry a δn).
template <bool kWrench>
struct MsDirections {
  static constexpr bool kWithWrench = kWrench;
  static constexpr int kCount = kWrench ? 15 : 9;
  static constexpr int kEta = kWrench ? 6 : 3, kDu = kWrench ? 9 : 6, kF = 3, kL = 12;
};

/// Start state of the segment from node k+1 down: p = 0, the node's (R, u), and a unit seed per
/// direction: ξ_M (which also rotates the tip segment's start) and l_b (u(L) changes by K⁻¹ e_i) at
/// the tip, η_{k+1} and δu_{k+1} elsewhere.
template <class Dir, class Ode>
void segment_start(const Ode& ode, const Mat3& R, const Vec3& u, bool tip, typename Ode::State* y) {
  y->setZero();
  Eigen::Map<Mat3>(y->data() + 3) = R;
  y->template segment<3>(12) = u;
  for (int i = 0; i < 3; ++i) {
    if (tip) {
      (*y)[Ode::kBase + Ode::kPerDir * i + i] = 1.0;
      if (Dir::kWithWrench) (*y)[Ode::kBase + Ode::kPerDir * (Dir::kL + i) + 3 + i] = ode.k_inv[i];
    } else {
      (*y)[Ode::kBase + Ode::kPerDir * (Dir::kEta + i) + i] = 1.0;
      (*y)[Ode::kBase + Ode::kPerDir * (Dir::kDu + i) + 3 + i] = 1.0;
    }
  }
}
}  // namespace

int ShootingSolver::auto_segments(const Load& load) const {
  // Pieces of growth exp(λL/M) ≈ e² each; at least 4 (the fallback also helps with nonlinearity).
  const double g = growth_estimate(load.wrench);
  return std::clamp(static_cast<int>(std::ceil(g / 2.0)), 4, 64);
}

ShootingSolver::Nodes ShootingSolver::ms_unloaded_nodes(int M) const {
  Nodes x;
  x.segments = M;
  x.R.resize(M + 1);
  x.u.assign(M + 1, model_.rod.precurvature);
  for (int k = 0; k <= M; ++k) x.R[k] = so3::exp(model_.rod.length * k / M * model_.rod.precurvature);
  return x;
}

ShootingSolver::Nodes ShootingSolver::ms_stored_nodes(int M) {
  if (!multiple_) return ms_nodes_from_tip(R_tip_, load_, M);
  return nodes_.segments == M ? nodes_ : ms_resample(nodes_, load_, M);
}

ShootingSolver::Nodes ShootingSolver::ms_nodes_from_tip(const Mat3& R_tip, const Load& load, int M) {
  using Ode = RodOde<0, CosseratGeneral>;
  Ode ode;
  setup_ode(&ode, R_tip, load);
  Ode::State y;
  internal::init_tip_state(ode, R_tip, load.wrench.moment, &y);
  Nodes x;
  x.segments = M;
  x.R.resize(M + 1);
  x.u.resize(M + 1);
  x.R[M] = R_tip;
  x.u[M] = y.segment<3>(12);
  const double L = model_.rod.length;
  IntegratorOptions is = settings_.integrator;
  is.steps = std::max(1, (settings_.integrator.steps + M - 1) / M);
  for (int k = M - 1; k >= 0; --k) {
    workspace_.integrate(ode, L * (k + 1) / M, L * k / M, &y, is);
    x.R[k] = so3::orthonormalize(Eigen::Map<const Mat3>(y.data() + 3));
    x.u[k] = y.segment<3>(12);
  }
  return x;
}

ShootingSolver::Nodes ShootingSolver::ms_resample(const Nodes& x, const Load& load, int M) {
  // Node values at s_j = j L / M from a multiple-shooting solution on other nodes: integrate each old
  // segment from its upper node down to the new nodes inside it.
  using Ode = RodOde<0, CosseratGeneral>;
  const int Mo = x.segments;
  const double L = model_.rod.length;
  Ode ode;
  setup_ode(&ode, x.R[Mo], load);
  Nodes y;
  y.segments = M;
  y.R.resize(M + 1);
  y.u.resize(M + 1);
  y.R[M] = x.R[Mo];
  y.u[M] = ode.u_tilde + ode.k_inv.cwiseProduct(load.wrench.moment);
  IntegratorOptions is = settings_.integrator;
  for (int j = M - 1; j >= 1; --j) {
    const double sj = L * j / M;
    const int k = std::min(Mo - 1, static_cast<int>(std::floor(sj / L * Mo)));  // old segment [s_k, s_k+1]
    Ode::State st;
    internal::init_tip_state(ode, x.R[k + 1], load.wrench.moment, &st);
    if (k + 1 < Mo) st.segment<3>(12) = x.u[k + 1];
    const double s0 = L * (k + 1) / Mo;
    is.steps = std::max(1, static_cast<int>(std::ceil(settings_.integrator.steps * (s0 - sj) / L - 1e-9)));
    workspace_.integrate(ode, s0, sj, &st, is);
    y.R[j] = so3::orthonormalize(Eigen::Map<const Mat3>(st.data() + 3));
    y.u[j] = st.segment<3>(12);
  }
  y.R[0] = Mat3::Identity();
  y.u[0] = y.u[1];
  return y;
}

template <bool kWithWrench>
bool ShootingSolver::ms_assemble(const Nodes& x, const Load& load, MsEval* e, int* rhs, int steps_per_segment) {
  using Dir = MsDirections<kWithWrench>;
  using Ode = RodOde<Dir::kCount, CosseratGeneral>;
  const int M = x.segments;
  const double L = model_.rod.length, h = L / M;
  e->reset(M, kWithWrench);
  IntegratorOptions is = settings_.integrator;
  is.steps = steps_per_segment > 0 ? steps_per_segment : std::max(1, (settings_.integrator.steps + M - 1) / M);
  const Mat3& RM = x.R[M];
  Ode ode;
  setup_ode(&ode, RM, load);
  for (int i = 0; i < 3; ++i) {
    ode.dn.col(i) = RM * Vec3::Unit(i).cross(load.wrench.force);
    if (kWithWrench) ode.dn.col(Dir::kF + i) = RM.col(i);
  }
  typename Ode::State y;
  for (int k = M - 1; k >= 0; --k) {
    const bool tip = k + 1 == M;
    const Vec3 u = tip ? Vec3(ode.u_tilde + ode.k_inv.cwiseProduct(load.wrench.moment)) : x.u[k + 1];
    segment_start<Dir>(ode, x.R[k + 1], u, tip, &y);
    const IntegrationStats st = workspace_.integrate(ode, L * (k + 1) / M, L * k / M, &y, is);
    *rhs += st.rhs_evaluations;
    if (!st.ok || !y.allFinite()) return false;
    e->add_segment<Dir, Ode>(x, k, h, y);
  }
  e->ok = e->F.allFinite() && e->J.allFinite();
  return e->ok;
}

bool ShootingSolver::ms_newton(Nodes* x, const Load& load, RodSolution* sol, double* det) {
  const int M = x->segments;
  const double h = model_.rod.length / M;
  MsEval e;
  if (!ms_assemble<false>(*x, load, &e, &sol->rhs_evaluations)) {
    sol->message = "integration failed (non-finite state or step limit)";
    return false;
  }
  auto apply = [&](const Nodes& from, const Eigen::VectorXd& step, double alpha) {
    Nodes t = from;
    t.R[M] = so3::orthonormalize(from.R[M] * so3::exp(alpha * step.head<3>()));
    for (int k = 1; k < M; ++k) {
      const int c = MsEval::node_col(M, k);
      t.R[k] = so3::orthonormalize(from.R[k] * so3::exp(alpha * step.segment<3>(c)));
      t.u[k] = from.u[k] + alpha * step.segment<3>(c + 3);
    }
    return t;
  };
  for (int it = 0;; ++it) {
    sol->residual = e.F.norm();
    if (sol->residual <= settings_.residual_tolerance) {
      const Eigen::PartialPivLU<Eigen::MatrixXd> lu(e.J);
      *det = lu.determinant() / e.det_scale;
      sol->tip_rotation = so3::orthonormalize(e.R0.transpose() * x->R[M]);
      sol->tip_position = -e.R0.transpose() * e.sum_dp;
      return true;
    }
    if (it >= settings_.max_iterations) {
      sol->message = "Newton iteration limit reached";
      return false;
    }
    ++sol->iterations;
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(e.J);
    Eigen::VectorXd step = -lu.solve(e.F);
    if (!step.allFinite()) {
      sol->message = "singular multiple-shooting Jacobian";
      return false;
    }
    // Cap every rotation part at max_step [rad] and every curvature part at max_step / h.
    double worst = step.head<3>().norm();
    for (int k = 1; k < M; ++k) {
      const int c = MsEval::node_col(M, k);
      worst = std::max({worst, step.segment<3>(c).norm(), h * step.segment<3>(c + 3).norm()});
    }
    if (worst > settings_.max_step) step *= settings_.max_step / worst;
    bool accepted = false;
    double alpha = 1.0;
    for (int k = 0; k < 12; ++k, alpha *= 0.5) {
      const Nodes t = apply(*x, step, alpha);
      MsEval et;
      if (ms_assemble<false>(t, load, &et, &sol->rhs_evaluations) &&
          et.F.norm() < (1.0 - 1e-4 * alpha) * sol->residual) {
        *x = t;
        e = std::move(et);
        accepted = true;
        break;
      }
    }
    if (!accepted) {
      sol->message = "line search failed (no descent)";
      return false;
    }
  }
}

double ShootingSolver::ms_error_estimate(const Nodes& x, const Load& load) {
  // The Richardson estimate of error_t() for multiple shooting: every segment once more with half
  // (or twice) its steps; the change of the residuals F and of Σ Δp goes through the Jacobian.
  const int M = x.segments;
  const int n = std::max(1, (settings_.integrator.steps + M - 1) / M);
  const double q = settings_.integrator.type == IntegratorType::kRk4 ? 16.0 : 256.0;
  const int other = n % 2 == 0 ? n / 2 : 2 * n;
  const double f = n % 2 == 0 ? -1.0 / (q - 1.0) : q / (q - 1.0);
  MsEval fine, coarse;
  int rhs = 0;
  if (!ms_assemble<true>(x, load, &fine, &rhs) || !ms_assemble<false>(x, load, &coarse, &rhs, other))
    return std::numeric_limits<double>::infinity();
  const Eigen::VectorXd dF = f * (coarse.F - fine.F);
  const Eigen::VectorXd dX = -Eigen::PartialPivLU<Eigen::MatrixXd>(fine.J).solve(dF);
  const Vec3 dsum = f * (coarse.sum_dp - fine.sum_dp) + fine.dP_X * dX;
  return dsum.norm();
}

bool ShootingSolver::ms_solve(const Load& target, int M, RodSolution* sol) {
  sol->segments = M;
  FoldTracker folds;
  MultipleShooting ms{*this, target, sol};
  sol->converged = converged(ms.reach_equilibrium(M, &folds), *sol);
  if (!sol->converged) {
    if (sol->message.empty()) sol->message = "did not converge";
    return false;
  }
  if (accuracy_check_applies()) {
    sol->error_estimate = ms_error_estimate(ms.x, target);
    if (!accurate_enough(sol, M)) return false;
  }
  folds.note(ms.det);
  sol->jacobian_det = ms.det;
  sol->message.clear();
  report_folds(folds, sol);
  commit_multiple(ms.x, target, ms.det, *sol);
  return true;
}

void ShootingSolver::commit_multiple(const Nodes& x, const Load& load, double det, const RodSolution& sol) {
  have_solution_ = true;
  multiple_ = true;
  nodes_ = x;
  R_tip_ = x.R[x.segments];
  tip_pos_ = sol.tip_position;
  load_ = load;
  det_ = det;
}

bool ShootingSolver::ms_compliance(Mat6* C) {
  MsEval e;
  int rhs = 0;
  if (!ms_assemble<true>(nodes_, load_, &e, &rhs)) return false;
  const Eigen::PartialPivLU<Eigen::MatrixXd> lu(e.J);
  const Eigen::MatrixXd dX_dw = -lu.solve(e.Fw);
  const Eigen::Matrix<double, 3, 6> dsum = e.dP_X * dX_dw + e.dP_w;
  const Mat3& RM = nodes_.R[nodes_.segments];
  // ω = dξ_M/dw; p_T = −R(0)ᵀ Σ Δp with R(0) = I along the solution: v = R_Mᵀ δp_T = −R_Mᵀ δΣ.
  C->topRows<3>() = -RM.transpose() * dsum;
  C->bottomRows<3>() = dX_dw.topRows<3>();
  return C->allFinite();
}

}  // namespace rod
}  // namespace hydrojet
