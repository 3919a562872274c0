// The Aurora's ASCII TX replies (the fallback of firmware that refuses BX), CRC removed as the
// driver does. Contract (aurora_protocol.h, parse_tx_reply): never throws, never reads past the
// text; a refused reply has a reason; an accepted one has handles whose valid poses carry a finite
// unit quaternion (renormalised), finite positions within the TX field's ±9999.99 mm and rms >= 0;
// the same text parses the same way twice (no hidden state). pvwr_params() on the input as an SROM
// image: the chunks cover it exactly, 64 bytes each, in address order.
#include <cmath>
#include <stdexcept>

#include "fuzz_common.h"
#include "hydrojet_control/devices/aurora_protocol.h"

using namespace hydrojet::devices;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = hydrojet::fuzz::as_text(data, size);
  BxFrame f, g;
  std::string err, err2;
  const bool ok = parse_tx_reply(text, kDefaultOutOfVolumeMask, &f, &err);
  FUZZ_CHECK(ok == parse_tx_reply(text, kDefaultOutOfVolumeMask, &g, &err2), "deterministic");
  if (!ok) {
    FUZZ_CHECK(!err.empty(), "a refused TX reply needs a reason");
  } else {
    FUZZ_CHECK(f.handles.size() == g.handles.size(), "deterministic handle count");
    for (const HandlePose& h : f.handles) {
      if (h.status != HandlePose::kValid) continue;
      FUZZ_CHECK(h.has_transform(), "a valid handle carries a transform");
      const double n = std::sqrt(h.q[0] * h.q[0] + h.q[1] * h.q[1] + h.q[2] * h.q[2] + h.q[3] * h.q[3]);
      FUZZ_CHECK(std::abs(n - 1.0) < 1e-9, "quaternion renormalised");
      for (double t : h.t) FUZZ_CHECK(std::isfinite(t) && std::abs(t) <= 10.0, "finite position within the field");
      FUZZ_CHECK(h.rms_m >= 0.0, "rms not negative");
    }
  }
  const std::vector<uint8_t> image(data, data + size);
  try {
    const std::vector<std::string> chunks = pvwr_params(0x0A, image);
    FUZZ_CHECK(!image.empty() && image.size() <= kMaxSromBytes, "accepted only a usable image size");
    FUZZ_CHECK(chunks.size() == (image.size() + kPvwrChunk - 1) / kPvwrChunk, "one chunk per 64 bytes");
    for (size_t i = 0; i < chunks.size(); ++i) {
      FUZZ_CHECK(chunks[i].size() == 2 + 4 + 2 * kPvwrChunk, "handle, address, 64 bytes as hex");
      FUZZ_CHECK(std::stoul(chunks[i].substr(2, 4), nullptr, 16) == i * kPvwrChunk, "addresses in order");
    }
  } catch (const std::invalid_argument&) {
    FUZZ_CHECK(image.empty() || image.size() > kMaxSromBytes, "refused only an unusable image size");
  }
  return 0;
}
