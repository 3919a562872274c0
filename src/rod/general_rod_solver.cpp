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
  Vec3 eta_tip = Vec3::Zero();     ///< η at the start: a change of the start frame (Newton directions)
  Vec3 du0 = Vec3::Zero();         ///< δu at the start (multiple shooting's node directions)
  Vec3 dn0 = Vec3::Zero();         ///< δn at the start [N] (multiple shooting's node directions)
  Vec6 tip_wrench = Vec6::Zero();  ///< a change of the tip follower wrench (f_b, l_b)
  int actuator = -1;               ///< a unit change of this actuator's input
};

/// Arc lengths at which a sweep records the frame (descending), and what it recorded there.
struct Recorder {
  std::vector<double> at;  ///< descending, each in [0, L]
  std::vector<Mat3> R;
  std::vector<Vec3> p;
  std::vector<Vec3> u, n;  ///< u (body frame) and n (base frame) there, just above any station
};

/// A sweep's start inside the rod (multiple shooting): the state just above any station at s.
struct SweepStart {
  double s = 0.0;
  Mat3 R = Mat3::Identity();
  Vec3 u = Vec3::Zero();  ///< body frame [1/m]
  Vec3 n = Vec3::Zero();  ///< internal force, base (integration) frame [N]
};

/// What a sweep that ends inside the rod hands on besides y: n and its directions' δn there.
template <int D>
struct SweepEnd {
  Vec3 n = Vec3::Zero();
  Eigen::Matrix<double, 3, (D > 0 ? D : 1)> dn;
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

  /// Integrates y from the tip (R(L) = R_tip; `from` null) or from the state `from` at an interior
  /// arc length (just above any station there) down to s_end (just above any station there; 0: the
  /// base), through the stations in between. `to`, when given, receives n and its directions' δn at
  /// s_end (u, R and their directions are in y). False when an integration failed.
  template <int D, class T>
  bool run(const Mat3& R_tip, const Direction* dirs, typename Ode<D, T>::State* y, Recorder* rec = nullptr,
           const SweepStart* from = nullptr, double s_end = 0.0, SweepEnd<D>* to = nullptr) {
    using O = Ode<D, T>;
    using Block = Eigen::Matrix<double, 3, (D > 0 ? D : 1)>;
    const GeneralRodModel& m = solver.model_;
    const auto& sts = solver.stations_;
    const double tol = 1e-12 * m.length();
    // One input per actuator (a load built without them would read past q: refuse instead).
    if (load.q.size() != static_cast<Eigen::Index>(m.actuators.size())) return false;
    y->setZero();
    Eigen::Map<Mat3>(y->data() + 3) = from ? from->R : R_tip;
    Vec3 n = Vec3::Zero(), M = Vec3::Zero();
    Block dn = Block::Zero(), dM = Block::Zero();
    for (int d = 0; d < D; ++d) {
      y->template segment<3>(O::kBase + O::kPerDir * d) = dirs[d].eta_tip;
      y->template segment<3>(O::kBase + O::kPerDir * d + 3) = dirs[d].du0;
      dn.col(d) = dirs[d].dn0;
    }
    size_t i = 0, r = 0;
    if (from) {  // the stations at or below the start; the piece down to the first of them
      y->template segment<3>(12) = from->u;
      n = from->n;
      while (i < sts.size() && sts[i].s > from->s + tol) ++i;
      if (i == 0) return false;  // not below the tip
      const double s_lo = std::max(i < sts.size() ? sts[i].s : 0.0, s_end);
      if (!piece<D, T>(m.segments[sts[i - 1].segment_below], from->s, s_lo, &n, dn, y, rec, &r)) return false;
      if (s_lo <= s_end + tol) return finish_at(n, dn, to);
    }
    for (; i < sts.size(); ++i) {
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
      // The piece from this station down to the next (or the base, or s_end).
      const double s_lo = std::max(i + 1 < sts.size() ? sts[i + 1].s : 0.0, s_end);
      if (!piece<D, T>(below, sts[i].s, s_lo, &n, dn, y, rec, &r)) return false;
      if (s_lo <= s_end + tol) break;
    }
    return finish_at(n, dn, to);
  }

