#include "hydrojet_control/rod/general_rod_solver.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "damped_newton.h"
#include "hydrojet_control/rod/cvode_integrator.h"
#include "load_path.h"
#include "hydrojet_control/rod/stability.h"
#include "rod_integration.h"

namespace hydrojet {
namespace rod {

using internal::FoldTracker;
using Load = GeneralRodSolver::Load;

/// The load a fraction t of the way from `from` to `to` (load_path.h finds it by argument lookup).
Load load_between(const Load& from, const Load& to, double t) {
  Load l;
  l.wrench.force = from.wrench.force + t * (to.wrench.force - from.wrench.force);
  l.wrench.moment = from.wrench.moment + t * (to.wrench.moment - from.wrench.moment);
  l.q = from.q + t * (to.q - from.q);
  l.gravity_scale = from.gravity_scale + t * (to.gravity_scale - from.gravity_scale);
  return l;
}

namespace {

/// One sensitivity direction of a sweep: where it starts at the tip and what it changes directly.
struct Direction {
  Vec3 eta_tip = Vec3::Zero();     ///< η(L): a change of the unknown R(L) (Newton directions)
  Vec6 tip_wrench = Vec6::Zero();  ///< a change of the tip follower wrench (f_b, l_b)
  int actuator = -1;               ///< a unit change of this actuator's input
};

/// Arc lengths at which a sweep records the frame (descending), and what it recorded there.
struct Recorder {
  std::vector<double> at;  ///< descending, each in [0, L]
  std::vector<Mat3> R;
  std::vector<Vec3> p;
};

Load no_load(int n) {
  Load l;
  l.q = ActuatorInputs::Zero(n);
  l.gravity_scale = 0.0;
  return l;
}

}  // namespace

/// One tip-to-base integration through the stations with D sensitivity directions (the jump
/// conditions of general_rod_solver.h at each station).
struct GeneralRodSolver::Sweep {
  template <int D, class T>
  using Ode = RodOde<D, T>;

  const GeneralRodSolver& solver;
  const Load& load;
  IntegratorOptions integrator;
  CvodeWorkspace* cvode;
  int rhs = 0;
  int step_multiplier = 1;  ///< 2: every piece with exactly twice its steps (the Richardson estimate)

  /// Steps of a fixed-step method over a piece of length ds: the rod's steps in proportion, ≥ 1.
  int piece_steps(double ds) const {
    const double share = integrator.steps * ds / solver.model_.length();
    return step_multiplier * std::max(1, static_cast<int>(std::ceil(share - 1e-9)));
  }

  /// Adds what station `st` applies to the internal wrench (n base frame, M body frame) and to the
  /// directions' (δn, δM), at the frame R and the directions' η held in y.
  template <int D, class State>
  void apply_station(const Station& st, bool tip, const Direction* dirs, const State& y, Vec3* n, Vec3* M,
                     Eigen::Matrix<double, 3, (D > 0 ? D : 1)>* dn,
                     Eigen::Matrix<double, 3, (D > 0 ? D : 1)>* dM) const {
    const GeneralRodModel& m = solver.model_;
    const Eigen::Map<const Mat3> R(y.data() + 3);
    const double c = load.gravity_scale;
    Vec3 f_fol = c * st.f_body, l_fol = c * st.l_body;
    for (int j : st.actuators) {
      const Vec6 w = m.actuators[j].unit_wrench();
      f_fol += load.q[j] * w.head<3>();
      l_fol += load.q[j] * w.tail<3>();
    }
    if (tip) {
      f_fol += load.wrench.force;
      l_fol += load.wrench.moment;
    }
    const Vec3 f_dead = c * (st.f_base + st.mass * m.gravity);
    const Vec3 l_dead_body = R.transpose() * (c * st.l_base);
    *n += R * f_fol + f_dead;
    *M += l_fol + l_dead_body;
    for (int d = 0; d < D; ++d) {
      const Vec3 eta = y.template segment<3>(15 + 9 * d);
      dn->col(d) += R * eta.cross(f_fol);
      dM->col(d) -= eta.cross(l_dead_body);
      const int a = dirs[d].actuator;
      if (a >= 0 && std::find(st.actuators.begin(), st.actuators.end(), a) != st.actuators.end()) {
        const Vec6 w = m.actuators[a].unit_wrench();
        dn->col(d) += R * w.head<3>();
        dM->col(d) += w.tail<3>();
      }
      if (tip) {
        dn->col(d) += R * dirs[d].tip_wrench.head<3>();
        dM->col(d) += dirs[d].tip_wrench.tail<3>();
      }
    }
  }

