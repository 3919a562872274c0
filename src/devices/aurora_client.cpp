// NDI Aurora session and tracking loop (see aurora_client.h).
#include "hydrojet_control/devices/aurora_client.h"

#include <cmath>
#include <cstdio>
#include <iterator>
#include <stdexcept>
#include <thread>

#include "hydrojet_control/devices/crc16.h"
#include "hydrojet_control/util/files.h"

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

bool load_srom(const std::string& path, std::vector<uint8_t>* data, std::string* err) {
  // A regular file only, and never more than the limit read (util/files.h): a device or a FIFO
  // (/dev/zero, a pipe) would otherwise hang or exhaust the node at start.
  std::string bytes;
  if (const std::string e = util::read_regular_file(path, &bytes, kMaxSromBytes); !e.empty()) {
    *err = "'" + path + "': " + e;
    return false;
  }
  if (bytes.empty()) {
    *err = "'" + path + "' is empty";
    return false;
  }
  data->assign(bytes.begin(), bytes.end());
  return true;
}

const char* to_string(AuroraOptions::ReplyFormat f) { return f == AuroraOptions::ReplyFormat::kTx ? "tx" : "bx"; }

const char* to_string(AuroraStatus::Connect c) {
  switch (c) {
    case AuroraStatus::Connect::kNone: return "none";
    case AuroraStatus::Connect::kBreak: return "BREAK";
    case AuroraStatus::Connect::kInitProbe9600: return "INIT probe at 9600 baud";
    case AuroraStatus::Connect::kInitProbeConfigured: return "INIT probe at the configured baud";
  }
  return "?";
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
  if (!(std::isfinite(latency) && latency >= 0.0 && latency <= 1.0)) return "latency: must lie in [0, 1] s";
  // The files themselves are read once, by the constructor (and by the rig YAML's parser, which names
  // the key of a missing one before anything starts).
  for (const auto& f : srom_files)
    if (f.first == 0) return "srom_files/" + hex2(f.first) + ": port handle 00 does not exist";
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
  for (const auto& f : cfg_.srom_files) {
    std::string e;
    if (!load_srom(f.second, &srom_[f.first], &e))
      throw std::invalid_argument("tracker: srom_files/" + hex2(f.first) + ": " + e);
  }
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
  if (port_.is_open() && device_up_) {
    closing_ = true;  // read the replies although stopping
    std::string reply, err;
    if (was_tracking) {
      if (command("TSTOP", "", &reply, &err, 0.5))
        worker_.log(LogLevel::kInfo, "TSTOP, tracking stopped");
      else
        worker_.log(LogLevel::kWarn, "TSTOP failed: " + err);
    }
    // Back to 9600, where the next start (ours, ndicapi's, NDI ToolBox's) looks first.
    if (host_baud_ != 9600) {
      if (command("COMM", "00000", &reply, &err, 0.5) && okay_text(reply)) {
        std::string e;
        if (!switch_host_baud(9600, &e)) worker_.log(LogLevel::kWarn, "host port back to 9600: " + e);
        worker_.log(LogLevel::kInfo, "COMM 00000, tracker back at 9600 baud");
      } else {
        worker_.log(LogLevel::kWarn, "COMM 00000 failed: " + err + " (the next start probes the configured baud)");
      }
    }
    closing_ = false;
  }
  device_up_ = false;
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
  device_up_ = false;
  if (!port_.open(cfg_.port, 9600, &e)) return fail(e);
  host_baud_ = 9600;
  parser_.reset();
  have_tip_frame_ = have_base_frame_ = false;
  use_tx_ = cfg_.reply_format == AuroraOptions::ReplyFormat::kTx;

  AuroraStatus::Connect how = AuroraStatus::Connect::kNone;
  if (!wake_device(&how, &e)) return fail(e);
  std::string reply;
  if (how != AuroraStatus::Connect::kInitProbeConfigured && !change_baud(&e)) return fail(e);
  if (how == AuroraStatus::Connect::kBreak) {
    worker_.set_link(LinkState::kConnecting, "INIT");
    if (!command("INIT", "", &reply, &e, cfg_.command_timeout)) return fail(e);
    if (!okay_text(reply)) return fail("INIT: unexpected reply '" + reply + "'");
    device_up_ = true;
  }
  if (!setup_handles(&e)) return fail(e);
  if (!command("TSTART", "", &reply, &e, cfg_.command_timeout)) return fail(e);
  if (!okay_text(reply)) return fail("TSTART: unexpected reply '" + reply + "'");
  std::lock_guard<std::mutex> l(mu_);
  status_.state = LinkState::kRunning;
  status_.tracking = true;
  status_.tx_mode = use_tx_;
  status_.connected_by = how;
  status_.message = "tracking";
  status_.last_frame = SteadyClock::now();  // the silence clock starts at TSTART
  ++status_.sessions;
  return true;
}