  /// The piece [s_lo, s_hi] of one segment: y integrated down, n by its closed form (n(σ) = n(s) +
  /// w_dist (s − σ)); the recorder's points inside cut it further.
  template <int D, class T>
  bool piece(const RodSegment& sg, double s_hi, double s_lo, Vec3* n,
             const Eigen::Matrix<double, 3, (D > 0 ? D : 1)>& dn, typename Ode<D, T>::State* y, Recorder* rec,
             size_t* r) {
    Ode<D, T> ode;
    ode.k_diag = sg.stiffness;
    ode.k_inv = sg.stiffness.cwiseInverse();
    ode.u_tilde = sg.precurvature;
    ode.kse_inv = solver.model_.kind == RodKind::kCosserat
                      ? Vec3(1.0 / sg.shear_stiffness, 1.0 / sg.shear_stiffness, 1.0 / sg.axial_stiffness)
                      : Vec3::Zero();
    ode.w_dist = load.gravity_scale * sg.linear_density * solver.model_.gravity;
    ode.dn = dn;
    double s = s_hi;
    while (true) {
      double next = s_lo;
      const bool record = rec && *r < rec->at.size() && rec->at[*r] >= s_lo - 1e-15 && rec->at[*r] <= s + 1e-15;
      if (record) next = std::max(s_lo, std::min(s, rec->at[*r]));
      if (next < s) {
        ode.length = s;  // n(σ) = n(s) + w_dist (s − σ) on [next, s]
        ode.n_tip = *n;
        IntegratorOptions is = integrator;
        is.steps = piece_steps(s - next);
        const IntegrationStats st = internal::integrate_rod(is, cvode, ode, s, next, y);
        rhs += st.rhs_evaluations;
        if (!st.ok || !y->allFinite()) return false;
        *n += ode.w_dist * (s - next);
        s = next;
      }
      if (!record) return true;
      rec->R.push_back(Eigen::Map<const Mat3>(y->data() + 3));
      rec->p.push_back(y->template segment<3>(0));
      rec->u.push_back(y->template segment<3>(12));
      rec->n.push_back(*n);
      ++*r;
    }
  }

  template <int D>
  static bool finish_at(const Vec3& n, const Eigen::Matrix<double, 3, (D > 0 ? D : 1)>& dn, SweepEnd<D>* to) {
    if (to) {
      to->n = n;
      to->dn = dn;
    }
    return true;
  }

