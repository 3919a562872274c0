// Valve backends, safety gate and valve loop (see valve_board.h).
#include "hydrojet_control/devices/valve_board.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "hydrojet_control/devices/line_protocols.h"

namespace hydrojet {
namespace devices {
namespace {

bool positive_finite(double x) { return std::isfinite(x) && x > 0.0; }

std::unique_ptr<ValveDriver> require_driver(std::unique_ptr<ValveDriver> driver) {
  if (!driver) throw std::invalid_argument("valves: no valve driver");
  return driver;
}

std::string duty_text(const Duty& d) {
  char b[64];
  std::snprintf(b, sizeof b, "%.4f, %.4f, %.4f", d[0], d[1], d[2]);
  return b;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// SerialValveBoard
// ---------------------------------------------------------------------------------------------

std::string SerialValveBoardOptions::validate() const {
  if (port.empty()) return "port: must not be empty";
  if (!is_supported_baud(baud)) return "baud: " + std::to_string(baud) + " is not a supported rate";
  if (!positive_finite(ack_timeout) || ack_timeout > 1.0) return "ack_timeout: must lie in (0, 1] s";
  return "";
}

SerialValveBoard::SerialValveBoard(const SerialValveBoardOptions& config) : cfg_(config) {
  const std::string err = cfg_.validate();
  if (!err.empty()) throw std::invalid_argument("valves: " + err);
}

bool SerialValveBoard::open(std::string* err) { return port_.open(cfg_.port, cfg_.baud, err); }

ValveDriver::Result SerialValveBoard::apply(const Duty& duty, Duty* applied, std::string* err) {
  std::string cmd;
  try {
    cmd = format_valve_command(duty);
  } catch (const std::invalid_argument& e) {
    *err = e.what();
    return Result::kRejected;
  }
  // What the board will echo: the duties exactly as printed (4 decimals).
  Duty sent{};
  std::string e;
  parse_valve_command(cmd, &sent, &e);
  port_.flush_input();  // a late ack of an earlier command must not count for this one
  if (!port_.write_all(cmd, cfg_.ack_timeout, &e)) {
    *err = e;
    return Result::kHangup;
  }
  LineSplitter lines(kValveMaxLineLength + 2);
  const SteadyTime until = SteadyClock::now() + seconds(cfg_.ack_timeout);
  uint8_t buf[256];
  for (;;) {
    std::string line;
    if (lines.next(&line)) {
      Duty echo{};
      if (!parse_valve_ack(line, &echo, &e)) {
        *err = e;  // a nack ("valve board rejected command: ...") or a corrupt reply
        return Result::kRejected;
      }
      for (int i = 0; i < 3; ++i) {
        if (std::fabs(echo[i] - sent[i]) > 5e-5) {
          *err = "valve board acknowledged " + duty_text(echo) + " for a command of " + duty_text(sent);
          return Result::kRejected;
        }
      }
      *applied = echo;
      return Result::kApplied;
    }
    const double left = seconds_between(SteadyClock::now(), until);
    if (left <= 0.0) {
      char b[80];
      std::snprintf(b, sizeof b, "no acknowledgement within %.0f ms", cfg_.ack_timeout * 1e3);
      *err = b;
      return Result::kNoReply;
    }
    size_t n = 0;
    const auto st = port_.read_some(buf, sizeof buf, left, &n, &e);
    if (st == SerialPort::ReadStatus::kHangup || st == SerialPort::ReadStatus::kError) {
      *err = e;
      return Result::kHangup;
    }
    lines.feed(buf, n);
  }
}

// ---------------------------------------------------------------------------------------------
// CommandGate
// ---------------------------------------------------------------------------------------------

bool CommandGate::set_command(const Duty& duty, SteadyTime now) {
  bool finite = true;
  for (double d : duty) finite = finite && std::isfinite(d);
  for (int i = 0; i < 3; ++i) duty_[i] = finite ? (duty[i] <= 0.0 ? 0.0 : (duty[i] >= 1.0 ? 1.0 : duty[i])) : 0.0;
  stamp_ = now;
  have_ = true;
  return finite;
}

Duty CommandGate::duty(SteadyTime now, bool devices_ok, const std::string& devices_reason, std::string* reason) const {
  const Duty zero{};
  if (!have_) {
    *reason = "no command received yet";
    return zero;
  }
  const double age = seconds_between(stamp_, now);
  if (age > timeout_) {
    char b[96];
    std::snprintf(b, sizeof b, "command timeout (last command %.3f s old)", age);
    *reason = b;
    return zero;
  }
  if (!devices_ok) {
    *reason = devices_reason.empty() ? std::string("a device is unhealthy") : devices_reason;
    return zero;
  }
  reason->clear();
  return duty_;
}

// ---------------------------------------------------------------------------------------------
// ValveLoop
// ---------------------------------------------------------------------------------------------

std::string ValveLoopOptions::validate() const {
  if (!(positive_finite(rate) && rate <= 1000.0)) return "rate: must lie in (0, 1000] Hz";
  if (!positive_finite(command_timeout)) return "command_timeout: must be finite and > 0";
  if (max_failures < 1) return "max_failures: must be >= 1";
  if (!positive_finite(reconnect_period)) return "reconnect_period: must be finite and > 0";
  return "";
}

ValveLoop::ValveLoop(std::unique_ptr<ValveDriver> driver, const ValveLoopOptions& config, HealthFn health,
                     AppliedCallback on_applied, LogCallback log)
    : driver_(require_driver(std::move(driver))),
      cfg_(config),
      health_(std::move(health)),
      on_applied_(std::move(on_applied)),
      gate_(config.command_timeout),
      worker_(*this, mu_, status_, driver_->describe(), config.reconnect_period, std::move(log)) {
  const std::string err = cfg_.validate();
  if (!err.empty()) throw std::invalid_argument("valves: " + err);
}

ValveLoop::~ValveLoop() { stop(); }

void ValveLoop::command(const Duty& duty) {
  {
    std::lock_guard<std::mutex> l(mu_);
    if (!gate_.set_command(duty, SteadyClock::now())) ++status_.bad_commands;
  }
  notify();
}

ValveStatus ValveLoop::status() const {
  std::lock_guard<std::mutex> l(mu_);
  return status_;
}

bool ValveLoop::run_session(std::string* fault) {
  if (!connect(fault)) return false;
  exchange(fault);
  return true;
}

bool ValveLoop::connect(std::string* err) {
  {
    std::lock_guard<std::mutex> l(mu_);
    status_.state = LinkState::kConnecting;
  }
  Duty applied{};
  bool ok = driver_->open(err);
  if (ok) {
    // Healthy again only once the board acknowledged closed valves.
    ok = driver_->apply(Duty{}, &applied, err) == ValveDriver::Result::kApplied;
    if (!ok) *err = "after reconnecting: " + *err;
  }
  if (!ok) {
    driver_->close();
    std::lock_guard<std::mutex> l(mu_);
    ++status_.connect_failures;
    return false;
  }
  const SteadyTime now = SteadyClock::now();
  {
    std::lock_guard<std::mutex> l(mu_);
    ++status_.connects;
    ++status_.sent;
    record_ack(applied, now);
  }
  worker_.log(LogLevel::kInfo, "connected, valves closed");
  if (on_applied_) on_applied_(applied, now);
  return true;
}

void ValveLoop::exchange(std::string* fault) {
  const double period = 1.0 / cfg_.rate;
  int failures = 0;
  while (driver_->is_open() && worker_.wait_for_wake(period)) {
    std::string err;
    const ValveDriver::Result r = send_gated_duty(&err);
    if (r == ValveDriver::Result::kApplied) {
      failures = 0;
    } else if (r == ValveDriver::Result::kHangup) {
      *fault = err;
      return;
    } else if (++failures >= cfg_.max_failures) {
      *fault = std::to_string(failures) + " commands in a row not acknowledged (" + err + ")";
      return;
    }
  }
}

Duty ValveLoop::gated_duty() {
  std::string devices_reason, reason;
  const bool devices_ok = health_ ? health_(&devices_reason) : true;
  std::lock_guard<std::mutex> l(mu_);
  const Duty duty = gate_.duty(SteadyClock::now(), devices_ok, devices_reason, &reason);
  status_.gate_open = reason.empty();
  status_.gate_reason = reason;
  return duty;
}

ValveDriver::Result ValveLoop::send_gated_duty(std::string* err) {
  const Duty duty = gated_duty();
  Duty applied{};
  const ValveDriver::Result r = driver_->apply(duty, &applied, err);
  const SteadyTime now = SteadyClock::now();
  {
    std::lock_guard<std::mutex> l(mu_);
    ++status_.sent;
    switch (r) {
      case ValveDriver::Result::kApplied: record_ack(applied, now); break;
      case ValveDriver::Result::kNoReply:
        ++status_.no_reply;
        status_.last_error = *err;
        break;
      case ValveDriver::Result::kRejected:
        ++status_.rejected;
        status_.last_error = *err;
        break;
      case ValveDriver::Result::kHangup: ++status_.hangups; break;
    }
  }
  if (r == ValveDriver::Result::kApplied && on_applied_) on_applied_(applied, now);
  return r;
}

void ValveLoop::record_ack(const Duty& applied, SteadyTime when) {
  ++status_.acknowledged_count;
  status_.acknowledged = applied;
  status_.ever_acknowledged = true;
  status_.last_ack = when;
  status_.healthy = true;
  status_.state = LinkState::kRunning;
  status_.message = "acknowledging";
}

void ValveLoop::shut_down() {
  if (driver_->is_open()) {
    Duty applied{};
    std::string err;
    const auto r = driver_->apply(Duty{}, &applied, &err);
    if (r == ValveDriver::Result::kApplied) {
      worker_.log(LogLevel::kInfo, "valves closed on shutdown");
      std::lock_guard<std::mutex> l(mu_);
      status_.acknowledged = applied;
      status_.last_ack = SteadyClock::now();
    } else {
      worker_.log(LogLevel::kWarn, "closing valves on shutdown failed: " + err);
    }
  }
  driver_->close();
}

}  // namespace devices
}  // namespace hydrojet
