#include "hydrojet_control/control/resolved_rates.h"

#include <Eigen/Cholesky>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>

#include "hydrojet_control/actuation/bounded_allocation.h"

#include "hydrojet_control/rod/so3.h"
#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {

double fast_path_weight(double rate, double min_rate) {
  if (!(min_rate > 0.0)) return 1.0;
  const double v2 = rate * rate;
  return std::isfinite(v2) ? v2 / (v2 + min_rate * min_rate) : 1.0;
}

std::string PdOptions::validate() const {
  const struct {
    const char* field;
    double value, lo, hi;
  } ranges[] = {{"kp", kp, 0.0, 50.0},
                {"kd", kd, 0.0, 5.0},
                {"ki", ki, 0.0, 100.0},
                {"max_integral", max_integral, 0.0, 10.0},
                {"feedforward", feedforward, 0.0, 2.0},
                {"fast_path_rate", fast_path_rate, 0.0, 10.0}};
  for (const auto& r : ranges)
    if (std::string err = util::check_range(r.field, r.value, r.lo, r.hi); !err.empty()) return err;
  return "";
}

std::string AllocationOptions::validate() const {
  if (std::string err = util::check_range("damping", damping, 1e-4, 10.0); !err.empty()) return err;
  if (!(std::isfinite(weight) && weight >= 0.0)) return util::bad("weight", weight, "must be finite and >= 0");
  if (std::string err = util::check_range("smoothing", smoothing, 0.0, 10.0); !err.empty()) return err;
  if (!(max_common_force_rate > 0.0 && max_common_force_rate <= 20.0))
    return util::bad("max_common_force_rate", max_common_force_rate, "must lie in (0, 20] N/s");
  return "";
}

Vec3 DirectionPd::correction(const Vec3& observed, const Vec3& desired, double dt, const PdOptions& gains) {
  const Vec3 err = rotation_between(observed, desired);  // x_err of eq. (17)
  if (!primed_) {
    prev_error_ = err;
    prev_desired_ = desired;
    integral_.setZero();
    primed_ = true;
  }
  // The integral of the error (on a ramp, a fast path, it leaves nearly no steady error),
  // bounded, weighted by the reference's speed and leaking as it slows (PdOptions::ki,
  // fast_path_rate).
  const Vec3 own_motion = rotation_between(prev_desired_, desired);  // x_des's own motion since the last step
  const double span = dt + skipped_;                                 // ... which took this long [s]
  speed_ = span > 0.0 ? own_motion.norm() / span : 0.0;
  skipped_ = 0.0;
  if (gains.ki > 0.0) {
    const double w = fast_path_weight(speed_, gains.fast_path_rate);
    Vec3 increment = dt * w * err;
    if (const double along = increment.dot(held_axis_); along > 0.0) increment -= along * held_axis_;
    integral_ += increment - std::min(1.0, dt * (1.0 - w) * gains.kp) * integral_;
    if (integral_.norm() > gains.max_integral) integral_ *= gains.max_integral / integral_.norm();
  }
  const Vec3 x_cntr =
      gains.kp * dt * err + gains.ki * dt * integral_ + gains.kd * (err - prev_error_) + gains.feedforward * own_motion;
  prev_error_ = err;
  prev_desired_ = desired;
  return x_cntr;
}

InputVector jet_common_mode(const rod::ActuationJacobian& actuation, const InputVector& jets) {
  const int n = static_cast<int>(jets.size());
  InputVector mode = InputVector::Zero(n);
  Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxInputs> A(6, 0);
  Eigen::Matrix<int, Eigen::Dynamic, 1, 0, kMaxInputs, 1> index(0);
  for (int i = 0; i < n; ++i)
    if (jets[i] != 0.0) {
      A.conservativeResize(Eigen::NoChange, A.cols() + 1);
      A.col(A.cols() - 1) = actuation.col(i);
      index.conservativeResize(index.size() + 1);
      index(index.size() - 1) = i;
    }
  const int m = static_cast<int>(A.cols());
  if (m < 2 || !A.allFinite()) return mode;
  // The null space: right singular vectors of the 6 × m jet columns with σ ≤ 1e-6 σ_max (and
  // every vector past the sixth when m > 6). 1e-6, not rounding's 1e-16: a general robot's J_q is
  // computed, to about 1e-9; a direction that moves the tip by 1e-6 of the others is still a
  // common mode for this purpose.
  const Eigen::JacobiSVD<Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxInputs>> svd(A, Eigen::ComputeFullV);
  const auto& s = svd.singularValues();
  const double tol = 1e-6 * (s.size() > 0 ? s(0) : 0.0);
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxInputs, 1> ones = Eigen::VectorXd::Ones(m);
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxInputs, 1> nearest = Eigen::VectorXd::Zero(m);
  for (int k = 0; k < m; ++k)
    if (k >= s.size() || s(k) <= tol) nearest += svd.matrixV().col(k) * svd.matrixV().col(k).dot(ones);
  const double top = nearest.maxCoeff();
  if (!(top > 0.0) || nearest.minCoeff() <= 1e-6 * top) return mode;  // cannot raise every jet
  for (int k = 0; k < m; ++k) mode[index(k)] = nearest(k) / top;
  return mode;
}

