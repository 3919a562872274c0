// One line from a flow sensor, read with the formats a rig.yaml can give (a regex with a capture
// group, a comma field, a blank-separated field). The first byte picks the format. Contract
// (line_protocols.h): a reading is accepted only as a finite, non-negative flow; a refused line
// has a reason; the output is written only on success.
#include <cmath>

#include "fuzz_common.h"
#include "hydrojet_control/devices/line_protocols.h"

using namespace hydrojet::devices;

namespace {

FlowLineFormat format(uint8_t pick) {
  FlowLineFormat f;
  f.scale_to_m3_per_s = kMlPerMinToM3PerS;
  switch (pick % 4) {
    case 0: f.regex = "FLOW=([-+0-9.eE]+)"; break;
    case 1:
      f.field_index = 1;
      f.separator = ',';
      break;
    case 2:
      f.field_index = 2;
      f.separator = ' ';
      break;
    default:
      f.field_index = 0;
      f.separator = '\t';
      f.scale_to_m3_per_s = kLPerMinToM3PerS;
      break;
  }
  return f;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0 || size > 512) return 0;  // the line splitter caps lines far below this
  const FlowLineFormat fmt = format(data[0]);
  const std::string line = hydrojet::fuzz::as_text(data + 1, size - 1);
  double flow = -12345.0;
  std::string err;
  if (parse_flow_line(line, fmt, &flow, &err)) {
    FUZZ_CHECK(std::isfinite(flow), "an accepted flow is finite");
    FUZZ_CHECK(flow >= 0.0, "an accepted flow is not negative");
  } else {
    FUZZ_CHECK(flow == -12345.0, "the output is written only on success");
    FUZZ_CHECK(!err.empty(), "a refused line needs a reason");
  }
  return 0;
}
