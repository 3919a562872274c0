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
};

/// Parses scene YAML text. Known sections: rod, tip, gravity, solver and jets (optional). Other top-level
/// sections are allowed (later tools add jets, plant, ...); unknown keys inside a known section are
/// errors.
Scene parse_scene(const std::string& yaml_text);
/// The controller's model of the robot from a scene (its rod, solver, jets and nozzles) and the
/// flow-regulator gains. SceneError("jets", ...) when the scene has no jets section.
control::RobotModel make_controller_model(const Scene& scene, const actuation::FlowRegulatorOptions& flow);

/// Reads and parses a scene file; SceneError("scene", ...) when the file cannot be read.
Scene load_scene(const std::string& path);

}  // namespace config
}  // namespace hydrojet
