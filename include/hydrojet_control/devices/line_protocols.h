// Line-oriented device protocols of the HydroJet test bench. ROS-free, no I/O: strings in,
// values out.
//
// (a) Flow sensors. No public serial protocol exists for the Titan Atrato sensors, so the reader is
//     configurable: one text line per reading, the number picked either by a regular expression
//     (first capture group) or by field index after splitting on a separator, then scaled to SI.
//
// (b) Valve board. Our own NMEA-like protocol, one ASCII line per message, '\n' terminated
//     (a '\r' before the '\n' is tolerated on input, never produced):
//
//       host -> board  command:  V,<d1>,<d2>,<d3>*<XX>\n
//       board -> host  ack:      A,<d1>,<d2>,<d3>*<XX>\n   (echo of the duties the board applied)
//       board -> host  nack:     N,<reason>*<XX>\n         (command rejected, nothing applied)
//
//     d1..d3 are valve duty cycles in [0, 1] printed with exactly 4 decimals ("0.2500"); the
//     board accepts any plain decimal number in [0, 1]. <XX> is the checksum: the XOR of every
//     byte before the '*' (starting with and including the leading 'V' / 'A' / 'N'), printed as
//     two uppercase hex digits (either case is accepted on input). Example exchange:
//       host:  "V,0.2500,0.5000,1.0000*67\n"
//       board: "A,0.2500,0.5000,1.0000*70\n"
//     Lines are at most kValveMaxLineLength characters, excluding the terminator.
#pragma once

#include <array>
#include <cstdint>
#include <string>

namespace hydrojet {
namespace devices {

// ---------------------------------------------------------------------------------------------
// (a) Flow sensors
// ---------------------------------------------------------------------------------------------

/// Scale factors to [m^3/s].
constexpr double kMlPerMinToM3PerS = 1e-6 / 60.0;
constexpr double kLPerMinToM3PerS = 1e-3 / 60.0;

/// How to read one flow value from a sensor line.
struct FlowLineFormat {
  /// ECMAScript regular expression searched in the line; its first capture group is the number.
  /// Empty: use `field_index` and `separator` instead.
  std::string regex;
  /// 0-based field index when `regex` is empty.
  int field_index = 0;
  /// Field separator when `regex` is empty. ' ' or '\t' split on runs of blanks (spaces and tabs,
  /// leading blanks ignored); any other character splits on every occurrence (empty fields count).
  char separator = ',';
  /// Multiplier from the sensor's unit to [m^3/s], e.g. kMlPerMinToM3PerS for mL/min. The default 0
  /// is deliberately invalid: the unit must be stated.
  double scale_to_m3_per_s = 0.0;
};

/// Reads one flow value [m^3/s] from `line` (a trailing "\r\n" / "\n" is ignored).
/// Validates: `fmt.scale_to_m3_per_s` is finite and > 0; the regex compiles and has a capture group
/// that participated in the match, or `fmt.field_index` exists; the selected text (blanks trimmed)
/// is entirely one decimal number (optional sign, optional exponent; locale-independent); the value
/// is finite ("non-finite flow") and not negative ("negative flow"; -0 is accepted as 0).
/// @return false with `*err` set (if non-null) on any violation; `*flow_m3s` is only written on
/// success.
bool parse_flow_line(const std::string& line, const FlowLineFormat& fmt, double* flow_m3s, std::string* err);

// ---------------------------------------------------------------------------------------------
// (b) Valve board
// ---------------------------------------------------------------------------------------------

/// Longest accepted line, terminator excluded [characters].
constexpr size_t kValveMaxLineLength = 80;

/// XOR of all bytes of `payload` (the text before '*').
uint8_t valve_checksum(const std::string& payload);

/// Host side: the command line for three duty cycles, terminator included.
/// Validates: every duty is finite (NaN or +-inf throw std::invalid_argument: never send a command
/// computed from invalid data). Finite duties are clamped to [0, 1] before printing.
std::string format_valve_command(const std::array<double, 3>& duty);

/// Host side: checks a board reply line.
/// Validates: framing (type letter, ',', '*', 2 hex digits, length, no control characters), the
/// checksum, and that it is an 'A' line with three duties in [0, 1]. An 'N' line is a rejection:
/// returns false with `*err` = "valve board rejected command: <reason>".
/// @return true for a well-formed ack.
bool parse_valve_ack(const std::string& line, std::string* err);

/// As above, also returning the echoed duties (only written on success) so that the caller can
/// compare them with what it sent (they match to 5e-5 when the board applied the command).
bool parse_valve_ack(const std::string& line, std::array<double, 3>* echoed, std::string* err);

/// Board side (emulators, tests): parses a command line.
/// Validates: framing as for parse_valve_ack, checksum, type 'V', exactly three fields, each a
/// finite decimal number within [0, 1] (out-of-range values are rejected, not clamped: the host
/// always clamps, so they indicate corruption).
/// @return false with `*err` set on any violation; `*duty` is only written on success.
bool parse_valve_command(const std::string& line, std::array<double, 3>* duty, std::string* err);

/// Board side: the ack line echoing the applied duties (printed like format_valve_command()).
/// Validates as format_valve_command() (throws std::invalid_argument on non-finite values).
std::string format_valve_ack(const std::array<double, 3>& duty);

/// Board side: a rejection line. Characters of `reason` that would break the framing (control
/// characters, '*', non-ASCII) are replaced by '_'; an empty reason becomes "unspecified", and it is
/// truncated to fit kValveMaxLineLength.
std::string format_valve_nack(const std::string& reason);

}  // namespace devices
}  // namespace hydrojet
