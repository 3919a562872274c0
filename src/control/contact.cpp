#include "hydrojet_control/control/contact.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "hydrojet_control/rod/so3.h"
#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {

namespace {
constexpr double kPriorForce = 0.05;  ///< [N] the σ of a force along an axis not observed (a stomach's contact forces)
constexpr double kObservable = 0.005;  ///< [N] an axis is observed when one sample's σ along it is below this
// The mismatch model's prior σ per coefficient [N]: what calibration leaves (docs/contact.md). It
// bounds the model's covariance, so the nearly collinear regressors of a nearly straight rod cannot
// learn large coefficients that cancel where they were learned and not where the path goes next.
constexpr double kPriorConstant = 0.03;  ///< a force fixed in the tip frame
constexpr double kPriorRotation = 0.01;  ///< per entry of the tip frame (a gravity tilted wrongly)
constexpr double kPriorInputs = 0.015;   ///< per input at its scale (a stiffness or a jet's direction off)
constexpr double kVarianceTime = 10.0;   ///< [s] the residual variance's averaging time
constexpr double kHistory = 0.5;         ///< [s] of model poses kept for the tracker's latency
}  // namespace

const char* to_string(ContactReaction r) {
  switch (r) {
    case ContactReaction::kComply: return "comply";
    case ContactReaction::kHold: return "hold";
    case ContactReaction::kRetreat: return "retreat";
  }
  return "unknown";
}

bool parse_contact_reaction(const std::string& name, ContactReaction* reaction) {
  for (const ContactReaction r : {ContactReaction::kComply, ContactReaction::kHold, ContactReaction::kRetreat})
    if (name == to_string(r)) {
      *reaction = r;
      return true;
    }
  return false;
}

std::string ContactOptions::validate() const {
  if (std::string err = util::check_range("force_threshold", force_threshold, 0.001, 1.0); !err.empty()) return err;
  if (std::string err = util::check_range("max_force", max_force, 0.005, 2.0); !err.empty()) return err;
  if (!(max_force >= 2.5 * force_threshold))
    return util::bad("max_force", max_force,
                     "must be at least 2.5 force_threshold (comply holds 0.4 of it, above the detector's threshold)");
  return "";
}

ContactEstimator::ContactEstimator(const ContactOptions& options, int inputs, double input_scale)
    : options_(options), input_scale_(input_scale > 0.0 ? input_scale : 1.0) {
  theta_ = Eigen::MatrixXd::Zero(10 + inputs, 3);
  residual_var_ = Vec3::Constant(std::pow(options.force_threshold / 3.0, 2));
  Eigen::VectorXd prior(10 + inputs);
  prior[0] = kPriorConstant * kPriorConstant;
  prior.segment<9>(1).setConstant(kPriorRotation * kPriorRotation);
  prior.tail(inputs).setConstant(kPriorInputs * kPriorInputs);
  info0_ = (residual_var_[0] * prior.cwiseInverse()).asDiagonal();  // in 1 / residual variances
  info_ = info0_;
  p_ = info_.inverse();
}

void ContactEstimator::reset() {
  history_.clear();
  last_sample_t_ = -1.0;
  first_sample_t_ = -1.0;
  learning_load_ = false;
  load_held_ = false;
  load_.setZero();
  rising_ = false;
  looks_.clear();
  snapshots_.clear();
  direction_known_ = false;
  below_since_ = -1.0;
  load_since_ = -1.0;
  above_ = 0;
  filtered_.setZero();
  state_ = ContactState();
}

void ContactEstimator::take_as_load(double t) {
  load_since_ = t;
  state_.in_contact = false;
  state_.normal.setZero();
  state_.since = 0.0;
  free_since_ = t - kRelearnDelay;
  learning_load_ = true;
  load_held_ = true;
  if (rising_) {  // what the mismatch model learned since the force rose was the load
    theta_ = rise_theta_;
    info_ = rise_info_;
    p_ = info_.inverse();
    while (!snapshots_.empty() && snapshots_.back().t > rise_.t) snapshots_.pop_back();
  }
  load_ += to_force_ * filtered_;  // what is beyond the load now joins it; it settles over kLoadSettle
  filtered_.setZero();
  state_.force = load_;
  state_.reading.setZero();
  state_.load = load_;
  state_.deflection.setZero();
  rising_ = false;
  looks_.clear();
  above_ = 0;
}

