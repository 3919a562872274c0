// Shared fixture for the simulated plant's tests: a scene's plant exactly as the scene says.
#pragma once

#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/config/scene.h"

namespace hydrojet {
namespace test {

/// The plant of scene `sc` exactly as the scene says: no mismatch, no sensor noise.
inline plant::PlantModel exact_plant(const config::Scene& sc) {
  return config::make_plant(
      sc,
      "plant: {sensor_noise: false, dynamics: {kelvin_voigt_time: 0.03}, mismatch: {precurvature_offset: [0, 0, 0], "
      "bending_stiffness_scale: 1, misalignment_offset: [0, 0, 0], tip_mass_scale: 1, base_tilt_offset: 0}}");
}

}  // namespace test
}  // namespace hydrojet
