// Any follower-actuated rod (the paper's §5 and §8: "a full 6 DoF wrench applied at any
// location along the body or a connection of multiple soft bodies with different stiffness
// characteristics"): segments of different material base to tip, point loads along the body (a mass,
// a wrench fixed in the base frame or following the body), and N actuators anywhere, each applying
// the force q_i · d_i at a point p_i of the body frame at its arc length (a follower force with a
// moment arm). The HydroJet (one uniform rod, three jets at the tip) is the special case that
// ShootingSolver solves on its fast path; GeneralRodSolver (general_rod_solver.h) solves any model
// described here. Data only; ROS-free (Eigen only).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "hydrojet_control/rod/rod_model.h"

namespace hydrojet {
namespace rod {

/// Most actuators a model may have (the allocation and the controller's fixed-size vectors).
constexpr int kMaxActuators = 8;

/// One piece of the rod with uniform material and precurvature, base to tip.
struct RodSegment {
  double length = 0.0;               ///< [m], > 0
  Vec3 stiffness = Vec3::Zero();     ///< diag(E·Ix, E·Iy, G·J) [N m^2], each > 0
  Vec3 precurvature = Vec3::Zero();  ///< ũ in the body frame [1/m]
  double linear_density = 0.0;       ///< ρA [kg/m], ≥ 0
  double shear_stiffness = 0.0;      ///< GA [N] (Cosserat only; then > 0)
  double axial_stiffness = 0.0;      ///< EA [N] (Cosserat only; then > 0)
};

/// In which frame a point load's force and moment are fixed.
enum class LoadFrame {
  kBody,  ///< the body frame at its arc length: a follower load
  kBase,  ///< the base frame: a dead load (as a weight)
};

/// A wrench applied at one point of the backbone (besides the tip's), at the centreline.
struct PointLoad {
  double at = 0.0;                     ///< arc length s [m], 0 < s ≤ L
  double mass = 0.0;                   ///< [kg], ≥ 0: its weight m·g (base frame) acts at s
  Vec3 force = Vec3::Zero();           ///< [N], in `frame`
  Vec3 moment = Vec3::Zero();          ///< [N m], in `frame`
  LoadFrame frame = LoadFrame::kBody;  ///< frame of force and moment
};

/// How an actuator's input becomes its force.
enum class ActuatorType {
  kForce,  ///< the input q is the force [N]
  kJet,    ///< a water jet: q from the flow by the thrust equation (26) (needs the scene's nozzle)
};

/// One actuator: input q [N] applies the follower force q·direction at `position` of the body frame
/// at arc length `at`, i.e. the body wrench q·(d, p × d) at the centreline there.
struct Actuator {
  std::string name;
  double at = 0.0;                 ///< arc length s [m], 0 < s ≤ L
  Vec3 position = Vec3::Zero();    ///< point of application, body frame at s [m] (moment arm)
  Vec3 direction = Vec3::UnitX();  ///< unit force direction on the rod, body frame at s
  double min_force = 0.0;          ///< [N] (negative: reversible)
  double max_force = 0.0;          ///< [N], ≥ min_force
  ActuatorType type = ActuatorType::kForce;

  /// Body wrench (f, m) at the centreline at s per unit input: (d, p × d).
  Vec6 unit_wrench() const {
    Vec6 w;
    w << direction, position.cross(direction);
    return w;
  }
};

/// Everything the static model of a general follower-actuated rod needs besides the inputs.
struct GeneralRodModel {
  std::vector<RodSegment> segments;  ///< base to tip, at least one
  RodKind kind = RodKind::kKirchhoff;
  std::vector<PointLoad> loads;     ///< besides the tip's, any order
  std::vector<Actuator> actuators;  ///< inputs in this order (0..8 of them)
  double tip_mass = 0.0;            ///< m_t [kg] at s = L
  Vec3 gravity = Vec3::Zero();      ///< g in the base frame [m/s^2]

  /// L [m]: the sum of the segment lengths.
  double length() const {
    double L = 0.0;
    for (const auto& s : segments) L += s.length;
    return L;
  }
  /// Empty when valid, else a message naming the offending field ("segments[1].length: ...").
  std::string validate() const;
};

/// The uniform rod of `m` as one segment, no point loads, no actuators (the tip wrench stays the
/// caller's, as for ShootingSolver).
GeneralRodModel general_model(const RodModel& m);

}  // namespace rod
}  // namespace hydrojet
