// NDI Aurora (Combined API) wire protocol: command framing, ASCII reply checking, error codes, the
// PHSR reply, the binary BX tracking reply and the ASCII TX tracking reply. Bytes in, structs out:
// no I/O, no ROS, no threads.
//
// Wire format summary (all CRCs are CRC-16/ARC, see crc16.h):
//  * Command:      "NAME:params" + CRC of "NAME:params" as 4 uppercase hex digits + '\r'.
//                  e.g. "INIT:" -> "INIT:E3A5\r".
//  * ASCII reply:  text + CRC of text as 4 hex digits + '\r'; text is "OKAY", "ERRORxx",
//                  "WARNINGxx", "RESET" or command-specific data (e.g. PHSR).
//  * BX reply (binary, little-endian):
//      header: C4 A5 | uint16 body length | uint16 CRC of the 4 preceding header bytes
//      body:   uint8 handle count, then per handle
//                uint8 handle, uint8 handle status (0x01 valid, 0x02 missing, 0x04 disabled),
//                valid:    8 x float32 q0 qx qy qz, tx ty tz [mm], rms error [mm],
//                          uint32 port status, uint32 frame number
//                missing:  uint32 port status, uint32 frame number
//                disabled: nothing more
//              then (real devices, reply option 0x0001) uint16 system status
//      uint16 CRC of the body bytes.
//    The body length counts the body only (not the 6 header bytes nor the 2 body-CRC bytes).
//    decode_bx_body() accepts bodies with or without the trailing system-status word.
//
// Units: this is the boundary where the device's millimetres become metres. Every length in the
// structs below is in [m].
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace hydrojet {
namespace devices {

// ---------------------------------------------------------------------------------------------
// ASCII commands and replies
// ---------------------------------------------------------------------------------------------

/// Frames an NDI command: "NAME:params" + CRC16 (4 uppercase hex) + "\r".
/// Validates: `name` is non-empty and only uppercase letters / digits (e.g. "INIT", "PHSR", "BX",
/// "3D"); `params` contains only printable ASCII (0x20..0x7E) and no ':'.
/// @throws std::invalid_argument when either check fails (nothing must be sent then).
std::string format_command(const std::string& name, const std::string& params);

/// A checked ASCII reply.
struct AsciiReply {
  /// True when the CRC is correct and the text is not an ERRORxx reply.
  bool ok = false;
  /// True when the 4 trailing hex digits are present and equal the CRC of the text before them.
  bool crc_ok = false;
  /// The reply with its CRC removed (e.g. "OKAY", "ERROR0C", "020A0010B001"). Filled even when the
  /// CRC is wrong (for logging only; do not act on it).
  std::string text;
  /// Empty when ok; otherwise a readable reason: a CRC problem, or describe_error() of the code.
  std::string error;
};

/// Checks one ASCII reply line (everything up to, not including, the terminating '\r').
/// Validates: length >= 4; the last 4 characters are hex digits (either case accepted); they equal
/// crc16_arc() of the preceding text; and, if the text starts with "ERROR", decodes the code.
/// A "WARNINGxx" reply is ok == true (the command was executed); the caller can inspect `text`.
/// Never throws.
AsciiReply parse_ascii_reply(const std::string& line_without_cr);

/// Readable message for an NDI error code, given as "ERRORxx" or just "xx" (hex, either case).
/// Returns "ERRORxx: <message>" with xx in uppercase, "ERRORxx: unknown" for codes not in the table,
/// and "malformed error code '<code>'" when `code` is not of either form.
std::string describe_error(const std::string& code);

/// Parses the text of a PHSR reply (CRC already removed, e.g. by parse_ascii_reply):
/// 2 hex digits handle count n, then n times (2 hex digits handle, 3 hex digits handle status).
/// Validates: all characters hex; length == 2 + 5 n exactly.
/// @return (handle, status) pairs in reply order.
/// @throws std::invalid_argument on malformed text.
std::vector<std::pair<uint8_t, uint16_t>> parse_phsr(const std::string& text);

/// Non-throwing variant of parse_phsr(): returns false and sets `*err` (if non-null) on malformed
/// text; `*out` is only written on success.
bool parse_phsr(const std::string& text, std::vector<std::pair<uint8_t, uint16_t>>* out, std::string* err);

// ---------------------------------------------------------------------------------------------
// BX binary tracking reply
// ---------------------------------------------------------------------------------------------

/// Handle-status byte values of the BX reply.
constexpr uint8_t kBxHandleValid = 0x01;
constexpr uint8_t kBxHandleMissing = 0x02;
constexpr uint8_t kBxHandleDisabled = 0x04;

/// Port-status bits relevant here. The NDI API guide numbers the BX/TX port-status bits from 0:
/// bit 6 (0x40) "out of volume", bit 7 (0x80) "partially out of volume" (ndicapi uses the same
/// values). Bit 8 (0x100) is included in the default mask as a conservative measure: some
/// descriptions count the bits from 1, which shifts both flags up by one. The mask is a BxParser
/// parameter.
constexpr uint32_t kPortOutOfVolume = 0x40;
constexpr uint32_t kPortPartiallyOutOfVolume = 0x80;
constexpr uint32_t kPortBit8 = 0x100;
constexpr uint32_t kDefaultOutOfVolumeMask = kPortOutOfVolume | kPortPartiallyOutOfVolume | kPortBit8;

/// BX start sequence (0xA5C4 little-endian) as it appears on the wire.
constexpr uint8_t kBxStart0 = 0xC4;
constexpr uint8_t kBxStart1 = 0xA5;
/// Bytes before the body: start (2) + length (2) + header CRC (2).
constexpr size_t kBxHeaderSize = 6;
/// Largest plausible body [bytes]: 255 valid handles of 42 bytes, the count and the system status.
/// Longer lengths are rejected as corrupt (they would otherwise stall the stream for up to 64 kB).
constexpr size_t kBxMaxBodyLength = 1 + 255 * (2 + 32 + 8) + 2;

/// One handle of a BX reply, in SI units.
struct HandlePose {
  enum Status : uint8_t {
    kValid,        ///< transform present and port status has no out-of-volume bit
    kMissing,      ///< no transform (q, t, rms_m are NaN)
    kDisabled,     ///< handle disabled: no transform, port_status and frame are 0
    kOutOfVolume,  ///< an out-of-volume bit is set; q/t/rms_m are filled only if the device sent a
                   ///< transform (handle status 0x01), NaN otherwise. Never use it for control.
  };
  uint8_t handle = 0;
  Status status = kMissing;
  /// Unit quaternion (w, x, y, z) of the sensor in the field-generator frame (renormalised), or NaN.
  double q[4] = {0.0, 0.0, 0.0, 0.0};
  /// Sensor position in the field-generator frame [m] (device sends [mm]), or NaN.
  double t[3] = {0.0, 0.0, 0.0};
  /// RMS fit error reported by the device [m] (device sends [mm]), or NaN.
  double rms_m = 0.0;
  /// Raw 32-bit port status (0 for disabled handles).
  uint32_t port_status = 0;
  /// Device frame number of this measurement (0 for disabled handles).
  uint32_t frame = 0;

  /// True when q, t and rms_m hold a measured transform (status kValid, or kOutOfVolume with one).
  bool has_transform() const;
};

/// One decoded BX reply.
struct BxFrame {
  std::vector<HandlePose> handles;
  /// Whether the body carried the trailing uint16 system status (real devices do). encode_bx()
  /// writes it when true.
  bool has_system_status = true;
  uint16_t system_status = 0;

  /// The entry for `handle`, or nullptr.
  const HandlePose* find(uint8_t handle) const;
};

/// Decodes a BX body (the bytes between the header and the body CRC; CRCs already checked).
/// Validates: the handle count and every handle fit exactly, leaving 0 or 2 (system status) bytes;
/// handle status bytes are 0x01, 0x02 or 0x04; a valid handle's 8 floats are finite, its rms >= 0
/// and its quaternion norm is within 1e-2 of 1 (then renormalised). Port-status bits in
/// `out_of_volume_mask` turn kValid / kMissing into kOutOfVolume.
/// @return false (with `*err` set if non-null; `*out` unspecified) on any violation.
bool decode_bx_body(const uint8_t* body, size_t n, uint32_t out_of_volume_mask, BxFrame* out, std::string* err);

/// Encodes a complete BX reply (header, body, both CRCs) from `frame`, converting [m] back to [mm]
/// as float32. Status mapping: kValid -> 0x01 with transform; kMissing -> 0x02; kDisabled -> 0x04
/// (nothing else written); kOutOfVolume -> 0x01 with transform if has_transform() else 0x02, and
/// kPortOutOfVolume is OR-ed into the port status if no bit of kDefaultOutOfVolumeMask is set.
/// Port status is otherwise written verbatim, so a kValid handle whose port_status carries an
/// out-of-volume bit decodes as kOutOfVolume.
/// Validates: at most 255 handles; kValid handles have finite q, t, rms_m.
/// @throws std::invalid_argument when a check fails. Used by tests and emulators.
std::vector<uint8_t> encode_bx(const BxFrame& frame);

/// Streaming BX reply parser: feed it raw bytes as they arrive from the port (any chunking), and
/// pull complete frames with next(). It hunts for the C4 A5 start sequence, verifies the header
/// CRC, waits for the body, verifies the body CRC and decodes. It never emits a frame whose header
/// or body CRC is wrong. After garbage, a corrupt frame or a truncated frame it resynchronises by
/// resuming the hunt one byte after the rejected start sequence, so a good frame that begins inside
/// the rejected bytes is still found. While a frame is incomplete, a complete CRC-valid frame that
/// starts inside its claimed extent marks it as truncated, so a truncated reply followed by a good
/// one yields the good one without waiting for more bytes.
///
/// ASCII replies in the stream (e.g. "ERROR0C....\r" to a BX sent outside tracking mode) are
/// discarded as garbage: a driver that must see them should read the first reply bytes itself.
class BxParser {
 public:
  /// @param out_of_volume_mask port-status bits that mark a handle kOutOfVolume.
  explicit BxParser(uint32_t out_of_volume_mask = kDefaultOutOfVolumeMask);

  /// Appends `n` bytes to the internal buffer. Validates nothing (all checks happen in next()).
  void feed(const uint8_t* data, size_t n);
  /// Appends the bytes of `bytes`.
  void feed(const std::string& bytes);

  /// Extracts the next complete, CRC-valid, decodable frame into `*out` and returns true; returns
  /// false when more bytes are needed. Rejected candidates are counted (see the counters) and
  /// skipped.
  bool next(BxFrame* out);

  /// Drops all buffered bytes (counted as garbage), e.g. after a read time-out, so a stale partial
  /// frame cannot be completed by unrelated later bytes. Counters are kept.
  void reset();

  /// Bytes currently buffered and not yet consumed.
  size_t buffered() const { return buf_.size() - head_; }

  /// Frames returned by next().
  uint64_t frames() const { return frames_; }
  /// Candidate frames rejected for a wrong header CRC or a wrong body CRC.
  uint64_t crc_errors() const { return crc_errors_; }
  /// Bytes discarded without being part of a returned frame (garbage, rejected frames).
  uint64_t garbage_bytes() const { return garbage_bytes_; }
  /// CRC-valid frames that could not be decoded, and headers with an impossible body length.
  uint64_t format_errors() const { return format_errors_; }
  /// Incomplete frames abandoned because a complete valid frame started inside them.
  uint64_t truncated_frames() const { return truncated_frames_; }

 private:
  /// Total frame size (header + body + CRC) if a CRC-valid header with a plausible length starts at
  /// absolute buffer index `pos`; 0 if not (or not enough bytes to tell).
  size_t header_at(size_t pos) const;
  /// True if a complete frame with valid header and body CRCs starts at `pos`.
  bool complete_valid_frame_at(size_t pos) const;
  void discard(size_t n);
  void compact();

  uint32_t oov_mask_;
  std::vector<uint8_t> buf_;
  size_t head_ = 0;
  uint64_t frames_ = 0;
  uint64_t crc_errors_ = 0;
  uint64_t garbage_bytes_ = 0;
  uint64_t format_errors_ = 0;
  uint64_t truncated_frames_ = 0;
};

// ---------------------------------------------------------------------------------------------
// PVWR: writing a tool definition (SROM image) to a port handle
// ---------------------------------------------------------------------------------------------

/// Bytes of tool-definition data per PVWR command.
constexpr size_t kPvwrChunk = 64;
/// Largest SROM image accepted [bytes] (the Aurora's tool-definition memory).
constexpr size_t kMaxSromBytes = 1024;

/// The parameters of the PVWR commands that write `data` to `handle`: one per 64-byte chunk,
/// "<hh><AAAA><128 hex digits>" (handle, start address, data; uppercase hex; the last chunk padded
/// with 00 to 64 bytes).
/// @throws std::invalid_argument when `data` is empty or longer than kMaxSromBytes.
std::vector<std::string> pvwr_params(uint8_t handle, const std::vector<uint8_t>& data);

// ---------------------------------------------------------------------------------------------
// TX ASCII tracking reply (the fallback for firmware that rejects BX)
// ---------------------------------------------------------------------------------------------

/// Characters of one TX transform: q0 qx qy qz (sign + 5 digits each, implied / 10000), tx ty tz
/// (sign + 6 digits each, [mm], implied / 100), rms error (sign + 5 digits, [mm], implied / 10000).
constexpr size_t kTxTransformChars = 4 * 6 + 3 * 7 + 6;

/// Parses the text of a TX:0001 reply (CRC and CR already removed, e.g. by parse_ascii_reply):
///   2 hex digits handle count n, then n times
///     2 hex digits handle, then one of
///       <transform (kTxTransformChars)> 8 hex port status, 8 hex frame number
///       "MISSING"                        8 hex port status, 8 hex frame number
///       "DISABLED"                       [8 hex port status, 8 hex frame number] (optional)
///       "UNOCCUPIED"                     (skipped: no entry in the frame)
///     then LF
///   then 4 hex digits system status, and nothing after it.
/// (Layout as NDI's ndicapi reads it, ndiTXHelper / ndiGetTXTransform.) The result uses the BX
/// conventions: lengths in [m], the quaternion renormalised (its norm must be within 1e-2 of 1),
/// rms >= 0, port-status bits in `out_of_volume_mask` turn kValid / kMissing into kOutOfVolume,
/// disabled handles carry port_status 0 and frame 0 unless the reply had them.
/// @return false (with `*err` naming the handle and the field, if non-null; `*out` unspecified)
/// on any violation. Never throws, never reads past the text.
bool parse_tx_reply(const std::string& text, uint32_t out_of_volume_mask, BxFrame* out, std::string* err);

}  // namespace devices
}  // namespace hydrojet
