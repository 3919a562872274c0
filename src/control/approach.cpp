#include "hydrojet_control/control/approach.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {
namespace {
/// At most this many samples in the window (10 s at 1 kHz): the work per cycle stays bounded.
constexpr size_t kMaxWindow = 10000;
}  // namespace

std::string ApproachOptions::validate() const {
  const struct {
    const char* field;
    double value, hi;
    const char* unit;
  } ranges[] = {
      {"tolerance", tolerance, 0.5, "rad"}, {"settle_time", settle_time, 10.0, "s"}, {"timeout", timeout, 600.0, "s"}};
  for (const auto& r : ranges)
    if (!(r.value > 0.0 && r.value <= r.hi))
      return util::bad(r.field, r.value, "must lie in (0, " + util::num(r.hi) + "] " + r.unit);
  return "";
}

ApproachMonitor::ApproachMonitor(const ApproachOptions& options) { set_options(options); }

void ApproachMonitor::set_options(const ApproachOptions& options) {
  if (std::string err = options.validate(); !err.empty()) throw std::invalid_argument(err);
  options_ = options;
}

void ApproachMonitor::reset() {
  window_.clear();
  reached_ = false;
  failure_.clear();
}

void ApproachMonitor::window_stats(double* rms_error, double* spread) const {
  double e2 = 0.0;
  Vec3 mean = Vec3::Zero();
  for (const Sample& s : window_) e2 += s.error * s.error, mean += s.measured;
  const double n = static_cast<double>(window_.size());
  *rms_error = std::sqrt(e2 / n);
  mean.normalize();
  double a2 = 0.0;
  for (const Sample& s : window_) a2 += std::pow(geodesic_error(mean, s.measured), 2);
  *spread = std::sqrt(a2 / n);
}

ApproachMonitor::Verdict ApproachMonitor::update(double t, bool reference_there, double loop_error,
                                                 const Vec3& measured) {
  if (!reference_there) {
    reached_ = false;
    window_.clear();
    return Verdict::kMoving;
  }
  if (!reached_) reached_ = true, reached_at_ = t;
  window_.push_back({t, loop_error, measured});
  while (window_.size() > kMaxWindow || (window_.size() > 1 && window_.front().t < t - options_.settle_time))
    window_.pop_front();
  double rms_error = 0.0, spread = 0.0;
  window_stats(&rms_error, &spread);
  // A full window: it reaches back settle_time (within one sample's rounding).
  const bool full = t - reached_at_ >= options_.settle_time - 1e-9;
  if (full && rms_error <= options_.tolerance && spread <= options_.tolerance && std::isfinite(rms_error + spread))
    return Verdict::kSettled;
  if (t - reached_at_ <= options_.timeout) return Verdict::kSettling;
  char b[320];
  std::snprintf(b, sizeof(b),
                "the tip did not settle on the path's first direction within %.3g s (over the last %.3g s: RMS "
                "error %.4f rad, RMS spread %.4f rad; tolerance %.4f rad)",
                options_.timeout, options_.settle_time, rms_error, spread, options_.tolerance);
  failure_ = b;
  return Verdict::kFailed;
}

}  // namespace control
}  // namespace hydrojet
