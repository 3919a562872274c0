// Calibration data as CSV (q1,q2,q3,qw,qx,qy,qz in any order, extra columns ignored). Contract
// (calibration/samples.h): parse_csv() fails only with DataError; accepted samples have finite,
// non-negative jet forces and unit quaternions, and name their line.
#include <cmath>

#include "fuzz_common.h"
#include "hydrojet_control/calibration/samples.h"

using namespace hydrojet;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size > 16384) return 0;
  std::vector<calibration::Sample> samples;
  try {
    samples = calibration::parse_csv(fuzz::as_text(data, size), "fuzz");
  } catch (const calibration::DataError& e) {
    FUZZ_CHECK(std::string(e.what()).size() > 0, "an error says what");
    return 0;
  }
  for (const auto& s : samples) {
    for (int k = 0; k < 3; ++k) FUZZ_CHECK(std::isfinite(s.jet_force[k]) && s.jet_force[k] >= 0.0, "q_i finite, >= 0");
    FUZZ_CHECK(std::abs(s.tip_orientation.norm() - 1.0) < 1e-9, "a unit quaternion");
    FUZZ_CHECK(s.origin.rfind("fuzz:", 0) == 0, "a sample names its line");
  }
  return 0;
}
