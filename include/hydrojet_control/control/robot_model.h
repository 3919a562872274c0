// The robot as the controller needs it (RobotModel), and its model at given inputs (ActuatedModel):
// equilibrium, actuation Jacobian J_q, C^b, stability. ROS-free (Eigen, the rod and actuation libraries).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "hydrojet_control/actuation/flow_regulator.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/control/task_space.h"
#include "hydrojet_control/rod/rod_model.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/stability.h"

namespace hydrojet {
namespace control {

using rod::InputVector;
using rod::kMaxInputs;

/// The robot as the controller needs it: its rod model (segments, loads, actuators: the HydroJet's
/// three jets of eq. 24 are actuators of type jet at the tip), the solver's options, the nozzles of
/// the jets (eq. 26) and the flow regulators' gains.
struct RobotModel {
  rod::RodModel rod;
  rod::ShootingOptions solver;
  actuation::Nozzle nozzle;              ///< of every actuator of type jet
  actuation::FlowRegulatorOptions flow;  ///< per-jet PI flow regulator (the same for every jet)
};

/// The three jets of eq. (24) for `jets` at arc length `length` [m] as actuators of type jet: jet i
/// pushes along column i of the jet map at the point nozzle_offset·e_z, bounds [0, max_force[i]].
std::vector<rod::Actuator> jet_actuators(const actuation::JetGeometry& jets, const Vec3& max_force, double length);
/// q_max [N] of the three jets jet_actuators() made (the first three actuators of `rod`).
Vec3 jet_max_force(const rod::RodModel& rod);

/// The model at actuator inputs q [N]: its equilibrium (rod::RodSolver), then (at the last converged
/// solve) C^b, the actuation Jacobian J_q (6×N: tip body twist (v, ω) per unit input) and the
/// stability of eq. (23) on the actuated directions. Warm-started from the last converged solve. Not
/// thread-safe; a copy keeps the warm start (with integrator memories of its own).
class ActuatedModel {
 public:
  /// Throws std::invalid_argument naming the field when the model is invalid.
  explicit ActuatedModel(const RobotModel& model);

  struct Linearisation {
    bool ok = false;
    rod::Mat6 body_compliance = rod::Mat6::Zero();  ///< C^b [m/N, rad/N, ...]: tip twist per tip body wrench
    rod::ActuationJacobian actuation;               ///< J_q [m/N; rad/N]: tip twist per unit input
    /// Tip body wrench [N; N m] per unit input that moves the tip as the input does: (C^b)^† J_q
    /// (rod::equivalent_tip_wrenches; the actuators' unit wrenches W when all sit at the tip).
    rod::ActuationJacobian wrenches;
  };

  int input_count() const { return solver_.input_count(); }
  const InputVector& lower() const { return lower_; }  ///< q_min [N] per input
  const InputVector& upper() const { return upper_; }  ///< q_max [N] per input
  const rod::RodModel& rod() const { return solver_.model(); }
  /// The solver (warm-started at the last solve): for models built about that equilibrium.
  const rod::RodSolver& solver() const { return solver_; }

  /// The equilibrium at inputs q [N] (input_count() entries).
  rod::RodSolution solve(const InputVector& q) { return solver_.solve(q, rod::TipWrench()); }
  /// C^b and J_q at the last converged solve (ok = false when there is none).
  Linearisation linearise();
  /// σ_c and eig_min of eq. (23) on the span of lin.wrenches (stability.h).
  rod::StabilityReport stability(const Linearisation& lin) const;
  /// Tip body wrench [N, N m] of the actuators at the tip (s = L) at inputs q; the others load the
  /// body elsewhere and are not in it (information: the controller's w_a).
  rod::Vec6 tip_wrench(const InputVector& q) const { return tip_wrenches_ * q; }
  /// Backbone at the last converged solve: segments + 1 points [m], base frame.
  std::vector<Vec3> shape(int segments) const { return solver_.shape(segments); }
  /// Forgets the warm start.
  void reset() { solver_.reset(); }

 private:
  rod::RodSolver solver_;
  InputVector lower_, upper_;
  rod::ActuationJacobian tip_wrenches_;  ///< W: unit wrenches of the actuators at s = L (zero elsewhere)
};

}  // namespace control
}  // namespace hydrojet
