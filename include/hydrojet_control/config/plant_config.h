// The simulated plant's configuration: the nominal scene (rod, jets, base tilt through its gravity
// vector) plus a `plant` section (model mismatch, dynamics, hydraulics, sensors). Every key is
// optional; an unknown or invalid key raises SceneError naming it ("plant.valves[1].dead_zone").
#pragma once

#include <string>

#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/plant/plant.h"

namespace hydrojet {
namespace config {

/// Builds the true plant from the nominal scene and the YAML text of a file holding a `plant:`
/// section (empty text: the defaults, which are config/plant.yaml's): the scene's rod, jets and
/// nozzles with the ModelMismatch applied. The base tilt is read off the scene's gravity vector
/// (which must lie in the base y–z plane).
plant::PlantModel make_plant(const Scene& nominal, const std::string& plant_yaml_text);
/// Same, reading the plant file from disk ("" = defaults).
plant::PlantModel load_plant(const Scene& nominal, const std::string& plant_yaml_path);

}  // namespace config
}  // namespace hydrojet
