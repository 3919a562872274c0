#include "hydrojet_control/control/look_at.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "force_polygon.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace control {
namespace {

/// Line-search halvings of a Gauss–Newton step before the iteration gives up.
constexpr int kMaxHalvings = 12;
constexpr const char* kOutOfReach = "the point is out of the jets' reach: the closest aim misses it by";

Eigen::Vector3d jet_force_bounds(const RobotModel& model) {
  if (model.max_jet_force.size() != 3)
    throw std::invalid_argument("max_jet_force: " + std::to_string(model.max_jet_force.size()) + " entries for 3 jets");
  return model.max_jet_force;
}

std::string metres(const char* what, double v) {
  std::ostringstream os;
  os << what << " " << v << " m";
  return os.str();
}

}  // namespace

std::string LookAtOptions::validate() const {
  std::ostringstream os;
  if (max_iterations < 1)
    os << "max_iterations: must be >= 1, got " << max_iterations;
  else if (!std::isfinite(tolerance) || !(tolerance > 0.0))
    os << "tolerance: must be finite and > 0, got " << tolerance;
  else if (!std::isfinite(min_distance) || !(min_distance > 0.0))
    os << "min_distance: must be finite and > 0, got " << min_distance;
  return os.str();
}

struct LookAtSolver::Impl {
  /// One model equilibrium of the iteration.
  struct State {
    Eigen::Vector2d force = Eigen::Vector2d::Zero();  ///< lateral tip force [N], tip frame
    Mat3 rotation = Mat3::Identity();
    Vec3 tip = Vec3::Zero();
    Eigen::Matrix<double, 6, 2> twist_per_force;  ///< C^b times the wrench per lateral force
    Vec3 d() const { return rotation.col(2); }
  };

  Impl(const RobotModel& model, const LookAtOptions& o)
      : options(o),
        jets(model.jets),
        polygon(jets.planar(), jet_force_bounds(model)),
        wrench_per_force(control::wrench_per_force(jets)),
        solver(model.rod, model.solver) {
    if (std::string err = o.validate(); !err.empty()) throw std::invalid_argument(err);
  }

  /// The model at a lateral tip force (false when the solve does not converge).
  bool equilibrium(const Eigen::Vector2d& force, State* s) {
    const rod::Vec6 w = wrench_per_force * force;
    rod::TipWrench tip;
    tip.force = w.head<3>();
    tip.moment = w.tail<3>();
    const rod::RodSolution sol = solver.solve(tip);
    if (!sol.converged) return false;
    s->force = force;
    s->rotation = sol.tip_rotation;
    s->tip = sol.tip_position;
    return true;
  }

  /// C^b at the solver's last converged solution, which must be s's.
  bool linearise(State* s) {
    const rod::Compliance C = solver.compliance();
    s->twist_per_force = C.body * wrench_per_force;
    return C.ok;
  }

  /// The fixed-point residual u − d: zero iff P lies on the tip's axis, in front.
  static Vec3 residual(const State& s, const Vec3& P) { return (P - s.tip).normalized() - s.d(); }

  /// Damped Gauss–Newton step of the residual in the lateral tip force [N].
  static Eigen::Vector2d newton_step(const State& s, const Vec3& P) {
    const Vec3 to_point = P - s.tip;
    const Vec3 u = to_point.normalized();
    const Eigen::Matrix<double, 3, 2> dp = s.rotation * s.twist_per_force.topRows<3>();  // tip motion
    const Eigen::Matrix<double, 3, 2> dd = -so3::hat(s.d()) * s.rotation * s.twist_per_force.bottomRows<3>();
    const Eigen::Matrix<double, 3, 2> J = -(Mat3::Identity() - u * u.transpose()) * dp / to_point.norm() - dd;
    const Eigen::Matrix2d H = J.transpose() * J + 1e-12 * J.squaredNorm() * Eigen::Matrix2d::Identity();
    return -H.ldlt().solve(J.transpose() * residual(s, P));
  }

  /// Backtracking along the step, each trial force clamped into the polygon the jets can allocate
  /// (so that at the edge the iteration slides along it): the first trial whose residual is smaller
  /// than s's replaces s (then linearised). False when none is.
  bool line_search(State* s, const Vec3& P, const Eigen::Vector2d& step) {
    const double r0 = residual(*s, P).norm();
    State trial;
    double fraction = 1.0;
    for (int k = 0; k < kMaxHalvings; ++k, fraction *= 0.5) {
      if (!equilibrium(polygon.clamp(s->force + fraction * step), &trial)) continue;
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
    r.tip_force = s.force;
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
    if (polygon.edge_gap(s.force) < 1e-9) return metres(kOutOfReach, miss_distance(s, P));
    return metres(stalled ? "no convergence (the line search stalled); the aim misses by"
                          : "no convergence within max_iterations; the aim misses by",
                  miss_distance(s, P));
  }

  /// The iteration's start: the last successful solution (kept with its C^b), else the jets off.
  bool start(State* s) {
    if (have_warm) {
      *s = warm;
      return true;
    }
    solver.reset();
    return equilibrium(Eigen::Vector2d::Zero(), s) && linearise(s);
  }

  LookAtResult solve(const Vec3& P) {
    State s;
    if (!P.allFinite()) return result(s, P, 0, "the point is not finite");
    if (!start(&s)) return result(s, P, 0, "the model solve failed with the jets off");
    if ((P - s.tip).norm() < options.min_distance)
      return result(s, P, 0, metres("the point is closer to the tip than min_distance", options.min_distance));
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
  actuation::JetMap jets;
  ForcePolygon polygon;
  Eigen::Matrix<double, 6, 2> wrench_per_force;
  rod::ShootingSolver solver;
  bool have_warm = false;
  State warm;  ///< the last successful solution: the warm start
};

LookAtSolver::LookAtSolver(const RobotModel& model, const LookAtOptions& options)
    : impl_(std::make_shared<Impl>(model, options)) {}

LookAtResult LookAtSolver::solve(const Vec3& point) { return impl_->solve(point); }

void LookAtSolver::reset() {
  impl_->have_warm = false;
  impl_->solver.reset();
}

}  // namespace control
}  // namespace hydrojet