// (1, the tip frame's nine entries, q / input_scale): a force fixed in the tip frame (a precurvature
// offset), one fixed in the base frame seen from the tip (a gravity the model tilts wrongly), and
// one that grows with the inputs (a stiffness or a jet's direction off).
Eigen::VectorXd ContactEstimator::regressor(const Mat3& rotation, const InputVector& q) const {
  Eigen::VectorXd phi = Eigen::VectorXd::Ones(theta_.rows());
  phi.segment<9>(1) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(rotation.data());
  for (int i = 0; i < q.size() && i + 10 < phi.size(); ++i) phi[i + 10] = q[i] / input_scale_;
  return phi;
}

// The latest model pose at or before `stamp` (the oldest kept when the stamp is older still).
const ContactEstimator::ModelPose* ContactEstimator::pose_at(double stamp) const {
  if (history_.empty()) return nullptr;
  const ModelPose* best = &history_.front();
  for (const ModelPose& p : history_)
    if (p.t <= stamp + 1e-9) best = &p;
  return best;
}

// How the mismatch model reads a force f that the jets take up: (I + G) f, G = (dm/dq) B⁺, dm/dq the
// model's growth with the inputs (its regressors follow the model's pose, which the inputs turn:
// C^b's rotation rows times each input's wrench), B the inputs' tip forces. Learned in free space,
// dm/dq is C_m⁻¹ (C_plant − C_m) B: a plant stiffer or softer than the model, or a capsule whose
// weight the model does not carry, reads f as C_m⁻¹ C_plant f. G's mean over the jets' forces is
// taken (a compliance's ratio, not a misaligned jet's turn, which stays with the inputs under a
// load too), bounded to [kMinReadingGain, kMaxReadingGain]; a model that has learned nothing reads 1.
Mat3 ContactEstimator::reading_gain(const ModelPose& pose) const {
  const int n = static_cast<int>(pose.inputs.size());
  if (pose.wrenches.cols() != n || n == 0) return Mat3::Identity();
  Eigen::Matrix<double, 3, Eigen::Dynamic> dm(3, n);
  for (int i = 0; i < n; ++i) {
    const Vec3 turn = pose.compliance.block<3, 6>(3, 0) * pose.wrenches.col(i);
    dm.col(i) = mismatch_change(pose.rotation * so3::hat(turn), i);
  }
  const Eigen::Matrix<double, 3, Eigen::Dynamic> B = pose.wrenches.topRows<3>();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(B.rows(), B.cols(), Eigen::ComputeThinU | Eigen::ComputeThinV);
  svd.setThreshold(1e-3);  // of the largest singular value: the HydroJet's jets make no axial force
  const Eigen::MatrixXd pinv = svd.compute(B).solve(Eigen::Matrix3d::Identity());  // B⁺, least norm
  const Mat3 P = B * pinv;  // the projector on the forces the jets make
  const double ratio = 1.0 + (dm * pinv).trace() / std::max(1.0, P.trace());
  if (!std::isfinite(ratio)) return Mat3::Identity();
  return Mat3::Identity() + (std::clamp(ratio, kMinReadingGain, kMaxReadingGain) - 1.0) * P;
}

// The regressor is affine in (R, q): the mismatch model's change along (dR, one unit of input i) is
// Θᵀ [0; vec(dR); e_i / input_scale].
Vec3 ContactEstimator::mismatch_change(const Mat3& dR, int input) const {
  Vec3 d = theta_.middleRows(1, 9).transpose() * Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dR.data());
  if (input + 10 < theta_.rows()) d += theta_.row(input + 10).transpose() / input_scale_;
  return d;
}

Vec3 ContactEstimator::deflection(const Vec3& force) const {
  const Vec3 turn = last_compliance_.block<3, 3>(3, 0) * (last_rotation_.transpose() * force);
  return last_rotation_ * Vec3(turn.y(), -turn.x(), 0.0);  // (θ × e3) in the tip frame
}

