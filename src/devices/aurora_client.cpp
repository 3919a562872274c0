// NDI Aurora session and tracking loop (see aurora_client.h).
#include "hydrojet_control/devices/aurora_client.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "hydrojet_control/devices/crc16.h"

namespace hydrojet {
namespace devices {
namespace {

std::string hex2(uint8_t v) {
  char b[3];
  std::snprintf(b, sizeof b, "%02X", v);
  return b;
}

std::string handle_names(const std::vector<std::pair<uint8_t, uint16_t>>& v) {
  if (v.empty()) return "none";
  std::string s;
  for (const auto& h : v) s += (s.empty() ? "" : " ") + hex2(h.first);
  return s;
}

bool contains(const std::vector<std::pair<uint8_t, uint16_t>>& v, uint8_t h) {
  for (const auto& e : v)
    if (e.first == h) return true;
  return false;
}

bool positive_finite(double x) { return std::isfinite(x) && x > 0.0; }

/// Checks an ASCII reply to a command that answers OKAY (WARNINGxx: executed with a warning).
bool okay_text(const std::string& t) { return t == "OKAY" || t.compare(0, 7, "WARNING") == 0; }

}  // namespace

std::string aurora_comm_params(int baud) {
  switch (baud) {
    case 9600: return "00000";
    case 19200: return "20000";
    case 38400: return "30000";
    case 57600: return "40000";
    case 115200: return "50000";
    case 921600: return "60000";
    default: return "";
  }
}

std::string AuroraOptions::validate() const {
  if (port.empty()) return "port: must not be empty";
  if (aurora_comm_params(baud).empty())
    return "baud: " + std::to_string(baud) + " is not one of 9600, 19200, 38400, 57600, 115200, 921600";
  if (!(positive_finite(rate) && rate <= 1000.0)) return "rate: must lie in (0, 1000] Hz";
  if (!positive_finite(reply_timeout)) return "reply_timeout: must be finite and > 0";
  if (!positive_finite(command_timeout)) return "command_timeout: must be finite and > 0";
  if (!positive_finite(reset_timeout)) return "reset_timeout: must be finite and > 0";
  if (!positive_finite(timeout)) return "timeout: must be finite and > 0";
  if (timeout < reply_timeout) return "timeout: must be >= reply_timeout";
  if (timeout < 1.0 / rate) return "timeout: must be >= one tracking period (1 / rate)";
  if (!positive_finite(reconnect_period)) return "reconnect_period: must be finite and > 0";
  if (tip_handle == base_handle) return "base_handle: must differ from tip_handle";
  if (tracking_priority != 'S' && tracking_priority != 'D' && tracking_priority != 'B')
    return "tracking_priority: must be S, D or B";
  if (out_of_volume_mask == 0) return "out_of_volume_mask: must not be 0 (out-of-volume poses would pass)";
  if (bx_options.size() != 4) return "bx_options: must be 4 hex digits";
  unsigned opt = 0;
  for (char c : bx_options) {
    const bool hex = (c >= '0' && c <= '9') || (c >= 'A' && c <= 'F');
    if (!hex) return "bx_options: must be 4 uppercase hex digits";
    opt = opt * 16 + static_cast<unsigned>(c <= '9' ? c - '0' : c - 'A' + 10);
  }
  if (!(opt & 0x0001)) return "bx_options: must include 0001 (transformation data)";
  if (opt & ~0x0801u) return "bx_options: only 0001 and 0800 are decoded";
  return "";
}

bool AuroraStatus::healthy(SteadyTime now, double timeout) const {
  return tracking && ever_frame && seconds_between(last_frame, now) <= timeout;
}

bool AuroraStatus::handle_ok(const HandleStats& h, SteadyTime now, double timeout) {
  return h.ever_valid && h.last_status == HandlePose::kValid && seconds_between(h.last_valid, now) <= timeout;
}

AuroraClient::AuroraClient(const AuroraOptions& config, SampleCallback on_sample, LogCallback log)
    : cfg_(config),
      on_sample_(std::move(on_sample)),
      parser_(config.out_of_volume_mask),
      worker_(*this, mu_, status_, "tracker", config.reconnect_period, std::move(log)) {
  const std::string err = cfg_.validate();
  if (!err.empty()) throw std::invalid_argument("tracker: " + err);
}

AuroraClient::~AuroraClient() { stop(); }

AuroraStatus AuroraClient::status() const {
  std::lock_guard<std::mutex> l(mu_);
  return status_;
}

bool AuroraClient::run_session(std::string* fault) {
  if (!connect(fault)) return false;
  worker_.log(LogLevel::kInfo, "tracking on " + cfg_.port);
  track(fault);
  return true;
}

void AuroraClient::shut_down() {
  bool was_tracking;
  {
    std::lock_guard<std::mutex> l(mu_);
    was_tracking = status_.tracking;
  }
  if (was_tracking && port_.is_open()) {
    closing_ = true;  // read TSTOP's reply although stopping
    std::string reply, err;
    if (command("TSTOP", "", &reply, &err, 0.5))
      worker_.log(LogLevel::kInfo, "TSTOP, tracking stopped");
    else
      worker_.log(LogLevel::kWarn, "TSTOP failed: " + err);
    closing_ = false;
  }
  port_.close();
}

bool AuroraClient::connect(std::string* err) {
  worker_.set_link(LinkState::kConnecting, "opening " + cfg_.port);
  auto fail = [&](const std::string& e) {
    *err = e;
    std::lock_guard<std::mutex> l(mu_);
    ++status_.connect_failures;
    return false;
  };
  std::string e;
  if (!port_.open(cfg_.port, 9600, &e)) return fail(e);
  parser_.reset();
  have_tip_frame_ = have_base_frame_ = false;

  worker_.set_link(LinkState::kConnecting, "resetting (BREAK)");
  if (!reset_device(&e)) return fail(e);
  std::string reply;
  if (cfg_.baud != 9600) {
    worker_.set_link(LinkState::kConnecting, "COMM " + std::to_string(cfg_.baud));
    if (!command("COMM", aurora_comm_params(cfg_.baud), &reply, &e, cfg_.command_timeout)) return fail(e);
    if (!okay_text(reply)) return fail("COMM: unexpected reply '" + reply + "'");
    if (!port_.set_baud(cfg_.baud, &e)) return fail(e);
    // The device switches after its OKAY; give it time before the first byte at the new rate.
    if (!worker_.sleep_for(0.1)) return fail("stopping");
    port_.flush_input();
  }
  worker_.set_link(LinkState::kConnecting, "INIT");
  if (!command("INIT", "", &reply, &e, cfg_.command_timeout)) return fail(e);
  if (!okay_text(reply)) return fail("INIT: unexpected reply '" + reply + "'");

  std::vector<std::pair<uint8_t, uint16_t>> all, to_free, to_init, to_enable, enabled;
  if (!handle_list("00", &all, &e)) return fail(e);
  for (const auto& h : {std::make_pair(cfg_.tip_handle, "tip"), std::make_pair(cfg_.base_handle, "base")})
    if (!contains(all, h.first))
      return fail(std::string(h.second) + " sensor: port handle " + hex2(h.first) +
                  " not reported by the tracker (handles: " + handle_names(all) + ")");
  if (!handle_list("01", &to_free, &e)) return fail(e);
  for (const auto& h : to_free)
    if (!command("PHF", hex2(h.first), &reply, &e, cfg_.command_timeout)) return fail(e);
  if (!handle_list("02", &to_init, &e)) return fail(e);
  for (uint8_t h : {cfg_.tip_handle, cfg_.base_handle}) {
    if (!contains(to_init, h)) continue;
    worker_.set_link(LinkState::kConnecting, "PINIT " + hex2(h));
    if (!command("PINIT", hex2(h), &reply, &e, cfg_.command_timeout)) return fail(e);
    if (!okay_text(reply)) return fail("PINIT " + hex2(h) + ": unexpected reply '" + reply + "'");
  }
  if (!handle_list("03", &to_enable, &e)) return fail(e);
  for (uint8_t h : {cfg_.tip_handle, cfg_.base_handle}) {
    if (!contains(to_enable, h)) continue;
    if (!command("PENA", hex2(h) + std::string(1, cfg_.tracking_priority), &reply, &e, cfg_.command_timeout))
      return fail(e);
    if (!okay_text(reply)) return fail("PENA " + hex2(h) + ": unexpected reply '" + reply + "'");
  }
  if (!handle_list("04", &enabled, &e)) return fail(e);
  for (const auto& h : {std::make_pair(cfg_.tip_handle, "tip"), std::make_pair(cfg_.base_handle, "base")})
    if (!contains(enabled, h.first))
      return fail(std::string(h.second) + " sensor: port handle " + hex2(h.first) +
                  " not enabled after PINIT/PENA (enabled: " + handle_names(enabled) + ")");
  if (!command("TSTART", "", &reply, &e, cfg_.command_timeout)) return fail(e);
  if (!okay_text(reply)) return fail("TSTART: unexpected reply '" + reply + "'");
  std::lock_guard<std::mutex> l(mu_);
  status_.state = LinkState::kRunning;
  status_.tracking = true;
  status_.message = "tracking";
  status_.last_frame = SteadyClock::now();  // the silence clock starts at TSTART
  ++status_.sessions;
  return true;
}

bool AuroraClient::reset_device(std::string* err) {
  auto wait_reset = [&](double timeout) {
    const SteadyTime until = SteadyClock::now() + seconds(timeout);
    for (;;) {
      const double left = seconds_between(SteadyClock::now(), until);
      if (left <= 0.0 || stopping()) return false;
      std::string line, e;
      if (!read_ascii_line(&line, left, &e)) return false;
      const AsciiReply r = parse_ascii_reply(line);
      if (r.crc_ok && r.text == "RESET") return true;
      // Anything else (noise while the line settles, a late reply of an old session): keep waiting.
    }
  };
  port_.flush_input();
  std::string e;
  const bool pty = port_.is_pseudo_terminal();
  if (port_.send_break(&e) && wait_reset(pty ? 0.05 : cfg_.reset_timeout)) {
    std::lock_guard<std::mutex> l(mu_);
    status_.reset_by_break = true;
    return true;
  }
  // Fallback: the BREAK did not arrive (pseudo-terminal, adapter without BREAK support). A NUL byte
  // is what a UART receives for a BREAK; the test emulator resets on it.
  const uint8_t nul = 0;
  if (!port_.write_all(&nul, 1, 0.5, &e)) {
    *err = "reset: " + e;
    return false;
  }
  if (wait_reset(cfg_.reset_timeout)) {
    std::lock_guard<std::mutex> l(mu_);
    status_.reset_by_break = false;
    return true;
  }
  char buf[160];
  std::snprintf(buf, sizeof buf,
                "reset: no RESET reply within %.1f s to a BREAK nor to the NUL-byte fallback "
                "(tracker off, wrong port, or not an NDI device)",
                cfg_.reset_timeout);
  *err = buf;
  return false;
}

bool AuroraClient::read_ascii_line(std::string* line, double timeout, std::string* err) {
  line->clear();
  const SteadyTime until = SteadyClock::now() + seconds(timeout);
  uint8_t buf[256];
  for (;;) {
    const double left = seconds_between(SteadyClock::now(), until);
    if (left <= 0.0 || (stopping() && !closing_)) {
      *err = "no reply within " + std::to_string(timeout).substr(0, 5) + " s";
      return false;
    }
    // Read one byte at a time near the end of a line would be slow; read what is there and keep
    // the remainder (a reply is one line and nothing follows it until the next command).
    size_t n = 0;
    std::string e;
    const auto st = port_.read_some(buf, sizeof buf, std::min(left, 0.05), &n, &e);
    if (st == SerialPort::ReadStatus::kHangup || st == SerialPort::ReadStatus::kError) {
      *err = e;
      return false;
    }
    for (size_t i = 0; i < n; ++i) {
      if (buf[i] == '\r') return true;  // bytes after the CR (none expected) are dropped
      if (line->size() < 4096) line->push_back(static_cast<char>(buf[i]));
    }
  }
}

bool AuroraClient::command(const std::string& name, const std::string& params, std::string* reply, std::string* err,
                           double timeout) {
  port_.flush_input();
  const std::string cmd = format_command(name, params);
  std::string e;
  if (!port_.write_all(cmd, 0.5, &e)) {
    *err = name + ": " + e;
    return false;
  }
  std::string line;
  if (!read_ascii_line(&line, timeout, &e)) {
    *err = name + ": " + e;
    return false;
  }
  const AsciiReply r = parse_ascii_reply(line);
  if (!r.crc_ok) {
    std::lock_guard<std::mutex> l(mu_);
    ++ascii_crc_errors_;
    status_.crc_errors = parser_.crc_errors() + ascii_crc_errors_;
    *err = name + ": " + r.error;
    return false;
  }
  if (!r.ok) {
    std::lock_guard<std::mutex> l(mu_);
    ++status_.device_errors;
    *err = name + (params.empty() ? "" : " " + params) + ": " + r.error;
    return false;
  }
  *reply = r.text;
  return true;
}

bool AuroraClient::handle_list(const std::string& option, std::vector<std::pair<uint8_t, uint16_t>>* out,
                               std::string* err) {
  std::string reply, e;
  if (!command("PHSR", option, &reply, &e, cfg_.command_timeout)) {
    *err = e;
    return false;
  }
  if (!parse_phsr(reply, out, &e)) {
    *err = "PHSR " + option + ": " + e;
    return false;
  }
  return true;
}

void AuroraClient::track(std::string* err) {
  const double period = 1.0 / cfg_.rate;
  SteadyTime next = SteadyClock::now();
  while (!stopping()) {
    SteadyTime now = SteadyClock::now();
    if (next > now) {
      if (!worker_.sleep_for(seconds_between(now, next))) return;
    } else if (seconds_between(next, now) > period) {
      next = now;  // fell behind (a fault, a slow reply): do not burst
    }
    next += seconds(period);

    BxFrame f;
    std::string e;
    const BxResult r = request_bx(&f, &e);
    now = SteadyClock::now();
    {
      std::lock_guard<std::mutex> l(mu_);
      // The parser's counters are cumulative over sessions; mirror them.
      status_.crc_errors = parser_.crc_errors() + ascii_crc_errors_;
      status_.garbage_bytes = parser_.garbage_bytes();
      status_.format_errors = parser_.format_errors();
      status_.truncated_frames = parser_.truncated_frames();
      if (r == BxResult::kFrame) {
        ++status_.frames;
        status_.last_frame = now;
        status_.ever_frame = true;
      } else if (r == BxResult::kNoFrame) {
        ++status_.reply_timeouts;
      } else if (r == BxResult::kDeviceError) {
        ++status_.device_errors;
      }
    }
    if (r == BxResult::kHangup || r == BxResult::kDeviceError) {
      *err = e;
      return;
    }
    if (r == BxResult::kFrame) deliver(f, now);
    AuroraStatus s = status();
    if (seconds_between(s.last_frame, now) > cfg_.timeout) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "no valid BX reply for %.2f s (tracker silent)",
                    seconds_between(s.last_frame, now));
      *err = buf;
      return;
    }
  }
}

