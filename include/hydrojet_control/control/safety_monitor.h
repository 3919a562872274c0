// The controller's safety monitor (§7.3 and the brief): every reason to stop the jets that is not
// a law of the paper. Sensor health (stale, missing or non-finite tracker and flow samples), flow
// faults (a jet that does not follow its command: valve stuck, line blocked), rod-solver failures,
// elastic stability (eq. 23) and oscillation. Each check returns an empty string when healthy, else
// the abort reason, prefixed with its source ("tracker: ...", "flow: ...", "model: ...",
// "stability: ...", "oscillation: ..."). ROS-free; time is passed in.
#pragma once

#include <string>

#include "hydrojet_control/control/controller_io.h"
#include "hydrojet_control/rod/rod_solver.h"

namespace hydrojet {
namespace control {

/// The monitor's thresholds (`safety/` in the controller file).
struct SafetyOptions {
  double max_oscillation = 0.5;         ///< abort when the desired–measured tip angle exceeds this [rad]
                                        ///< (armed once the tip has come within the limit)
  double sample_period = 0.01;          ///< tracker and flow sample period [s]
  int stale_periods = 3;                ///< data older than stale_periods·sample_period is stale
  int max_solver_failures = 2;          ///< abort after this many non-converged solves in a row
  double min_stability_margin = 0.5;    ///< abort when σ_c (eq. 23) falls below this [N/m]
  double unreachable_tolerance = 1e-3;  ///< allocation residual [N] above which the force is out of reach
  double flow_fault_tolerance = 3e-6;   ///< |measured − commanded flow| that counts as a jet fault [m^3/s]
  double flow_fault_time = 0.5;         ///< a deviation twice the tolerance trips after this long [s]
  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};

class SafetyMonitor {
 public:
  /// The thresholds of `options` (validated: std::invalid_argument naming the field) for
  /// input_count inputs.
  SafetyMonitor(const SafetyOptions& options, int input_count);

  /// New thresholds (validated as by the constructor); the history is kept.
  void set_options(const SafetyOptions& options);
  const SafetyOptions& options() const { return options_; }
  /// Forgets the history (start of a path): solver failures, oscillation arming, flow-fault
  /// integrals and the last flow command.
  void reset();

  /// Sensor health: a valid tracker sample, no older than stale_periods·sample_period, finite; a
  /// valid flow sample as fresh, with one finite, non-negative flow per jet.
  std::string check_sensors(const ControllerInputs& in) const;

  /// Flow faults: a jet whose measured flow stays far from the flow it was last commanded cannot
  /// be controlled; the flow loop would only wind up. The excess deviation beyond the tolerance is
  /// integrated, so that a gross fault trips sooner than a marginal one: trip when
  /// ∫(|ΔQ| − tol)⁺ dt ≥ tol · flow_fault_time. flows [m^3/s], dt [s].
  std::string check_flow_faults(const InputVector& flows, double dt);
  /// Remembers this cycle's flow command [m^3/s], the reference of the next check_flow_faults().
  void record_flow_command(const InputVector& flow_command) { last_flow_command_ = flow_command; }

  /// Solver failures: counts non-converged solves in a row (a converged one resets the count) and
  /// trips at max_solver_failures.
  std::string check_solver(const rod::RodSolution& solution);

  /// Stability of the equilibrium (§4.1): finite compliance, min Re eig(S) > 0 and
  /// σ_c (eq. 23) ≥ min_stability_margin.
  std::string check_stability(const rod::Compliance& compliance, const rod::StabilityReport& report) const;

  /// Oscillation (§7.3): trips when the tip is more than max_oscillation from the commanded
  /// direction. Arms once the tip has come within the limit, so that a far-away static target can
  /// still be reached. error_geodesic [rad].
  std::string check_oscillation(double error_geodesic);

 private:
  SafetyOptions options_;
  int solver_failures_ = 0;
  bool oscillation_armed_ = false;
  InputVector flow_fault_integral_;  ///< ∫(|ΔQ| − tol)⁺ dt per jet [m^3]
  InputVector last_flow_command_;    ///< [m^3/s]
};

}  // namespace control
}  // namespace hydrojet
