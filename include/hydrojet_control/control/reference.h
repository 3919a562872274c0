// The reference x_des the controller tracks: who commands it (one source at a time, the
// latest command wins) and how it moves. A new target is not a step: the reference moves toward it
// along the great circle at most max_angular_rate [rad/s]; a path, once the reference is on it,
// is followed as written at its own speed (the paper's printed rates). Its own motion per
// step is the PD's feedforward (DirectionPd takes the change of x_des, eq. 17; preview() gives the
// path ahead for a lead). Every commanded direction goes
// through ReachableSet::clip first, so the reference never leaves the reachable set. Two sets:
// operator targets (direction, look_at, rates) are clipped to the set swept with a force reserve,
// so that the closed loop keeps authority where a person may park the tip; a path (designed, as the
// paper's §7 spiral, which the paper ran on hardware) is clipped only to what the jets can reach at
// all, so that a path inside that set runs exactly as written; an operator's path (a follow_path
// goal) is clipped as operator targets are.
// Sources:
//   path       a Path from its start time (the configured §7 spiral, or a follow_path goal)
//   direction  a fixed target direction (controller/target_direction)
//   look_at    a fixed target direction solved by LookAtSolver (the node re-solves it)
//   joy        view rates about the tip frame's axes (up = +x, right = +y) until they expire
//   keyboard   the same, from the keyboard
//   hold       the reference stays where it is
// ROS-free; time is passed in.
#pragma once

#include <Eigen/Core>
#include <memory>

#include "hydrojet_control/control/path.h"
#include "hydrojet_control/control/reachable_set.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

enum class Source { kPath, kDirection, kLookAt, kJoy, kKeyboard, kHold };
/// "path", "direction", "look_at", "joy", "keyboard", "hold".
const char* to_string(Source s);

class Reference {
 public:
  /// max_angular_rate [rad/s] > 0; `target_set` clips fixed and rate targets, `path_set` the points
  /// of a path; either may be null (then nothing of that kind is clipped).
  Reference(double max_angular_rate, std::shared_ptr<const ReachableSet> target_set,
            std::shared_ptr<const ReachableSet> path_set);

  void set_max_angular_rate(double rate) { max_rate_ = rate; }

  // Commands: each replaces the one before (the latest wins).
  /// Which set a path's points are clipped to: a designed path (the configured §7 spiral) only to
  /// what the jets reach at all; an operator's path (a follow_path goal) as operator targets are.
  enum class PathClip { kDesigned, kOperator };
  /// Follow `path` from time t [s]; `starts_at_path`: the reference jumps onto the path at its
  /// first step (the configured path at start, as the paper's experiment does) instead of moving there.
  void follow(std::shared_ptr<const Path> path, double t, bool starts_at_path = false,
              PathClip clip = PathClip::kDesigned);
  /// Move to the fixed `target` (base frame, any length: normalised without overflow); source
  /// kDirection or kLookAt. False, and nothing changes, when `target` is not finite or is zero.
  bool aim(const Vec3& target, Source source);
  /// Turn the target at `up_right` [rad/s] (about the tip frame's +x, +y axes) until time `until` [s],
  /// then hold; source kJoy or kKeyboard. The rate is capped at max_angular_rate.
  void turn(const Eigen::Vector2d& up_right, Source source, double until);
  /// Stop where the reference is now.
  void hold();

  /// The reference at the first cycle after start: `direction` (unit), unless a path that starts at
  /// itself drives; a path's clock restarts at t [s].
  void start(const Vec3& direction, double t);

  /// One step to time t [s] (dt [s] since the last): moves the target of a path or of a rate source,
  /// clips it, and moves the reference toward it by at most max_angular_rate·dt. tip_frame: the
  /// tip's rotation (base frame) whose x and y axes the rate sources turn about.
  const Vec3& advance(double t, double dt, const Mat3& tip_frame);

  Source source() const { return source_; }
  /// On a path and joined to it: the reference moves with time, as the path is written.
  bool on_path() const { return source_ == Source::kPath && on_path_; }
  const Vec3& direction() const { return reference_; }
  /// The last target was outside the reachable set and moved by clip_angle() [rad].
  bool clipped() const { return clip_angle_ > 0.0; }
  double clip_angle() const { return clip_angle_; }
  /// The path being followed (null when another source drives).
  const Path* path() const { return source_ == Source::kPath ? path_.get() : nullptr; }
  /// The direction the reference will have `lead` [s] after t [s] on a path it is on (clipped as the
  /// path's points); the reference itself for any other source, or before it has joined the path.
  Vec3 preview(double t, double lead) const;
  /// Time along the path at t [s] (0 when no path drives).
  double path_time(double t) const { return path() ? t - path_start_ : 0.0; }
  /// A path drives and has reached its end.
  bool path_finished(double t) const { return path() && path_time(t) >= path_->duration(); }

 private:
  void set_target(const Vec3& target, const ReachableSet* set);
  void move_toward_target(double dt);

  double max_rate_;
  std::shared_ptr<const ReachableSet> target_set_;  ///< with reserve: fixed and rate targets
  std::shared_ptr<const ReachableSet> path_set_;    ///< full force: path points
  Source source_ = Source::kHold;
  Vec3 reference_ = Vec3::UnitZ();  ///< x_des, unit, base frame
  Vec3 target_ = Vec3::UnitZ();     ///< where the reference is going (clipped)
  double clip_angle_ = 0.0;         ///< how far the last target was moved by the clip [rad]
  std::shared_ptr<const Path> path_;
  const ReachableSet* path_clip_ = nullptr;         ///< the set path_'s points are clipped to (null: none)
  double path_start_ = 0.0;                         ///< [s]
  bool jump_to_path_ = false;                       ///< the next advance() puts the reference on the path
  bool on_path_ = false;                            ///< the reference has joined the path: it follows it as written
  bool path_advanced_ = false;                      ///< advance() has set a path target since follow()
  Eigen::Vector2d rate_ = Eigen::Vector2d::Zero();  ///< (up, right) [rad/s], tip frame
  double rate_until_ = 0.0;                         ///< [s]
};

}  // namespace control
}  // namespace hydrojet