bool AuroraClient::change_baud(std::string* err) {
  if (cfg_.baud == 9600) return true;
  worker_.set_link(LinkState::kConnecting, "COMM " + std::to_string(cfg_.baud));
  std::string reply;
  if (!command("COMM", aurora_comm_params(cfg_.baud), &reply, err, cfg_.command_timeout)) return false;
  if (!okay_text(reply)) {
    *err = "COMM: unexpected reply '" + reply + "'";
    return false;
  }
  // The device switches after its OKAY; give it time before the first byte at the new rate.
  if (!worker_.sleep_for(0.1)) {
    *err = "stopping";
    return false;
  }
  return switch_host_baud(cfg_.baud, err);
}

bool AuroraClient::switch_host_baud(int baud, std::string* err) {
  if (!port_.set_baud(baud, err)) return false;
  host_baud_ = baud;
  port_.flush_input();
  return true;
}

bool AuroraClient::setup_handles(std::string* err) {
  std::string reply, e;
  auto fail = [&](const std::string& m) {
    *err = m;
    return false;
  };
  std::vector<std::pair<uint8_t, uint16_t>> all, to_free, to_init, to_enable, enabled;
  if (!handle_list("00", &all, err)) return false;
  for (const auto& h : {std::make_pair(cfg_.tip_handle, "tip"), std::make_pair(cfg_.base_handle, "base")})
    if (!contains(all, h.first))
      return fail(std::string(h.second) + " sensor: port handle " + hex2(h.first) +
                  " not reported by the tracker (handles: " + handle_names(all) + ")");
  if (!handle_list("01", &to_free, err)) return false;
  for (const auto& h : to_free)
    if (!command("PHF", hex2(h.first), &reply, err, cfg_.command_timeout)) return false;
  if (!handle_list("02", &to_init, err)) return false;
  for (uint8_t h : {cfg_.tip_handle, cfg_.base_handle}) {
    if (!contains(to_init, h)) continue;
    if (srom_.count(h) && !write_srom(h, err)) return false;
    worker_.set_link(LinkState::kConnecting, "PINIT " + hex2(h));
    if (!command("PINIT", hex2(h), &reply, &e, cfg_.command_timeout)) {
      if (!srom_.count(h) && !last_error_code_.empty())
        e += " (a tool without a programmed ROM needs its tool-definition file in tracker/srom_files/" + hex2(h) + ")";
      return fail(e);
    }
    if (!okay_text(reply)) return fail("PINIT " + hex2(h) + ": unexpected reply '" + reply + "'");
  }
  if (!handle_list("03", &to_enable, err)) return false;
  for (uint8_t h : {cfg_.tip_handle, cfg_.base_handle}) {
    if (!contains(to_enable, h)) continue;
    if (!command("PENA", hex2(h) + std::string(1, cfg_.tracking_priority), &reply, err, cfg_.command_timeout))
      return false;
    if (!okay_text(reply)) return fail("PENA " + hex2(h) + ": unexpected reply '" + reply + "'");
  }
  if (!handle_list("04", &enabled, err)) return false;
  for (const auto& h : {std::make_pair(cfg_.tip_handle, "tip"), std::make_pair(cfg_.base_handle, "base")})
    if (!contains(enabled, h.first))
      return fail(std::string(h.second) + " sensor: port handle " + hex2(h.first) +
                  " not enabled after PINIT/PENA (enabled: " + handle_names(enabled) + ")");
  return true;
}

