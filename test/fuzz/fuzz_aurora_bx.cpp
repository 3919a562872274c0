// The Aurora's binary BX replies as a byte stream, chunked as a serial port delivers them. The
// first byte of the input sets the chunk size. Contract (aurora_protocol.h): BxParser emits only
// CRC-valid, decodable frames whose valid handles carry finite unit quaternions and finite
// positions; every emitted frame survives encode_bx() -> parser unchanged (a second, independent
// path through the encoder); the byte accounting never loses a byte. decode_bx_body() on the raw
// input obeys the same invariants.
#include <cmath>

#include "fuzz_common.h"
#include "hydrojet_control/devices/aurora_protocol.h"

using namespace hydrojet::devices;

namespace {

void check_frame(const BxFrame& f) {
  for (const HandlePose& h : f.handles) {
    if (h.status == HandlePose::kValid) {
      FUZZ_CHECK(h.has_transform(), "a valid handle carries a transform");
      const double n = std::sqrt(h.q[0] * h.q[0] + h.q[1] * h.q[1] + h.q[2] * h.q[2] + h.q[3] * h.q[3]);
      FUZZ_CHECK(std::abs(n - 1.0) < 1e-9, "quaternion renormalised");
      for (double t : h.t) FUZZ_CHECK(std::isfinite(t), "finite position");
      FUZZ_CHECK(h.rms_m >= 0.0, "rms not negative");
    }
  }
}

void check_round_trip(const BxFrame& f) {
  const std::vector<uint8_t> bytes = encode_bx(f);
  BxParser again;
  again.feed(bytes.data(), bytes.size());
  BxFrame g;
  FUZZ_CHECK(again.next(&g), "a re-encoded frame parses");
  FUZZ_CHECK(g.handles.size() == f.handles.size(), "same handle count");
  for (size_t i = 0; i < f.handles.size(); ++i) {
    FUZZ_CHECK(g.handles[i].handle == f.handles[i].handle, "same handle");
    FUZZ_CHECK(g.handles[i].status == f.handles[i].status, "same status");
    if (f.handles[i].has_transform())
      for (int k = 0; k < 3; ++k)  // float32 on the wire: metres -> mm -> metres
        FUZZ_CHECK(std::abs(g.handles[i].t[k] - f.handles[i].t[k]) <= 1e-6 * (1.0 + std::abs(f.handles[i].t[k])),
                   "same position");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const size_t chunk = 1 + data[0] % 64;
  ++data;
  --size;
  BxParser parser;
  BxFrame f;
  size_t emitted = 0;
  for (size_t at = 0; at < size; at += chunk) {
    parser.feed(data + at, std::min(chunk, size - at));
    while (parser.next(&f)) {
      check_frame(f);
      check_round_trip(f);
      ++emitted;
    }
  }
  FUZZ_CHECK(parser.frames() == emitted, "frames() counts what next() returned");
  FUZZ_CHECK(parser.buffered() <= size, "never more buffered than fed");
  parser.reset();
  FUZZ_CHECK(parser.buffered() == 0, "reset drops the buffer");

  std::string err;
  if (decode_bx_body(data, size, kDefaultOutOfVolumeMask, &f, &err))
    check_frame(f);
  else
    FUZZ_CHECK(!err.empty(), "a refused body needs a reason");
  return 0;
}