  /// Integrates y (set up at the tip with R(L) = R_tip) to the base. False when an integration failed.
  template <int D, class T>
  bool run(const Mat3& R_tip, const Direction* dirs, typename Ode<D, T>::State* y, Recorder* rec = nullptr) {
    using O = Ode<D, T>;
    using Block = Eigen::Matrix<double, 3, (D > 0 ? D : 1)>;
    const GeneralRodModel& m = solver.model_;
    const auto& sts = solver.stations_;
    // One input per actuator (a load built without them would read past q: refuse instead).
    if (load.q.size() != static_cast<Eigen::Index>(m.actuators.size())) return false;
    y->setZero();
    Eigen::Map<Mat3>(y->data() + 3) = R_tip;
    for (int d = 0; d < D; ++d) y->template segment<3>(O::kBase + O::kPerDir * d) = dirs[d].eta_tip;
    Vec3 n = Vec3::Zero(), M = Vec3::Zero();
    Block dn = Block::Zero(), dM = Block::Zero();
    size_t r = 0;
    for (size_t i = 0; i < sts.size(); ++i) {
      const RodSegment& below = m.segments[sts[i].segment_below];
      if (i > 0) {  // the moment arriving from above, M_b = K (u − ũ) of the segment above
        const RodSegment& above = m.segments[sts[i - 1].segment_below];
        M = above.stiffness.cwiseProduct(y->template segment<3>(12) - above.precurvature);
        for (int d = 0; d < D; ++d)
          dM.col(d) = above.stiffness.cwiseProduct(y->template segment<3>(O::kBase + O::kPerDir * d + 3));
      }
      apply_station<D>(sts[i], i == 0, dirs, *y, &n, &M, &dn, &dM);
      const Vec3 k_inv = below.stiffness.cwiseInverse();
      y->template segment<3>(12) = below.precurvature + k_inv.cwiseProduct(M);
      for (int d = 0; d < D; ++d) y->template segment<3>(O::kBase + O::kPerDir * d + 3) = k_inv.cwiseProduct(dM.col(d));
      // The piece from this station down to the next (or the base).
      O ode;
      ode.k_diag = below.stiffness;
      ode.k_inv = k_inv;
      ode.u_tilde = below.precurvature;
      ode.kse_inv = m.kind == RodKind::kCosserat
                        ? Vec3(1.0 / below.shear_stiffness, 1.0 / below.shear_stiffness, 1.0 / below.axial_stiffness)
                        : Vec3::Zero();
      ode.w_dist = load.gravity_scale * below.linear_density * m.gravity;
      ode.dn = dn;
      const double s_hi = sts[i].s, s_lo = i + 1 < sts.size() ? sts[i + 1].s : 0.0;
      double s = s_hi;
      // Record points inside the piece (and at its lower end) cut it further.
      while (true) {
        double next = s_lo;
        const bool record = rec && r < rec->at.size() && rec->at[r] >= s_lo - 1e-15 && rec->at[r] <= s + 1e-15;
        if (record) next = std::max(s_lo, std::min(s, rec->at[r]));
        if (next < s) {
          ode.length = s;  // n(σ) = n(s) + w_dist (s − σ) on [next, s]
          ode.n_tip = n;
          IntegratorOptions is = integrator;
          is.steps = piece_steps(s - next);
          const IntegrationStats st = internal::integrate_rod(is, cvode, ode, s, next, y);
          rhs += st.rhs_evaluations;
          if (!st.ok || !y->allFinite()) return false;
          n += ode.w_dist * (s - next);
          s = next;
        }
        if (!record) break;
        rec->R.push_back(Eigen::Map<const Mat3>(y->data() + 3));
        rec->p.push_back(y->template segment<3>(0));
        ++r;
      }
    }
    return true;
  }

