// Per-jet flow regulation: the actuator feedback loop of Campisano et al. 2021, §4 / Figure 3
// (q_obs from the flow sensors). ROS-free; time is passed in, no clock is read.
//
// PI with optional feedforward, output clamped to [output_min, output_max] ⊆ [0, 1] (valve duty):
//   e = Q_des − Q_meas
//   I ← I + k_i e dt      (unless frozen, see below)
//   u = clamp(k_ff (Q_des + T_lead dQ_des/dt) + k_p e + I,  output_min, output_max)
// T_lead (for fast paths): the feedforward inverts a first-order valve lag of that time constant, so that
// a fast-changing desired flow is met on time, not one valve time constant late (0 = off). The rate
// is the backward difference of Q_des over dt (the desired flow is the controller's smooth command).
// Anti-windup by conditional integration (clamping): the integration step is skipped when the output
// computed with the current I is already beyond a limit AND the error would push it further out; it
// keeps integrating when the error drives the output back into range. So I exceeds the headroom to
// the limit by at most one step k_i e dt, and the loop leaves saturation as soon as the setpoint
// becomes reachable (no wound-up integral to unwind).
// A valve with play (backlash of width p, identified from the flow sensors: ValveLagEstimator) moves
// its opening only once the duty leaves the band about it; set_play makes u the opening and commands
// u ± p/2 on the side it moves to (the play's inverse), so a reversal of the flow does not wait for
// the integral to cross the band.
#pragma once

#include <string>

namespace hydrojet {
namespace actuation {

struct FlowRegulatorOptions {
  double kp = 0.0;           ///< proportional gain [1/(m^3/s)] (duty per flow error)
  double ki = 0.0;           ///< integral gain [1/m^3] (duty per flow error per second)
  double feedforward = 0.0;  ///< k_ff [1/(m^3/s)]: duty per unit desired flow; 0 = none
  double lead_time = 0.0;    ///< T_lead [s]: the feedforward leads the desired flow by this lag; 0 = none
  /// The valve's curve, flow ∝ duty^valve_exponent, inverted by the feedforward (1: linear). A
  /// valve whose flow rises faster than its duty at small openings (< 1) lags less near zero flow.
  double valve_exponent = 1.0;
  double output_min = 0.0;  ///< lower duty limit [1], ≥ 0
  double output_max = 1.0;  ///< upper duty limit [1], ≤ 1
};

/// Empty if usable, else a message naming the bad field (non-finite or negative gains, limits not
/// within 0 ≤ output_min ≤ output_max ≤ 1).
std::string validate(const FlowRegulatorOptions& p);

/// A valve's opening with play (backlash) of `width` [duty] after `command`: it moves only when the
/// command leaves the band of half the width about it (the regulator's model of its valve, and the
/// flow sensors' fit of the play).
double play_opening(double opening, double command, double width);

/// PI flow regulator for one jet.
class FlowRegulator {
 public:
  /// Throws std::invalid_argument if validate(params) is non-empty.
  explicit FlowRegulator(const FlowRegulatorOptions& params = FlowRegulatorOptions());

  /// One control step. q_des, q_meas: desired and measured flow [m^3/s]; dt: time since the last
  /// step [s]. Returns the valve command [1] in [output_min, output_max]. On non-finite q_des or
  /// q_meas, or dt not finite and > 0: returns 0 (valve closed), sets ok() = false and error(), and
  /// leaves the integrator untouched (the next valid step resumes; call reset() to restart).
  double update(double q_des, double q_meas, double dt);

  /// Zeroes the integrator and the output and clears the error.
  void reset();
  /// The valve's play [duty] the command inverts (0: none); a width outside [0, 0.5) or not finite is
  /// taken as 0.
  void set_play(double width);
  double play() const { return play_; }

  double output() const { return output_; }          ///< last command [1]
  double integrator() const { return integrator_; }  ///< I [1]
  bool saturated() const { return saturated_; }      ///< last unclamped output was out of range
  bool ok() const { return error_.empty(); }         ///< false after a rejected step
  const std::string& error() const { return error_; }
  const FlowRegulatorOptions& options() const { return params_; }

 private:
  double feedforward(double q) const;

  FlowRegulatorOptions params_;
  double integrator_ = 0.0;
  double output_ = 0.0;
  double play_ = 0.0;              ///< [duty] (set_play)
  double opening_ = 0.0;           ///< the duty past the play, as the commands since reset() left it
  double previous_desired_ = 0.0;  ///< Q_des of the last valid step [m^3/s] (T_lead's rate)
  bool primed_ = false;            ///< a valid step since reset() (the first has no rate)
  bool saturated_ = false;
  std::string error_;
};

}  // namespace actuation
}  // namespace hydrojet
