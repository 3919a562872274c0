// Flow sensors that stream one ASCII line per reading over a serial port (the HydroJet's Titan
// Atrato sensors, one per jet), and the aggregation of three of them into one jet-state sample.
// ROS-free; one thread (DeviceWorker, device_worker.h) per sensor.
//
// No public serial protocol of the Atrato is known: every line is read with a configurable
// FlowLineFormat (regex or field index, unit scale; line_protocols.h) and converted to [m^3/s] at
// this boundary. Rejected lines (no number, NaN, negative, garbage, too long) are counted and
// reported, never delivered as readings with a value.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>

#include "hydrojet_control/devices/device_status.h"
#include "hydrojet_control/devices/device_worker.h"
#include "hydrojet_control/devices/line_protocols.h"
#include "hydrojet_control/devices/serial_port.h"

namespace hydrojet {
namespace devices {

struct FlowSensorOptions {
  std::string name = "flow sensor";  ///< for messages ("flow sensor 1")
  std::string port;                  ///< serial device path
  int baud = 9600;
  FlowLineFormat format;          ///< how to read the number; scale_to_m3_per_s > 0 required
  double timeout = 0.25;          ///< no accepted reading for this long: unhealthy, reconnect [s]
  double reconnect_period = 1.0;  ///< wait between connection attempts [s]
  size_t max_line_length = 128;   ///< longer lines are garbage [characters]
  std::string start_command;      ///< optional text sent after opening (e.g. to start streaming)

  /// Empty when usable, else "<field>: <what>" (also checks the format on a probe line).
  std::string validate() const;
};

/// One line from a sensor.
struct FlowReading {
  SteadyTime time;        ///< when the line was complete
  bool accepted = false;  ///< the line parsed to a finite, non-negative flow
  double flow = 0.0;      ///< [m^3/s] when accepted (NaN otherwise)
  std::string error;      ///< why the line was rejected
};

/// Link state, message and last fault or rejected line (LinkStatus), and the line counters.
struct FlowSensorStatus : LinkStatus {
  SteadyTime last_accepted{};
  bool ever_accepted = false;
  double last_flow = 0.0;  ///< [m^3/s]
  uint64_t lines = 0, accepted = 0, rejected = 0;
  uint64_t discarded = 0;  ///< over-long lines / lines with NUL bytes
  uint64_t connects = 0, connect_failures = 0;

  /// True when an accepted reading arrived within `timeout` of `now`.
  bool healthy(SteadyTime now, double timeout) const {
    return ever_accepted && seconds_between(last_accepted, now) <= timeout;
  }
};

class FlowSensor : private DeviceSession {
 public:
  using ReadingCallback = std::function<void(const FlowReading&)>;

  /// @throws std::invalid_argument when config.validate() fails.
  FlowSensor(const FlowSensorOptions& config, ReadingCallback on_reading, LogCallback log = nullptr);
  ~FlowSensor() override;
  FlowSensor(const FlowSensor&) = delete;
  FlowSensor& operator=(const FlowSensor&) = delete;

  void start() { worker_.start(); }
  void stop() { worker_.stop(); }
  FlowSensorStatus status() const;
  const FlowSensorOptions& options() const { return cfg_; }

 private:
  // DeviceSession: one session is open_port() then stream().
  bool run_session(std::string* fault) override;
  void close_port() override { port_.close(); }
  void shut_down() override { port_.close(); }

  /// Opens the port and sends the start command (if any).
  bool open_port(std::string* err);
  /// Reads lines until stop, hang-up or silence; returns the fault.
  std::string stream();
  /// Counts one line and delivers it as a reading; an accepted one sets *last_accepted.
  void deliver_line(const std::string& line, SteadyTime* last_accepted);

  const FlowSensorOptions cfg_;
  ReadingCallback on_reading_;
  SerialPort port_;
  mutable std::mutex mu_;  ///< guards status_
  FlowSensorStatus status_;
  DeviceWorker worker_;  ///< last: its thread uses the members above
};

/// The three jets' latest readings, combined into samples for the jet state. Thread-safe.
///
/// A jet's flow is valid when its latest line was accepted (with invalidate_on_reject; otherwise
/// its latest accepted reading counts) and that reading is at most `stale_timeout` old. Invalid
/// jets carry NaN. A sample is produced only when some sensor delivered a line since the last
/// sample, so nothing is ever republished; its stamp is the oldest valid reading's time (the age a
/// consumer must assume), or the newest line's time when no jet is valid.
class FlowAggregator {
 public:
  struct Sample {
    std::array<double, 3> flow{};  ///< [m^3/s], NaN where invalid
    std::array<bool, 3> valid{};
    SteadyTime stamp{};
  };

  FlowAggregator(double stale_timeout, bool invalidate_on_reject)
      : stale_timeout_(stale_timeout), invalidate_on_reject_(invalidate_on_reject) {}

  /// Records a line of jet `jet` (0, 1, 2).
  void add(size_t jet, const FlowReading& r);
  /// The sample at `now`; false when no line arrived since the last take() (nothing new).
  bool take(SteadyTime now, Sample* out);

 private:
  struct Jet {
    bool have_accepted = false;
    SteadyTime accepted_time{};
    double flow = 0.0;
    bool last_rejected = false;
    SteadyTime last_line{};
  };
  const double stale_timeout_;
  const bool invalidate_on_reject_;
  std::mutex mu_;
  std::array<Jet, 3> jets_{};
  bool fresh_ = false;
};

}  // namespace devices
}  // namespace hydrojet
