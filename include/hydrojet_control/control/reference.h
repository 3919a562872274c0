// The reference x_des the controller tracks: who commands it (one source at a time, the
// latest command wins) and how it moves. A new target is not a step: the reference moves toward it
// along the great circle at most max_angular_rate [rad/s]; a path is first approached (the
// reference moves to its first direction that way and waits there until the controller says the tip
// has settled, approach.h), then followed as written at its own speed (the paper's printed rates);
// the paper's experiment instead jumps onto its spiral at start. Its own motion per
// step is the PD's feedforward (DirectionPd takes the change of x_des, eq. 17; preview() gives the
// path ahead for a lead). Every commanded direction goes
// through ReachableSet::clip first, so the reference never leaves the reachable set (and then out of
// the keep-out regions, keep_out.h). Two sets:
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
#include <limits>
#include <memory>

#include "hydrojet_control/control/keep_out.h"
#include "hydrojet_control/control/learned_reach.h"
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
  /// A path's clock runs slower where the path would turn the reference faster than `rate` [rad/s]
  /// (time scaling: the path as written, later). Infinity: as written.
  void set_max_path_rate(double rate) { max_path_rate_ = rate; }
  /// The reach the jets have shown (it clips every target that a set clips, after the set); the
  /// controller teaches it (LearnedReach::update).
  LearnedReach& learned_reach() { return learned_; }
  const LearnedReach& learned_reach() const { return learned_; }

  /// Keep-out regions (keep_out.h; null: none): every target is clipped out of them after the sets,
  /// and the reference moving toward a target slides along their edge instead of entering.
  void set_keep_out(std::shared_ptr<const KeepOut> keep_out);
  const KeepOut* keep_out() const { return keep_out_.get(); }
  /// How far the plant's tip is off the model's at the same direction [m] (KeepOut::clearance): the
  /// keep-out regions are checked at the model's position plus this.
  void set_keep_out_offset(const Vec3& offset) { keep_out_offset_ = offset; }
  const Vec3& keep_out_offset() const { return keep_out_offset_; }

  // Commands: each replaces the one before (the latest wins).
  /// Which set a path's points are clipped to: a designed path (the configured §7 spiral) only to
  /// what the jets reach at all; an operator's path (a follow_path goal) as operator targets are.
  enum class PathClip { kDesigned, kOperator };
  /// How a path begins.
  enum class PathStart {
    /// The reference jumps onto the path at its first step and the clock runs from start (the
    /// paper's experiment: the configured spiral from rest).
    kJump,
    /// The approach (approach.h): the reference moves to the path's first direction at
    /// max_angular_rate and holds it there; the path's clock starts at begin_path().
    kApproach,
  };
  /// Follow `path` from time t [s] (the approach, or the clock, starts then).
  void follow(std::shared_ptr<const Path> path, double t, PathStart start = PathStart::kApproach,
              PathClip clip = PathClip::kDesigned);
  /// Move to the fixed `target` (base frame, any length: normalised without overflow); source
  /// kDirection or kLookAt. False, and nothing changes, when `target` is not finite or is zero.
  bool aim(const Vec3& target, Source source);
  /// Turn the target at `up_right` [rad/s] (about the tip frame's +x, +y axes) until time `until` [s],
  /// then hold; source kJoy or kKeyboard. The rate is capped at max_angular_rate.
  void turn(const Eigen::Vector2d& up_right, Source source, double until);
  /// Stop where the reference is now.
  void hold();

  /// The reference at the first cycle after start: `direction` (unit), unless a path that jumps
  /// onto itself drives; a path's clock (or its approach) restarts at t [s].
  void start(const Vec3& direction, double t);

  /// One step to time t [s] (dt [s] since the last): moves the target of a path or of a rate source,
  /// clips it, and moves the reference toward it by at most max_angular_rate·dt. tip_frame: the
  /// tip's rotation (base frame) whose x and y axes the rate sources turn about.
  const Vec3& advance(double t, double dt, const Mat3& tip_frame);

  Source source() const { return source_; }
  /// On a path and its clock running: the reference moves with time, as the path is written.
  bool on_path() const { return source_ == Source::kPath && on_path_; }
  /// A path drives and is being approached: its clock has not started.
  bool approaching() const { return source_ == Source::kPath && !on_path_; }
  /// Approaching, and the reference is on the path's first direction (clipped as the path's points).
  bool at_path_start() const { return approaching() && reference_ == target_ && path_advanced_; }
  /// Starts the path's clock at t [s] (the tip has settled on its first direction).
  void begin_path(double t);
  /// [s] the last path's approach took (0 for a jump; while approaching: so far, at the last advance).
  double approach_time() const { return approach_time_; }
  const Vec3& direction() const { return reference_; }
  /// The last target was outside the reachable set and moved by clip_angle() [rad].
  bool clipped() const { return clip_angle_ > 0.0; }
  double clip_angle() const { return clip_angle_; }
  /// The path being followed (null when another source drives).
  const Path* path() const { return source_ == Source::kPath ? path_.get() : nullptr; }
  /// The direction the reference will have `lead` [s] after t [s] on a path it is on (clipped as the
  /// path's points); the reference itself for any other source, or while the path is approached.
  Vec3 preview(double t, double lead) const;
  /// Time along the path at t [s] (0 when no path drives or while it is approached): its clock,
  /// which time scaling may have slowed.
  double path_time(double t) const { return on_path() ? t - path_start_ - slowed_ : 0.0; }
  /// A path drives, its clock runs and it has reached its end.
  bool path_finished(double t) const { return on_path() && path_time(t) >= path_->duration(); }
  /// How much longer than written the path has taken so far: (elapsed) / (path time) ≥ 1 [-].
  double time_scale() const { return path_clock_ > 0.0 ? (path_clock_ + slowed_) / path_clock_ : 1.0; }
  /// The last target was clipped by the learned reach (LearnedReach), not by the set alone.
  bool reach_limited() const { return reach_limited_; }
  /// The last target, or the reference on its way, was moved out of a keep-out region.
  bool kept_out() const { return kept_out_; }

 private:
  void set_target(const Vec3& target, const ReachableSet* set);
  void advance_clock(double t, double dt);
  void move_toward_target(double step);
  /// Clear of the keep-out regions (within kEdgeTolerance: an edge point is clear).
  bool clear(const Vec3& d) const;
  static constexpr double kEdgeTolerance = 1e-6;  ///< [m]

  double max_rate_;
  double max_path_rate_ = std::numeric_limits<double>::infinity();
  LearnedReach learned_;
  double path_clock_ = 0.0;  ///< [s] along the path (its clock, time-scaled)
  double slowed_ = 0.0;      ///< [s] the clock has lost to time scaling
  bool reach_limited_ = false;
  bool kept_out_ = false;
  std::shared_ptr<const KeepOut> keep_out_;
  Vec3 keep_out_offset_ = Vec3::Zero();
  double time_scale_now_ = 1.0;                     ///< the clock's slowing at the last advance (1: as written)
  std::shared_ptr<const ReachableSet> target_set_;  ///< with reserve: fixed and rate targets
  std::shared_ptr<const ReachableSet> path_set_;    ///< full force: path points
  Source source_ = Source::kHold;
  Vec3 reference_ = Vec3::UnitZ();  ///< x_des, unit, base frame
  Vec3 target_ = Vec3::UnitZ();     ///< where the reference is going (clipped)
  double clip_angle_ = 0.0;         ///< how far the last target was moved by the clip [rad]
  std::shared_ptr<const Path> path_;
  const ReachableSet* path_clip_ = nullptr;         ///< the set path_'s points are clipped to (null: none)
  double path_start_ = 0.0;                         ///< [s] the clock's start (or the approach's, until it has begun)
  bool jump_to_path_ = false;                       ///< the next advance() puts the reference on the path
  bool on_path_ = false;                            ///< the path's clock runs: the reference follows it as written
  bool path_advanced_ = false;                      ///< advance() has set a path target since follow()
  double approach_time_ = 0.0;                      ///< [s] see approach_time()
  Eigen::Vector2d rate_ = Eigen::Vector2d::Zero();  ///< (up, right) [rad/s], tip frame
  double rate_until_ = 0.0;                         ///< [s]
};

}  // namespace control
}  // namespace hydrojet
