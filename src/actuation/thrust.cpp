#include "hydrojet_control/actuation/thrust.h"

#include <cmath>
#include <cstdio>

namespace hydrojet {
namespace actuation {

namespace {
std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

std::string positive(const char* name, double v) {
  if (!std::isfinite(v)) return std::string(name) + " must be finite, got " + fmt(v);
  if (!(v > 0.0)) return std::string(name) + " must be positive, got " + fmt(v);
  return {};
}
}  // namespace

std::string validate(const Nozzle& n) {
  for (const auto& e : {positive("inlet_area", n.inlet_area), positive("outlet_area", n.outlet_area),
                        positive("water_density", n.water_density)}) {
    if (!e.empty()) return e;
  }
  if (!(n.outlet_area < n.inlet_area))
    return "outlet_area must be smaller than inlet_area (else eq. 26 gives thrust <= 0), got " + fmt(n.outlet_area) +
           " >= " + fmt(n.inlet_area);
  return {};
}

double thrust_coefficient(const Nozzle& n) { return n.water_density * (1.0 / n.outlet_area - 1.0 / n.inlet_area); }

double force_from_flow(double Q, const Nozzle& n) {
  if (Q <= 0.0) return 0.0;
  // eq. (26): −ṁ (v_in − v_out) with ṁ = ρQ, v = Q/A
  const double mdot = n.water_density * Q;
  return -mdot * (Q / n.inlet_area - Q / n.outlet_area);
}

double flow_from_force(double F, const Nozzle& n) {
  if (F <= 0.0) return 0.0;
  return std::sqrt(F / thrust_coefficient(n));
}

}  // namespace actuation
}  // namespace hydrojet
