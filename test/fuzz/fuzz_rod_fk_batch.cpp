// `rod_fk --batch` input: one tip wrench per line (config/wrench_batch.h). Contract: fails only with
// BatchError naming the line; every accepted wrench is finite.
#include <cmath>
#include <sstream>

#include "fuzz_common.h"
#include "hydrojet_control/config/wrench_batch.h"

using namespace hydrojet;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(fuzz::as_text(data, size));
  std::vector<rod::TipWrench> w;
  try {
    w = config::parse_wrench_batch(in);
  } catch (const config::BatchError& e) {
    FUZZ_CHECK(e.key().rfind("--batch line ", 0) == 0, "the error names the line");
    return 0;
  }
  for (const auto& x : w)
    for (int k = 0; k < 3; ++k) FUZZ_CHECK(std::isfinite(x.force[k]) && std::isfinite(x.moment[k]), "finite wrench");
  return 0;
}
