#include "hydrojet_control/control/look_at.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "hydrojet_control/actuation/bounded_allocation.h"
#include "hydrojet_control/rod/so3.h"
#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {
namespace {

/// Line-search halvings of a Gauss–Newton step before the iteration gives up.
constexpr int kMaxHalvings = 12;
constexpr const char* kOutOfReach = "the point is out of the jets' reach: the closest aim misses it by";

std::string metres(const char* what, double v) { return std::string(what) + " " + util::num(v) + " m"; }

}  // namespace

std::string LookAtOptions::validate() const {
  std::ostringstream os;
  if (max_iterations < 1)
    os << "max_iterations: must be >= 1, got " << max_iterations;
  else if (!std::isfinite(tolerance) || !(tolerance > 0.0))
    os << "tolerance: must be finite and > 0, got " << tolerance;
  else if (!std::isfinite(min_distance) || !(min_distance > 0.0))
    os << "min_distance: must be finite and > 0, got " << min_distance;
  else if (!std::isfinite(max_distance) || !(max_distance > min_distance))
    os << "max_distance: must be finite and > min_distance, got " << max_distance;
  return os.str();
}

struct LookAtSolver::Impl {
  using TaskJacobian = Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxInputs>;

  /// One model equilibrium of the iteration.
  struct State {
    InputVector q;  ///< actuator inputs [N], within their bounds
    Mat3 rotation = Mat3::Identity();
    Vec3 tip = Vec3::Zero();
    rod::ActuationJacobian twist_per_input;  ///< J_q at this equilibrium
    Vec3 d() const { return rotation.col(2); }
  };

  Impl(const RobotModel& m, const LookAtOptions& o) : options(o), model(m) {
    if (std::string err = o.validate(); !err.empty()) throw std::invalid_argument(err);
  }

  /// The model at inputs q (false when the solve does not converge).
  bool equilibrium(const InputVector& q, State* s) {
    const rod::RodSolution sol = model.solve(q);
    if (!sol.converged) return false;
    s->q = q;
    s->rotation = sol.tip_rotation;
    s->tip = sol.tip_position;
    return true;
  }

  /// J_q at the model's last converged solution, which must be s's.
  bool linearise(State* s) {
    const ActuatedModel::Linearisation lin = model.linearise();
    s->twist_per_input = lin.actuation;
    return lin.ok;
  }

  /// The fixed-point residual u − d: zero iff P lies on the tip's axis, in front.
  static Vec3 residual(const State& s, const Vec3& P) { return (P - s.tip).normalized() - s.d(); }

  /// ∂(u − d)/∂q: the tip direction turns by −d̂ R J_q,ω per input and the tip moves by R J_q,v, which
  /// turns u.
  static TaskJacobian jacobian(const State& s, const Vec3& P) {
    const Vec3 to_point = P - s.tip;
    const Vec3 u = to_point.normalized();
    const TaskJacobian dp = s.rotation * s.twist_per_input.topRows<3>();
    const TaskJacobian dd = -so3::hat(s.d()) * s.rotation * s.twist_per_input.bottomRows<3>();
    return -(Mat3::Identity() - u * u.transpose()) * dp / to_point.norm() - dd;
  }

  /// Gauss–Newton step of the residual in the inputs [N] within their bounds (q + step stays in the
  /// box); *blocked: the bounds keep the step from most of the reduction the free step would give.
  InputVector newton_step(const State& s, const Vec3& P, bool* blocked = nullptr) const {
    const TaskJacobian J = jacobian(s, P);
    const Vec3 r = residual(s, P);
    actuation::InputHessian H = J.transpose() * J;
    H.diagonal().array() += 1e-12 * H.trace() / static_cast<double>(s.q.size()) + 1e-300;
    const InputVector g = -J.transpose() * r;
    const InputVector lo = model.lower() - s.q, hi = model.upper() - s.q;
    const actuation::BoxQpResult qp = actuation::minimise_box_qp(H, g, lo, hi);
    const InputVector step = qp.ok ? qp.q : InputVector(InputVector::Zero(s.q.size()));
    if (blocked) {
      const double free_gain = r.norm() - (J * InputVector(H.ldlt().solve(g)) + r).norm();
      const double box_gain = r.norm() - (J * step + r).norm();
      *blocked = free_gain > 0.0 && box_gain < 0.1 * free_gain;
    }
    return step;
  }

