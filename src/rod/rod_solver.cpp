#include "hydrojet_control/rod/rod_solver.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "damped_newton.h"
#include "hydrojet_control/rod/cvode_integrator.h"
#include "kinsol_workspace.h"
#include "load_path.h"
#include "rod_integration.h"
#include "sweep.h"

namespace hydrojet {
namespace rod {

using internal::Direction;
using internal::FoldTracker;
using internal::Recorder;
using internal::SweepCall;
using internal::SweepState;
using Load = RodSolver::Load;

/// The load a fraction t of the way from `from` to `to` (load_path.h finds it by argument lookup).
Load load_between(const Load& from, const Load& to, double t) {
  Load l;
  l.wrench.force = from.wrench.force + t * (to.wrench.force - from.wrench.force);
  l.wrench.moment = from.wrench.moment + t * (to.wrench.moment - from.wrench.moment);
  l.q = from.q + t * (to.q - from.q);
  l.gravity_scale = from.gravity_scale + t * (to.gravity_scale - from.gravity_scale);
  return l;
}

// ---------------------------------------------------------------------------------------------
// The model

RodSolver::Workspace::Workspace() = default;
RodSolver::Workspace::~Workspace() = default;

CvodeWorkspace* RodSolver::Workspace::cvode(IntegratorType t) {
  if (t != IntegratorType::kCvodeAdams && t != IntegratorType::kCvodeBdf) return nullptr;
  if (!cvode_) cvode_.reset(new CvodeWorkspace);
  return cvode_.get();
}

RodSolver::RodSolver(const RodModel& model, const ShootingOptions& options) : model_(model), options_(options) {
  if (const std::string why = model_.validate(); !why.empty()) throw std::invalid_argument("rod model: " + why);
  build_stations();
  select_kernels();
  update_unloaded_shape();
}

RodSolver::~RodSolver() = default;
RodSolver::RodSolver(const RodSolver& other) = default;
RodSolver& RodSolver::operator=(const RodSolver& other) = default;

void RodSolver::set_model(const RodModel& model) {
  if (const std::string why = model.validate(); !why.empty()) throw std::invalid_argument("rod model: " + why);
  model_ = model;
  build_stations();
  select_kernels();
  update_unloaded_shape();
  reset();
}

void RodSolver::set_options(const ShootingOptions& options) {
  options_ = options;
  select_kernels();
  update_unloaded_shape();
}

void RodSolver::reset() { have_solution_ = have_tangent_ = false; }

Load RodSolver::no_load() const {
  Load l;
  l.q = InputVector::Zero(input_count());
  l.gravity_scale = 0.0;
  return l;
}

// Stations, tip first: s = L (tip mass, loads and actuators there), then every segment end, load and
// actuator arc length below it (merged when closer than 1e-12 L).
void RodSolver::build_stations() {
  const double L = model_.length();
  const double tol = 1e-12 * L;
  std::vector<double> cuts{L};
  double s = 0.0;
  for (size_t k = 0; k + 1 < model_.segments.size(); ++k) cuts.push_back(s += model_.segments[k].length);
  for (const PointLoad& l : model_.loads) cuts.push_back(std::min(l.at, L));
  for (const Actuator& a : model_.actuators) cuts.push_back(std::min(a.at, L));
  std::sort(cuts.begin(), cuts.end(), std::greater<double>());
  stations_.clear();
  for (double c : cuts)
    if (stations_.empty() || stations_.back().s - c > tol) {
      Station st;
      st.s = c;
      stations_.push_back(st);
    }
  const auto station_at = [&](double at) -> Station& {
    for (Station& st : stations_)
      if (std::abs(st.s - std::min(at, L)) <= tol) return st;
    return stations_.front();  // not reached: every arc length is a cut
  };
  // The segment just below each station: the one whose span (start, end] holds s.
  for (Station& st : stations_) {
    double end = 0.0;
    st.segment_below = static_cast<int>(model_.segments.size()) - 1;
    for (size_t k = 0; k < model_.segments.size(); ++k) {
      end += model_.segments[k].length;
      if (st.s <= end + tol) {
        st.segment_below = static_cast<int>(k);
        break;
      }
    }
  }
  stations_.front().mass += model_.tip_mass;
  for (const PointLoad& l : model_.loads) {
    Station& st = station_at(l.at);
    st.mass += l.mass;
    (l.frame == LoadFrame::kBody ? st.f_body : st.f_base) += l.force;
    (l.frame == LoadFrame::kBody ? st.l_body : st.l_base) += l.moment;
  }
  for (size_t j = 0; j < model_.actuators.size(); ++j)
    station_at(model_.actuators[j].at).actuators.push_back(static_cast<int>(j));
}

// With no load u(s) = ũ(s) piecewise, so the unloaded tip frame is the product of the segments' arcs.
void RodSolver::update_unloaded_shape() {
  unloaded_tip_.setIdentity();
  for (const RodSegment& g : model_.segments) unloaded_tip_ = unloaded_tip_ * so3::exp(g.length * g.precurvature);
  int rhs = 0;
  const Eval e = evaluate(unloaded_tip_, no_load(), &rhs);
  unloaded_det_ = e.ok ? e.J.determinant() : std::nan("");
  unloaded_pos_ = e.ok ? Vec3(-e.R0.transpose() * e.p0) : Vec3::Zero();
}

// A bound on |n(s)| [N]: every force on the rod (tip wrench, inputs, point loads, weights; the tip
// moment counted as |l|/L).
double RodSolver::load_bound(const InputVector& q, const TipWrench& tip) const {
  const double g = model_.gravity.norm();
  double n = tip.force.norm() + tip.moment.norm() / model_.length() + model_.tip_mass * g;
  for (int j = 0; j < q.size(); ++j) n += std::abs(q[j]);
  for (const PointLoad& l : model_.loads) n += l.force.norm() + l.mass * g;
  for (const RodSegment& s : model_.segments) n += s.linear_density * g * s.length;
  return n;
}

double RodSolver::growth_estimate(const InputVector& q, const TipWrench& tip) const {
  double ei = 1e300;
  for (const RodSegment& s : model_.segments) ei = std::min(ei, std::min(s.stiffness.x(), s.stiffness.y()));
  return model_.length() * std::sqrt(load_bound(q, tip) / ei);
}

// ---------------------------------------------------------------------------------------------
// Single shooting

RodSolver::Eval RodSolver::evaluate(const Mat3& R_tip, const Load& load, int* rhs) {
  Direction dirs[3];
  for (int i = 0; i < 3; ++i) dirs[i].eta_tip = Vec3::Unit(i);
  SweepState<3> y;
  SweepCall<3> c(load, options_.integrator, workspace_.cvode(options_.integrator.type), &y);
  c.R_tip = R_tip;
  c.dirs = dirs;
  Eval e;
  e.ok = kernels_->run<3>(*this, c);
  *rhs += c.rhs;
  if (!e.ok) return e;
  using O = RodOde<3, CosseratGeneral>;
  e.R0 = Eigen::Map<const Mat3>(y.data() + 3);
  e.p0 = y.segment<3>(0);
  Mat3 deta0;
  for (int i = 0; i < 3; ++i) {
    deta0.col(i) = y.segment<3>(O::kBase + O::kPerDir * i);
    e.dp0.col(i) = y.segment<3>(O::kBase + O::kPerDir * i + 6);
  }
  // Shooting residual, eq. (15): R(0) = I  <=>  log R(0) = 0.
  e.r = so3::log(so3::orthonormalise(e.R0));
  e.J = so3::right_jacobian_inverse(e.r) * deta0;
  e.ok = e.r.allFinite() && e.J.allFinite();
  return e;
}

namespace {

/// True when every piece of the model (between stations) gets an even number of fixed steps.
bool pieces_even(const RodSolver& s) {
  const auto& st = s.stations();
  const double L = s.model().length();
  for (size_t i = 0; i < st.size(); ++i) {
    const double lo = i + 1 < st.size() ? st[i + 1].s : 0.0;
    if (internal::piece_steps(s.options().integrator.steps, st[i].s - lo, L) % 2 != 0) return false;
  }
  return true;
}

}  // namespace

// Richardson estimate of the discretisation error of the converged fixed-step solve: integrate the
// state alone with half the steps on every piece (or twice, when a piece's count is odd), compare
// R(0), p(0), and carry the difference through the shooting problem: the exact integrator would
// leave the residual δr ≈ f·log(R0ᵀR0'), which Newton removes with δx = −J⁻¹δr, moving the tip by
// δp ≈ f·(p0' − p0) + ∂p0/∂x·δx.
double RodSolver::error_estimate(const Mat3& R_tip, const Load& load, const Eval& e) {
  const double q = options_.integrator.type == IntegratorType::kRk4 ? 16.0 : 256.0;  // 2^order
  const bool halve = pieces_even(*this);
  const double f = halve ? -1.0 / (q - 1.0)  // exact − fine ≈ (fine − coarse)/(2^p − 1)
                         : q / (q - 1.0);    // exact − coarse ≈ (fine − coarse)·2^p/(2^p − 1)
  SweepState<0> y;
  SweepCall<0> c(load, options_.integrator, workspace_.cvode(options_.integrator.type), &y);
  c.R_tip = R_tip;
  (halve ? c.step_divisor : c.step_multiplier) = 2;
  if (!kernels_->run<0>(*this, c)) return std::numeric_limits<double>::infinity();
  const Mat3 R0o = Eigen::Map<const Mat3>(y.data() + 3);
  const Vec3 dr = f * so3::log(so3::orthonormalise(e.R0.transpose() * R0o));
  const Vec3 dp = f * (y.segment<3>(0) - e.p0);
  const Vec3 dx = -e.J.partialPivLu().solve(dr);
  return (dp + e.dp0 * dx).norm();
}

namespace {

/// Single shooting's unknown for damped_newton: the tip orientation, moved by R·exp(α x̂).
template <class Evaluate>
struct TipOrientationNewton {
  using Step = Vec3;
  Evaluate evaluate;
  // (templates: the evaluation is the solver's private Eval)
  template <class Eval>
  static double residual(const Eval& e) {
    return e.r.norm();
  }
  template <class Eval>
  static bool step(const Eval& e, Vec3* dx) {
    *dx = -Eigen::PartialPivLU<Mat3>(e.J).solve(e.r);
    return dx->allFinite() && std::abs(e.J.determinant()) >= 1e-300;
  }
  static double size(const Vec3& dx) { return dx.norm(); }
  static Mat3 moved(const Mat3& R, const Vec3& dx, double a) { return R * so3::exp(a * dx); }
  static Mat3 accepted(const Mat3& R) { return so3::orthonormalise(R); }
};

template <class Evaluate>
TipOrientationNewton<Evaluate> tip_orientation_newton(Evaluate f) {
  return {f};
}

}  // namespace

bool RodSolver::newton(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last) {
  if (options_.newton == NewtonBackend::kKinsol) return newton_kinsol(R_tip, load, sol, last);
  auto p = tip_orientation_newton([&](const Mat3& R) { return evaluate(R, load, &sol->rhs_evaluations); });
  return internal::damped_newton(p, options_, R_tip, sol, last);
}

// ---------------------------------------------------------------------------------------------
// The solve

/// Single shooting on the load path (load_path.h): the unknown is the tip orientation R(L) (the x of
/// eq. 15); Newton's last evaluation `e` describes the equilibrium reached.
struct RodSolver::Shooting : internal::TipOrientationShooting<Shooting, Load, Eval> {
  Shooting(RodSolver& s, const Load& t, RodSolution* out) : TipOrientationShooting(t, out), solver(s) {}

