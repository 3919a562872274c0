// Lines of the valve board's protocol: the host parses the board's acks and nacks
// (parse_valve_ack), the emulated board parses commands (parse_valve_command). Contract
// (line_protocols.h): accepted duties are finite and in [0, 1], the checksum of an accepted line is
// right, an accepted ack's duties survive format_valve_ack() -> parse_valve_ack() to half a unit of the 4th decimal,
// and a refused line has a reason.
#include <cctype>
#include <cmath>

#include "fuzz_common.h"
#include "hydrojet_control/devices/line_protocols.h"

using namespace hydrojet::devices;

namespace {

void check_duties(const std::array<double, 3>& d) {
  for (double v : d) FUZZ_CHECK(std::isfinite(v) && v >= 0.0 && v <= 1.0, "duty in [0, 1]");
}

void check_checksum(const std::string& line) {
  const size_t star = line.find('*');
  FUZZ_CHECK(star != std::string::npos && star + 3 <= line.size(), "an accepted line has '*XX'");
  const std::string xx = line.substr(star + 1, 2);
  FUZZ_CHECK(std::isxdigit(static_cast<unsigned char>(xx[0])) && std::isxdigit(static_cast<unsigned char>(xx[1])),
             "the checksum is two hex digits");
  const unsigned long sum = std::strtoul(xx.c_str(), nullptr, 16);
  FUZZ_CHECK(sum == valve_checksum(line.substr(0, star)), "an accepted line has the right checksum");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string line = hydrojet::fuzz::as_text(data, size);
  std::array<double, 3> d{-1.0, -1.0, -1.0};
  std::string err;
  const bool acked = parse_valve_ack(line, &d, &err);
  if (acked) {
    check_duties(d);
    check_checksum(line);
    std::array<double, 3> again{};
    FUZZ_CHECK(parse_valve_ack(format_valve_ack(d), &again, &err), "a formatted ack parses");
    // Printed with 4 decimals: off by at most half a unit of the last, 5e-5 (found by fuzzing: an
    // exact tie such as 0.05205 rounds to 0.0521, 5e-5 away give or take one rounding of a double).
    for (int k = 0; k < 3; ++k)
      FUZZ_CHECK(std::abs(again[k] - d[k]) <= 5e-5 + 1e-12, "the ack round trip keeps the duty");
  } else {
    FUZZ_CHECK(!err.empty(), "a refused ack needs a reason");
    FUZZ_CHECK(d[0] == -1.0 && d[1] == -1.0 && d[2] == -1.0, "the duties are written only on success");
  }
  err.clear();
  std::string err2;
  FUZZ_CHECK(parse_valve_ack(line, &err2) == acked, "the short overload agrees with the full one");
  if (parse_valve_command(line, &d, &err)) {
    check_duties(d);
    check_checksum(line);
  } else {
    FUZZ_CHECK(!err.empty(), "a refused command needs a reason");
  }
  (void)format_valve_nack(line);  // sanitises any reason without breaking the framing
  std::string nack_err;
  FUZZ_CHECK(!parse_valve_ack(format_valve_nack(line), &nack_err), "a nack is never an ack");
  FUZZ_CHECK(nack_err.find("rejected") != std::string::npos, "a sanitised nack parses as a rejection");
  return 0;
}
