// Waterjet thrust of Campisano et al. 2021, §6.2, eq. (26). ROS-free.
//
//   q_f = −ṁ (v_in − v_out),   ṁ = ρ Q,   v_in = Q / A_in,   v_out = Q / A_out   (continuity)
//   =>  F = ρ Q² (1/A_out − 1/A_in)                                          [N]
// for a volumetric flow Q [m^3/s] through a nozzle that narrows from A_in to A_out.
#pragma once

#include <string>

namespace hydrojet {
namespace actuation {

/// Nozzle of one jet. Defaults: Table 1 (A_in, A_out) and water at ~20 °C.
struct Nozzle {
  double inlet_area = 1.13e-6;   ///< A_in [m^2]
  double outlet_area = 3.84e-7;  ///< A_out [m^2]; must be < A_in for positive thrust
  double water_density = 998.0;  ///< ρ [kg/m^3]
};

/// Empty if the parameters are usable, else a message naming the bad field: non-finite or
/// non-positive values, or outlet_area ≥ inlet_area (eq. 26 would then give thrust ≤ 0).
std::string validate(const Nozzle& nozzle);

/// Thrust coefficient k = ρ (1/A_out − 1/A_in) [kg/m^4], so that F = k Q².
double thrust_coefficient(const Nozzle& nozzle);

/// Jet force F = ρ Q² (1/A_out − 1/A_in) [N] for flow Q [m^3/s], eq. (26). Q ≤ 0 gives 0 (a jet
/// cannot pull); NaN propagates.
double force_from_flow(double Q, const Nozzle& nozzle);

/// Inverse of force_from_flow: Q = sqrt(F / k) [m^3/s] for a jet force F [N]. F ≤ 0 gives 0 (a
/// negative force is not producible; the allocator never asks for one when q_min ≥ 0); NaN
/// propagates.
double flow_from_force(double F, const Nozzle& nozzle);

}  // namespace actuation
}  // namespace hydrojet