  RodSolver& solver;

  const ShootingOptions& options() const { return solver.options_; }
  double length() const { return solver.model_.length(); }
  double growth() const { return solver.growth_estimate(target.q, target.wrench); }
  bool newton_at(Mat3* R, const Load& load, Eval* last) { return solver.newton(R, load, sol, last); }
  Point unloaded() const {
    return {solver.unloaded_tip_, solver.no_load(), solver.unloaded_pos_, solver.unloaded_det_};
  }
};

RodSolution RodSolver::solve(const InputVector& q, const TipWrench& tip) {
  RodSolution sol;
  if (q.size() != input_count()) {
    sol.message = "expected " + std::to_string(input_count()) + " actuator input(s), got " + std::to_string(q.size());
    sol.residual = std::nan("");
    return remember(sol);
  }
  if (!q.allFinite() || !tip.force.allFinite() || !tip.moment.allFinite()) {
    sol.message = "non-finite actuator input or tip wrench";
    sol.residual = std::nan("");
    return remember(sol);
  }
  Load target;
  target.wrench = tip;
  target.q = q;
  const int seg = options_.shooting_segments;
  // Multiple shooting first when forced (shooting_segments ≥ 2) or past single shooting's reach.
  const bool ms_first = multiple_shooting_first(target);
  if (ms_first) {
    RodSolution ms;
    if (ms_solve(target, seg >= 2 ? seg : auto_segments(target), &ms) || seg >= 2) return remember(ms);
    sol.message = ms.message + "; ";
  }
  // Single shooting: Newton from the warm solution (or the unloaded shape) → load continuation from
  // the warm solution → from the unloaded shape.
  const bool cold = !have_solution_;
  FoldTracker folds;
  Shooting p{*this, target, &sol};
  const Shooting::Point unloaded = p.unloaded();
  const Shooting::Point start = have_solution_ ? Shooting::Point{R_tip_, load_, tip_pos_, det_} : unloaded;
  Mat3 guess;
  const bool predicted = predict(target, &guess);
  const bool ok = internal::reach_equilibrium(p, start, have_solution_, unloaded, &folds, predicted ? &guess : nullptr);
  if (finish(&p, ok, &folds)) {
    if (cold) load_from_rest_if_unstable(target, &sol);
    return remember(sol);
  }
  // A solve refused by the accuracy check gets no multiple-shooting retry: it would use the same steps.
  if (!std::isnan(sol.error_estimate) || seg == 1 || ms_first) return remember(sol);
  // Multiple shooting when single shooting failed (automatic mode).
  RodSolution ms;
  ms.iterations = sol.iterations;
  ms.continuation_steps = sol.continuation_steps;
  ms.rhs_evaluations = sol.rhs_evaluations;
  const int M = auto_segments(target);
  if (ms_solve(target, M, &ms)) return remember(ms);
  sol.message += "; multiple shooting (" + std::to_string(M) + " segments): " + ms.message;
  return remember(sol);
}

// The first-order prediction of the tip rotation at `target` from the stored solution and its tangent
// (the compliance's ω rows): R(L)·exp(dx/dw Δw + dx/dq Δq). None without a tangent, at a changed
// gravity scale, or for a step longer than max_step (the load path's business).
bool RodSolver::predict(const Load& target, Mat3* guess) const {
  if (!have_solution_ || !have_tangent_ || target.gravity_scale != load_.gravity_scale) return false;
  Vec6 dw;
  dw << target.wrench.force - load_.wrench.force, target.wrench.moment - load_.wrench.moment;
  Vec3 dx = dx_dw_ * dw;
  if (dx_dq_.cols() > 0) dx += dx_dq_ * (target.q - load_.q);
  if (!dx.allFinite() || dx.norm() > options_.max_step) return false;
  *guess = R_tip_ * so3::exp(dx);
  return true;
}

bool RodSolver::multiple_shooting_first(const Load& target) const {
  const int seg = options_.shooting_segments;
  // Single shooting loses about λL/ln 10 digits to the growth of its sensitivities; past λL ≈ 12 its
  // Newton iteration and load continuation become unreliable (they drift onto other, better
  // conditioned branches), so the automatic mode goes to multiple shooting directly.
  return seg >= 2 || (seg == 0 && growth_estimate(target.q, target.wrench) > kSingleShootingGrowthLimit);
}

// The end of a load path at p->x: tip pose, accuracy check (fixed-step methods), convergence; a
// converged equilibrium is committed (the next warm start) with its fold report.
bool RodSolver::finish(Shooting* p, bool ok, FoldTracker* folds) {
  RodSolution& sol = *p->sol;
  if (p->e.ok) {
    sol.tip_rotation = so3::orthonormalise(p->e.R0.transpose() * p->x);
    sol.tip_position = -p->e.R0.transpose() * p->e.p0;
    sol.jacobian_det = p->e.J.determinant();
  }
  sol.converged = ok && p->e.ok && std::isfinite(sol.residual) && sol.residual <= options_.residual_tolerance &&
                  sol.tip_position.allFinite();
  if (sol.converged && accuracy_check_applies()) {
    sol.error_estimate = error_estimate(p->x, p->target, p->e);
    sol.converged = accurate_enough(&sol, 1);
  }
  if (!sol.converged) {
    internal::report_folds(*folds, &sol);
    if (sol.message.empty()) sol.message = "did not converge";
    return false;
  }
  folds->note(sol.jacobian_det);
  internal::report_folds(*folds, &sol);
  sol.message.clear();
  commit(p->x, p->target, p->e, sol);
  return true;
}

bool RodSolver::accuracy_check_applies() const {
  return options_.accuracy_tolerance > 0.0 && !is_adaptive(options_.integrator.type);
}

// A fixed-step solve is only as good as its steps: an under-resolved solve is refused (no silent
// inaccuracy under extreme loads).
bool RodSolver::accurate_enough(RodSolution* sol, int segments) const {
  const double allowed = options_.accuracy_tolerance * model_.length();
  if (sol->error_estimate <= allowed) return true;
  sol->message = internal::accuracy_refusal(sol->error_estimate, options_.integrator.type, options_.integrator.steps,
                                            segments, allowed);
  return false;
}

void RodSolver::commit(const Mat3& R_tip, const Load& load, const Eval& e, const RodSolution& sol) {
  have_solution_ = true;
  have_tangent_ = false;
  R_tip_ = R_tip;
  load_ = load;
  eval_ = e;
  det_ = sol.jacobian_det;
  tip_pos_ = sol.tip_position;
}

RodSolution RodSolver::remember(const RodSolution& sol) {
  last_ = sol;
  return sol;
}

// ---------------------------------------------------------------------------------------------
// The stability restart

// The smallest eigenvalue of the stiffness on options_.cold_stability_check at the stored solution
// (≤ 0: unstable); +inf when no component is checked, NaN when C^b fails.
double RodSolver::stability_indicator() {
  return internal::cold_stability_indicator(options_.cold_stability_check, [this](bool* ok) {
    const Compliance c = compliance();
    *ok = c.ok;
    return c.body;
  });
}

// A cold direct Newton may land on an equilibrium the rod cannot hold (the straight branch of a
// column loaded past buckling). Then the rod is loaded from rest with a small push along its softest
// direction (the stiffness's eigenvector of the most negative eigenvalue, scaled to a tenth of the
// load), toward the unloaded tip's side where a real column buckles, and the push is taken away along
// the load path. An unstable result of both is kept and says so in `warning`.
void RodSolver::load_from_rest_if_unstable(const Load& target, RodSolution* sol) {
  const double direct = stability_indicator();
  if (!(direct <= 0.0)) return;
  const Mat3 R_tip = R_tip_;  // the direct solution, committed: restored if the path does no better
  const Eval eval = eval_;
  const RodSolution kept = *sol;
  Vec6 push = 0.1 * std::max(load_bound(target.q, target.wrench), 1e-6) *
              softest_wrench_direction(compliance().body, options_.cold_stability_check);
  push.tail<3>() *= model_.length();
  if ((R_tip_ * push.head<3>()).dot(unloaded_pos_) < 0.0) push = -push;
  RodSolution path;
  FoldTracker folds;
  if (push.allFinite() && push.norm() > 0.0) {
    Load pushed = target;
    pushed.wrench.force += push.head<3>();
    pushed.wrench.moment += push.tail<3>();
    Shooting to_pushed{*this, pushed, &path}, back{*this, target, &path};
    folds.start(unloaded_det_);
    if (internal::follow_load_path(to_pushed, to_pushed.unloaded(), &folds) &&
        internal::follow_load_path(back, {to_pushed.x, pushed, to_pushed.tip, to_pushed.det}, &folds))
      finish(&back, true, &folds);
  }
  if (path.converged && stability_indicator() > 0.0) {
    path.iterations += kept.iterations;
    path.rhs_evaluations += kept.rhs_evaluations;
    *sol = path;
    return;
  }
  commit(R_tip, target, eval, kept);
  *sol = kept;
  internal::warn_unstable(direct, sol);
}

// ---------------------------------------------------------------------------------------------
// Compliance and actuation Jacobian

// Directions: the six tip wrench components (f_b, l_b), then one per actuator inside the rod, in
// sweeps of six. Implicit function theorem on r(x, w) = 0: dx/dw = −(∂r/∂x)⁻¹ ∂r/∂w; the tip moves
// by δp_T = −R(0)ᵀ(δp(0) + ∂p(0)/∂x dx) with R(0) = I, so the body twist is ω = dx/dw,
// v = −R(L)ᵀ δp(0). An actuator at the tip is a tip wrench: its column of J_q is C^b (d, p × d).
Compliance RodSolver::compliance() {
  Compliance out;
  if (!have_solution_) return out;
  const int N = input_count();
  // Fixed capacity: no heap allocation per call.
  Direction dirs[6 * ((6 + kMaxInputs + 5) / 6)];  // whole sweeps of six (the unused ones: zero)
  int column_of[kMaxInputs];
  int total = 6;
  for (int i = 0; i < 6; ++i) dirs[i].tip_wrench[i] = 1.0;
  for (int j = 0; j < N; ++j) {
    column_of[j] = model_.actuators[j].at < model_.length() ? total++ : -1;
    if (column_of[j] >= 0) dirs[column_of[j]].actuator = j;
  }
  Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6 + kMaxInputs> columns(6, total);
  const Mat3 Jr_inv = so3::right_jacobian_inverse(eval_.r);
  const Eigen::PartialPivLU<Mat3> lu(eval_.J);
  using O = RodOde<6, CosseratGeneral>;
  for (int first = 0; first < total; first += 6) {
    const int count = std::min(6, total - first);
    SweepState<6> y;
    SweepCall<6> c(load_, options_.integrator, workspace_.cvode(options_.integrator.type), &y);
    c.R_tip = R_tip_;
    c.dirs = dirs + first;
    if (!kernels_->run<6>(*this, c)) return out;
    for (int k = 0; k < count; ++k) {
      const Vec3 eta0 = y.segment<3>(O::kBase + O::kPerDir * k);
      const Vec3 dp_w = y.segment<3>(O::kBase + O::kPerDir * k + 6);
      const Vec3 dx = -lu.solve(Jr_inv * eta0);
      const Vec3 dp0 = eval_.dp0 * dx + dp_w;
      columns.col(first + k) << -R_tip_.transpose() * dp0, dx;
    }
  }
  out.body = columns.leftCols<6>();
  out.actuation.resize(6, N);
  for (int j = 0; j < N; ++j)
    out.actuation.col(j) =
        column_of[j] >= 0 ? Vec6(columns.col(column_of[j])) : Vec6(out.body * model_.actuators[j].unit_wrench());
  out.ok = columns.allFinite() && out.actuation.allFinite();
  if (out.ok) {  // the tangent of this solution: the next warm solve's predictor
    dx_dw_ = out.body.bottomRows<3>();
    dx_dq_ = out.actuation.bottomRows<3>();
    have_tangent_ = true;
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Shape

namespace {

/// Integrator options for the const sweeps (shape, frame_at): the solve's, with dopri5 for the CVODE
/// methods (no CVODE memory outside the solves).
IntegratorOptions const_sweep_integrator(const IntegratorOptions& is) {
  IntegratorOptions o = is;
  if (is_adaptive(o.type)) o.type = IntegratorType::kDopri5;
  return o;
}

}  // namespace

bool RodSolver::frame_at(double s, Mat3* R, Vec3* p) const {
  if (!have_solution_ || !(s >= 0.0 && s <= model_.length())) return false;
  Recorder rec;
  rec.at = {s, 0.0};
  SweepState<0> y;
  SweepCall<0> c(load_, const_sweep_integrator(options_.integrator), nullptr, &y);
  c.R_tip = R_tip_;
  c.rec = &rec;
  if (!kernels_->run<0>(*this, c) || rec.R.size() != 2) return false;
  *R = rec.R.back().transpose() * rec.R.front();
  *p = rec.R.back().transpose() * (rec.p.front() - rec.p.back());
  return true;
}

std::vector<Vec3> RodSolver::shape(int K) const {
  std::vector<Vec3> pts;
  if (!have_solution_ || K < 1) return pts;
  const double L = model_.length();
  Recorder rec;
  for (int k = K; k >= 0; --k) rec.at.push_back(L * k / K);
  SweepState<0> y;
  SweepCall<0> c(load_, const_sweep_integrator(options_.integrator), nullptr, &y);
  c.R_tip = R_tip_;
  c.rec = &rec;
  if (!kernels_->run<0>(*this, c) || static_cast<int>(rec.p.size()) != K + 1) return pts;
  const Mat3 R0 = rec.R.back();
  const Vec3 p0 = rec.p.back();
  for (int k = K; k >= 0; --k) pts.push_back(R0.transpose() * (rec.p[k] - p0));
  return pts;
}

}  // namespace rod
}  // namespace hydrojet