bool AuroraClient::write_srom(uint8_t handle, std::string* err) {
  worker_.set_link(LinkState::kConnecting, "PVWR " + hex2(handle));
  const std::vector<std::string> chunks = pvwr_params(handle, srom_.at(handle));
  for (const std::string& p : chunks) {
    std::string reply, e;
    if (!command("PVWR", p, &reply, &e, cfg_.command_timeout)) {
      *err = "tracker/srom_files/" + hex2(handle) + ": " + e;
      return false;
    }
    if (!okay_text(reply)) {
      *err = "PVWR " + p.substr(0, 6) + ": unexpected reply '" + reply + "'";
      return false;
    }
  }
  worker_.log(LogLevel::kInfo, "tool definition " + cfg_.srom_files.at(handle) + " written to port handle " +
                                   hex2(handle) + " (" + std::to_string(chunks.size()) + " PVWR)");
  return true;
}

bool AuroraClient::wake_device(AuroraStatus::Connect* how, std::string* err) {
  worker_.set_link(LinkState::kConnecting, "resetting (BREAK)");
  if (reset_by_break()) {
    *how = AuroraStatus::Connect::kBreak;
    return true;
  }
  if (stopping()) {
    *err = "stopping";
    return false;
  }
  worker_.set_link(LinkState::kConnecting, "no RESET after the BREAK: INIT probe at 9600 baud");
  if (probe_init(9600)) {
    *how = AuroraStatus::Connect::kInitProbe9600;
    return true;
  }
  std::string tried = "9600";
  if (cfg_.baud != 9600 && !stopping()) {
    worker_.set_link(LinkState::kConnecting, "INIT probe at " + std::to_string(cfg_.baud) + " baud");
    std::string e;
    if (!switch_host_baud(cfg_.baud, &e)) {
      *err = "reset: " + e;
      return false;
    }
    if (probe_init(cfg_.baud)) {
      *how = AuroraStatus::Connect::kInitProbeConfigured;
      return true;
    }
    tried += " nor at " + std::to_string(cfg_.baud);
  }
  const bool pty = port_.is_pseudo_terminal();
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "reset: no RESET reply within %.2f s to a BREAK%s, and no reply to INIT at %s baud "
                "(tracker off, wrong port, or not an NDI device)",
                pty ? std::min(cfg_.reset_timeout, 0.5) : cfg_.reset_timeout, pty ? " (NUL stand-in on a pty)" : "",
                tried.c_str());
  *err = buf;
  return false;
}

bool AuroraClient::reset_by_break() {
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
  if (!port_.send_break(&e)) worker_.log(LogLevel::kWarn, "BREAK: " + e);
  if (pty) {
    // A pty drops the BREAK; the emulator takes a NUL byte for one (see the header comment).
    const uint8_t nul = 0;
    if (!port_.write_all(&nul, 1, 0.5, &e)) return false;
  }
  return wait_reset(pty ? std::min(cfg_.reset_timeout, 0.5) : cfg_.reset_timeout);
}

bool AuroraClient::probe_init(int baud) {
  std::string e;
  if (host_baud_ != baud && !switch_host_baud(baud, &e)) return false;
  for (int attempt = 0; attempt < 2 && !stopping(); ++attempt) {
    std::string reply;
    if (command("INIT", "", &reply, &e, cfg_.command_timeout) && okay_text(reply)) {
      device_up_ = true;
      return true;
    }
    if (last_error_code_.empty() || attempt == 1) return false;  // silent, garbled, or still refusing
    // A CRC-valid ERROR: the device is there (e.g. ERROR0C, still tracking from an earlier run).
    worker_.log(LogLevel::kInfo, "INIT at " + std::to_string(baud) + " baud: " + e + "; TSTOP and INIT again");
    std::string ignored;
    command("TSTOP", "", &reply, &ignored, cfg_.command_timeout);
  }
  return false;
}

