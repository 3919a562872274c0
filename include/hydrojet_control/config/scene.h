// Scene files: the YAML that says which rod, load and solver a run uses (docs/rod_model.md, "Scene files").
// Loaded and validated here; a missing or invalid key raises SceneError naming the key.
// ROS-free (yaml-cpp + Eigen).
#pragma once

#include <optional>
#include <stdexcept>
#include <string>

#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/config/yaml_tree.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/rod/rod_model.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/stability.h"

namespace hydrojet {
namespace config {

/// A scene (or plant file) key is missing or invalid; key() is its dotted path ("rod.length").
class SceneError : public KeyError {
 public:
  using KeyError::KeyError;
};

struct Scene {
  /// The robot: its segments (one for a single-rod scene), point loads (`loads`), actuators
  /// (`actuators`, or the three jets of a `jets` section at the tip), tip mass and gravity.
  rod::RodModel rod;
  /// tip.actuated: the tip-wrench components the solver's cold stability check looks at.
  rod::ActuatedSet actuated = rod::lateral_force_actuation();
  rod::ShootingOptions solver;
  actuation::Nozzle nozzle;  ///< A_in, A_out [m^2], water density [kg/m^3] of the actuators of type jet
  /// The `jets` section as given (misalignment (δα, δβ, δγ) [rad], nozzle offset [m] of the HydroJet's
  /// three jets, paper §6.2): what the calibration fits and writes back. Empty with `actuators`.
  std::optional<actuation::JetGeometry> jets;
};

/// Parses scene YAML text. Known sections: rod (single-rod keys, or rod.segments), tip, gravity, and
/// the optional solver, jets, loads, actuators (instead of jets) and nozzle (for actuators of type
/// jet). Other top-level sections are allowed (later tools add plant, ...); unknown keys inside a
/// known section are errors.
Scene parse_scene(const std::string& yaml_text);
/// The controller's model of the robot from a scene (its rod, solver and nozzles) and the
/// flow-regulator gains. SceneError("actuators", ...) when the robot has no actuators.
control::RobotModel make_controller_model(const Scene& scene, const actuation::FlowRegulatorOptions& flow);

/// Reads and parses a scene file; SceneError("scene", ...) when the file cannot be read.
Scene load_scene(const std::string& path);

}  // namespace config
}  // namespace hydrojet