const ContactState& ContactEstimator::update(const ContactCycle& c) {
  if (c.model_rotation.allFinite() && c.model_position.allFinite() && c.compliance.allFinite() &&
      c.inputs.size() + 10 == theta_.rows() && c.inputs.allFinite())
    history_.push_back({c.t, c.model_rotation, c.model_position, c.compliance, c.inputs,
                        c.input_wrenches.cols() == c.inputs.size() && c.input_wrenches.allFinite()
                            ? c.input_wrenches
                            : rod::ActuationJacobian::Zero(6, 0)});
  while (!history_.empty() && history_.front().t < c.t - kHistory) history_.pop_front();
  const ModelPose* pose = c.new_sample ? pose_at(c.stamp) : nullptr;
  Vec3 raw;
  Mat3 raw_cov;
  if (!pose || !c.measured_rotation.allFinite() || !deflection_force(c, *pose, &raw, &raw_cov)) return state_;

  const double dt = last_sample_t_ < 0.0 ? 0.0 : std::clamp(c.t - last_sample_t_, 0.0, 1.0);
  last_sample_t_ = c.t;
  if (first_sample_t_ < 0.0) first_sample_t_ = c.t;
  const Mat3& R = pose->rotation;
  const Eigen::VectorXd phi = regressor(R, pose->inputs);
  // Beyond the mismatch and the load (tip frame), as the model reads it: a force f that the jets
  // take up reads (I + G) f (reading_gain). The detector compares that reading, as before; the
  // force reported, and the load, are the reading divided by it.
  const Mat3 gain = reading_gain(*pose);
  to_force_ = R * gain.inverse() * R.transpose();
  // A held load that, with the push beyond it, passes kMaxLoad × max_force goes back to the reading:
  // the detector judges the whole push.
  if (load_held_ && !(held_push() <= kMaxLoad * options_.max_force)) {
    filtered_ += R * gain * R.transpose() * load_;
    load_.setZero();
    load_held_ = learning_load_ = false;
  }
  const Vec3 error = raw - theta_.transpose() * phi - gain * (R.transpose() * load_);
  const double spread = phi.dot(p_ * phi);  // the mismatch model's uncertainty here, in residual variances
  // The threshold, or 3σ of what the mismatch model leaves (its residual, wider where it has not
  // seen the configuration): a plant far from its model is read less finely rather than falsely.
  const double threshold =
      std::max(options_.force_threshold, 3.0 * std::sqrt(residual_var_.maxCoeff() * (1.0 + spread)));
  // Free space: a load being settled follows what is left (the mismatch frozen meanwhile), then is
  // kept; long enough after a contact the mismatch is learned beside it.
  const bool settling = load_held_ && c.t - load_since_ < kLoadSettle;
  if (!state_.in_contact && dt > 0.0) {
    if (settling) load_ += dt / (kLoadTime + dt) * (to_force_ * (R * error));
    if (load_held_ && !settling && load_.norm() < 0.5 * options_.force_threshold) {
      load_held_ = false;  // the load went away
      load_.setZero();
    }
    // A sample above the threshold counts toward a flag (a contact, or a load to be told apart): not learned.
    if (!settling && error.norm() <= threshold && c.t - free_since_ >= kRelearnDelay) learn(phi, error, dt);
  }

  // The estimate: low-passed, in the base frame.
  const double alpha = dt > 0.0 ? dt / (kFilterTime + dt) : 1.0;
  filtered_ += alpha * (R * error - filtered_);
  // The mismatch model's snapshots (in free space), for unlearn().
  if (!state_.in_contact && (snapshots_.empty() || c.t - snapshots_.back().t >= kSnapshotPeriod))
    snapshots_.push_back({c.t, theta_, info_});
  while (!snapshots_.empty() && snapshots_.front().t < c.t - kUnlearnLookBack) snapshots_.pop_front();
  phi_ = phi;
  last_rotation_ = R;
  last_compliance_ = pose->compliance;
  const Mat3 mismatch_cov = (residual_var_ * spread).asDiagonal();
  state_.force = load_ + to_force_ * filtered_;
  state_.reading = filtered_;
  state_.load = load_;
  state_.covariance =
      to_force_ * R * (raw_cov * (alpha / (2.0 - alpha)) + mismatch_cov) * R.transpose() * to_force_.transpose();
  state_.threshold = threshold;
  state_.deflection = deflection(filtered_);
  state_.ready = true;
  // The tip's direction for the give, low-passed as the force is: one sample's noise (0.3° per axis)
  // is as large as the give that tells a small load, and turned a wall's onset into a load.
  if (!direction_known_) measured_direction_ = c.measured_rotation.col(2);
  direction_known_ = true;
  measured_direction_ += alpha * (c.measured_rotation.col(2) - measured_direction_);
  detect(c.t, alpha, c, measured_direction_, R.col(2));
  return state_;
}