  /// run() with the model's right-hand side (Kirchhoff or Cosserat; the state is the same).
  template <int D>
  bool sweep(const Mat3& R_tip, const Direction* dirs, typename Ode<D, CosseratGeneral>::State* y,
             Recorder* rec = nullptr, const SweepStart* from = nullptr, double s_end = 0.0, SweepEnd<D>* to = nullptr) {
    if (solver.model_.kind == RodKind::kCosserat) return run<D, CosseratGeneral>(R_tip, dirs, y, rec, from, s_end, to);
    return run<D, KirchhoffGeneral>(R_tip, dirs, y, rec, from, s_end, to);
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
  // Multiple shooting first when forced (shooting_segments ≥ 2) or past single shooting's reach.
  const int seg = settings_.shooting_segments;
  const bool ms_first = seg >= 2 || (seg == 0 && growth_estimate(q, tip) > ShootingSolver::kSingleShootingGrowthLimit);
  if (ms_first) {
    RodSolution ms;
    FoldTracker ms_folds;
    if (multiple_shooting(target, &ms, &ms_folds, seg) || seg >= 2) return remember(ms);
    sol.message = ms.message + "; ";
  }
  FoldTracker folds;
  Shooting p{*this, target, &sol};
  const Shooting::Point unloaded{unloaded_tip_, no_load(actuator_count()), unloaded_pos_, unloaded_det_};
  const Shooting::Point start = have_solution_ ? Shooting::Point{R_tip_, load_, tip_pos_, det_} : unloaded;
  const bool ok = internal::reach_equilibrium(p, start, have_solution_, unloaded, &folds);
  if (!finish(&p, ok, &folds)) {
    // Multiple shooting when single shooting failed (automatic mode).
    if (seg == 1 || ms_first) return remember(sol);
    RodSolution ms;
    ms.iterations = sol.iterations;
    ms.continuation_steps = sol.continuation_steps;
    ms.rhs_evaluations = sol.rhs_evaluations;
    FoldTracker ms_folds;
    if (!multiple_shooting(target, &ms, &ms_folds, 0)) {
      sol.message += "; multiple shooting: " + ms.message;
      return remember(sol);
    }
    sol = ms;
  }
  if (cold) load_from_rest_if_unstable(target, &sol);
  return remember(sol);
}

// The end of a load path at p->x: tip pose, accuracy check (fixed-step methods), convergence; a
// converged equilibrium is committed (the next warm start) with its fold report.
bool GeneralRodSolver::finish(Shooting* p, bool ok, FoldTracker* folds, bool check_accuracy) {
  RodSolution& sol = *p->sol;
  if (p->e.ok) {
    sol.tip_rotation = so3::orthonormalize(p->e.R0.transpose() * p->x);
    sol.tip_position = -p->e.R0.transpose() * p->e.p0;
    sol.jacobian_det = p->e.J.determinant();
  }
  bool accurate = true;
  if (ok && check_accuracy && settings_.accuracy_tolerance > 0.0 && !is_adaptive(settings_.integrator.type)) {
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
  return internal::cold_stability_indicator(settings_.cold_stability_check, [this](bool* ok) {
    const GeneralCompliance c = compliance();
    *ok = c.ok;
    return c.body;
  });
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
// Multiple shooting: where single shooting cannot go (λL > 12)
//
// Nodes s_k = k L / M (k = 0..M). Unknowns: the tip frame R_M (ξ, 3) and at every interior node the
// state just above any station there: R_k (η_k), n_k (δn_k, integration frame) and u_k (δu_k).
// Sweep k runs from node k+1 (from the tip for k = M−1) down to s_k; the residuals are
//   c_k = [log(R_kᵀ R⁻(s_k)); (n⁻(s_k) − n_k) / F; h (u⁻(s_k) − u_k)],  k = 1..M−1,
//   r_0 = log R⁻(0)   (h = L / M, F = max EI / L², all in rad),
// with the Jacobian from each sweep's sensitivities (3 directions at the tip, 9 at a node) and the node
// columns in closed form (−J_l⁻¹, −I/F, −h I). Damped Newton on the dense system along a load path from
// the unloaded shape (the fraction's step doubled on success, halved on failure). The converged tip
// frame then goes through the single-shooting machinery (one sweep: pose, C^b, J_q, shape, warm start);
// at these λL that sweep loses at most ~e^{λL}·1e-16 of accuracy.

struct GeneralRodSolver::MsNodes {
  std::vector<double> s;   ///< s_0 = 0 .. s_M = L
  std::vector<Mat3> R;     ///< frames at the nodes (R[M]: the tip), integration frame
  std::vector<Vec3> n, u;  ///< internal force and curvature at the nodes (interior ones used)
  int segments() const { return static_cast<int>(s.size()) - 1; }
};

// The nodes of a single sweep from R_tip under `load` (exact for the unloaded shape).
bool GeneralRodSolver::ms_nodes(const Mat3& R_tip, const Load& load, int M, MsNodes* x) {
  const double L = model_.length();
  x->s.resize(M + 1);
  for (int k = 0; k <= M; ++k) x->s[k] = L * k / M;
  Recorder rec;
  for (int k = M - 1; k >= 1; --k) rec.at.push_back(x->s[k]);
  Sweep sw{*this, load, settings_.integrator, cvode()};
  RodOde<0, CosseratGeneral>::State y;
  if (!sw.sweep<0>(R_tip, nullptr, &y, &rec) || static_cast<int>(rec.R.size()) != M - 1) return false;
  x->R.assign(M + 1, Mat3::Identity());
  x->n.assign(M + 1, Vec3::Zero());
  x->u.assign(M + 1, Vec3::Zero());
  x->R[M] = R_tip;
  for (int j = 0; j < M - 1; ++j) {
    const int k = M - 1 - j;
    x->R[k] = rec.R[j];
    x->n[k] = rec.n[j];
    x->u[k] = rec.u[j];
  }
  return true;
}

// F and J of the node values x (the unknowns' perturbations at zero); Σ Δp and R⁻(0) for the pose.
bool GeneralRodSolver::ms_evaluate(const MsNodes& x, const Load& load, Eigen::VectorXd* F, Eigen::MatrixXd* J,
                                   Vec3* sum_dp, Mat3* R0, int* rhs) {
  using O9 = RodOde<9, CosseratGeneral>;
  const int M = x.segments(), N = 3 + 9 * (M - 1);
  const double L = model_.length(), h = L / M;
  double ei = 0.0;
  for (const RodSegment& sg : model_.segments) ei = std::max(ei, sg.stiffness.maxCoeff());
  const double Fs = ei / (L * L);
  F->setZero(N);
  J->setZero(N, N);
  sum_dp->setZero();
  auto col = [M](int k) { return 3 + 9 * (M - 1 - k); };  // node k's unknowns (k = 1..M−1)
  for (int k = M - 1; k >= 0; --k) {
    const int D = k == M - 1 ? 3 : 9;
    Direction dirs[9];
    for (int i = 0; i < 3; ++i) {
      dirs[i].eta_tip = Vec3::Unit(i);
      dirs[3 + i].dn0 = Vec3::Unit(i);
      dirs[6 + i].du0 = Vec3::Unit(i);
    }
    Sweep sw{*this, load, settings_.integrator, cvode()};
    O9::State y;
    SweepEnd<9> end;
    bool ok;
    if (D == 3) {
      RodOde<3, CosseratGeneral>::State y3;
      SweepEnd<3> end3;
      ok = sw.sweep<3>(x.R[M], dirs, &y3, nullptr, nullptr, x.s[k], &end3);
      y.setZero();
      y.head<RodOde<3, CosseratGeneral>::kSize>() = y3;
      end.n = end3.n;
      end.dn.leftCols<3>() = end3.dn;
    } else {
      const SweepStart from{x.s[k + 1], x.R[k + 1], x.u[k + 1], x.n[k + 1]};
      ok = sw.sweep<9>(Mat3::Identity(), dirs, &y, nullptr, &from, x.s[k], &end);
    }
    *rhs += sw.rhs;
    if (!ok || !y.allFinite()) return false;
    *sum_dp += y.segment<3>(0);
    const Mat3 Rm = Eigen::Map<const Mat3>(y.data() + 3);
    const int c0 = k == M - 1 ? 0 : col(k + 1);
    if (k == 0) {
      const int row = 9 * (M - 1);
      const Vec3 r = so3::log(so3::orthonormalize(Rm));
      F->segment<3>(row) = r;
      const Mat3 Jri = so3::right_jacobian_inverse(r);
      for (int d = 0; d < D; ++d) J->block<3, 1>(row, c0 + d) = Jri * y.segment<3>(O9::kBase + O9::kPerDir * d);
      *R0 = Rm;
      continue;
    }
    const int row = 9 * (M - 1 - k);
    const Vec3 r = so3::log(so3::orthonormalize(x.R[k].transpose() * Rm));
    F->segment<3>(row) = r;
    F->segment<3>(row + 3) = (end.n - x.n[k]) / Fs;
    F->segment<3>(row + 6) = h * (y.segment<3>(12) - x.u[k]);
    const Mat3 Jri = so3::right_jacobian_inverse(r);
    for (int d = 0; d < D; ++d) {
      J->block<3, 1>(row, c0 + d) = Jri * y.segment<3>(O9::kBase + O9::kPerDir * d);
      J->block<3, 1>(row + 3, c0 + d) = end.dn.col(d) / Fs;
      J->block<3, 1>(row + 6, c0 + d) = h * y.segment<3>(O9::kBase + O9::kPerDir * d + 3);
    }
    J->block<3, 3>(row, col(k)) = -so3::right_jacobian_inverse(-r);
    J->block<3, 3>(row + 3, col(k) + 3) = -Mat3::Identity() / Fs;
    J->block<3, 3>(row + 6, col(k) + 6) = -h * Mat3::Identity();
  }
  return F->allFinite() && J->allFinite();
}

// Damped Newton on the node values at `load`; *residual: ‖F‖ at the end, *pose: the tip frame and
// position it gives (R⁻(0)ᵀ R_M, −R⁻(0)ᵀ Σ Δp), when non-null.
bool GeneralRodSolver::ms_newton(MsNodes* x, const Load& load, double* residual, RodSolution* sol,
                                 std::pair<Mat3, Vec3>* pose) {
  Eigen::VectorXd F, Ft;
  Eigen::MatrixXd J, Jt;
  Vec3 dp, dpt;
  Mat3 R0, R0t;
  if (!ms_evaluate(*x, load, &F, &J, &dp, &R0, &sol->rhs_evaluations)) return false;
  // The step's size in rad: η, δn / F, h δu (as the residuals are scaled).
  const int M = x->segments();
  double ei = 0.0;
  for (const RodSegment& sg : model_.segments) ei = std::max(ei, sg.stiffness.maxCoeff());
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(F.size());
  for (int k = 1; k < M; ++k) {
    const int c = 3 + 9 * (M - 1 - k);
    scale.segment<3>(c + 3).setConstant(model_.length() * model_.length() / ei);
    scale.segment<3>(c + 6).setConstant(model_.length() / M);
  }
  for (int it = 0;; ++it) {
    *residual = F.norm();
    if (pose) *pose = {so3::orthonormalize(R0.transpose() * x->R[M]), Vec3(-R0.transpose() * dp)};
    if (*residual <= settings_.residual_tolerance) return true;
    if (it == settings_.max_iterations) return false;
    Eigen::VectorXd dX = -J.partialPivLu().solve(F);
    if (!dX.allFinite()) return false;
    const double big = dX.cwiseProduct(scale).cwiseAbs().maxCoeff();
    if (big > settings_.max_step) dX *= settings_.max_step / big;
    ++sol->iterations;
    bool accepted = false;
    for (double a = 1.0; a > 1e-4 && !accepted; a *= 0.5) {
      const MsNodes xt = ms_moved(*x, a * dX);
      if (!ms_evaluate(xt, load, &Ft, &Jt, &dpt, &R0t, &sol->rhs_evaluations) ||
          Ft.norm() >= (1.0 - 1e-4 * a) * F.norm())
        continue;
      *x = xt;
      F.swap(Ft);
      J.swap(Jt);
      dp = dpt;
      R0 = R0t;
      accepted = true;
    }
    if (!accepted) return false;
  }
}

// The node values moved by the unknowns' step dX.
GeneralRodSolver::MsNodes GeneralRodSolver::ms_moved(const MsNodes& x, const Eigen::VectorXd& dX) {
  MsNodes y = x;
  const int M = x.segments();
  y.R[M] = x.R[M] * so3::exp(dX.head<3>());
  for (int k = 1; k < M; ++k) {
    const int c = 3 + 9 * (M - 1 - k);
    y.R[k] = x.R[k] * so3::exp(dX.segment<3>(c));
    y.n[k] = x.n[k] + dX.segment<3>(c + 3);
    y.u[k] = x.u[k] + dX.segment<3>(c + 6);
  }
  return y;
}

// Multiple shooting to `target` with M segments (0: automatic, pieces of growth ≈ e² each, 4..64):
// Newton from the warm solution's nodes, else along the load path from the unloaded shape. On
// success the tip frame goes through finish() as a single-shooting solution would.
bool GeneralRodSolver::multiple_shooting(const Load& target, RodSolution* sol, FoldTracker* folds, int M) {
  if (M < 2) M = std::clamp(static_cast<int>(std::ceil(growth_estimate(target.q, target.wrench) / 2.0)), 4, 64);
  sol->segments = M;
  double residual = 0.0;
  std::pair<Mat3, Vec3> pose;
  MsNodes x;
  bool done = have_solution_ && ms_nodes(R_tip_, load_, M, &x) && ms_newton(&x, target, &residual, sol, &pose);
  const Load rest = no_load(actuator_count());
  if (!done && !ms_nodes(unloaded_tip_, rest, M, &x)) {
    sol->message = "multiple shooting: the unloaded shape failed to integrate";
    return false;
  }
  double t = done ? 1.0 : 0.0, dt = 0.25;
  int steps = 0;
  while (t < 1.0 && steps < settings_.max_continuation_steps) {
    const double t_next = std::min(1.0, t + dt);
    MsNodes trial = x;
    ++steps;
    if (ms_newton(&trial, load_between(rest, target, t_next), &residual, sol, &pose)) {
      x = trial;
      t = t_next;
      dt = std::min(0.5, 2.0 * dt);
    } else if ((dt *= 0.5) < 1e-4) {
      break;
    }
  }
  sol->continuation_steps += steps;
  if (t < 1.0) {
    sol->message = "multiple shooting (" + std::to_string(M) + " segments) stopped at load fraction " +
                   std::to_string(t) + " (|F| = " + std::to_string(residual) + ")";
    return false;
  }
  // The tip frame through the single-shooting machinery (pose, C^b, J_q, shape, warm start); the
  // residual is multiple shooting's, and no Richardson check (as ShootingSolver's multiple shooting).
  Shooting p{*this, target, sol};
  p.x = x.R[M];
  p.e = evaluate(p.x, target, &sol->rhs_evaluations);
  sol->residual = residual;
  if (!finish(&p, p.e.ok, folds, false)) return false;
  // The pose is multiple shooting's own; the single sweep that C^b, J_q and the shape use loses
  // ~e^{λL}·1e-16: say so when it no longer reproduces the base.
  sol->tip_rotation = pose.first;
  sol->tip_position = pose.second;
  if (p.e.r.norm() > 1e-6)
    sol->warning += std::string(sol->warning.empty() ? "" : "; ") +
                    "multiple shooting at λL = " + std::to_string(growth_estimate(target.q, target.wrench)) +
                    ": C^b, J_q and the shape come from one sweep from the tip, which reaches the base only to " +
                    std::to_string(p.e.r.norm()) + " rad";
  return true;
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