  /// run() with the model's right-hand side (Kirchhoff or Cosserat; the state is the same).
  template <int D>
  bool sweep(const Mat3& R_tip, const Direction* dirs, typename Ode<D, CosseratGeneral>::State* y,
             Recorder* rec = nullptr) {
    if (solver.model_.kind == RodKind::kCosserat) return run<D, CosseratGeneral>(R_tip, dirs, y, rec);
    return run<D, KirchhoffGeneral>(R_tip, dirs, y, rec);
  }
};

// ---------------------------------------------------------------------------------------------
// Model

GeneralRodSolver::GeneralRodSolver(const GeneralRodModel& model, const ShootingOptions& settings)
    : model_(model), settings_(settings) {
  const std::string why = model_.validate();
  if (!why.empty()) throw std::invalid_argument("GeneralRodSolver: " + why);
  build_stations();
  update_unloaded_shape();
}

GeneralRodSolver::~GeneralRodSolver() = default;

// A copy starts with no CVODE memory of its own (created on first use).
GeneralRodSolver::GeneralRodSolver(const GeneralRodSolver& o) { *this = o; }

GeneralRodSolver& GeneralRodSolver::operator=(const GeneralRodSolver& o) {
  if (this == &o) return *this;
  model_ = o.model_;
  settings_ = o.settings_;
  stations_ = o.stations_;
  unloaded_tip_ = o.unloaded_tip_;
  unloaded_pos_ = o.unloaded_pos_;
  unloaded_det_ = o.unloaded_det_;
  cvode_.reset();
  have_solution_ = o.have_solution_;
  R_tip_ = o.R_tip_;
  load_ = o.load_;
  eval_ = o.eval_;
  det_ = o.det_;
  tip_pos_ = o.tip_pos_;
  last_ = o.last_;
  return *this;
}

CvodeWorkspace* GeneralRodSolver::cvode() {
  const IntegratorType t = settings_.integrator.type;
  if (t != IntegratorType::kCvodeAdams && t != IntegratorType::kCvodeBdf) return nullptr;
  if (!cvode_) cvode_.reset(new CvodeWorkspace);
  return cvode_.get();
}

// Stations, tip first: s = L (tip mass, loads and actuators there), then every segment end, load and
// actuator arc length below it (merged when closer than 1e-12 L).
void GeneralRodSolver::build_stations() {
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
  for (size_t j = 0; j < model_.actuators.size(); ++j) station_at(model_.actuators[j].at).actuators.push_back(j);
}

// With no load u(s) = ũ(s) piecewise, so the unloaded tip frame is the product of the segments' arcs.
void GeneralRodSolver::update_unloaded_shape() {
  unloaded_tip_.setIdentity();
  for (const RodSegment& g : model_.segments) unloaded_tip_ = unloaded_tip_ * so3::exp(g.length * g.precurvature);
  int rhs = 0;
  const Eval e = evaluate(unloaded_tip_, no_load(actuator_count()), &rhs);
  unloaded_det_ = e.ok ? e.J.determinant() : std::nan("");
  unloaded_pos_ = e.ok ? Vec3(-e.R0.transpose() * e.p0) : Vec3::Zero();
}

void GeneralRodSolver::reset() { have_solution_ = false; }

// A bound on |n(s)| [N]: every force on the rod (tip wrench, inputs, point loads, weights; the tip
// moment counted as |l|/L).
double GeneralRodSolver::load_bound(const ActuatorInputs& q, const TipWrench& tip) const {
  const double g = model_.gravity.norm();
  double n = tip.force.norm() + tip.moment.norm() / model_.length() + model_.tip_mass * g;
  for (int j = 0; j < q.size(); ++j) n += std::abs(q[j]);
  for (const PointLoad& l : model_.loads) n += l.force.norm() + l.mass * g;
  for (const RodSegment& s : model_.segments) n += s.linear_density * g * s.length;
  return n;
}

double GeneralRodSolver::growth_estimate(const ActuatorInputs& q, const TipWrench& tip) const {
  double ei = 1e300;
  for (const RodSegment& s : model_.segments) ei = std::min(ei, std::min(s.stiffness.x(), s.stiffness.y()));
  return model_.length() * std::sqrt(load_bound(q, tip) / ei);
}

// ---------------------------------------------------------------------------------------------
// Evaluations

GeneralRodSolver::Eval GeneralRodSolver::evaluate(const Mat3& R_tip, const Load& load, int* rhs) {
  using O = RodOde<3, CosseratGeneral>;
  Direction dirs[3];
  for (int i = 0; i < 3; ++i) dirs[i].eta_tip = Vec3::Unit(i);
  Sweep sw{*this, load, settings_.integrator, cvode()};
  O::State y;
  Eval e;
  e.ok = sw.sweep<3>(R_tip, dirs, &y);
  *rhs += sw.rhs;
  if (!e.ok) return e;
  e.R0 = Eigen::Map<const Mat3>(y.data() + 3);
  e.p0 = y.segment<3>(0);
  Mat3 deta0;
  for (int i = 0; i < 3; ++i) {
    deta0.col(i) = y.segment<3>(O::kBase + O::kPerDir * i);
    e.dp0.col(i) = y.segment<3>(O::kBase + O::kPerDir * i + 6);
  }
  // Shooting residual, eq. (15): R(0) = I  <=>  log R(0) = 0.
  e.r = so3::log(so3::orthonormalize(e.R0));
  e.J = so3::right_jacobian_inverse(e.r) * deta0;
  e.ok = e.r.allFinite() && e.J.allFinite();
  return e;
}

// Richardson estimate of the tip-position error of a fixed-step solve: the state alone with twice the
// steps on every piece (exact − coarse ≈ (fine − coarse)·2^p/(2^p − 1)), carried through the shooting
// problem as in ShootingSolver.
double GeneralRodSolver::error_estimate(const Mat3& R_tip, const Load& load, const Eval& e) {
  const double q = settings_.integrator.type == IntegratorType::kRk4 ? 16.0 : 256.0;
  const double f = q / (q - 1.0);
  Sweep sw{*this, load, settings_.integrator, cvode(), 0, 2};
  RodOde<0, CosseratGeneral>::State y;
  if (!sw.sweep<0>(R_tip, nullptr, &y)) return std::numeric_limits<double>::infinity();
  const Mat3 R0f = Eigen::Map<const Mat3>(y.data() + 3);
  const Vec3 dr = f * so3::log(so3::orthonormalize(e.R0.transpose() * R0f));
  const Vec3 dp = f * (y.segment<3>(0) - e.p0);
  const Vec3 dx = -e.J.partialPivLu().solve(dr);
  return (dp + e.dp0 * dx).norm();
}

bool GeneralRodSolver::newton(Mat3* R_tip, const Load& load, RodSolution* sol, Eval* last) {
  return internal::damped_newton([&](const Mat3& R) { return evaluate(R, load, &sol->rhs_evaluations); }, settings_,
                                 R_tip, sol, last);
}

// ---------------------------------------------------------------------------------------------
// The solve

/// Single shooting on the load path (load_path.h), as ShootingSolver::SingleShooting.
struct GeneralRodSolver::Shooting : internal::TipOrientationShooting<Shooting, Load, Eval> {
  Shooting(GeneralRodSolver& s, const Load& t, RodSolution* out) : TipOrientationShooting(t, out), solver(s) {}

