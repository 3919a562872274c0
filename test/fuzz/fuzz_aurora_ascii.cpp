// The Aurora's ASCII replies (OKAY, ERRORxx, PHSR lists, ...) as they come off the serial line:
// parse_ascii_reply() never throws, crc_ok only when the CRC really matches, ok only for a
// CRC-valid non-error reply; parse_phsr() accepts only well-formed handle lists.
#include <cctype>

#include "fuzz_common.h"
#include "hydrojet_control/devices/aurora_protocol.h"
#include "hydrojet_control/devices/crc16.h"

using namespace hydrojet::devices;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string line = hydrojet::fuzz::as_text(data, size);
  const AsciiReply r = parse_ascii_reply(line);
  if (r.crc_ok) {
    FUZZ_CHECK(line.size() >= 4, "a CRC needs 4 characters");
    const std::string body = line.substr(0, line.size() - 4);
    FUZZ_CHECK(r.text == body, "text is the line without its CRC");
    const std::string hex = line.substr(line.size() - 4);
    FUZZ_CHECK(std::strtoul(hex.c_str(), nullptr, 16) == crc16_arc(body), "crc_ok with a wrong CRC");
  }
  if (r.ok) {
    FUZZ_CHECK(r.crc_ok, "ok without a valid CRC");
    FUZZ_CHECK(r.text.rfind("ERROR", 0) != 0, "an ERROR reply reported ok");
    FUZZ_CHECK(r.error.empty(), "ok with an error text");
  } else {
    FUZZ_CHECK(!r.error.empty(), "a refused reply needs a reason");
  }
  std::vector<std::pair<uint8_t, uint16_t>> handles;
  std::string err;
  if (parse_phsr(line, &handles, &err)) {
    // "nn" then nn entries of "hh" + "sss": 2 + 5 n characters, all hex.
    FUZZ_CHECK(line.size() == 2 + 5 * handles.size(), "PHSR length matches its count");
    for (char c : line) FUZZ_CHECK(std::isxdigit(static_cast<unsigned char>(c)), "PHSR is hex");
  } else {
    FUZZ_CHECK(!err.empty(), "a refused PHSR reply needs a reason");
  }
  if (line.size() >= 2) (void)describe_error(line.substr(0, 2));
  return 0;
}
