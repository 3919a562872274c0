// The reach the jets show, beside the one the model computes (reachable_set.h): where the jets
// saturate and the error stays, the tip has reached as far as this plant goes. Kept as the largest
// angle from the reachable set's centre per azimuth bin (the set's own shape); a target beyond it is
// pulled in along its azimuth, clipped and reported as the model's set clips. The limit is continuous
// in azimuth (a bin's limit widens by `slope` per radian of azimuth away from it) and takes effect
// gradually (from where the target was, at tighten_rate), so a path is never made to jump. It relaxes
// outward slowly once the jets have authority again, so a plant that was only briefly short is given
// its reach back. A plant that rings even under the paper's law (a follower load past its flutter
// load) closes the reach in at every azimuth while its ringing grows; that limit relaxes outward
// as slowly. ROS-free (Eigen).
#pragma once

#include <limits>
#include <vector>

#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

struct LearnedReachOptions {
  double saturation = 0.97;   ///< a jet at this fraction of its q_max or more is saturated [-]
  double min_error = 0.02;    ///< [rad] the error that must stay, outward, while saturated ...
  double hold_time = 0.2;     ///< [s] ... this long before the reach is learned there
  double relax_rate = 0.02;   ///< [rad/s] a limit moves back out at this rate once its cause is gone
  double tighten_rate = 0.2;  ///< [rad/s] a new limit takes effect from where the target was at this rate
  /// [rad/rad] a bin's limit widens by this per radian of azimuth away from it: at 0.3 a limit learned
  /// on a spiral's outer turn still clips the next azimuths it sweeps (at 1 it had widened past them)
  double slope = 0.3;
  double ring_rate = 0.5;  ///< [rad/s] the reach at every azimuth closes in at this rate while the plant rings
};

class LearnedReach {
 public:
  /// `center`: the reachable set's (unit, base frame); `bins` azimuth bins about it.
  explicit LearnedReach(const Vec3& center = Vec3::UnitZ(), int bins = 72, const LearnedReachOptions& o = {});
  const LearnedReachOptions& options() const { return options_; }
  /// Forgets every limit (a new plant, a restart).
  void reset();
  /// One cycle of dt [s]: whether a jet is saturated, the measured and the desired tip directions.
  void update(bool saturated, const Vec3& measured, const Vec3& desired, double dt);
  /// One cycle of dt [s]: while `rings` (the mode grows under the paper's law: the jets' force is past
  /// what the plant holds still), the reach at every azimuth closes in at ring_rate from the desired
  /// direction's angle where the ringing began; otherwise it relaxes outward at relax_rate (slowly: a
  /// reach given back at once would ring the plant again).
  void ring(bool rings, const Vec3& desired, double dt);
  /// [rad from the centre] the reach at every azimuth the ringing left (infinity: none).
  double ring_limit() const { return ring_limit_; }
  /// `target` within the limit that clips now; *moved the angle it was pulled in by [rad] (0: inside).
  Vec3 clip(const Vec3& target, double* moved = nullptr) const;
  /// Some azimuth has a limit.
  bool learned() const;
  /// The limit that clips at the azimuth of `direction` now [rad from the centre] (infinity: none).
  double limit(const Vec3& direction) const;
  /// The limit learned in the bin of `direction` [rad from the centre] (infinity: none).
  double learned_limit(const Vec3& direction) const { return limits_[bin_of(direction)]; }

 private:
  double azimuth(const Vec3& d) const;
  int bin_of(const Vec3& d) const;
  double angle_from_center(const Vec3& d) const;
  Vec3 at_angle(const Vec3& d, double angle) const;
  double relaxed(double limit, double dt) const;

  LearnedReachOptions options_;
  Vec3 center_;
  Vec3 e1_, e2_;                   ///< axes of the azimuth about the centre
  std::vector<double> limits_;     ///< learned, per bin [rad from the centre] (infinity: none)
  std::vector<double> effective_;  ///< what clips now: follows limits_, tightening at tighten_rate
  double saturated_for_ = 0.0;     ///< [s] saturated with the error staying outward
  double ring_limit_ = std::numeric_limits<double>::infinity();  ///< (ring_limit())
  bool ringing_ = false;                                         ///< rang at the last ring()
};

}  // namespace control
}  // namespace hydrojet
