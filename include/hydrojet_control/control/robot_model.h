// What the controller needs from a scene: the rod and its solver, the actuators (the HydroJet's
// three jets of eq. 24, or any follower actuators) and the nozzles of the jets; and the
// model itself at given inputs (ActuatedModel): equilibrium, actuation Jacobian J_q, C^b, stability.
// ROS-free (Eigen, the rod and actuation libraries).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "hydrojet_control/actuation/flow_regulator.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/control/task_space.h"
#include "hydrojet_control/rod/general_rod.h"
#include "hydrojet_control/rod/general_rod_solver.h"
#include "hydrojet_control/rod/shooting_solver.h"
#include "hydrojet_control/rod/stability.h"

namespace hydrojet {
namespace control {

/// Storage bound of a JetVector (no heap allocation); the count itself comes from the model.
constexpr int kMaxJets = rod::kMaxActuators;
/// One entry per actuator (inputs q [N], flows, valve duties), in the model's actuator order. The
/// name is the HydroJet's (its actuators are jets); any follower actuator has an entry.
using JetVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxJets, 1>;

/// Inputs the controller needs from a scene. Two ways to describe the robot:
///   - the HydroJet's (body.segments empty, the default): the uniform `rod` with the three jets of
///     `jets` at its tip, bounds [0, max_jet_force];
///   - any follower-actuated robot: `body` with its segments, point loads and actuators
///     (make_controller_model fills it from a scene; `rod` then only gives nothing the body lacks).
struct RobotModel {
  rod::RodModel rod;
  rod::ShootingOptions solver;
  /// The actuated tip-wrench components of the HydroJet description (eq. 23); a general body uses the
  /// span of its actuators' equivalent tip wrenches instead.
  rod::ActuatedSet actuated = rod::lateral_force_actuation();
  actuation::JetGeometry jets;
  actuation::Nozzle nozzle;                                        ///< of every actuator of type jet
  JetVector max_jet_force = Eigen::Vector3d(0.243, 0.224, 0.244);  ///< q_max [N], one per jet
  actuation::FlowRegulatorOptions flow;  ///< per-jet PI flow regulator (the same for every jet)
  rod::GeneralRodModel body;             ///< a general robot; empty segments: the HydroJet description
};

/// The three jets of eq. (24) for `jets` at arc length `length` [m] as actuators of type jet: jet i
/// pushes along column i of the jet map at the point nozzle_offset·e_z, bounds [0, max_force[i]].
std::vector<rod::Actuator> jet_actuators(const actuation::JetGeometry& jets, const JetVector& max_force, double length);

/// The robot of `m` as a general rod with its actuators (either description of RobotModel).
rod::GeneralRodModel actuated_body(const RobotModel& m);

/// The model at actuator inputs q [N]: its equilibrium, then (at the last converged solve) C^b, the
/// actuation Jacobian J_q (6×N: tip body twist (v, ω) per unit input) and the stability of eq. (23)
/// on the actuated directions. One uniform rod with every actuator at the tip (the HydroJet) runs on
/// ShootingSolver's fast path with the tip wrench W q (W: the actuators' unit wrenches, 6×N) and
/// J_q = C^b W; any other robot on GeneralRodSolver (J_q from its sensitivities). Warm-started from
/// the last converged solve. Not thread-safe; a copy starts without the warm start.
class ActuatedModel {
 public:
  /// Throws std::invalid_argument naming the field when the model is invalid.
  explicit ActuatedModel(const RobotModel& model);
  ActuatedModel(const ActuatedModel& other);
  ActuatedModel& operator=(const ActuatedModel& other);
  ~ActuatedModel();

  struct Linearisation {
    bool ok = false;
    rod::Mat6 body_compliance = rod::Mat6::Zero();  ///< C^b [m/N, rad/N, ...]: tip twist per tip body wrench
    rod::ActuationJacobian actuation;               ///< J_q [m/N; rad/N]: tip twist per unit input
    /// Tip body wrench [N; N m] per unit input that moves the tip as the input does: the actuators'
    /// unit wrenches W on the fast path, (C^b)^† J_q otherwise (rod::equivalent_tip_wrenches).
    rod::ActuationJacobian wrenches;
  };

  int input_count() const { return static_cast<int>(body_.actuators.size()); }
  const JetVector& lower() const { return lower_; }  ///< q_min [N] per input
  const JetVector& upper() const { return upper_; }  ///< q_max [N] per input
  const rod::GeneralRodModel& body() const { return body_; }
  /// The uniform rod with tip actuators only: ShootingSolver's fast path.
  bool fast_path() const { return static_cast<bool>(fast_); }

  /// The equilibrium at inputs q [N] (input_count() entries), the tip loaded besides with `extra`
  /// (a follower wrench, tip frame: the disturbance observer's estimate).
  rod::RodSolution solve(const JetVector& q, const rod::TipWrench& extra = rod::TipWrench());
  /// C^b and J_q at the last converged solve (ok = false when there is none).
  Linearisation linearise();
  /// σ_c and eig_min of eq. (23) on the actuated directions: the HydroJet description's ActuatedSet
  /// ({f_x, f_y}); else the span of lin.wrenches (stability.h; equal on the HydroJet).
  rod::StabilityReport stability(const Linearisation& lin) const;
  /// Tip body wrench [N, N m] of the actuators at the tip (s = L) at inputs q; the others load the
  /// body elsewhere and are not in it (information: the controller's w_a).
  rod::Vec6 tip_wrench(const JetVector& q) const { return tip_wrenches_ * q; }
  /// Backbone at the last converged solve: segments + 1 points [m], base frame.
  std::vector<Vec3> shape(int segments) const;
  /// Forgets the warm start.
  void reset();

 private:
  void build();

  RobotModel model_;
  rod::GeneralRodModel body_;
  JetVector lower_, upper_;
  Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxJets> tip_wrenches_;  ///< W: unit wrenches at s = L
  std::unique_ptr<rod::ShootingSolver> fast_;
  std::unique_ptr<rod::GeneralRodSolver> general_;
};

}  // namespace control
}  // namespace hydrojet
