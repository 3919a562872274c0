// Shared fixtures for the calibration tests: the paper's cross-section, the shipped scenes, and the ζ
// of the test truth.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "hydrojet_control/calibration/zeta.h"
#include "hydrojet_control/config/scene.h"

namespace hydrojet {
namespace test {

// Hollow cylinder of the paper (§6.2), written out here independently of CrossSection.
inline const double kI = M_PI * (std::pow(0.008, 4) - std::pow(0.006, 4)) / 64.0;

inline config::Scene shipped(const std::string& name) {
  return config::load_scene(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/" + name + ".yaml");
}

/// The HydroJet's three jets (the actuators of a jets section).
inline std::vector<rod::Actuator> jets() { return shipped("hydrojet_0deg").rod.actuators; }

/// The paper's ζ names in its order (the CLI's and the JSON's contract), written out here.
inline std::string param_name(int i) {
  static const char* const names[calibration::kNumParams] = {"ux", "uy", "E", "G", "da", "db", "dg"};
  return names[i];
}

/// ζ of the test truth: the plant-like mismatch of config/plant.yaml applied to Table 1
/// (ũ + (0.6, −0.4), EI × 0.8, GJ × 1.25, misalignments + (0.06, −0.06, 0.05)).
inline calibration::ZetaVector truth_zeta() {
  calibration::ZetaVector z(calibration::kNumParams);
  z << 0.034 + 0.6, 0.88 - 0.4, 0.8 * 6.01e-4 / kI, 1.25 * 2.23e-4 / (2 * kI), 0.12 + 0.06, 0.06 - 0.06, -0.08 + 0.05;
  return z;
}

}  // namespace test
}  // namespace hydrojet
