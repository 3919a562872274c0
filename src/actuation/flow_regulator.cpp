#include "hydrojet_control/actuation/flow_regulator.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hydrojet {
namespace actuation {

std::string validate(const FlowRegulatorOptions& p) {
  const std::pair<const char*, double> gains[] = {
      {"kp", p.kp}, {"ki", p.ki}, {"feedforward", p.feedforward}, {"lead_time", p.lead_time}};
  for (const auto& g : gains)
    if (!std::isfinite(g.second) || g.second < 0.0) return std::string(g.first) + " must be finite and >= 0";
  if (p.lead_time > 1.0) return "lead_time must lie in [0, 1] s";
  if (!(p.valve_exponent >= 0.1 && p.valve_exponent <= 10.0)) return "valve_exponent must lie in [0.1, 10]";
  if (!std::isfinite(p.output_min) || p.output_min < 0.0) return "output_min must be in [0, 1]";
  if (!std::isfinite(p.output_max) || p.output_max > 1.0) return "output_max must be in [0, 1]";
  if (!(p.output_min <= p.output_max)) return "output_min must be <= output_max";
  return {};
}

FlowRegulator::FlowRegulator(const FlowRegulatorOptions& params) : params_(params) {
  const std::string e = validate(params);
  if (!e.empty()) throw std::invalid_argument("FlowRegulatorOptions: " + e);
}

void FlowRegulator::reset() {
  integrator_ = 0.0;
  output_ = 0.0;
  opening_ = 0.0;
  previous_desired_ = 0.0;
  primed_ = false;
  saturated_ = false;
  error_.clear();
}

double FlowRegulator::update(double q_des, double q_meas, double dt) {
  const char* bad = !std::isfinite(q_des)              ? "desired flow is not finite"
                    : !std::isfinite(q_meas)           ? "measured flow is not finite"
                    : !(std::isfinite(dt) && dt > 0.0) ? "dt must be finite and > 0"
                                                       : nullptr;
  if (bad) {
    error_ = bad;
    output_ = 0.0;
    opening_ = play_opening(opening_, output_, play_);
    return output_;
  }
  error_.clear();

  const double e = q_des - q_meas;
  const double rate = primed_ ? (q_des - previous_desired_) / dt : 0.0;
  previous_desired_ = q_des;
  primed_ = true;
  const double base = feedforward(q_des + params_.lead_time * rate) + params_.kp * e;
  // Conditional integration: if the output (with the integrator as it stands) is already beyond a
  // limit and e pushes further out, freeze I. So I overshoots its headroom by at most one step.
  const double before = base + integrator_;
  const bool frozen = (before > params_.output_max && e > 0.0) || (before < params_.output_min && e < 0.0);
  if (!frozen) integrator_ += params_.ki * e * dt;
  const double unclamped = base + integrator_;
  saturated_ = unclamped > params_.output_max || unclamped < params_.output_min;
  output_ = std::clamp(unclamped, params_.output_min, params_.output_max);
  if (play_ > 0.0) {  // the play's inverse: the opening moves onto u from the side it moves to
    const double half = 0.5 * play_, u = output_;
    if (u > opening_) output_ = std::min(u + half, params_.output_max);
    if (u < opening_) output_ = std::max(u - half, params_.output_min);
  }
  opening_ = play_opening(opening_, output_, play_);
  return output_;
}

double play_opening(double opening, double command, double width) {
  const double half = 0.5 * width;
  if (command > opening + half) return command - half;
  if (command < opening - half) return command + half;
  return opening;
}

void FlowRegulator::set_play(double width) { play_ = std::isfinite(width) && width > 0.0 && width < 0.5 ? width : 0.0; }

// The duty for flow q by the inverted valve curve: k_ff q is the fraction of the flow at full duty.
double FlowRegulator::feedforward(double q) const {
  const double u = params_.feedforward * q;
  return u <= 0.0 || params_.valve_exponent == 1.0 ? u : std::pow(u, 1.0 / params_.valve_exponent);
}

}  // namespace actuation
}  // namespace hydrojet