  /// Backtracking along the step (within the bounds, as the box is convex; at the edge the iteration
  /// slides along it): the first trial whose residual is smaller than s's replaces s (then
  /// linearised). False when none is.
  bool line_search(State* s, const Vec3& P, const InputVector& step) {
    const double r0 = residual(*s, P).norm();
    State trial;
    double fraction = 1.0;
    for (int k = 0; k < kMaxHalvings; ++k, fraction *= 0.5) {
      if (!equilibrium(s->q + fraction * step, &trial)) continue;
      if (residual(trial, P).norm() >= r0) continue;
      *s = trial;
      return linearise(s);
    }
    return false;
  }

  static double miss_distance(const State& s, const Vec3& P) {
    const Vec3 to_point = P - s.tip;
    return (to_point - to_point.dot(s.d()) * s.d()).norm();
  }

  /// P on the tip's axis within the tolerance, and in front.
  bool aimed(const State& s, const Vec3& P) const {
    return miss_distance(s, P) <= options.tolerance && (P - s.tip).dot(s.d()) > 0.0;
  }

  LookAtResult result(const State& s, const Vec3& P, int iterations, const std::string& message) const {
    LookAtResult r;
    r.direction = s.d();
    r.tip_position = s.tip;
    r.inputs = s.q;
    r.tip_force = model.tip_wrench(s.q).head<2>();
    r.miss_distance = miss_distance(s, P);
    r.iterations = iterations;
    r.message = message;
    r.ok = message.empty();
    r.out_of_reach = message.rfind(kOutOfReach, 0) == 0;
    return r;
  }

  /// Why the final iterate does not aim at P (empty: it does).
  std::string verdict(const State& s, const Vec3& P, bool stalled) const {
    const Vec3 to_point = P - s.tip;
    if (to_point.norm() < options.min_distance)
      return metres("the point is closer to the tip than min_distance", options.min_distance);
    if (to_point.dot(s.d()) <= 0.0) return "the point is behind the camera: no reachable direction has it in front";
    if (aimed(s, P)) return "";
    bool blocked = false;
    newton_step(s, P, &blocked);
    if (blocked) return metres(kOutOfReach, miss_distance(s, P));
    return metres(stalled ? "no convergence (the line search stalled); the aim misses by"
                          : "no convergence within max_iterations; the aim misses by",
                  miss_distance(s, P));
  }

  /// The iteration's start: the last successful solution (kept with its J_q), else the inputs at rest
  /// (0, or the bound nearest to it).
  bool start(State* s) {
    if (have_warm) {
      *s = warm;
      return true;
    }
    model.reset();
    const InputVector rest = InputVector::Zero(model.input_count()).cwiseMax(model.lower()).cwiseMin(model.upper());
    return equilibrium(rest, s) && linearise(s);
  }

  LookAtResult solve(const Vec3& P) {
    State s;
    s.q = InputVector::Zero(model.input_count());
    if (!P.allFinite()) return result(s, P, 0, "the point is not finite");
    if (!start(&s)) return result(s, P, 0, "the model solve failed with the jets off");
    if ((P - s.tip).norm() < options.min_distance)
      return result(s, P, 0, metres("the point is closer to the tip than min_distance", options.min_distance));
    if (!((P - s.tip).norm() <= options.max_distance))  // inf beyond the doubles: refused too
      return result(s, P, 0, metres("the point is farther from the tip than max_distance", options.max_distance));
    int it = 0;
    bool stalled = false;
    while (it < options.max_iterations && !aimed(s, P)) {
      ++it;
      if (!line_search(&s, P, newton_step(s, P))) {
        stalled = true;
        break;
      }
    }
    const std::string why = verdict(s, P, stalled);
    if (why.empty()) warm = s;
    have_warm = have_warm || why.empty();
    return result(s, P, it, why);
  }

  LookAtOptions options;
  ActuatedModel model;
  bool have_warm = false;
  State warm;  ///< the last successful solution: the warm start
};

LookAtSolver::LookAtSolver(const RobotModel& model, const LookAtOptions& options)
    : impl_(std::make_shared<Impl>(model, options)) {}

LookAtResult LookAtSolver::solve(const Vec3& point) { return impl_->solve(point); }

void LookAtSolver::reset() {
  impl_->have_warm = false;
  impl_->model.reset();
}

}  // namespace control
}  // namespace hydrojet
