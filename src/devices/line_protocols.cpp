// Flow-sensor line reader and valve-board protocol (see line_protocols.h).
#include "hydrojet_control/devices/line_protocols.h"

#include <charconv>
#include <cmath>
#include <regex>
#include <stdexcept>
#include <vector>

namespace hydrojet {
namespace devices {
namespace {

void set_err(std::string* err, const std::string& msg) {
  if (err) *err = msg;
}

bool is_blank(char c) { return c == ' ' || c == '\t'; }

std::string trim(const std::string& s) {
  size_t b = 0, e = s.size();
  while (b < e && is_blank(s[b])) ++b;
  while (e > b && is_blank(s[e - 1])) --e;
  return s.substr(b, e - b);
}

/// Removes one trailing "\n" and then one trailing "\r".
std::string strip_terminator(const std::string& line) {
  size_t e = line.size();
  if (e > 0 && line[e - 1] == '\n') --e;
  if (e > 0 && line[e - 1] == '\r') --e;
  return line.substr(0, e);
}

/// Parses all of `s` as one decimal number (optional sign; "inf"/"nan" parse and are left to the
/// caller's finiteness check). Locale-independent.
bool parse_number(const std::string& s, double* v) {
  if (s.empty()) return false;
  const char* b = s.data();
  const char* e = s.data() + s.size();
  if (*b == '+') {
    ++b;
    if (b == e || *b == '-' || *b == '+') return false;
  }
  const auto r = std::from_chars(b, e, *v, std::chars_format::general);
  return r.ec == std::errc() && r.ptr == e;
}

/// Compiled regex cache (one entry per thread): flow sensors use one pattern each, so recompiling
/// on every line is avoided without any shared state.
struct RegexCache {
  std::string pattern;
  std::regex re;
  bool valid = false;
  std::string error;
};

const RegexCache& compiled(const std::string& pattern) {
  thread_local RegexCache c;
  if (c.valid || !c.error.empty()) {
    if (c.pattern == pattern) return c;
  }
  c.pattern = pattern;
  c.valid = false;
  c.error.clear();
  try {
    c.re = std::regex(pattern, std::regex::ECMAScript);
    if (c.re.mark_count() < 1)
      c.error = "regex '" + pattern + "' has no capture group";
    else
      c.valid = true;
  } catch (const std::regex_error& e) {
    c.error = "invalid regex '" + pattern + "': " + e.what();
  }
  return c;
}

/// Selects the number text of a flow line; false with err on failure.
bool select_field(const std::string& line, const FlowLineFormat& fmt, std::string* field, std::string* err) {
  if (!fmt.regex.empty()) {
    const RegexCache& c = compiled(fmt.regex);
    if (!c.valid) {
      set_err(err, c.error);
      return false;
    }
    std::smatch m;
    if (!std::regex_search(line, m, c.re) || !m[1].matched) {
      set_err(err, "line does not match regex '" + fmt.regex + "'");
      return false;
    }
    *field = m[1].str();
    return true;
  }
  if (fmt.field_index < 0) {
    set_err(err, "negative field index " + std::to_string(fmt.field_index));
    return false;
  }
  std::vector<std::string> fields;
  if (is_blank(fmt.separator)) {
    size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && is_blank(line[i])) ++i;
      if (i == line.size()) break;
      size_t j = i;
      while (j < line.size() && !is_blank(line[j])) ++j;
      fields.push_back(line.substr(i, j - i));
      i = j;
    }
  } else {
    size_t i = 0;
    for (;;) {
      const size_t j = line.find(fmt.separator, i);
      fields.push_back(line.substr(i, j == std::string::npos ? std::string::npos : j - i));
      if (j == std::string::npos) break;
      i = j + 1;
    }
  }
  if (static_cast<size_t>(fmt.field_index) >= fields.size()) {
    set_err(err, "line has " + std::to_string(fields.size()) + " fields, field " + std::to_string(fmt.field_index) +
                     " requested");
    return false;
  }
  *field = fields[static_cast<size_t>(fmt.field_index)];
  return true;
}

/// Fixed 4-decimal text of a duty already clamped to [0, 1] (locale-independent).
std::string duty_text(double d) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, d, std::chars_format::fixed, 4);
  return std::string(buf, r.ptr);
}

std::string hex2(uint8_t v) {
  static const char kHex[] = "0123456789ABCDEF";
  return std::string{kHex[v >> 4], kHex[v & 0xF]};
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

std::string with_checksum(const std::string& payload) { return payload + "*" + hex2(valve_checksum(payload)) + "\n"; }

std::string duties_line(char type, const std::array<double, 3>& duty) {
  std::string p(1, type);
  for (double d : duty) {
    if (!std::isfinite(d)) throw std::invalid_argument(std::string("valve duty is not finite (") + type + " line)");
    const double c = d <= 0.0 ? 0.0 : (d >= 1.0 ? 1.0 : d);
    p += "," + duty_text(c);
  }
  return with_checksum(p);
}

/// Checks framing and checksum of a valve line; on success `*type` is the leading letter and
/// `*fields` the comma-separated fields after it.
bool check_frame(const std::string& raw, char* type, std::vector<std::string>* fields, std::string* err) {
  const std::string line = strip_terminator(raw);
  if (line.empty()) {
    set_err(err, "empty valve line");
    return false;
  }
  if (line.size() > kValveMaxLineLength) {
    set_err(err, "valve line too long (" + std::to_string(line.size()) + " characters)");
    return false;
  }
  for (char c : line) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u > 0x7E) {
      set_err(err, "valve line contains a control or non-ASCII character");
      return false;
    }
  }
  const size_t star = line.find('*');
  if (star == std::string::npos || star + 3 != line.size()) {
    set_err(err, "valve line must end in '*' and 2 hex checksum digits: '" + line + "'");
    return false;
  }
  const int hi = hex_value(line[star + 1]), lo = hex_value(line[star + 2]);
  if (hi < 0 || lo < 0) {
    set_err(err, "valve line checksum is not hex: '" + line + "'");
    return false;
  }
  const std::string payload = line.substr(0, star);
  const uint8_t want = valve_checksum(payload);
  if (static_cast<uint8_t>(hi * 16 + lo) != want) {
    set_err(err, "valve line checksum mismatch (received " + line.substr(star + 1) + ", computed " + hex2(want) + ")");
    return false;
  }
  if (payload.size() < 2 || payload[1] != ',') {
    set_err(err, "valve line must start with '<letter>,': '" + line + "'");
    return false;
  }
  *type = payload[0];
  fields->clear();
  size_t i = 2;
  for (;;) {
    const size_t j = payload.find(',', i);
    fields->push_back(payload.substr(i, j == std::string::npos ? std::string::npos : j - i));
    if (j == std::string::npos) break;
    i = j + 1;
  }
  return true;
}

