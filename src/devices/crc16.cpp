// CRC-16/ARC (see crc16.h). Table-driven, one table lookup per byte.
#include "hydrojet_control/devices/crc16.h"

#include <array>

namespace hydrojet {
namespace devices {
namespace {

/// 256-entry table for the reflected polynomial 0xA001, built at compile time.
constexpr std::array<uint16_t, 256> make_table() {
  std::array<uint16_t, 256> t{};
  for (unsigned i = 0; i < 256; ++i) {
    uint16_t c = static_cast<uint16_t>(i);
    for (int k = 0; k < 8; ++k)
      c = (c & 1u) ? static_cast<uint16_t>((c >> 1) ^ 0xA001u) : static_cast<uint16_t>(c >> 1);
    t[i] = c;
  }
  return t;
}

constexpr std::array<uint16_t, 256> kTable = make_table();

}  // namespace

uint16_t crc16_arc(const uint8_t* data, size_t n) {
  uint16_t crc = 0;
  for (size_t i = 0; i < n; ++i) crc = static_cast<uint16_t>((crc >> 8) ^ kTable[(crc ^ data[i]) & 0xFFu]);
  return crc;
}

uint16_t crc16_arc(const std::string& bytes) {
  return crc16_arc(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
}

std::string crc16_hex(uint16_t crc) {
  static const char kHex[] = "0123456789ABCDEF";
  std::string s(4, '0');
  for (int i = 0; i < 4; ++i) s[static_cast<size_t>(i)] = kHex[(crc >> (12 - 4 * i)) & 0xFu];
  return s;
}

}  // namespace devices
}  // namespace hydrojet
