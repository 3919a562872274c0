// Shared fixtures for the calibration tests: the paper's cross-section, the shipped scenes, and the ζ
// of the test truth.
#pragma once

#include <cmath>
#include <string>

#include "hydrojet_control/calibration/zeta.h"
#include "hydrojet_control/config/scene.h"

namespace hydrojet {
namespace test {

// Hollow cylinder of the paper (§6.2), written out here independently of CrossSection.
inline const double kI = M_PI * (std::pow(0.008, 4) - std::pow(0.006, 4)) / 64.0;

inline config::Scene shipped(const std::string& name) {
  return config::load_scene(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/" + name + ".yaml");
}

/// ζ of the test truth: the plant-like mismatch of config/plant.yaml applied to Table 1
/// (ũ + (0.6, −0.4), EI × 0.8, GJ × 1.25, misalignments + (0.06, −0.06, 0.05)).
inline calibration::ZetaVector truth_zeta() {
  calibration::ZetaVector z;
  z << 0.034 + 0.6, 0.88 - 0.4, 0.8 * 6.01e-4 / kI, 1.25 * 2.23e-4 / (2 * kI), 0.12 + 0.06, 0.06 - 0.06, -0.08 + 0.05;
  return z;
}

}  // namespace test
}  // namespace hydrojet