bool AuroraClient::read_ascii_line(std::string* line, double timeout, std::string* err, bool* hangup) {
  line->clear();
  if (hangup) *hangup = false;
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
      if (hangup) *hangup = true;
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
  last_error_code_.clear();
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
    last_error_code_ = r.text;
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
    const bool tx = use_tx_;
    BxResult r = tx ? request_tx(&f, &e) : request_bx(&f, &e);
    now = SteadyClock::now();
    if (r == BxResult::kDeviceError && !tx && fall_back_to_tx(e)) continue;  // TX from the next period on
    count_reply(r, now);
    if (r == BxResult::kHangup || r == BxResult::kDeviceError) {
      *err = e;
      return;
    }
    if (r == BxResult::kFrame) deliver(f, now);
    AuroraStatus s = status();
    if (seconds_between(s.last_frame, now) > cfg_.timeout) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "no valid %s reply for %.2f s (tracker silent)", use_tx_ ? "TX" : "BX",
                    seconds_between(s.last_frame, now));
      *err = buf;
      return;
    }
  }
}

void AuroraClient::count_reply(BxResult r, SteadyTime now) {
  std::lock_guard<std::mutex> l(mu_);
  // The parser's counters are cumulative over sessions; mirror them.
  status_.crc_errors = parser_.crc_errors() + ascii_crc_errors_;
  status_.garbage_bytes = parser_.garbage_bytes();
  status_.format_errors = parser_.format_errors() + tx_format_errors_;
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

bool AuroraClient::fall_back_to_tx(const std::string& bx_error) {
  if (!cfg_.tx_fallback || bx_error_code_.empty()) return false;  // off, or the device reset itself
  use_tx_ = true;
  {
    std::lock_guard<std::mutex> l(mu_);
    ++status_.device_errors;
    status_.tx_mode = true;
    ++status_.tx_fallbacks;
  }
  worker_.log(LogLevel::kWarn, bx_error + "; this firmware refuses BX: polling with TX:0001 for this session");
  return true;
}

AuroraClient::BxResult AuroraClient::request_tx(BxFrame* frame, std::string* err) {
  port_.flush_input();  // a late reply to an earlier TX must not pass for this one's
  std::string e;
  if (!port_.write_all(format_command("TX", "0001"), 0.05, &e)) {
    *err = "TX: " + e;
    return BxResult::kHangup;
  }
  std::string line;
  bool hangup = false;
  if (!read_ascii_line(&line, cfg_.reply_timeout, &e, &hangup)) {
    if (hangup) *err = "TX: " + e;
    return hangup ? BxResult::kHangup : BxResult::kNoFrame;
  }
  const AsciiReply a = parse_ascii_reply(line);
  if (!a.crc_ok) {
    std::lock_guard<std::mutex> l(mu_);
    ++ascii_crc_errors_;
    return BxResult::kNoFrame;
  }
  if (!a.ok) {
    *err = "TX: " + a.error;
    return BxResult::kDeviceError;
  }
  if (a.text == "RESET") {
    *err = "TX: the tracker reset itself (power glitch?)";
    return BxResult::kDeviceError;
  }
  if (!parse_tx_reply(a.text, cfg_.out_of_volume_mask, frame, &e)) {
    std::lock_guard<std::mutex> l(mu_);
    ++tx_format_errors_;
    return BxResult::kNoFrame;
  }
  return BxResult::kFrame;
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
  bx_error_code_.clear();
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
        if (a.text != "RESET") bx_error_code_ = a.text;
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
  s.stamp = received - seconds(cfg_.latency);
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
  if (!s.tip_new && !s.base_new) return;
  // Strictly increasing stamps: a reply that came sooner after the previous one than the jitter of
  // the host's receive time must not be stamped before it.
  if (have_stamp_ && s.stamp <= last_stamp_) s.stamp = last_stamp_ + std::chrono::microseconds(1);
  last_stamp_ = s.stamp;
  have_stamp_ = true;
  if (on_sample_) on_sample_(s);
}

}  // namespace devices
}  // namespace hydrojet
