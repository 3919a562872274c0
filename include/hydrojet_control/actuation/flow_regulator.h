// Per-jet flow regulation: the actuator feedback loop of Campisano et al. 2021, §4 / Figure 3
// (q_obs from the flow sensors). ROS-free (Eigen only); time is passed in, no clock is read.
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
#pragma once

#include <array>
#include <string>

#include <Eigen/Core>

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
  bool anti_windup = true;  ///< false: plain PI (integrator unbounded), for comparison only
};

/// Empty if usable, else a message naming the bad field (non-finite or negative gains, limits not
/// within 0 ≤ output_min ≤ output_max ≤ 1).
std::string validate(const FlowRegulatorOptions& p);

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

  double output() const { return output_; }          ///< last command [1]
  double integrator() const { return integrator_; }  ///< I [1]
  bool saturated() const { return saturated_; }      ///< last unclamped output was out of range
  bool ok() const { return error_.empty(); }         ///< false after a rejected step
  const std::string& error() const { return error_; }
  const FlowRegulatorOptions& parameters() const { return params_; }

 private:
  double feedforward(double q) const;

  FlowRegulatorOptions params_;
  double integrator_ = 0.0;
  double output_ = 0.0;
  double previous_desired_ = 0.0;  ///< Q_des of the last valid step [m^3/s] (T_lead's rate)
  bool primed_ = false;            ///< a valid step since reset() (the first has no rate)
  bool saturated_ = false;
  std::string error_;
};

/// Three regulators, one per jet.
class FlowRegulatorBank {
 public:
  explicit FlowRegulatorBank(const FlowRegulatorOptions& params = FlowRegulatorOptions());
  explicit FlowRegulatorBank(const std::array<FlowRegulatorOptions, 3>& params);

  /// Valve commands [1] for desired / measured flows [m^3/s] after dt [s]. A jet with bad input
  /// gets 0 (see FlowRegulator::update); the others are unaffected.
  Eigen::Vector3d update(const Eigen::Vector3d& q_des_flow, const Eigen::Vector3d& q_meas_flow, double dt);
  void reset();
  bool ok() const;
  /// First error among the jets, prefixed with "jet i: ", or empty.
  std::string error() const;
  const FlowRegulator& operator[](int i) const { return jets_[i]; }

 private:
  std::array<FlowRegulator, 3> jets_;
};

}  // namespace actuation
}  // namespace hydrojet