AllocationRounding round_allocation(const InputVector& q, const InputVector& lower, const InputVector& mode,
                                    double scale) {
  AllocationRounding r;
  double y0 = std::numeric_limits<double>::infinity();
  for (int i = 0; i < q.size(); ++i)
    if (mode[i] > 0.0) y0 = std::min(y0, (q[i] - lower[i]) / mode[i]);
  if (!std::isfinite(y0)) return r;
  r.excess = std::max(0.0, y0);
  if (!(scale > 0.0)) return r;  // no rounding: the least common mode
  double sum = 0.0;
  for (int i = 0; i < q.size(); ++i)
    if (mode[i] > 0.0) sum += std::exp(-((q[i] - lower[i]) / mode[i] - y0) / scale);  // each term in (0, 1]
  r.amount = scale * std::log(sum);
  return r;
}

namespace {

using WrenchRows = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxInputs>;

/// The step's QP: H = MᵀM + μ²W̃ᵀW̃ + λI, g = Mᵀ(δd + M base) + μ²W̃ᵀW̃ base (½qᵀHq − gᵀq).
void step_qp(const Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxInputs>& M, const WrenchRows& W, const Vec3& dd,
             const InputVector& base, const InputStepOptions& o, actuation::InputHessian* H, InputVector* g) {
  const int n = static_cast<int>(base.size());
  const actuation::InputHessian WtW = W.transpose() * W;
  *H = M.transpose() * M + o.damping * o.damping * WtW;
  // λ, made definite as bounded_allocation.h does for λ = 0.
  H->diagonal().array() += std::max(o.allocation_weight, 1e-12 * H->trace() / n + 1e-300);
  *g = M.transpose() * (dd + M * base) + o.damping * o.damping * (WtW * base);
}

/// Scales the step q − base so that its tip-force change is at most max_step [N], then q so that its
/// tip force is at most max_force [N] (toward 0, clamped into the box should 0 lie outside it).
InputVector limit(InputVector q, const InputVector& base, const WrenchRows& W, const InputVector& lower,
                  const InputVector& upper, const InputStepOptions& o) {
  const double step = (W.topRows<3>() * (q - base)).norm();
  if (step > o.max_force_step) q = base + (q - base) * (o.max_force_step / step);
  const double force = (W.topRows<3>() * q).norm();
  if (force > o.max_force) q *= o.max_force / force;
  return q.cwiseMax(lower).cwiseMin(upper);
}

}  // namespace

InputStep input_step(const Mat3& tip_rotation, const ActuatedModel::Linearisation& lin, const Vec3& x_cntr,
                     const InputVector& base_in, const InputVector& lower, const InputVector& upper,
                     const InputStepOptions& o) {
  InputStep out;
  const int n = static_cast<int>(base_in.size());
  out.q = base_in;
  if (!lin.ok || lin.actuation.cols() != n || lin.wrenches.cols() != n || lower.size() != n || upper.size() != n) {
    out.message = "control: actuation Jacobian missing or of the wrong size";
    return out;
  }
  const InputVector base = base_in.cwiseMax(lower).cwiseMin(upper);
  out.q = base;
  const Vec3 d = tip_rotation.col(2);  // the model's tip direction
  const Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxInputs> M =
      -so3::hat(d) * tip_rotation * lin.actuation.bottomRows<3>();
  WrenchRows W = lin.wrenches;
  W.bottomRows<3>() /= o.length;  // moments as forces at the arm L
  actuation::InputHessian H;
  InputVector g;
  step_qp(M, W, x_cntr.cross(d), base, o, &H, &g);
  const actuation::BoxQpResult qp = actuation::minimise_box_qp(H, g, lower, upper, &base);
  if (!qp.ok) {
    out.message = "control: " + qp.message;
    return out;
  }
  const InputVector q_free = H.ldlt().solve(g);
  out.bound_cost = (W.topRows<3>() * (qp.q - q_free)).norm();
  out.q = limit(qp.q, base, W, lower, upper, o);
  out.lost = M * (q_free - out.q);
  out.ok = out.q.allFinite();
  if (!out.ok) {
    out.message = "control: non-finite input command";
    out.q = base;
  }
  return out;
}

CornerRounding::CornerRounding(const ActuatedModel& model, const InputVector& jets)
    : jets_(jets), lower_(model.lower()), upper_(model.upper()), length_(model.rod().length()) {}

void CornerRounding::reset() {
  common_force_ = 0.0;
  common_mode_.resize(0);
}

InputVector CornerRounding::apply(const InputVector& q, const ActuatedModel::Linearisation& lin, const Cycle& cycle,
                                  const AllocationOptions& options) {
  bool fresh = false;  // a mode found this cycle (else only the excess along the last one)
  double scale = 0.0;
  if (options.smoothing > 0.0) {
    const InputVector mode = jet_common_mode(lin.actuation, jets_);
    if (!mode.isZero()) {
      common_mode_ = mode;
      fresh = true;
      rod::Vec6 wrench = lin.wrenches * q;  // the mode adds none
      wrench.tail<3>() /= length_;
      scale = options.smoothing * std::max(wrench.norm(), cycle.min_force);
    }
  }
  if (common_mode_.size() != q.size()) return q;  // never rounded
  const AllocationRounding r = round_allocation(q, lower_, common_mode_, scale);
  const double target = fresh ? (r.amount - r.excess) * cycle.speed_weight : 0.0;
  double room = std::numeric_limits<double>::infinity();
  for (int i = 0; i < q.size(); ++i)
    if (common_mode_[i] > 0.0) room = std::min(room, (cycle.top * upper_[i] - q[i]) / common_mode_[i]);
  const double step = options.max_common_force_rate * cycle.dt;
  common_force_ = std::clamp(target, common_force_ - step, common_force_ + step);
  common_force_ = std::clamp(common_force_, -r.excess, std::max(room, 0.0));
  if (common_force_ == 0.0) return q;
  return q + common_force_ * common_mode_;
}

}  // namespace control
}  // namespace hydrojet
