// The HydroJet's three solenoid valves: a backend interface (ValveDriver), its serial valve-board
// implementation (the line protocol of line_protocols.h), the safety gate that decides which duty
// may be applied, and the loop (one thread, DeviceWorker of device_worker.h) that applies it and
// reconnects. ROS-free.
//
// Safety rules (CommandGate + ValveLoop):
//  * the valves get the controller's last command only while it is at most `command_timeout` old
//    and every other device is healthy (the caller's health function); otherwise zero duty;
//  * a non-finite command is a zero command;
//  * the gated duty is (re)sent at least `rate` times per second (keep-alive; the board should close
//    its valves by itself when commands stop) and at once when a command arrives;
//  * `max_failures` commands in a row without a valid acknowledgement, or a hang-up, make the board
//    unhealthy: the port is closed and reopened every `reconnect_period`; the board counts as
//    healthy again only after it acknowledged a zero-duty command;
//  * on stop, zero duty is sent (best effort) before the port closes.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "hydrojet_control/devices/device_status.h"
#include "hydrojet_control/devices/device_worker.h"
#include "hydrojet_control/devices/serial_port.h"

namespace hydrojet {
namespace devices {

using Duty = std::array<double, 3>;

/// Anything that can set the three valve duties: the serial valve board here, a DAQ with PWM
/// outputs elsewhere. Called from one thread only (ValveLoop's).
class ValveDriver {
 public:
  enum class Result {
    kApplied,   ///< the hardware confirmed the duties (*applied holds them)
    kNoReply,   ///< no confirmation in time (the command may or may not have been applied)
    kRejected,  ///< the hardware refused the command, or its reply was corrupt or did not match
    kHangup,    ///< the device went away: close and reconnect
  };
  virtual ~ValveDriver() = default;
  /// For messages: "valve board (/dev/ttyACM0)".
  virtual std::string describe() const = 0;
  virtual bool open(std::string* err) = 0;
  virtual void close() = 0;
  virtual bool is_open() const = 0;
  /// Applies `duty` (each finite, in [0, 1]).
  virtual Result apply(const Duty& duty, Duty* applied, std::string* err) = 0;
};

struct SerialValveBoardOptions {
  std::string port;
  int baud = 115200;
  double ack_timeout = 0.05;  ///< [s]
  std::string validate() const;
};

/// The valve-driver board on a serial port: "V,d1,d2,d3*XX\n" -> "A,d1,d2,d3*XX\n" (or "N,...").
/// The echoed duties must equal the sent ones (4 decimals); anything else is kRejected.
class SerialValveBoard : public ValveDriver {
 public:
  explicit SerialValveBoard(const SerialValveBoardOptions& config);
  std::string describe() const override { return "valve board (" + cfg_.port + ")"; }
  bool open(std::string* err) override;
  void close() override { port_.close(); }
  bool is_open() const override { return port_.is_open(); }
  Result apply(const Duty& duty, Duty* applied, std::string* err) override;

 private:
  SerialValveBoardOptions cfg_;
  SerialPort port_;
};

/// Decides the duty the valves may get. Not thread-safe (ValveLoop guards it).
class CommandGate {
 public:
  explicit CommandGate(double command_timeout) : timeout_(command_timeout) {}
  /// Records a command received at `now`. A non-finite duty makes it a zero command; returns false
  /// then. Finite duties are clamped to [0, 1].
  bool set_command(const Duty& duty, SteadyTime now);
  /// The duty to apply at `now`: the last command if it is at most command_timeout old and
  /// `devices_ok`; zeros otherwise, with `*reason` saying why (empty when the command passes).
  Duty duty(SteadyTime now, bool devices_ok, const std::string& devices_reason, std::string* reason) const;

 private:
  double timeout_;
  Duty duty_{};
  SteadyTime stamp_{};
  bool have_ = false;
};

struct ValveLoopOptions {
  double rate = 50.0;             ///< keep-alive: minimum commands per second [Hz]
  double command_timeout = 0.1;   ///< controller command older than this: zero duty [s]
  int max_failures = 3;           ///< unacknowledged commands in a row before the board is unhealthy
  double reconnect_period = 1.0;  ///< [s]
  std::string validate() const;
};

/// Link state, message and last fault (LinkStatus), and the command counters.
struct ValveStatus : LinkStatus {
  bool healthy = false;  ///< open, and the last command was acknowledged
  Duty acknowledged{};   ///< duty last acknowledged by the board
  bool ever_acknowledged = false;
  SteadyTime last_ack{};
  bool gate_open = false;   ///< the last command sent was the controller's (not forced zero)
  std::string gate_reason;  ///< why the last command sent was forced to zero
  uint64_t sent = 0, acknowledged_count = 0, no_reply = 0, rejected = 0, hangups = 0;
  uint64_t bad_commands = 0;  ///< non-finite controller commands (replaced by zero)
  uint64_t connects = 0, connect_failures = 0;
};

class ValveLoop : private DeviceSession {
 public:
  /// Whether the other devices are healthy; sets *reason (naming the device) when not.
  using HealthFn = std::function<bool(std::string* reason)>;
  /// Called after every acknowledged command with the applied duty.
  using AppliedCallback = std::function<void(const Duty& applied, SteadyTime when)>;

  /// @throws std::invalid_argument when config.validate() fails or driver is null.
  ValveLoop(std::unique_ptr<ValveDriver> driver, const ValveLoopOptions& config, HealthFn health,
            AppliedCallback on_applied = nullptr, LogCallback log = nullptr);
  ~ValveLoop() override;
  ValveLoop(const ValveLoop&) = delete;
  ValveLoop& operator=(const ValveLoop&) = delete;

  /// A controller command (thread-safe); the loop sends it (gated) at once.
  void command(const Duty& duty);
  /// Re-evaluates the gate now (e.g. a device's health changed).
  void notify() { worker_.wake(); }
  void start() { worker_.start(); }
  /// Sends zero duty (best effort), closes the port, joins the thread.
  void stop() { worker_.stop(); }
  ValveStatus status() const;

 private:
  // DeviceSession: one session is connect() then exchange().
  bool run_session(std::string* fault) override;
  void close_port() override { driver_->close(); }
  void shut_down() override;  ///< zero duty (best effort), then closes the port
  void mark_link_down() override { status_.healthy = false; }

  /// Opens the driver; connected once it acknowledged zero duty.
  bool connect(std::string* err);
  /// Sends the gated duty every keep-alive period and at once on a command, until stop or a fault.
  void exchange(std::string* fault);
  /// The duty the gate lets through now (records the gate's verdict in the status).
  Duty gated_duty();
  /// Applies the gated duty and records the result.
  ValveDriver::Result send_gated_duty(std::string* err);
  /// Counts an acknowledged duty (status mutex held).
  void record_ack(const Duty& applied, SteadyTime when);

  std::unique_ptr<ValveDriver> driver_;
  const ValveLoopOptions cfg_;
  HealthFn health_;
  AppliedCallback on_applied_;

  mutable std::mutex mu_;  ///< guards status_ and gate_
  ValveStatus status_;
  CommandGate gate_;
  DeviceWorker worker_;  ///< last: its thread uses the members above
};

}  // namespace devices
}  // namespace hydrojet
