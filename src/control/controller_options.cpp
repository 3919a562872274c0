#include "hydrojet_control/control/controller_options.h"

#include <cmath>
#include <sstream>

namespace hydrojet {
namespace control {
namespace {

std::string bad(const char* field, double v, const std::string& rule) {
  std::ostringstream os;
  os << field << ": " << rule << ", got " << v;
  return os.str();
}

bool finite_nonneg(double v) { return std::isfinite(v) && v >= 0.0; }
bool finite_pos(double v) { return std::isfinite(v) && v > 0.0; }

/// "" if lo ≤ v ≤ hi, else "<field>: must lie in [lo, hi], got v".
std::string check_range(const char* field, double v, double lo, double hi) {
  if (v >= lo && v <= hi) return "";
  std::ostringstream rule;
  rule << "must lie in [" << lo << ", " << hi << "]";
  return bad(field, v, rule.str());
}

}  // namespace

const char* to_string(LoopMode m) { return m == LoopMode::kClosed ? "closed" : "open"; }
const char* to_string(ControlLaw l) { return l == ControlLaw::kModal ? "modal" : "papers"; }
const char* to_string(PathType t) { return t == PathType::kSpiral ? "spiral" : "none"; }

/// A field, its value and its closed range.
struct Range {
  const char* field;
  double value, lo, hi;
};

std::string ControllerOptions::validate() const {
  // The live gains and limits: the ranges of cfg/Controller.cfg.
  const Range ranges[] = {
      {"kp", kp, 0.0, 50.0},
      {"kd", kd, 0.0, 5.0},
      {"feedforward", feedforward, 0.0, 2.0},
      {"damping", damping, 1e-4, 10.0},
      {"max_force", max_force, 0.01, 1.0},
      {"max_force_rate", max_force_rate, 0.01, 20.0},
  };
  for (const auto& r : ranges)
    if (std::string err = check_range(r.field, r.value, r.lo, r.hi); !err.empty()) return err;
  // Set at start only (not in cfg/Controller.cfg).
  if (!(ki >= 0.0 && ki <= 100.0)) return bad("ki", ki, "must lie in [0, 100] 1/s^2");
  if (!(max_integral >= 0.0 && max_integral <= 10.0))
    return bad("max_integral", max_integral, "must lie in [0, 10] rad s");
  if (!(fast_path_rate >= 0.0 && fast_path_rate <= 10.0))
    return bad("fast_path_rate", fast_path_rate, "must lie in [0, 10] rad/s");
  if (!finite_pos(max_angular_rate)) return bad("max_angular_rate", max_angular_rate, "must be finite and > 0");
  if (!(reachable_force_fraction > 0.0 && reachable_force_fraction <= 1.0))
    return bad("reachable_force_fraction", reachable_force_fraction, "must lie in (0, 1]");
  if (!finite_nonneg(allocation_weight)) return bad("allocation_weight", allocation_weight, "must be finite and >= 0");
  if (!(allocation_smoothing >= 0.0 && allocation_smoothing <= 10.0))
    return bad("allocation_smoothing", allocation_smoothing, "must lie in [0, 10]");
  if (!(max_common_force_rate > 0.0 && max_common_force_rate <= 20.0))
    return bad("max_common_force_rate", max_common_force_rate, "must lie in (0, 20] N/s");
  if (!finite_pos(max_oscillation)) return bad("max_oscillation", max_oscillation, "must be finite and > 0");
  if (!finite_pos(sample_period)) return bad("sample_period", sample_period, "must be finite and > 0");
  if (stale_periods < 1) return bad("stale_periods", stale_periods, "must be >= 1");
  if (max_solver_failures < 1) return bad("max_solver_failures", max_solver_failures, "must be >= 1");
  if (!finite_nonneg(min_stability_margin))
    return bad("min_stability_margin", min_stability_margin, "must be finite and >= 0");
  if (!finite_pos(unreachable_tolerance))
    return bad("unreachable_tolerance", unreachable_tolerance, "must be finite and > 0");
  if (!finite_pos(flow_fault_tolerance))
    return bad("flow_fault_tolerance", flow_fault_tolerance, "must be finite and > 0");
  if (!finite_pos(flow_fault_time)) return bad("flow_fault_time", flow_fault_time, "must be finite and > 0");
  if (!finite_pos(path.duration)) return bad("path.duration", path.duration, "must be finite and > 0");
  if (!(path.theta_start >= 0 && path.theta_start <= M_PI / 2))
    return bad("path.theta_start", path.theta_start, "must lie in [0, pi/2]");
  if (!(path.theta_end >= 0 && path.theta_end <= M_PI / 2))
    return bad("path.theta_end", path.theta_end, "must lie in [0, pi/2]");
  if (!std::isfinite(path.phi_start)) return bad("path.phi_start", path.phi_start, "must be finite");
  if (!std::isfinite(path.phi_end)) return bad("path.phi_end", path.phi_end, "must be finite");
  // The modal law's, at start only.
  const Range modal_ranges[] = {
      {"modal.kp", modal.kp, 0.0, 50.0},
      {"modal.ki", modal.ki, 0.0, 100.0},
      {"modal.gain_speed", modal.gain_speed, 0.0, 10.0},
      {"modal.damping_gain", modal.damping_gain, 0.0, 10.0},
      {"modal.actuator_lag", modal.actuator_lag, 0.0, 1.0},
      {"modal.rounding_force", modal.rounding_force, 0.0, 10.0},
      {"modal.tip_mass_scale", modal.tip_mass_scale, 0.1, 100.0},
      {"modal.damping_time", modal.damping_time, 0.0, 1.0},
      {"modal.tracker_sigma", modal.tracker_sigma, 1e-6, 1.0},
      {"modal.velocity_noise", modal.velocity_noise, 1e-6, 1e3},
      {"modal.disturbance_noise", modal.disturbance_noise, 1e-6, 1e3},
  };
  for (const auto& r : modal_ranges)
    if (std::string err = check_range(r.field, r.value, r.lo, r.hi); !err.empty()) return err;
  return approach.validate();
}

}  // namespace control
}  // namespace hydrojet
