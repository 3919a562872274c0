// Calibration data as CSV (q1..qN,qw,qx,qy,qz in any order, extra columns ignored). Contract
// (calibration/samples.h): parse_csv() fails only with DataError; accepted samples have N finite
// inputs, non-negative for actuators that cannot pull, unit quaternions, and name their line.
// The first byte chooses the robot: N = 1..8 actuators, every second one reversible or none.
#include <cmath>

#include "fuzz_common.h"
#include "hydrojet_control/calibration/samples.h"

using namespace hydrojet;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1 || size > 16384) return 0;
  const int n = data[0] % rod::kMaxInputs + 1;
  const bool reversible = (data[0] / rod::kMaxInputs) % 2 == 1;
  std::vector<rod::Actuator> actuators(n);
  for (int i = 0; i < n; ++i) {
    actuators[i].name = "a" + std::to_string(i + 1);
    actuators[i].max_force = 0.2;
    actuators[i].min_force = reversible && i % 2 == 1 ? -0.2 : 0.0;
  }
  std::vector<calibration::Sample> samples;
  try {
    samples = calibration::parse_csv(fuzz::as_text(data + 1, size - 1), actuators, "fuzz");
  } catch (const calibration::DataError& e) {
    FUZZ_CHECK(std::string(e.what()).size() > 0, "an error says what");
    return 0;
  }
  for (const auto& s : samples) {
    FUZZ_CHECK(s.inputs.size() == n, "one input per actuator");
    for (int k = 0; k < n; ++k) {
      FUZZ_CHECK(std::isfinite(s.inputs[k]), "q_i finite");
      FUZZ_CHECK(s.inputs[k] >= 0.0 || actuators[k].min_force < 0.0, "q_i >= 0 unless the actuator can pull");
    }
    FUZZ_CHECK(std::abs(s.tip_orientation.norm() - 1.0) < 1e-9, "a unit quaternion");
    FUZZ_CHECK(s.origin.rfind("fuzz:", 0) == 0, "a sample names its line");
  }
  return 0;
}
