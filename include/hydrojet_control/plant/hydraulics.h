// The simulated plant's hydraulics: valve command → flow per jet through a static nonlinearity with
// dead zone, hysteresis (play), a first-order lag and saturation; different constants per jet.
// Flow → jet force is the thrust equation (26) (actuation/thrust.h). ROS-free (Eigen only).
#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>
#include <string>

#include "hydrojet_control/rod/rod_model.h"

namespace hydrojet {
namespace plant {

/// One valve and its line. The defaults are jet 1's of config/plant.yaml (hydrojet_valves()).
struct ValveModel {
  double max_flow = 1.6e-5;     ///< steady flow at full duty before saturation [m^3/s]
  double dead_zone = 0.05;      ///< duty below which no water flows [0, 1)
  double exponent = 0.8;        ///< Q_ss = max_flow · u^exponent, u the duty past the dead zone [-]
  double hysteresis = 0.02;     ///< width of the play between command and effective duty [duty]
  double time_constant = 0.04;  ///< first-order lag of the flow [s]
  double saturation = 1.5e-5;   ///< flow ceiling [m^3/s]
  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};

/// The HydroJet's three valves as config/plant.yaml describes them: they differ a little (dead
/// zone, flow, lag), as three valves always do.
std::vector<ValveModel> hydrojet_valves();

/// One valve and its line.
class Valve {
 public:
  explicit Valve(const ValveModel& p = ValveModel()) : p_(p) {}
  /// Advances by dt [s] under valve duty `duty` (clamped to [0, 1]; NaN counts as closed).
  double step(double duty, double dt);
  /// Steady-state flow for a constant duty reached from below (hysteresis lower branch) [m^3/s].
  double steady_flow(double duty) const;
  double flow() const { return flow_; }
  void reset() { flow_ = 0.0, effective_ = 0.0; }
  /// Fault injection: the valve is stuck at `duty` [0, 1] whatever the command; < 0 frees it.
  void set_stuck(double duty) { stuck_duty_ = duty; }

 private:
  ValveModel p_;
  double flow_ = 0.0;
  double effective_ = 0.0;  ///< duty after the hysteresis play
  double stuck_duty_ = -1.0;
};

/// The jets' hydraulics: one valve per jet, valve i modelled by p[i], or by the models in turn when
/// there are fewer models than jets.
class Hydraulics {
 public:
  /// p: at least one model.
  Hydraulics(const std::vector<ValveModel>& p, int jets) {
    for (int i = 0; i < jets; ++i) valves_.emplace_back(p[i % p.size()]);
  }
  /// Advances every valve by dt [s] under its duty; returns the flows [m^3/s].
  rod::InputVector step(const rod::InputVector& duty, double dt) {
    rod::InputVector q(size());
    for (int i = 0; i < size(); ++i) q[i] = valves_[i].step(duty[i], dt);
    return q;
  }
  rod::InputVector flows() const {
    rod::InputVector q(size());
    for (int i = 0; i < size(); ++i) q[i] = valves_[i].flow();
    return q;
  }
  int size() const { return static_cast<int>(valves_.size()); }
  Valve& operator[](int i) { return valves_[i]; }
  void reset() {
    for (auto& v : valves_) v.reset();
  }

 private:
  std::vector<Valve> valves_;
};

}  // namespace plant
}  // namespace hydrojet
