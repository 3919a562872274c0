// Line-streaming flow sensors and the jet-state aggregator (see flow_sensors.h).
#include "hydrojet_control/devices/flow_sensors.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace hydrojet {
namespace devices {
namespace {

bool positive_finite(double x) { return std::isfinite(x) && x > 0.0; }

}  // namespace

std::string FlowSensorOptions::validate() const {
  if (port.empty()) return "port: must not be empty";
  if (!is_supported_baud(baud)) return "baud: " + std::to_string(baud) + " is not a supported rate";
  if (!positive_finite(format.scale_to_m3_per_s)) return "scale: the unit scale to m^3/s must be finite and > 0";
  if (format.regex.empty() && format.field_index < 0) return "field_index: must be >= 0";
  if (format.separator == '\n' || format.separator == '\r') return "separator: must not be a line end";
  if (!positive_finite(timeout)) return "timeout: must be finite and > 0";
  if (!positive_finite(reconnect_period)) return "reconnect_period: must be finite and > 0";
  if (max_line_length < 8 || max_line_length > 4096) return "max_line_length: must lie in [8, 4096]";
  if (!format.regex.empty()) {
    // Probe: surfaces an invalid pattern or a missing capture group now, not on the first line.
    std::string err;
    double q;
    parse_flow_line("0", format, &q, &err);
    if (err.find("invalid regex") != std::string::npos || err.find("capture group") != std::string::npos)
      return "regex: " + err;
  }
  return "";
}

FlowSensor::FlowSensor(const FlowSensorOptions& config, ReadingCallback on_reading, LogCallback log)
    : cfg_(config),
      on_reading_(std::move(on_reading)),
      worker_(*this, mu_, status_, config.name, config.reconnect_period, std::move(log)) {
  const std::string err = cfg_.validate();
  if (!err.empty()) throw std::invalid_argument(cfg_.name + ": " + err);
}

FlowSensor::~FlowSensor() { stop(); }

FlowSensorStatus FlowSensor::status() const {
  std::lock_guard<std::mutex> l(mu_);
  return status_;
}

bool FlowSensor::run_session(std::string* fault) {
  worker_.set_link(LinkState::kConnecting, "opening " + cfg_.port);
  if (!open_port(fault)) {
    std::lock_guard<std::mutex> l(mu_);
    ++status_.connect_failures;
    return false;
  }
  {
    std::lock_guard<std::mutex> l(mu_);
    ++status_.connects;
    status_.message = "waiting for data";
  }
  worker_.log(LogLevel::kInfo, "port " + cfg_.port + " open");
  *fault = stream();
  return true;
}

bool FlowSensor::open_port(std::string* err) {
  if (!port_.open(cfg_.port, cfg_.baud, err)) return false;
  return cfg_.start_command.empty() || port_.write_all(cfg_.start_command, 0.5, err);
}

std::string FlowSensor::stream() {
  LineSplitter lines(cfg_.max_line_length);
  lines.skip_first_line();                  // opened mid-stream: the first line may be a tail ("3.4" of "123.4")
  SteadyTime last_ok = SteadyClock::now();  // silence clock starts at open
  uint64_t discarded_seen = 0;
  uint8_t buf[512];
  while (!worker_.stopping()) {
    size_t n = 0;
    std::string e;
    const auto st = port_.read_some(buf, sizeof buf, 0.05, &n, &e);
    if (st == SerialPort::ReadStatus::kHangup || st == SerialPort::ReadStatus::kError) return e;
    if (n > 0) lines.feed(buf, n);
    std::string line;
    while (lines.next(&line)) deliver_line(line, &last_ok);
    if (lines.discarded() != discarded_seen) {
      std::lock_guard<std::mutex> l(mu_);
      status_.discarded += lines.discarded() - discarded_seen;
      discarded_seen = lines.discarded();
      status_.last_error = "discarded an over-long line or one with a NUL byte (garbage)";
    }
    const double silent = seconds_between(last_ok, SteadyClock::now());
    if (silent > cfg_.timeout) {
      char msg[96];
      std::snprintf(msg, sizeof msg, "no valid reading for %.2f s (sensor silent or sending garbage)", silent);
      return msg;
    }
  }
  return "stopped";
}

void FlowSensor::deliver_line(const std::string& line, SteadyTime* last_accepted) {
  FlowReading r;
  r.time = SteadyClock::now();
  double q = 0.0;
  r.accepted = parse_flow_line(line, cfg_.format, &q, &r.error);
  r.flow = r.accepted ? q : std::numeric_limits<double>::quiet_NaN();
  {
    std::lock_guard<std::mutex> l(mu_);
    ++status_.lines;
    if (r.accepted) {
      ++status_.accepted;
      status_.last_accepted = r.time;
      status_.ever_accepted = true;
      status_.last_flow = q;
      status_.state = LinkState::kRunning;
      status_.message = "streaming";
    } else {
      ++status_.rejected;
      status_.last_error = "rejected line '" + line.substr(0, 40) + "': " + r.error;
    }
  }
  if (r.accepted) *last_accepted = r.time;
  if (on_reading_) on_reading_(r);
}

// ---------------------------------------------------------------------------------------------
// FlowAggregator
// ---------------------------------------------------------------------------------------------

void FlowAggregator::add(size_t jet, const FlowReading& r) {
  if (jet >= 3) return;
  std::lock_guard<std::mutex> l(mu_);
  Jet& j = jets_[jet];
  j.last_line = r.time;
  j.last_rejected = !r.accepted;
  if (r.accepted) {
    j.have_accepted = true;
    j.accepted_time = r.time;
    j.flow = r.flow;
  }
  fresh_ = true;
}

bool FlowAggregator::take(SteadyTime now, Sample* out) {
  std::lock_guard<std::mutex> l(mu_);
  if (!fresh_) return false;
  fresh_ = false;
  Sample s;
  bool any_valid = false;
  SteadyTime oldest = now, newest{};
  for (size_t i = 0; i < 3; ++i) {
    const Jet& j = jets_[i];
    const bool valid = j.have_accepted && !(invalidate_on_reject_ && j.last_rejected) &&
                       seconds_between(j.accepted_time, now) <= stale_timeout_;
    s.valid[i] = valid;
    s.flow[i] = valid ? j.flow : std::numeric_limits<double>::quiet_NaN();
    if (valid) {
      any_valid = true;
      if (j.accepted_time < oldest) oldest = j.accepted_time;
    }
    if (j.last_line > newest) newest = j.last_line;
  }
  s.stamp = any_valid ? oldest : newest;
  *out = s;
  return true;
}

}  // namespace devices
}  // namespace hydrojet
