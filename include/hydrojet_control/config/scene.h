// Scene files: the YAML that says which rod, load and solver a run uses (docs/rod_model.md, "Scene files").
// Loaded and validated here; a missing or invalid key raises SceneError naming the key.
// ROS-free (yaml-cpp + Eigen).
#pragma once

#include <stdexcept>
#include <string>

#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/config/yaml_tree.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/rod/general_rod.h"
#include "hydrojet_control/rod/shooting_solver.h"
#include "hydrojet_control/rod/stability.h"

namespace hydrojet {
namespace config {

/// A scene (or plant file) key is missing or invalid; key() is its dotted path ("rod.length").
class SceneError : public KeyError {
 public:
  using KeyError::KeyError;
};

struct Scene {
  rod::RodModel model;
  rod::ActuatedSet actuated = rod::lateral_force_actuation();
  rod::ShootingOptions solver;
  /// The optional `jets` section (paper §6.2, Table 1).
  bool has_jets = false;
  actuation::JetGeometry jets;  ///< misalignment (δα, δβ, δγ) [rad], nozzle offset [m]
  actuation::Nozzle nozzle;     ///< A_in, A_out [m^2], water density [kg/m^3]
  Eigen::Vector3d max_jet_force = Eigen::Vector3d(0.243, 0.224, 0.244);  ///< q_max [N]

  /// The robot as a general follower-actuated rod, always filled: its segments (one for a
  /// single-rod scene), point loads (`loads`), actuators (`actuators`, or the three jets of a `jets`
  /// section at the tip), tip mass and gravity.
  rod::GeneralRodModel body;
  /// The scene has an `actuators` section (instead of `jets`).
  bool has_actuators = false;
  /// One uniform rod with no point loads: `model` describes it completely and ShootingSolver's fast
  /// path applies (the actuators, if any, then act at the tip as a tip wrench when all sit at L).
  bool uniform() const { return body.segments.size() == 1 && body.loads.empty(); }
};

/// Parses scene YAML text. Known sections: rod (single-rod keys, or rod.segments), tip, gravity, and
/// the optional solver, jets, loads, actuators (instead of jets) and nozzle (for actuators of type
/// jet). Other top-level sections are allowed (later tools add plant, ...); unknown keys inside a
/// known section are errors.
Scene parse_scene(const std::string& yaml_text);
/// The controller's model of the robot from a scene (its rod, solver, jets and nozzles) and the
/// flow-regulator gains. SceneError("jets", ...) when the scene has no jets section.
control::RobotModel make_controller_model(const Scene& scene, const actuation::FlowRegulatorOptions& flow);

/// SceneError naming rod.segments or loads when `scene` is not uniform(): for the parts of the stack
/// that solve one uniform rod with actuation at the tip only (`who`, e.g. "the controller"), until
/// they move to the general solver.
void require_uniform(const Scene& scene, const std::string& who);
/// Reads and parses a scene file; SceneError("scene", ...) when the file cannot be read.
Scene load_scene(const std::string& path);

}  // namespace config
}  // namespace hydrojet