bool parse_duties(const std::vector<std::string>& fields, std::array<double, 3>* duty, std::string* err) {
  if (fields.size() != 3) {
    set_err(err, "expected 3 duties, got " + std::to_string(fields.size()));
    return false;
  }
  std::array<double, 3> d{};
  for (size_t k = 0; k < 3; ++k) {
    double v = 0.0;
    if (!parse_number(fields[k], &v)) {
      set_err(err, "duty " + std::to_string(k + 1) + " '" + fields[k] + "' is not a number");
      return false;
    }
    if (!std::isfinite(v)) {
      set_err(err, "duty " + std::to_string(k + 1) + " is not finite");
      return false;
    }
    if (v < 0.0 || v > 1.0) {
      set_err(err, "duty " + std::to_string(k + 1) + " = " + fields[k] + " outside [0, 1]");
      return false;
    }
    d[k] = v == 0.0 ? 0.0 : v;  // -0 -> +0
  }
  *duty = d;
  return true;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// (a) Flow sensors
// ---------------------------------------------------------------------------------------------

bool parse_flow_line(const std::string& raw, const FlowLineFormat& fmt, double* flow_m3s, std::string* err) {
  if (!(std::isfinite(fmt.scale_to_m3_per_s) && fmt.scale_to_m3_per_s > 0.0)) {
    set_err(err, "scale_to_m3_per_s must be finite and > 0 (state the sensor's unit)");
    return false;
  }
  const std::string line = strip_terminator(raw);
  std::string field;
  if (!select_field(line, fmt, &field, err)) return false;
  field = trim(field);
  double v = 0.0;
  if (!parse_number(field, &v)) {
    set_err(err, "flow value '" + field + "' is not a number");
    return false;
  }
  if (!std::isfinite(v)) {
    set_err(err, "non-finite flow '" + field + "'");
    return false;
  }
  if (v < 0.0) {
    set_err(err, "negative flow " + field);
    return false;
  }
  const double q = (v == 0.0 ? 0.0 : v) * fmt.scale_to_m3_per_s;
  if (!std::isfinite(q)) {
    set_err(err, "non-finite flow after scaling '" + field + "'");
    return false;
  }
  if (flow_m3s) *flow_m3s = q;
  return true;
}

// ---------------------------------------------------------------------------------------------
// (b) Valve board
// ---------------------------------------------------------------------------------------------

uint8_t valve_checksum(const std::string& payload) {
  uint8_t x = 0;
  for (char c : payload) x ^= static_cast<uint8_t>(c);
  return x;
}

std::string format_valve_command(const std::array<double, 3>& duty) { return duties_line('V', duty); }

std::string format_valve_ack(const std::array<double, 3>& duty) { return duties_line('A', duty); }

std::string format_valve_nack(const std::string& reason) {
  std::string r = reason.empty() ? std::string("unspecified") : reason;
  for (char& c : r) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u > 0x7E || c == '*') c = '_';
  }
  const size_t max_reason = kValveMaxLineLength - 5;  // "N," + "*XX"
  if (r.size() > max_reason) r.resize(max_reason);
  return with_checksum("N," + r);
}

bool parse_valve_ack(const std::string& line, std::array<double, 3>* echoed, std::string* err) {
  char type = 0;
  std::vector<std::string> fields;
  if (!check_frame(line, &type, &fields, err)) return false;
  if (type == 'N') {
    std::string reason;
    for (size_t i = 0; i < fields.size(); ++i) reason += (i ? "," : "") + fields[i];
    set_err(err, "valve board rejected command: " + reason);
    return false;
  }
  if (type != 'A') {
    set_err(err, std::string("expected an 'A' (ack) line, got type '") + type + "'");
    return false;
  }
  std::array<double, 3> d{};
  if (!parse_duties(fields, &d, err)) return false;
  if (echoed) *echoed = d;
  return true;
}

bool parse_valve_ack(const std::string& line, std::string* err) { return parse_valve_ack(line, nullptr, err); }

bool parse_valve_command(const std::string& line, std::array<double, 3>* duty, std::string* err) {
  char type = 0;
  std::vector<std::string> fields;
  if (!check_frame(line, &type, &fields, err)) return false;
  if (type != 'V') {
    set_err(err, std::string("expected a 'V' (command) line, got type '") + type + "'");
    return false;
  }
  std::array<double, 3> d{};
  if (!parse_duties(fields, &d, err)) return false;
  if (duty) *duty = d;
  return true;
}

}  // namespace devices
}  // namespace hydrojet
