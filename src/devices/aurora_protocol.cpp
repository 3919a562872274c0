// NDI Aurora wire protocol (see aurora_protocol.h). Written from the public protocol description;
// no third-party code.
#include "hydrojet_control/devices/aurora_protocol.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "hydrojet_control/devices/crc16.h"

namespace hydrojet {
namespace devices {

static_assert(std::numeric_limits<float>::is_iec559, "BX floats are IEEE-754 binary32");

namespace {

constexpr double kMmToM = 1e-3;
constexpr double kMToMm = 1e3;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

/// Parses `n` hex digits of `s` starting at `pos`; false if any is not a hex digit.
bool parse_hex(const std::string& s, size_t pos, size_t n, uint32_t* v) {
  if (pos + n > s.size()) return false;
  uint32_t x = 0;
  for (size_t i = 0; i < n; ++i) {
    const int d = hex_value(s[pos + i]);
    if (d < 0) return false;
    x = (x << 4) | static_cast<uint32_t>(d);
  }
  *v = x;
  return true;
}

uint16_t le16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
uint32_t le32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
         (static_cast<uint32_t>(p[3]) << 24);
}
float lef32(const uint8_t* p) {
  const uint32_t u = le32(p);
  float f;
  std::memcpy(&f, &u, sizeof f);
  return f;
}
void put16(std::vector<uint8_t>* v, uint16_t x) {
  v->push_back(static_cast<uint8_t>(x & 0xFF));
  v->push_back(static_cast<uint8_t>(x >> 8));
}
void put32(std::vector<uint8_t>* v, uint32_t x) {
  for (int i = 0; i < 4; ++i) v->push_back(static_cast<uint8_t>((x >> (8 * i)) & 0xFF));
}
void putf32(std::vector<uint8_t>* v, double x) {
  const float f = static_cast<float>(x);
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  put32(v, u);
}

void set_err(std::string* err, const std::string& msg) {
  if (err) *err = msg;
}

void clear_pose(HandlePose* h) {
  for (double& x : h->q) x = kNaN;
  for (double& x : h->t) x = kNaN;
  h->rms_m = kNaN;
}

/// Messages for NDI error codes 0x01..0x1A (Combined API numbering).
const char* error_message(uint32_t code) {
  switch (code) {
    case 0x01: return "invalid command";
    case 0x02: return "command too long";
    case 0x03: return "command too short";
    case 0x04: return "invalid CRC in command";
    case 0x05: return "time-out on command execution";
    case 0x06: return "unable to set up new communication parameters";
    case 0x07: return "incorrect number of command parameters";
    case 0x08: return "invalid port handle selected";
    case 0x09: return "invalid tracking priority selected (must be S, D or B)";
    case 0x0A: return "invalid LED selected";
    case 0x0B: return "invalid LED state selected";
    case 0x0C: return "command invalid in the current operating mode";
    case 0x0D: return "no tool assigned to the selected port handle";
    case 0x0E: return "selected port handle not initialized";
    case 0x0F: return "selected port handle not enabled";
    case 0x10: return "system not initialized";
    case 0x11: return "unable to stop tracking";
    case 0x12: return "unable to start tracking";
    case 0x13: return "unable to initialize tool (port handle)";
    case 0x14: return "invalid field generator / sensor characterization parameters";
    case 0x15: return "unable to initialize the measurement system";
    case 0x16: return "unable to start diagnostic mode";
    case 0x17: return "unable to stop diagnostic mode";
    case 0x18: return "unable to determine environmental interference";
    case 0x19: return "unable to read firmware version information";
    case 0x1A: return "internal system error";
    default: return nullptr;
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// ASCII
// ---------------------------------------------------------------------------------------------

std::string format_command(const std::string& name, const std::string& params) {
  if (name.empty()) throw std::invalid_argument("format_command: empty command name");
  for (char c : name) {
    if (!((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9')))
      throw std::invalid_argument("format_command: command name '" + name + "' must be uppercase letters/digits");
  }
  for (char c : params) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u > 0x7E || c == ':')
      throw std::invalid_argument("format_command: parameters of " + name +
                                  " contain a control, non-ASCII or ':' character");
  }
  const std::string body = name + ":" + params;
  return body + crc16_hex(crc16_arc(body)) + "\r";
}

AsciiReply parse_ascii_reply(const std::string& line_without_cr) {
  AsciiReply r;
  const std::string& s = line_without_cr;
  if (s.size() < 4) {
    r.text = s;
    r.error = "reply too short for a CRC (" + std::to_string(s.size()) + " bytes)";
    return r;
  }
  r.text = s.substr(0, s.size() - 4);
  uint32_t got = 0;
  if (!parse_hex(s, s.size() - 4, 4, &got)) {
    r.error = "reply does not end in 4 hex CRC digits";
    return r;
  }
  const uint16_t want = crc16_arc(r.text);
  if (got != want) {
    r.error = "reply CRC mismatch (received " + s.substr(s.size() - 4) + ", computed " + crc16_hex(want) + ")";
    return r;
  }
  r.crc_ok = true;
  if (r.text.compare(0, 5, "ERROR") == 0) {
    r.error = describe_error(r.text);
    return r;
  }
  r.ok = true;
  return r;
}

std::string describe_error(const std::string& code) {
  std::string xx;
  if (code.size() == 7 && code.compare(0, 5, "ERROR") == 0)
    xx = code.substr(5);
  else if (code.size() == 2)
    xx = code;
  uint32_t v = 0;
  if (xx.empty() || !parse_hex(xx, 0, 2, &v)) return "malformed error code '" + code + "'";
  static const char kHex[] = "0123456789ABCDEF";
  std::string label = "ERROR";
  label += kHex[(v >> 4) & 0xF];
  label += kHex[v & 0xF];
  const char* msg = error_message(v);
  return label + ": " + (msg ? msg : "unknown");
}

bool parse_phsr(const std::string& text, std::vector<std::pair<uint8_t, uint16_t>>* out, std::string* err) {
  uint32_t n = 0;
  if (!parse_hex(text, 0, 2, &n)) {
    set_err(err, "PHSR reply '" + text + "': missing 2-hex-digit handle count");
    return false;
  }
  if (text.size() != 2 + 5 * static_cast<size_t>(n)) {
    set_err(err, "PHSR reply '" + text + "': " + std::to_string(n) + " handles need " + std::to_string(2 + 5 * n) +
                     " characters, got " + std::to_string(text.size()));
    return false;
  }
  std::vector<std::pair<uint8_t, uint16_t>> v;
  v.reserve(n);
  for (uint32_t i = 0; i < n; ++i) {
    uint32_t h = 0, st = 0;
    const size_t pos = 2 + 5 * static_cast<size_t>(i);
    if (!parse_hex(text, pos, 2, &h) || !parse_hex(text, pos + 2, 3, &st)) {
      set_err(err, "PHSR reply '" + text + "': non-hex character in entry " + std::to_string(i));
      return false;
    }
    v.emplace_back(static_cast<uint8_t>(h), static_cast<uint16_t>(st));
  }
  if (out) *out = std::move(v);
  return true;
}

std::vector<std::pair<uint8_t, uint16_t>> parse_phsr(const std::string& text) {
  std::vector<std::pair<uint8_t, uint16_t>> v;
  std::string err;
  if (!parse_phsr(text, &v, &err)) throw std::invalid_argument(err);
  return v;
}

// ---------------------------------------------------------------------------------------------
// BX decode / encode
// ---------------------------------------------------------------------------------------------

bool HandlePose::has_transform() const {
  if (status != kValid && status != kOutOfVolume) return false;
  for (double x : q)
    if (!std::isfinite(x)) return false;
  for (double x : t)
    if (!std::isfinite(x)) return false;
  return std::isfinite(rms_m);
}

const HandlePose* BxFrame::find(uint8_t handle) const {
  for (const HandlePose& h : handles)
    if (h.handle == handle) return &h;
  return nullptr;
}

namespace {

/// The 32-byte transform of a valid handle: quaternion (normalised), position [mm -> m], RMS error.
bool decode_transform(const uint8_t* data, HandlePose* h, std::string* err) {
  float v[8];
  for (int k = 0; k < 8; ++k) {
    v[k] = lef32(data + 4 * k);
    if (!std::isfinite(v[k])) {
      set_err(err, "BX handle " + std::to_string(h->handle) + " has a non-finite value");
      return false;
    }
  }
  const double norm = std::sqrt(double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2] + double(v[3]) * v[3]);
  if (std::fabs(norm - 1.0) > 1e-2) {
    set_err(err, "BX handle " + std::to_string(h->handle) + " quaternion norm " + std::to_string(norm) + " is not 1");
    return false;
  }
  if (v[7] < 0.0f) {
    set_err(err, "BX handle " + std::to_string(h->handle) + " has a negative rms error");
    return false;
  }
  for (int k = 0; k < 4; ++k) h->q[k] = double(v[k]) / norm;
  for (int k = 0; k < 3; ++k) h->t[k] = double(v[4 + k]) * kMmToM;
  h->rms_m = double(v[7]) * kMmToM;
  return true;
}

/// Handle entry `index` at body[*p]: handle, status byte, [transform,] port status, frame number.
/// Advances *p past it.
bool decode_handle(const uint8_t* body, size_t n, size_t index, uint32_t out_of_volume_mask, size_t* p, HandlePose* h,
                   std::string* err) {
  if (*p + 2 > n) {
    set_err(err, "BX body ends inside handle entry " + std::to_string(index));
    return false;
  }
  h->handle = body[*p];
  const uint8_t st = body[*p + 1];
  *p += 2;
  clear_pose(h);
  if (st == kBxHandleDisabled) {
    h->status = HandlePose::kDisabled;
    h->port_status = 0;
    h->frame = 0;
    return true;
  }
  if (st != kBxHandleValid && st != kBxHandleMissing) {
    set_err(err, "BX handle " + std::to_string(h->handle) + " has unknown status byte " + std::to_string(st));
    return false;
  }
  const size_t need = (st == kBxHandleValid ? 32 : 0) + 8;
  if (*p + need > n) {
    set_err(err, "BX body ends inside handle " + std::to_string(h->handle));
    return false;
  }
  if (st == kBxHandleValid) {
    if (!decode_transform(body + *p, h, err)) return false;
    *p += 32;
  }
  h->port_status = le32(body + *p);
  h->frame = le32(body + *p + 4);
  *p += 8;
  if (h->port_status & out_of_volume_mask)
    h->status = HandlePose::kOutOfVolume;
  else
    h->status = (st == kBxHandleValid) ? HandlePose::kValid : HandlePose::kMissing;
  return true;
}

/// What follows the handles: nothing, or the 2-byte system status.
bool decode_system_status(const uint8_t* body, size_t n, size_t p, BxFrame* f, std::string* err) {
  if (p == n) {
    f->has_system_status = false;
    f->system_status = 0;
  } else if (p + 2 == n) {
    f->has_system_status = true;
    f->system_status = le16(body + p);
  } else {
    set_err(err, "BX body has " + std::to_string(n - p) +
                     " unexpected trailing bytes (expected 0 or a 2-byte system status)");
    return false;
  }
  return true;
}

}  // namespace

bool decode_bx_body(const uint8_t* body, size_t n, uint32_t out_of_volume_mask, BxFrame* out, std::string* err) {
  if (n < 1) {
    set_err(err, "BX body is empty");
    return false;
  }
  BxFrame f;
  const size_t count = body[0];
  size_t p = 1;
  f.handles.reserve(count);
  for (size_t i = 0; i < count; ++i) {
    HandlePose h;
    if (!decode_handle(body, n, i, out_of_volume_mask, &p, &h, err)) return false;
    f.handles.push_back(h);
  }
  if (!decode_system_status(body, n, p, &f, err)) return false;
  if (out) *out = std::move(f);
  return true;
}

std::vector<uint8_t> encode_bx(const BxFrame& frame) {
  if (frame.handles.size() > 255) throw std::invalid_argument("encode_bx: more than 255 handles");
  std::vector<uint8_t> body;
  body.push_back(static_cast<uint8_t>(frame.handles.size()));
  for (const HandlePose& h : frame.handles) {
    body.push_back(h.handle);
    bool with_transform = false;
    uint32_t port = h.port_status;
    switch (h.status) {
      case HandlePose::kValid:
        if (!h.has_transform())
          throw std::invalid_argument("encode_bx: valid handle " + std::to_string(h.handle) +
                                      " has a non-finite transform");
        with_transform = true;
        break;
      case HandlePose::kMissing: break;
      case HandlePose::kDisabled: body.push_back(kBxHandleDisabled); continue;
      case HandlePose::kOutOfVolume:
        with_transform = h.has_transform();
        if (!(port & kDefaultOutOfVolumeMask)) port |= kPortOutOfVolume;
        break;
    }
    body.push_back(with_transform ? kBxHandleValid : kBxHandleMissing);
    if (with_transform) {
      for (double x : h.q) putf32(&body, x);
      for (double x : h.t) putf32(&body, x * kMToMm);
      putf32(&body, h.rms_m * kMToMm);
    }
    put32(&body, port);
    put32(&body, h.frame);
  }
  if (frame.has_system_status) put16(&body, frame.system_status);

  std::vector<uint8_t> out;
  out.reserve(kBxHeaderSize + body.size() + 2);
  out.push_back(kBxStart0);
  out.push_back(kBxStart1);
  put16(&out, static_cast<uint16_t>(body.size()));
  put16(&out, crc16_arc(out.data(), 4));
  out.insert(out.end(), body.begin(), body.end());
  put16(&out, crc16_arc(body.data(), body.size()));
  return out;
}

// ---------------------------------------------------------------------------------------------
// PVWR
// ---------------------------------------------------------------------------------------------

std::vector<std::string> pvwr_params(uint8_t handle, const std::vector<uint8_t>& data) {
  if (data.empty()) throw std::invalid_argument("pvwr_params: empty tool definition");
  if (data.size() > kMaxSromBytes)
    throw std::invalid_argument("pvwr_params: tool definition of " + std::to_string(data.size()) +
                                " bytes is longer than " + std::to_string(kMaxSromBytes));
  std::vector<std::string> out;
  char b[8];
  for (size_t addr = 0; addr < data.size(); addr += kPvwrChunk) {
    std::snprintf(b, sizeof b, "%02X%04X", handle, static_cast<unsigned>(addr));
    std::string p = b;
    for (size_t i = addr; i < addr + kPvwrChunk; ++i) {
      std::snprintf(b, sizeof b, "%02X", i < data.size() ? data[i] : 0);
      p += b;
    }
    out.push_back(p);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// TX decode
// ---------------------------------------------------------------------------------------------

namespace {

/// A signed decimal of `n` characters at s[pos]: '+' or '-' then n - 1 digits; false otherwise.
bool parse_signed(const std::string& s, size_t pos, size_t n, long* v) {
  if (pos + n > s.size() || (s[pos] != '+' && s[pos] != '-')) return false;
  long x = 0;
  for (size_t i = pos + 1; i < pos + n; ++i) {
    if (s[i] < '0' || s[i] > '9') return false;
    x = x * 10 + (s[i] - '0');
  }
  *v = s[pos] == '-' ? -x : x;
  return true;
}

std::string tx_handle_label(size_t index, uint32_t handle) {
  static const char kHex[] = "0123456789ABCDEF";
  std::string h;
  h += kHex[(handle >> 4) & 0xF];
  h += kHex[handle & 0xF];
  return "TX handle entry " + std::to_string(index) + " (" + h + ")";
}

/// The transform at s[*p]: q (4 x 6 chars, / 1e4), t (3 x 7 chars, / 100 mm), rms (6 chars, / 1e4 mm).
bool parse_tx_transform(const std::string& s, size_t* p, const std::string& label, HandlePose* h, std::string* err) {
  static const char* kField[8] = {"q0", "qx", "qy", "qz", "tx", "ty", "tz", "rms"};
  double v[8];
  size_t pos = *p;
  for (int k = 0; k < 8; ++k) {
    const size_t n = (k >= 4 && k < 7) ? 7 : 6;
    long x = 0;
    if (!parse_signed(s, pos, n, &x)) {
      set_err(err, label + ": field " + kField[k] + " is not a sign and " + std::to_string(n - 1) + " digits");
      return false;
    }
    v[k] = (k >= 4 && k < 7) ? x * 0.01 : x * 1e-4;
    pos += n;
  }
  const double norm = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]);
  if (std::fabs(norm - 1.0) > 1e-2) {
    set_err(err, label + ": quaternion norm " + std::to_string(norm) + " is not 1");
    return false;
  }
  if (v[7] < 0.0) {
    set_err(err, label + ": negative rms error");
    return false;
  }
  for (int k = 0; k < 4; ++k) h->q[k] = v[k] / norm;
  for (int k = 0; k < 3; ++k) h->t[k] = v[4 + k] * kMmToM;
  h->rms_m = v[7] * kMmToM;
  *p = pos;
  return true;
}

/// Port status and frame number (8 hex digits each) at s[*p].
bool parse_tx_status(const std::string& s, size_t* p, const std::string& label, HandlePose* h, std::string* err) {
  if (!parse_hex(s, *p, 8, &h->port_status) || !parse_hex(s, *p + 8, 8, &h->frame)) {
    set_err(err, label + ": port status and frame number must be 8 hex digits each");
    return false;
  }
  *p += 16;
  return true;
}

/// One handle entry at s[*p] up to and including its LF; *skip when it is UNOCCUPIED.
bool parse_tx_handle(const std::string& s, size_t index, uint32_t oov_mask, size_t* p, HandlePose* h, bool* skip,
                     std::string* err) {
  uint32_t handle = 0;
  if (!parse_hex(s, *p, 2, &handle)) {
    set_err(err, "TX handle entry " + std::to_string(index) + ": missing 2-hex-digit port handle");
    return false;
  }
  const std::string label = tx_handle_label(index, handle);
  *p += 2;
  h->handle = static_cast<uint8_t>(handle);
  clear_pose(h);
  *skip = false;
  bool transform = false;
  auto word = [&](const char* w) {
    const size_t n = std::strlen(w);
    if (s.compare(*p, n, w) != 0) return false;
    *p += n;
    return true;
  };
  if (word("UNOCCUPIED")) {
    *skip = true;
  } else if (word("DISABLED")) {
    h->status = HandlePose::kDisabled;
    h->port_status = h->frame = 0;
    if (*p < s.size() && s[*p] != '\n' && !parse_tx_status(s, p, label, h, err)) return false;
  } else if (word("MISSING")) {
    if (!parse_tx_status(s, p, label, h, err)) return false;
  } else {
    if (!parse_tx_transform(s, p, label, h, err) || !parse_tx_status(s, p, label, h, err)) return false;
    transform = true;
  }
  if (*p >= s.size() || s[*p] != '\n') {
    set_err(err, label + ": expected a line feed after the entry");
    return false;
  }
  ++*p;
  if (h->status != HandlePose::kDisabled && !*skip) {
    if (h->port_status & oov_mask)
      h->status = HandlePose::kOutOfVolume;
    else
      h->status = transform ? HandlePose::kValid : HandlePose::kMissing;
  }
  return true;
}

}  // namespace

bool parse_tx_reply(const std::string& text, uint32_t out_of_volume_mask, BxFrame* out, std::string* err) {
  uint32_t count = 0;
  if (!parse_hex(text, 0, 2, &count)) {
    set_err(err, "TX reply: missing 2-hex-digit handle count");
    return false;
  }
  BxFrame f;
  size_t p = 2;
  for (uint32_t i = 0; i < count; ++i) {
    HandlePose h;
    bool skip = false;
    if (!parse_tx_handle(text, i, out_of_volume_mask, &p, &h, &skip, err)) return false;
    if (!skip) f.handles.push_back(h);
  }
  uint32_t sys = 0;
  if (!parse_hex(text, p, 4, &sys) || p + 4 != text.size()) {
    set_err(err, "TX reply: expected 4 hex digits of system status after " + std::to_string(count) +
                     " handles, then the end (" + std::to_string(text.size() - std::min(p, text.size())) +
                     " characters left)");
    return false;
  }
  f.has_system_status = true;
  f.system_status = static_cast<uint16_t>(sys);
  if (out) *out = std::move(f);
  return true;
}

// ---------------------------------------------------------------------------------------------
// Streaming parser
// ---------------------------------------------------------------------------------------------

BxParser::BxParser(uint32_t out_of_volume_mask) : oov_mask_(out_of_volume_mask) {}

void BxParser::feed(const uint8_t* data, size_t n) {
  if (n == 0) return;
  compact();
  buf_.insert(buf_.end(), data, data + n);
}

void BxParser::feed(const std::string& bytes) { feed(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()); }

void BxParser::reset() {
  garbage_bytes_ += buffered();
  buf_.clear();
  head_ = 0;
}

void BxParser::discard(size_t n) {
  head_ += n;
  garbage_bytes_ += n;
}

void BxParser::compact() {
  if (head_ == 0) return;
  if (head_ == buf_.size()) {
    buf_.clear();
    head_ = 0;
  } else if (head_ >= 4096 || head_ * 2 >= buf_.size()) {
    buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(head_));
    head_ = 0;
  }
}

size_t BxParser::header_at(size_t pos) const {
  if (pos + kBxHeaderSize > buf_.size()) return 0;
  const uint8_t* h = buf_.data() + pos;
  if (h[0] != kBxStart0 || h[1] != kBxStart1) return 0;
  if (crc16_arc(h, 4) != le16(h + 4)) return 0;
  const size_t len = le16(h + 2);
  if (len < 1 || len > kBxMaxBodyLength) return 0;
  return kBxHeaderSize + len + 2;
}

bool BxParser::complete_valid_frame_at(size_t pos) const {
  const size_t total = header_at(pos);
  if (total == 0 || pos + total > buf_.size()) return false;
  const uint8_t* body = buf_.data() + pos + kBxHeaderSize;
  const size_t len = total - kBxHeaderSize - 2;
  return crc16_arc(body, len) == le16(body + len);
}

bool BxParser::next(BxFrame* out) {
  for (;;) {
    // 1. Hunt for the start sequence. A lone trailing C4 may be the first half of one: keep it.
    while (head_ < buf_.size()) {
      if (buf_[head_] == kBxStart0 && (head_ + 1 == buf_.size() || buf_[head_ + 1] == kBxStart1)) break;
      discard(1);
    }
    if (buf_.size() - head_ < kBxHeaderSize) return false;

    // 2. Header CRC and length plausibility.
    const uint8_t* h = buf_.data() + head_;
    if (crc16_arc(h, 4) != le16(h + 4)) {
      ++crc_errors_;
      discard(1);
      continue;
    }
    const size_t len = le16(h + 2);
    if (len < 1 || len > kBxMaxBodyLength) {
      ++format_errors_;
      discard(1);
      continue;
    }
    const size_t total = kBxHeaderSize + len + 2;

    // 3. Incomplete: wait, unless a complete valid frame starts inside the claimed extent, which
    //    means this one was truncated (the chance of a spurious header+body CRC match is ~2^-32).
    if (buf_.size() - head_ < total) {
      bool truncated = false;
      for (size_t p = head_ + 1; p + kBxHeaderSize <= buf_.size(); ++p) {
        if (buf_[p] == kBxStart0 && complete_valid_frame_at(p)) {
          ++truncated_frames_;
          discard(p - head_);
          truncated = true;
          break;
        }
      }
      if (!truncated) return false;  // wait for more bytes
      continue;
    }

    // 4. Body CRC.
    const uint8_t* body = h + kBxHeaderSize;
    if (crc16_arc(body, len) != le16(body + len)) {
      ++crc_errors_;
      discard(1);
      continue;
    }

    // 5. Decode (CRC-valid framing: a decode failure drops the whole frame).
    BxFrame f;
    if (!decode_bx_body(body, len, oov_mask_, &f, nullptr)) {
      ++format_errors_;
      discard(total);
      continue;
    }
    head_ += total;
    ++frames_;
    if (out) *out = std::move(f);
    compact();
    return true;
  }
}

}  // namespace devices
}  // namespace hydrojet
