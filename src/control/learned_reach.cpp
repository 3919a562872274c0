#include "hydrojet_control/control/learned_reach.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace hydrojet {
namespace control {

namespace {
constexpr double kNone = std::numeric_limits<double>::infinity();
}

LearnedReach::LearnedReach(const Vec3& center, int bins, const LearnedReachOptions& o)
    : options_(o), center_(center.normalized()), limits_(std::max(bins, 8), kNone), effective_(limits_) {
  e1_ = center_.unitOrthogonal();
  e2_ = center_.cross(e1_);
}

void LearnedReach::reset() {
  std::fill(limits_.begin(), limits_.end(), kNone);
  std::fill(effective_.begin(), effective_.end(), kNone);
  saturated_for_ = 0.0;
  ring_limit_ = kNone;
  ringing_ = false;
}

double LearnedReach::angle_from_center(const Vec3& d) const { return geodesic_error(center_, d); }

double LearnedReach::azimuth(const Vec3& d) const { return std::atan2(d.dot(e2_), d.dot(e1_)); }

int LearnedReach::bin_of(const Vec3& d) const {
  const int n = static_cast<int>(limits_.size());
  return std::clamp(static_cast<int>(std::floor((azimuth(d) + M_PI) / (2.0 * M_PI) * n)), 0, n - 1);
}

// The least of the bins' effective limits, each widened by `slope` per radian of azimuth beyond the
// bin: continuous in azimuth; and the ringing's limit at every azimuth.
double LearnedReach::limit(const Vec3& direction) const {
  const int n = static_cast<int>(limits_.size());
  const double a = azimuth(direction);
  double best = ring_limit_;
  for (int k = 0; k < n; ++k) {
    if (effective_[k] == kNone) continue;
    const double centre = -M_PI + (k + 0.5) * 2.0 * M_PI / n;
    const double apart = std::abs(std::remainder(a - centre, 2.0 * M_PI));
    best = std::min(best, effective_[k] + options_.slope * std::max(0.0, apart - M_PI / n));
  }
  return best;
}

// The direction at `angle` from the centre along the azimuth of d.
Vec3 LearnedReach::at_angle(const Vec3& d, double angle) const {
  Vec3 radial = d - d.dot(center_) * center_;
  if (radial.norm() < 1e-12) return center_;
  radial.normalize();
  return (std::cos(angle) * center_ + std::sin(angle) * radial).normalized();
}

// A limit moved out by relax_rate over dt; past π it is none.
double LearnedReach::relaxed(double limit, double dt) const {
  if (limit == kNone) return kNone;
  return limit + options_.relax_rate * dt > M_PI ? kNone : limit + options_.relax_rate * dt;
}

void LearnedReach::update(bool saturated, const Vec3& measured, const Vec3& desired, double dt) {
  if (!(dt > 0.0) || !measured.allFinite() || !desired.allFinite()) return;
  const double reached = angle_from_center(measured);
  const bool outward = angle_from_center(desired) > reached + options_.min_error &&
                       geodesic_error(desired, measured) > options_.min_error;
  saturated_for_ = saturated && outward ? saturated_for_ + dt : 0.0;
  if (saturated_for_ >= options_.hold_time) {
    const int k = bin_of(measured);
    limits_[k] = std::min(limits_[k], reached);
    if (effective_[k] == kNone)  // from where the target is (other bins' widened limits may lie far beyond it)
      effective_[k] = std::max(reached, std::min(angle_from_center(desired), limit(desired)));
  } else if (!saturated) {
    for (double& l : limits_) l = relaxed(l, dt);
  }
  for (size_t k = 0; k < limits_.size(); ++k) {  // what clips follows the limits, tightening gradually
    if (limits_[k] == kNone)
      effective_[k] = kNone;
    else if (effective_[k] > limits_[k])
      effective_[k] = std::max(limits_[k], effective_[k] - options_.tighten_rate * dt);
    else
      effective_[k] = limits_[k];
  }
}

void LearnedReach::ring(bool rings, const Vec3& desired, double dt) {
  if (!(dt > 0.0) || !desired.allFinite()) return;
  if (rings && !ringing_) {  // from where the target is (or the limit, when that is tighter)
    ring_limit_ = std::min(angle_from_center(desired), limit(desired));
  }
  ringing_ = rings;
  if (rings)
    ring_limit_ = std::max(0.0, ring_limit_ - options_.ring_rate * dt);
  else
    ring_limit_ = relaxed(ring_limit_, dt);
}

Vec3 LearnedReach::clip(const Vec3& target, double* moved) const {
  const double angle = angle_from_center(target), bound = limit(target);
  if (!(angle > bound)) {
    if (moved) *moved = 0.0;
    return target;
  }
  const Vec3 clipped = at_angle(target, bound);
  if (moved) *moved = geodesic_error(target, clipped);
  return clipped;
}

bool LearnedReach::learned() const {
  return ring_limit_ < kNone || std::any_of(effective_.begin(), effective_.end(), [](double l) { return l < kNone; });
}

}  // namespace control
}  // namespace hydrojet
