#include "hydrojet_control/control/safety_monitor.h"

#include <cmath>
#include <stdexcept>

#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {
namespace {

std::string jet_name(int i) { return "jet " + std::to_string(i + 1); }

}  // namespace

std::string SafetyOptions::validate() const {
  const auto positive = [](const char* field, double v) {
    return std::isfinite(v) && v > 0.0 ? std::string() : util::bad(field, v, "must be finite and > 0");
  };
  for (const auto& [field, v] : {std::pair<const char*, double>{"max_oscillation", max_oscillation},
                                 {"sample_period", sample_period},
                                 {"unreachable_tolerance", unreachable_tolerance},
                                 {"flow_fault_tolerance", flow_fault_tolerance},
                                 {"flow_fault_time", flow_fault_time}})
    if (std::string err = positive(field, v); !err.empty()) return err;
  if (stale_periods < 1) return util::bad("stale_periods", stale_periods, "must be >= 1");
  if (max_solver_failures < 1) return util::bad("max_solver_failures", max_solver_failures, "must be >= 1");
  if (!(std::isfinite(min_stability_margin) && min_stability_margin >= 0.0))
    return util::bad("min_stability_margin", min_stability_margin, "must be finite and >= 0");
  return "";
}

SafetyMonitor::SafetyMonitor(const SafetyOptions& options, int input_count)
    : flow_fault_integral_(InputVector::Zero(input_count)), last_flow_command_(InputVector::Zero(input_count)) {
  set_options(options);
}

void SafetyMonitor::set_options(const SafetyOptions& options) {
  if (std::string err = options.validate(); !err.empty()) throw std::invalid_argument(err);
  options_ = options;
}

void SafetyMonitor::reset() {
  solver_failures_ = 0;
  oscillation_armed_ = false;
  flow_fault_integral_.setZero();
  last_flow_command_.setZero();
}

std::string SafetyMonitor::check_sensors(const ControllerInputs& in) const {
  const double stale_after = options_.stale_periods * options_.sample_period + 1e-9;
  if (!in.tip_valid) return "tracker: no valid tip pose";
  if (in.t - in.tip_stamp > stale_after)
    return "tracker: tip pose stale (" + std::to_string(in.t - in.tip_stamp) + " s old)";
  if (!in.tip_rotation.allFinite()) return "tracker: non-finite tip pose";
  if (!in.flow_valid) return "flow: no valid flow sample";
  if (in.t - in.flow_stamp > stale_after)
    return "flow: samples stale (" + std::to_string(in.t - in.flow_stamp) + " s old)";
  if (in.flows.size() != flow_fault_integral_.size())
    return "flow: " + std::to_string(in.flows.size()) + " readings for " + std::to_string(flow_fault_integral_.size()) +
           " jets";
  for (int i = 0; i < in.flows.size(); ++i)
    if (!std::isfinite(in.flows[i]) || in.flows[i] < 0.0)
      return "flow: " + jet_name(i) + " reading invalid (" + std::to_string(in.flows[i]) + " m^3/s)";
  return "";
}

std::string SafetyMonitor::check_flow_faults(const InputVector& flows, double dt) {
  for (int i = 0; i < flows.size(); ++i) {
    const double excess = std::abs(flows[i] - last_flow_command_[i]) - options_.flow_fault_tolerance;
    flow_fault_integral_[i] = excess > 0.0 ? flow_fault_integral_[i] + excess * dt : 0.0;
    if (flow_fault_integral_[i] >= options_.flow_fault_tolerance * options_.flow_fault_time)
      return "flow: " + jet_name(i) + " does not follow its command (measured " + std::to_string(flows[i]) +
             " m^3/s, commanded " + std::to_string(last_flow_command_[i]) + " m^3/s): valve stuck or line blocked";
  }
  return "";
}

std::string SafetyMonitor::check_solver(const rod::RodSolution& solution) {
  if (solution.converged) {
    solver_failures_ = 0;
    return "";
  }
  if (++solver_failures_ < options_.max_solver_failures) return "";
  return "model: rod solver did not converge " + std::to_string(solver_failures_) + " times in a row (" +
         solution.message + ")";
}

std::string SafetyMonitor::check_stability(const rod::Compliance& compliance,
                                           const rod::StabilityReport& report) const {
  if (!compliance.ok || !report.ok) return "model: compliance not finite";
  if (report.eig_min <= 0.0)
    return "stability: equilibrium unstable (min Re eig S = " + std::to_string(report.eig_min) + ")";
  if (report.margin < options_.min_stability_margin)
    return "stability: sigma_c = " + std::to_string(report.margin) + " N/m below margin " +
           std::to_string(options_.min_stability_margin);
  return "";
}

std::string SafetyMonitor::check_oscillation(double error_geodesic) {
  if (error_geodesic <= options_.max_oscillation) oscillation_armed_ = true;
  if (oscillation_armed_ && error_geodesic > options_.max_oscillation)
    return "oscillation: tip " + std::to_string(error_geodesic) + " rad from the commanded direction (limit " +
           std::to_string(options_.max_oscillation) + ")";
  return "";
}

}  // namespace control
}  // namespace hydrojet
