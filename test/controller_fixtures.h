// Shared fixtures for the controller's tests: the quasi-static plant it steers, the gains the tests
// were tuned with, a run loop, and a great-circle path.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include <yaml-cpp/yaml.h>

#include "hydrojet_control/actuation/flow_regulator.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/control/path.h"
#include "hydrojet_control/rod/rod_solver.h"

namespace hydrojet {
namespace test {

inline constexpr double kDt = 0.01;             // 100 Hz
inline constexpr double kFlowPerDuty = 1.6e-5;  // plant valve: full duty gives 1.6e-5 m^3/s

inline actuation::FlowRegulatorOptions flow_gains() {
  actuation::FlowRegulatorOptions p;
  p.feedforward = 1.0 / kFlowPerDuty;
  p.kp = 0.3 / kFlowPerDuty;
  p.ki = 5.0 / kFlowPerDuty;
  return p;
}

/// Quasi-static plant: valves set flows instantly, flows set jet forces by eq. (26), the rod
/// settles at once. Its rod may differ from the controller's model.
struct StaticPlant {
  rod::RodSolver rod;
  actuation::JetMap jets;
  actuation::Nozzle nozzle;
  control::Vec3 flows = control::Vec3::Zero();
  control::Mat3 tip = control::Mat3::Identity();
  int stuck_jet = -1;       ///< fault injection: this jet's flow is stuck_flow whatever the valve
  double stuck_flow = 0.0;  ///< [m^3/s]

  StaticPlant(const config::Scene& sc, const rod::RodModel& truth)
      : rod(truth, sc.solver), jets(*sc.jets), nozzle(sc.nozzle) {
    apply(control::Vec3::Zero());
  }
  void apply(const control::Vec3& duty) {
    flows = duty.cwiseMax(0.0).cwiseMin(1.0) * kFlowPerDuty;
    if (stuck_jet >= 0) flows[stuck_jet] = stuck_flow;
    control::Vec3 q;
    for (int i = 0; i < 3; ++i) q[i] = actuation::force_from_flow(flows[i], nozzle);
    rod::TipWrench w;
    w.force = jets.wrench(q).head<3>();
    const rod::RodSolution s = rod.solve(w);
    ASSERT_TRUE(s.converged);
    tip = s.tip_rotation;
  }
  control::ControllerInputs inputs(double t) const {
    control::ControllerInputs in;
    in.t = t;
    in.tip_valid = in.flow_valid = true;
    in.tip_stamp = in.flow_stamp = t;
    in.tip_rotation = tip;
    in.flows = flows;
    return in;
  }
};

/// The gains these tests were tuned with (K_p 4/s, K_d 0.2; config/controller.yaml has 3/s, 0).
inline control::ControllerOptions tuned_gains() {
  control::ControllerOptions p;
  p.pd.kp = 4.0;
  p.pd.kd = 0.2;
  return p;
}

inline control::ControllerOptions static_target(double theta, double phi) {
  control::ControllerOptions p = tuned_gains();
  p.path.theta_start = p.path.theta_end = theta;
  p.path.phi_start = p.path.phi_end = phi;
  p.path.duration = 1000.0;
  return p;
}

/// Runs `seconds` of control; returns the last output.
inline control::ControllerOutput run(control::Controller& c, StaticPlant& plant, double t0, double seconds) {
  control::ControllerOutput out;
  const int n = static_cast<int>(std::lround(seconds / kDt));
  for (int k = 0; k < n; ++k) {
    out = c.update(plant.inputs(t0 + k * kDt));
    plant.apply(out.valve_command);
    if (out.state == control::ControllerState::kAborted) break;
  }
  return out;
}

/// The direction a [rad] from +z toward +x.
inline control::Vec3 dir(double a) { return control::Vec3(std::sin(a), 0.0, std::cos(a)); }

/// A great circle from +z toward +x at `rate` [rad/s] for `duration` [s].
class ArcPath : public control::Path {
 public:
  ArcPath(double rate, double duration) : rate_(rate), duration_(duration) {}
  control::Vec3 direction_at(double t) const override { return dir(rate_ * std::clamp(t, 0.0, duration_)); }
  double duration() const override { return duration_; }
  const char* type() const override { return "arc"; }

 private:
  double rate_, duration_;
};

/// A controller file's YAML that must be refused: the error names `key` and its detail holds `detail`.
struct RefusedOptions {
  const char* yaml;
  const char* key;
  const char* detail;
};
inline void expect_refused(const RefusedOptions& c) {
  try {
    config::parse_controller_options(YAML::Load(c.yaml));
    ADD_FAILURE() << c.yaml << " accepted";
  } catch (const config::ParamError& e) {
    EXPECT_EQ(e.key(), c.key) << e.what();
    EXPECT_NE(e.detail().find(c.detail), std::string::npos) << e.what();
  }
}

}  // namespace test
}  // namespace hydrojet