// Weighted least squares of the deflection (the direction's (θ_y, −θ_x) and the position's, in the
// model's tip frame) on C^b's force columns, on the axes it observes: an axis whose per-sample σ
// exceeds kObservable (the axial force of a straight, axially stiff rod, seen in the position
// alone) is reported as zero with the prior's variance.
bool ContactEstimator::deflection_force(const ContactCycle& c, const ModelPose& pose, Vec3* force, Mat3* cov) const {
  const Mat3& R = pose.rotation;
  const bool with_position = c.measured_position.allFinite();
  const int rows = with_position ? 5 : 2;
  Eigen::Matrix<double, 5, 3> G;
  Eigen::Matrix<double, 5, 1> r, w;
  G.row(0) = pose.compliance.block<1, 3>(4, 0);
  G.row(1) = -pose.compliance.block<1, 3>(3, 0);
  const Vec3 dx = R.transpose() * (c.measured_rotation.col(2) - R.col(2));
  r.head<2>() = dx.head<2>();
  w.head<2>().setConstant(1.0 / (kDirectionSigma * kDirectionSigma));
  if (with_position) {
    G.bottomRows<3>() = pose.compliance.block<3, 3>(0, 0);
    r.tail<3>() = R.transpose() * (c.measured_position - pose.position);
    w.tail<3>().setConstant(1.0 / (kPositionSigma * kPositionSigma));
  }
  const auto Gs = G.topRows(rows);
  const Mat3 info = Gs.transpose() * w.head(rows).asDiagonal() * Gs;
  const Vec3 projected = Gs.transpose() * w.head(rows).asDiagonal() * r.head(rows);
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(info);
  force->setZero();
  cov->setZero();
  for (int k = 0; k < 3; ++k) {
    const Vec3 v = eig.eigenvectors().col(k);
    const double lambda = eig.eigenvalues()[k];
    if (lambda * kObservable * kObservable >= 1.0) {
      *force += v * (v.dot(projected) / lambda);
      *cov += v * v.transpose() / lambda;
    } else {
      *cov += v * v.transpose() * (kPriorForce * kPriorForce);
    }
  }
  return force->allFinite() && cov->allFinite();
}

// Recursive least squares on the mismatch model with forgetting (kMemory) toward the prior's
// information rather than toward none (no wind-up where nothing moves), and the
// residual's variance (the threshold's floor): slow, and each sample counts at most the threshold
// squared, so that a contact's onset does not lift the threshold ahead of itself.
void ContactEstimator::learn(const Eigen::VectorXd& phi, const Vec3& error, double dt) {
  const double lambda = std::exp(-dt / kMemory);
  info_ = lambda * info_ + (1.0 - lambda) * info0_;  // forgetting toward the prior's information
  info_.noalias() += phi * phi.transpose();
  p_ = info_.ldlt().solve(Eigen::MatrixXd::Identity(info_.rows(), info_.cols()));
  theta_ += (p_ * phi) * error.transpose();
  const double a = std::min(1.0, dt / kVarianceTime);
  const double cap = options_.force_threshold * options_.force_threshold;
  residual_var_ += a * (error.cwiseAbs2().cwiseMin(cap) - residual_var_);
}

