#include "hydrojet_control/plant/hydraulics.h"

#include <algorithm>
#include <cmath>

namespace hydrojet {
namespace plant {

std::string ValveModel::validate() const {
  auto pos = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!pos(max_flow)) return "max_flow: must be positive";
  if (!(dead_zone >= 0.0 && dead_zone < 1.0)) return "dead_zone: must lie in [0, 1)";
  if (!pos(exponent)) return "exponent: must be positive";
  if (!(hysteresis >= 0.0 && hysteresis < 0.5)) return "hysteresis: must lie in [0, 0.5)";
  if (!pos(time_constant)) return "time_constant: must be positive";
  if (!pos(saturation)) return "saturation: must be positive";
  return "";
}

std::vector<ValveModel> hydrojet_valves() {
  std::vector<ValveModel> v(3);
  v[0].max_flow = 1.60e-5, v[0].dead_zone = 0.05, v[0].time_constant = 0.04;
  v[1].max_flow = 1.52e-5, v[1].dead_zone = 0.08, v[1].time_constant = 0.05;
  v[2].max_flow = 1.66e-5, v[2].dead_zone = 0.04, v[2].time_constant = 0.035;
  return v;
}

double Valve::steady_flow(double duty) const {
  const double d = std::max(0.0, duty - 0.5 * p_.hysteresis);
  const double u = std::max(0.0, (d - p_.dead_zone) / (1.0 - p_.dead_zone));
  return std::min(p_.saturation, p_.max_flow * std::pow(u, p_.exponent));
}

double Valve::step(double duty, double dt) {
  double d = std::isfinite(duty) ? std::min(1.0, std::max(0.0, duty)) : 0.0;
  if (stuck_duty_ >= 0.0) d = std::min(1.0, stuck_duty_);
  // Play (backlash) of width h: the effective duty moves only when the command leaves the band.
  const double h = 0.5 * p_.hysteresis;
  if (d > effective_ + h) effective_ = d - h;
  if (d < effective_ - h) effective_ = d + h;
  const double u = std::max(0.0, (effective_ - p_.dead_zone) / (1.0 - p_.dead_zone));
  const double q_ss = std::min(p_.saturation, p_.max_flow * std::pow(u, p_.exponent));
  // Exact discretisation of τ Q' = Q_ss − Q over dt.
  flow_ += (1.0 - std::exp(-dt / p_.time_constant)) * (q_ss - flow_);
  return flow_;
}

}  // namespace plant
}  // namespace hydrojet