AuroraClient::BxResult AuroraClient::request_bx(BxFrame* frame, std::string* err) {
  // A frame completed by bytes that arrived after the previous request's time-out: it is a real,
  // CRC-valid device frame (the frame-number check drops it if it is not new).
  if (parser_.next(frame)) return BxResult::kFrame;
  std::string e;
  if (!port_.write_all(format_command("BX", cfg_.bx_options), 0.05, &e)) {
    *err = "BX: " + e;
    return BxResult::kHangup;
  }
  const auto rejected = [this] { return parser_.crc_errors() + parser_.format_errors() + parser_.truncated_frames(); };
  const uint64_t rejected0 = rejected();
  ascii_tail_.clear();
  const SteadyTime until = SteadyClock::now() + seconds(cfg_.reply_timeout);
  uint8_t buf[512];
  for (;;) {
    if (parser_.next(frame)) return BxResult::kFrame;
    // A rejected reply with nothing left that could still become a frame: do not wait it out.
    if (rejected() != rejected0 && parser_.buffered() < kBxHeaderSize) return BxResult::kNoFrame;
    const double left = seconds_between(SteadyClock::now(), until);
    if (left <= 0.0 || stopping()) break;
    size_t n = 0;
    const auto st = port_.read_some(buf, sizeof buf, left, &n, &e);
    if (st == SerialPort::ReadStatus::kHangup || st == SerialPort::ReadStatus::kError) {
      *err = e;
      return BxResult::kHangup;
    }
    if (n == 0) continue;
    parser_.feed(buf, n);
    // ASCII replies in the binary stream: "ERRORxx" + CRC + CR (e.g. ERROR0C when the device left
    // tracking mode) or "RESET" + CRC + CR (the device reset itself).
    ascii_tail_.append(reinterpret_cast<const char*>(buf), n);
    if (ascii_tail_.size() > 256) ascii_tail_.erase(0, ascii_tail_.size() - 256);
    for (size_t i = ascii_tail_.find('\r'); i != std::string::npos; i = ascii_tail_.find('\r', i + 1)) {
      for (size_t len : {size_t(11), size_t(9)}) {
        if (i < len) continue;
        const std::string cand = ascii_tail_.substr(i - len, len);
        if (cand.compare(0, 5, "ERROR") != 0 && cand.compare(0, 5, "RESET") != 0) continue;
        const AsciiReply a = parse_ascii_reply(cand);
        if (!a.crc_ok) continue;
        *err = a.text == "RESET" ? "BX: the tracker reset itself (power glitch?)" : "BX: " + a.error;
        return BxResult::kDeviceError;
      }
    }
  }
  parser_.reset();  // a partial frame must not be completed by unrelated later bytes
  return BxResult::kNoFrame;
}

