#include "hydrojet_control/control/reference.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace hydrojet {
namespace control {

const char* to_string(Source s) {
  switch (s) {
    case Source::kPath: return "path";
    case Source::kDirection: return "direction";
    case Source::kLookAt: return "look_at";
    case Source::kJoy: return "joy";
    case Source::kKeyboard: return "keyboard";
    case Source::kHold: return "hold";
  }
  return "unknown";
}

Reference::Reference(double max_angular_rate, std::shared_ptr<const ReachableSet> target_set,
                     std::shared_ptr<const ReachableSet> path_set)
    : max_rate_(max_angular_rate),
      learned_(path_set ? path_set->center() : Vec3::UnitZ()),
      target_set_(std::move(target_set)),
      path_set_(std::move(path_set)) {}

void Reference::follow(std::shared_ptr<const Path> path, double t, PathStart start, PathClip clip) {
  source_ = Source::kPath;
  path_ = std::move(path);
  path_clip_ = clip == PathClip::kOperator ? target_set_.get() : path_set_.get();
  path_start_ = t;
  jump_to_path_ = start == PathStart::kJump;
  on_path_ = false;
  path_advanced_ = false;
  approach_time_ = 0.0;
  path_clock_ = slowed_ = 0.0;
}

void Reference::begin_path(double t) {
  if (!approaching()) return;
  approach_time_ = t - path_start_;
  path_start_ = t;
  on_path_ = true;
  path_clock_ = slowed_ = 0.0;
}

bool Reference::aim(const Vec3& target, Source source) {
  Vec3 unit;
  if (!unit_direction(target, &unit)) return false;
  source_ = source;
  set_target(unit, target_set_.get());
  return true;
}

void Reference::turn(const Eigen::Vector2d& up_right, Source source, double until) {
  if (source_ != source) target_ = reference_;  // a rate source turns the reference from where it is
  source_ = source;
  // Capped at max_angular_rate along its own direction; scaled first, so that a rate of 1e308 is
  // capped, not taken for an infinity (whose cap would be zero).
  const double scale = up_right.cwiseAbs().maxCoeff();
  const Eigen::Vector2d along = scale > 0.0 ? Eigen::Vector2d(up_right / scale) : Eigen::Vector2d::Zero();
  rate_ = scale * along.norm() > max_rate_ ? Eigen::Vector2d(along.normalized() * max_rate_) : up_right;
  rate_until_ = until;
}

void Reference::hold() {
  source_ = Source::kHold;
  target_ = reference_;
  clip_angle_ = 0.0;
}

void Reference::start(const Vec3& direction, double t) {
  if (source_ == Source::kPath) {
    path_start_ = t, approach_time_ = 0.0;
    path_clock_ = slowed_ = 0.0;
    if (jump_to_path_) return;          // advance() puts the reference on the path
    on_path_ = path_advanced_ = false;  // the approach starts again from here
  }
  reference_ = direction;
  if (source_ == Source::kHold || source_ == Source::kJoy || source_ == Source::kKeyboard) target_ = direction;
}

const Vec3& Reference::advance(double t, double dt, const Mat3& tip_frame) {
  if (source_ == Source::kPath) {
    if (jump_to_path_) on_path_ = true;  // the paper's start: on the path, its clock running
    jump_to_path_ = false;
    // On the path: followed as written, its clock slowed where the path is faster than
    // max_path_rate. Approaching: its first direction.
    if (on_path_) advance_clock(t, dt);
    set_target(path_->direction_at(on_path_ ? path_clock_ : 0.0), path_clip_);
    // On the path: onto its point, at most max_path_rate a step where keep-out regions are (off their
    // edge the clipped point may jump; the reference must not cross them).
    if (on_path_) move_toward_target(keep_out_ ? max_path_rate_ * dt : std::numeric_limits<double>::infinity());
    if (!on_path_) approach_time_ = t - path_start_;
    path_advanced_ = true;
  } else if (source_ == Source::kJoy || source_ == Source::kKeyboard) {
    if (t > rate_until_) {
      hold();  // no deadman or no message for the timeout: hold where it is
    } else {
      const Vec3 omega = tip_frame.col(0) * rate_.x() + tip_frame.col(1) * rate_.y();  // [rad/s], base frame
      const double angle = omega.norm() * dt;
      if (angle > 0.0) set_target(Eigen::AngleAxisd(angle, omega.normalized()) * target_, target_set_.get());
    }
  }
  move_toward_target(max_rate_ * dt);
  return reference_;
}

Vec3 Reference::preview(double t, double lead) const {
  if (source_ != Source::kPath || !on_path_ || !(lead > 0.0)) return reference_;
  (void)t;
  const Vec3 ahead = path_->direction_at(path_clock_ + lead / time_scale_now_);
  const Vec3 in_set = path_clip_ ? path_clip_->clip(ahead) : Vec3(ahead.normalized());
  const Vec3 reached = path_clip_ ? learned_.clip(in_set) : in_set;
  return keep_out_ ? keep_out_->clip(reached, nullptr, keep_out_offset_) : reached;
}

// The path's clock over dt [s]: at the path's own pace, or slower where the path would turn the
// reference by more than max_path_rate·dt this step (the step's own turn, so a corner of the path
// inside it counts). The first advance on a path that was jumped onto starts the clock at t.
void Reference::advance_clock(double t, double dt) {
  const double as_written = t - path_start_ - slowed_;  // the clock's next time at the path's own pace
  time_scale_now_ = 1.0;
  const double limit = max_path_rate_ * dt;
  const Vec3 from = path_->direction_at(path_clock_);
  double step = as_written - path_clock_;
  double turn = geodesic_error(from, path_->direction_at(path_clock_ + step));
  if (!(step > 0.0) || !(turn > limit)) {
    path_clock_ = as_written;
    return;
  }
  // The longest step of the path that turns by at most the limit: bisection between 0 (no turn) and
  // the step as written (too far), started at the proportional guess.
  double lo = 0.0, hi = step;
  double guess = step * limit / turn;
  for (int k = 0; k < 40 && hi - lo > 1e-9 * step; ++k) {
    const double mid = k == 0 ? guess : 0.5 * (lo + hi);
    (geodesic_error(from, path_->direction_at(path_clock_ + mid)) <= limit ? lo : hi) = mid;
  }
  step = lo;
  if (!(step > 0.0)) {  // the path jumps here: its clock waits (the reference's own rate limit moves it)
    slowed_ = t - path_start_ - path_clock_;
    return;
  }
  time_scale_now_ = dt / step;
  path_clock_ += step;
  slowed_ = t - path_start_ - path_clock_;
}

// The commanded direction (unit) clipped to `set` (none: not clipped), then to the learned reach,
// then out of the keep-out regions.
void Reference::set_target(const Vec3& target, const ReachableSet* set) {
  clip_angle_ = 0.0;
  reach_limited_ = kept_out_ = false;
  target_ = set ? set->clip(target, &clip_angle_) : target;
  if (set) {
    double pulled = 0.0;
    target_ = learned_.clip(target_, &pulled);
    reach_limited_ = pulled > 0.0;
  }
  if (keep_out_) {
    double moved = 0.0;
    target_ = keep_out_->clip(target_, &moved, keep_out_offset_);
    kept_out_ = moved > 0.0;
    if (!clear(target_)) target_ = reference_, kept_out_ = true;  // nothing allowed: hold
  }
  if (reach_limited_ || kept_out_) clip_angle_ = geodesic_error(target, target_);
}

// Along the great circle toward the target by at most `step` [rad]; exactly onto it when closer. A
// reference clear of the keep-out regions that the step would take in slides along their edge
// instead (or stays, where nothing is allowed); one that starts inside, where the tip was, moves out
// toward its allowed target.
void Reference::move_toward_target(double step) {
  const Vec3 before = reference_;
  const bool was_clear = clear(reference_);
  const Vec3 rotation = rotation_between(reference_, target_);
  const double angle = rotation.norm();
  reference_ = angle <= step ? target_ : Vec3((Eigen::AngleAxisd(step, rotation / angle) * reference_).normalized());
  if (keep_out_ && was_clear && !clear(reference_)) {
    const Vec3 slid = keep_out_->clip(reference_, nullptr, keep_out_offset_);
    reference_ = clear(slid) ? slid : before;
    kept_out_ = true;
  }
}

bool Reference::clear(const Vec3& d) const {
  return !keep_out_ || keep_out_->clearance(d, keep_out_offset_) >= -kEdgeTolerance;
}

void Reference::set_keep_out(std::shared_ptr<const KeepOut> keep_out) {
  keep_out_ = std::move(keep_out);
  if (keep_out_ && source_ != Source::kPath)
    set_target(target_, nullptr);  // a fixed target already set: out of them too
}

}  // namespace control
}  // namespace hydrojet
