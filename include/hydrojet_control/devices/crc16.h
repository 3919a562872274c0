// CRC-16/ARC as used by the NDI Combined API (Aurora, Polaris): polynomial 0x8005 processed
// LSB-first (reflected form 0xA001), initial value 0, no final XOR. Check value: "123456789" ->
// 0xBB3D. ROS-free, no I/O.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace hydrojet {
namespace devices {

/// CRC-16/ARC of `n` bytes starting at `data`.
/// Validates nothing: any byte sequence (including n == 0, which gives 0) has a CRC. `data` may be
/// null only when n == 0.
uint16_t crc16_arc(const uint8_t* data, size_t n);

/// CRC-16/ARC of the bytes of `bytes` (std::string is used as a byte container; embedded NULs
/// count).
uint16_t crc16_arc(const std::string& bytes);

/// `crc` as exactly four uppercase hexadecimal digits, most significant nibble first, as the NDI API
/// appends it to commands and ASCII replies (0xE3A5 -> "E3A5").
std::string crc16_hex(uint16_t crc);

}  // namespace devices
}  // namespace hydrojet