  GeneralRodSolver& solver;

  const ShootingOptions& options() const { return solver.settings_; }
  double length() const { return solver.model_.length(); }
  double growth() const { return solver.growth_estimate(target.q, target.wrench); }
  bool newton_at(Mat3* R, const Load& load, Eval* last) { return solver.newton(R, load, sol, last); }
};

RodSolution GeneralRodSolver::solve(const ActuatorInputs& q, const TipWrench& tip) {
  RodSolution sol;
  if (q.size() != actuator_count()) {
    sol.message =
        "expected " + std::to_string(actuator_count()) + " actuator input(s), got " + std::to_string(q.size());
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
  // Newton from the warm solution (or the unloaded shape) → load continuation from the warm solution
  // → from the unloaded shape (load_path.h) → accuracy check → fold report → for a cold solve, the
  // stability check (load from rest with a push when the equilibrium reached is unstable).
  const bool cold = !have_solution_;
  FoldTracker folds;
  Shooting p{*this, target, &sol};
  const Shooting::Point unloaded{unloaded_tip_, no_load(actuator_count()), unloaded_pos_, unloaded_det_};
  const Shooting::Point start = have_solution_ ? Shooting::Point{R_tip_, load_, tip_pos_, det_} : unloaded;
  const bool ok = internal::reach_equilibrium(p, start, have_solution_, unloaded, &folds);
  if (!finish(&p, ok, &folds)) {
    if (growth_estimate(q, tip) > ShootingSolver::kSingleShootingGrowthLimit)
      sol.message +=
          " (the load is beyond what single shooting handles, λL > 12; multiple shooting is not "
          "available for general rods yet)";
    return remember(sol);
  }
  if (cold) load_from_rest_if_unstable(target, &sol);
  return remember(sol);
}

// The end of a load path at p->x: tip pose, accuracy check (fixed-step methods), convergence; a
// converged equilibrium is committed (the next warm start) with its fold report.
bool GeneralRodSolver::finish(Shooting* p, bool ok, FoldTracker* folds) {
  RodSolution& sol = *p->sol;
  if (p->e.ok) {
    sol.tip_rotation = so3::orthonormalize(p->e.R0.transpose() * p->x);
    sol.tip_position = -p->e.R0.transpose() * p->e.p0;
    sol.jacobian_det = p->e.J.determinant();
  }
  bool accurate = true;
  if (ok && settings_.accuracy_tolerance > 0.0 && !is_adaptive(settings_.integrator.type)) {
    sol.error_estimate = error_estimate(p->x, p->target, p->e);
    accurate = accurate_enough(&sol);
  }
  sol.converged = ok && accurate && p->e.ok && std::isfinite(sol.residual) &&
                  sol.residual <= settings_.residual_tolerance && sol.tip_position.allFinite();
  if (!sol.converged) {
    if (sol.message.empty()) sol.message = "did not converge";
    return false;
  }
  folds->note(sol.jacobian_det);
  sol.message.clear();
  commit(p->x, p->target, p->e, sol);
  internal::report_folds(*folds, &sol);
  return true;
}

// The smallest eigenvalue of the stiffness on settings_.cold_stability_check at the stored solution
// (≤ 0: unstable); +inf when no component is checked, NaN when C^b fails (as ShootingSolver's).
double GeneralRodSolver::stability_indicator() {
  const ActuatedSet& a = settings_.cold_stability_check;
  if (std::none_of(a.begin(), a.end(), [](bool b) { return b; })) return std::numeric_limits<double>::infinity();
  const GeneralCompliance c = compliance();
  return c.ok ? stability(c.body, a).eig_min : std::nan("");
}

// As ShootingSolver::load_from_rest_if_unstable: a cold solve that reached an equilibrium the rod
// cannot hold (a column past buckling) is loaded again from rest with a small tip push along its
// softest direction, toward the unloaded tip's side, and the push is then taken away along the load
// path; an unstable result of both is kept and says so in `warning`.
void GeneralRodSolver::load_from_rest_if_unstable(const Load& target, RodSolution* sol) {
  const double direct = stability_indicator();
  if (!(direct <= 0.0)) return;
  const Mat3 R_tip = R_tip_;
  const Eval eval = eval_;
  const RodSolution kept = *sol;
  const double L = model_.length();
  Vec6 push = 0.1 * std::max(load_bound(target.q, target.wrench), 1e-6) *
              softest_wrench_direction(compliance().body, settings_.cold_stability_check);
  push.tail<3>() *= L;
  if ((R_tip_ * push.head<3>()).dot(unloaded_pos_) < 0.0) push = -push;
  RodSolution path;
  FoldTracker folds;
  if (push.allFinite() && push.norm() > 0.0) {
    Load pushed = target;
    pushed.wrench.force += push.head<3>();
    pushed.wrench.moment += push.tail<3>();
    Shooting to_pushed{*this, pushed, &path};
    Shooting back{*this, target, &path};
    folds.start(unloaded_det_);
    const Shooting::Point rest{unloaded_tip_, no_load(actuator_count()), unloaded_pos_, unloaded_det_};
    if (internal::follow_load_path(to_pushed, rest, &folds) &&
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

bool GeneralRodSolver::accurate_enough(RodSolution* sol) const {
  const double allowed = settings_.accuracy_tolerance * model_.length();
  if (sol->error_estimate <= allowed) return true;
  sol->message = internal::accuracy_refusal(sol->error_estimate, settings_.integrator.type, settings_.integrator.steps,
                                            1, allowed);
  return false;
}

void GeneralRodSolver::commit(const Mat3& R_tip, const Load& load, const Eval& e, const RodSolution& sol) {
  have_solution_ = true;
  R_tip_ = R_tip;
  load_ = load;
  eval_ = e;
  det_ = sol.jacobian_det;
  tip_pos_ = sol.tip_position;
}

RodSolution GeneralRodSolver::remember(const RodSolution& sol) {
  last_ = sol;
  return sol;
}

// ---------------------------------------------------------------------------------------------
// Compliance and actuation Jacobian

// Directions: the six tip wrench components (f_b, l_b), then one per actuator, in sweeps of six.
// Implicit function theorem on r(x, w) = 0: dx/dw = −(∂r/∂x)⁻¹ ∂r/∂w; the tip moves by
// δp_T = −R(0)ᵀ(δp(0) + ∂p(0)/∂x dx) with R(0) = I, so the body twist is ω = dx/dw, v = −R(L)ᵀ δp(0).
GeneralCompliance GeneralRodSolver::compliance() {
  GeneralCompliance out;
  if (!have_solution_) return out;
  const int N = actuator_count(), total = 6 + N;
  std::vector<Direction> dirs(total);
  for (int i = 0; i < 6; ++i) dirs[i].tip_wrench[i] = 1.0;
  for (int j = 0; j < N; ++j) dirs[6 + j].actuator = j;
  Eigen::Matrix<double, 6, Eigen::Dynamic> columns(6, total);
  const Mat3 Jr_inv = so3::right_jacobian_inverse(eval_.r);
  const Eigen::PartialPivLU<Mat3> lu(eval_.J);
  using O = RodOde<6, CosseratGeneral>;
  for (int first = 0; first < total; first += 6) {
    const int count = std::min(6, total - first);
    Direction chunk[6];
    for (int k = 0; k < count; ++k) chunk[k] = dirs[first + k];
    Sweep sw{*this, load_, settings_.integrator, cvode()};
    O::State y;
    if (!sw.sweep<6>(R_tip_, chunk, &y)) return out;
    for (int k = 0; k < count; ++k) {
      const Vec3 eta0 = y.segment<3>(O::kBase + O::kPerDir * k);
      const Vec3 dp_w = y.segment<3>(O::kBase + O::kPerDir * k + 6);
      const Vec3 dx = -lu.solve(Jr_inv * eta0);
      const Vec3 dp0 = eval_.dp0 * dx + dp_w;
      columns.col(first + k) << -R_tip_.transpose() * dp0, dx;
    }
  }
  out.body = columns.leftCols<6>();
  out.actuation = columns.rightCols(N);
  out.ok = columns.allFinite();
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

bool GeneralRodSolver::frame_at(double s, Mat3* R, Vec3* p) const {
  if (!have_solution_ || !(s >= 0.0 && s <= model_.length())) return false;
  Recorder rec;
  rec.at = {s, 0.0};
  Sweep sw{*this, load_, const_sweep_integrator(settings_.integrator), nullptr};
  RodOde<0, CosseratGeneral>::State y;
  if (!sw.sweep<0>(R_tip_, nullptr, &y, &rec) || rec.R.size() != 2) return false;
  *R = rec.R.back().transpose() * rec.R.front();
  *p = rec.R.back().transpose() * (rec.p.front() - rec.p.back());
  return true;
}

std::vector<Vec3> GeneralRodSolver::shape(int K) const {
  std::vector<Vec3> pts;
  if (!have_solution_ || K < 1) return pts;
  const double L = model_.length();
  Recorder rec;
  for (int k = K; k >= 0; --k) rec.at.push_back(L * k / K);
  Sweep sw{*this, load_, const_sweep_integrator(settings_.integrator), nullptr};
  RodOde<0, CosseratGeneral>::State y;
  if (!sw.sweep<0>(R_tip_, nullptr, &y, &rec) || static_cast<int>(rec.p.size()) != K + 1) return pts;
  const Mat3 R0 = rec.R.back();
  const Vec3 p0 = rec.p.back();
  for (int k = K; k >= 0; --k) pts.push_back(R0.transpose() * (rec.p[k] - p0));
  return pts;
}

}  // namespace rod
}  // namespace hydrojet
