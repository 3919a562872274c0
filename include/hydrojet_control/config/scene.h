// Scene files: the YAML that says which rod, load and solver a run uses (README, "Scene files").
// Loaded and validated here; a missing or invalid key raises SceneError naming the key.
// ROS-free (yaml-cpp + Eigen).
#pragma once

#include <stdexcept>
#include <string>

#include "hydrojet_control/rod/shooting_solver.h"
#include "hydrojet_control/rod/stability.h"

namespace hydrojet {
namespace config {

/// A scene key is missing or invalid; key() is its dotted path ("rod.length").
class SceneError : public std::runtime_error {
 public:
  SceneError(const std::string& key, const std::string& what)
      : std::runtime_error(key + ": " + what), key_(key) {}
  const std::string& key() const { return key_; }

 private:
  std::string key_;
};

struct Scene {
  rod::RodModel model;
  rod::ActuatedSet actuated = rod::lateral_force_actuation();
  rod::ShootingSettings solver;
};

/// Parses scene YAML text. Known sections: rod, tip, gravity, solver (optional). Other top-level
/// sections are allowed (later tools add jets, plant, ...); unknown keys inside a known section are
/// errors.
Scene parse_scene(const std::string& yaml_text);
/// Reads and parses a scene file; SceneError("scene", ...) when the file cannot be read.
Scene load_scene(const std::string& path);

}  // namespace config
}  // namespace hydrojet
