// A joystick on the Linux joystick API (<linux/joystick.h>, /dev/input/js*), read by its own
// thread (DeviceWorker, device_worker.h) for joystick_node. ROS-free.
//
// Conventions of ROS joy (joy_node), which teleoperation configurations assume:
//   - axes in [-1, 1], the kernel's value negated (pushing a stick up or left gives +), with a
//     deadzone rescaled so that values inside it read 0 and full deflection still reads ±1:
//       axis = -sign(v) · (|v| - 32767·deadzone) / (32767 · (1 - deadzone)), clamped to [-1, 1];
//   - buttons 0 or 1;
//   - the arrays grow as higher axis or button numbers appear;
//   - the kernel's initial-state (JS_EVENT_INIT) events create the axes and buttons; a button takes
//     the reported value, an axis stays 0 until it moves (some drivers report stale initial axes);
//   - a state is reported at once after a button change, coalesce_interval after the first of a
//     burst of axis (or initial) events, and again at autorepeat_rate while nothing changes.
// A device that cannot be opened or goes away (end of file, ENODEV) is reported once as a
// disconnected state with every axis and button zero, so that no command is left held; the reader
// retries every reconnect_period. Any openable path works, e.g. a FIFO fed with js_event records
// (read in any pieces: a record split over two reads is reassembled).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "hydrojet_control/devices/device_status.h"
#include "hydrojet_control/devices/device_worker.h"
#include "hydrojet_control/devices/serial_port.h"

namespace hydrojet {
namespace devices {

struct JoystickOptions {
  std::string device = "/dev/input/js0";  ///< joystick device (or any openable path, e.g. a FIFO)
  double deadzone = 0.05;                 ///< fraction of full deflection read as 0, in [0, 1)
  double autorepeat_rate = 20.0;     ///< republish the last state this often while connected [Hz]; 0 = on change only
  double coalesce_interval = 0.001;  ///< axis events within this time go out as one state [s]
  double reconnect_period = 1.0;     ///< wait between attempts to open the device [s]

  /// Empty when usable, else "<field>: <what>".
  std::string validate() const;
};

/// What a joystick reports: its axes and buttons as published (sensor_msgs/Joy conventions).
struct JoystickState {
  std::vector<double> axes;  ///< [-1, 1], deadzone applied
  std::vector<int> buttons;  ///< 0 or 1
  SteadyTime stamp{};        ///< when the state was reported
  bool connected = false;    ///< false: the device went away (every axis and button 0)
};

/// Link state and message (LinkStatus: kRunning once the device sent its first event), counters.
struct JoystickStatus : LinkStatus {
  std::string name;  ///< the device's own name (JSIOCGNAME); empty for a FIFO
  size_t axes = 0, buttons = 0;
  uint64_t events = 0;   ///< js_event records read
  uint64_t reports = 0;  ///< states reported (including autorepeats and disconnects)
  uint64_t connects = 0, connect_failures = 0;
};

/// Turns js_event records (8 bytes each, in any pieces) into the current axes and buttons. Not
/// thread-safe (the reader's thread owns it).
class JoystickDecoder {
 public:
  /// What the records just fed ask for (ROS joy's rules).
  enum class Publish {
    kNone,  ///< nothing new (no complete record, or an unknown event type)
    kSoon,  ///< an axis moved or initial state arrived: publish after coalesce_interval
    kNow,   ///< a button changed: publish at once
  };

  explicit JoystickDecoder(double deadzone) : deadzone_(deadzone) {}

  /// Feeds raw bytes; keeps an incomplete record for the next call.
  Publish feed(const uint8_t* data, size_t n);
  /// Every axis and button to 0 (sizes kept).
  void zero();
  /// Back to no axes, no buttons, no partial record (a new device session).
  void reset();

  const std::vector<double>& axes() const { return axes_; }
  const std::vector<int>& buttons() const { return buttons_; }
  uint64_t events() const { return events_; }

  /// The axis value of a raw kernel value (-32767 ... 32767) with a deadzone (see the file comment).
  static double scale_axis(int16_t value, double deadzone);

 private:
  /// Applies one complete 8-byte record.
  Publish apply(const uint8_t* record);

  const double deadzone_;
  std::vector<double> axes_;
  std::vector<int> buttons_;
  uint8_t partial_[8] = {};
  size_t partial_size_ = 0;
  uint64_t events_ = 0;
};

/// Reads one joystick device in its own thread and reports its state through a callback.
class JoystickReader : private DeviceSession {
 public:
  /// Called from the reader's thread with each reported state.
  using StateCallback = std::function<void(const JoystickState&)>;

  /// @throws std::invalid_argument when options.validate() fails.
  JoystickReader(const JoystickOptions& options, StateCallback on_state, LogCallback log = nullptr);
  ~JoystickReader() override;
  JoystickReader(const JoystickReader&) = delete;
  JoystickReader& operator=(const JoystickReader&) = delete;

  void start() { worker_.start(); }
  /// Stops the thread; a connected device is first reported as disconnected (all zero).
  void stop() { worker_.stop(); }
  /// The latest reported state (all empty and disconnected before the first).
  JoystickState state() const;
  JoystickStatus status() const;
  const JoystickOptions& options() const { return opt_; }

 private:
  // DeviceSession: one session is open_device() then stream().
  bool run_session(std::string* fault) override;
  void close_port() override { close_device(); }
  void shut_down() override { close_device(); }

  /// Opens the device non-blocking and reads its name.
  bool open_device(std::string* err);
  void close_device();
  /// Reads events and reports states until stop or a fault; returns the fault.
  std::string stream();
  /// Waits up to `timeout_s` for data and feeds what arrived to the decoder; "" or the fault.
  std::string read_events(double timeout_s, JoystickDecoder::Publish* publish);
  /// Counts `count` new events; the session's first marks the link running.
  void note_events(uint64_t count);
  /// Reports the decoder's state (connected or the all-zero disconnected one).
  void report(bool connected);

  const JoystickOptions opt_;
  StateCallback on_state_;
  JoystickDecoder decoder_;
  int fd_ = -1;
  mutable std::mutex mu_;  ///< guards status_ and state_
  JoystickStatus status_;
  JoystickState state_;
  DeviceWorker worker_;  ///< last: its thread uses the members above
};

}  // namespace devices
}  // namespace hydrojet