// A push that the mismatch model of a snapshot reads as free space (under half the threshold) is
// what the model learned since (a surface grazed under the threshold, learned, and left): the model
// goes back to the latest such snapshot, and the push with it. Only a snapshot that knew this
// configuration (its variance here at most the residual's, kSnapshotSpread) is trusted so: a model
// that had not seen it could read a genuine contact away.
bool ContactEstimator::unlearn() {
  const Mat3& R = last_rotation_;
  for (auto s = snapshots_.rbegin(); s != snapshots_.rend(); ++s) {
    const Vec3 then = filtered_ + R * ((theta_ - s->theta).transpose() * phi_);
    if (!(then.norm() <= 0.5 * options_.force_threshold)) continue;
    if (!(phi_.dot(s->info.ldlt().solve(phi_)) <= kSnapshotSpread)) continue;
    theta_ = s->theta;
    info_ = s->info;
    p_ = info_.inverse();
    snapshots_.erase(s.base(), snapshots_.end());
    filtered_ = then;
    state_.force = load_ + to_force_ * filtered_;
    state_.reading = filtered_;
    state_.deflection = deflection(filtered_);
    looks_.clear();
    return true;
  }
  return false;
}

// Two samples above the threshold in a row (once armed) flag a contact, unless the tip has given way
// along the force's turn since the force rose while the model stayed: a load (a surface stops the
// tip, or throws it back, while the model goes on into it; a load moves the tip). A
// surface only pushes: the force along the contact's normal below the release level for kReleaseTime
// (kHeldRelease while the reference is held back) releases it; the normal follows the force while
// the push is clear.
void ContactEstimator::detect(double t, double alpha, const ContactCycle& c, const Vec3& measured_direction,
                              const Vec3& model_direction) {
  if (!state_.in_contact) {
    if (learning_load_ && (filtered_.norm() < 0.5 * options_.force_threshold || t - load_since_ > kLoadLearnTime))
      learning_load_ = false;
    if (filtered_.norm() > 0.5 * options_.force_threshold) {
      if (!rising_ || t - rise_.t > kMaxRiseAge) {  // a rise long past without a flag or a give: counted afresh
        rising_ = true;
        rise_ = looks_.empty() ? Look{t, measured_direction, state_.deflection, model_direction} : looks_.front();
        rise_theta_ = theta_;
        rise_info_ = info_;
      }
    } else {
      rising_ = false;
    }
    looks_.push_back({t, measured_direction, state_.deflection, model_direction});
    while (looks_.size() > 1 && looks_.front().t < t - kGiveLookBack) looks_.pop_front();
    const bool armed = t - first_sample_t_ >= kArmTime && !learning_load_;
    if (rising_ && armed) {
      const Vec3 growth = state_.deflection - rise_.deflection;
      const double turn = growth.norm();
      if (turn >= kMinGiveTurn && load_fits() &&
          (measured_direction - rise_.measured).dot(growth) >= kGiveFraction * turn * turn &&
          (model_direction - rise_.model).dot(growth) >= -kPressFraction * turn * turn) {
        take_as_load(t);
        return;
      }
    }
    const double threshold = c.ringing ? kRingingThreshold * state_.threshold : state_.threshold;
    above_ = filtered_.norm() > threshold && armed ? above_ + 1 : 0;
    if (above_ >= 2 && unlearn()) {
      above_ = 0;
      rising_ = false;
      return;
    }
    if (above_ >= 2) {
      state_.in_contact = true;
      state_.since = t;
      state_.normal = filtered_.normalized();
      below_since_ = -1.0;
    }
    return;
  }
  // The release level: under comply's push even where the threshold has risen with the mismatch.
  const double release = 0.5 * std::min(state_.threshold, ContactOptions::kComplyFraction * options_.max_force);
  const double push = filtered_.dot(state_.normal);
  if (push < release) {
    if (below_since_ < 0.0) below_since_ = t;
    if (t - below_since_ >= (c.pressing ? kHeldRelease : kReleaseTime)) {
      state_.in_contact = false;
      rising_ = false;  // a give is counted from a look after the contact
      looks_.clear();
      state_.normal.setZero();
      state_.since = 0.0;
      free_since_ = t;
      above_ = 0;
    }
    return;
  }
  below_since_ = -1.0;
  if (push > state_.threshold)
    state_.normal = (state_.normal + alpha * (filtered_.normalized() - state_.normal)).normalized();
}

}  // namespace control
}  // namespace hydrojet