void AuroraClient::deliver(const BxFrame& frame, SteadyTime received) {
  AuroraSample s;
  s.received = received;
  s.system_status = frame.system_status;
  auto pick = [&](uint8_t handle, HandlePose* out, uint32_t* last, bool* have) {
    const HandlePose* h = frame.find(handle);
    if (!h) {
      out->handle = handle;
      out->status = HandlePose::kMissing;
      for (double& x : out->q) x = std::nan("");
      for (double& x : out->t) x = std::nan("");
      out->rms_m = std::nan("");
      return false;
    }
    *out = *h;
    const bool is_new = !*have || h->frame != *last;
    *last = h->frame;
    *have = true;
    return is_new;
  };
  s.tip_new = pick(cfg_.tip_handle, &s.tip, &last_tip_frame_, &have_tip_frame_);
  s.base_new = pick(cfg_.base_handle, &s.base, &last_base_frame_, &have_base_frame_);
  {
    std::lock_guard<std::mutex> l(mu_);
    auto count = [&](const HandlePose& h, bool is_new, HandleStats* st) {
      if (!is_new) {
        if (!frame.find(h.handle)) st->last_status = HandlePose::kMissing;
        return;
      }
      st->last_status = h.status;
      switch (h.status) {
        case HandlePose::kValid:
          ++st->valid;
          st->last_valid = received;
          st->ever_valid = true;
          st->last_rms_m = h.rms_m;
          break;
        case HandlePose::kMissing: ++st->missing; break;
        case HandlePose::kDisabled: ++st->disabled; break;
        case HandlePose::kOutOfVolume: ++st->out_of_volume; break;
      }
    };
    count(s.tip, s.tip_new, &status_.tip);
    count(s.base, s.base_new, &status_.base);
    if (!s.tip_new && !s.base_new) ++status_.duplicate_frames;
  }
  if ((s.tip_new || s.base_new) && on_sample_) on_sample_(s);
}

}  // namespace devices
}  // namespace hydrojet
