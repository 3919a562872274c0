// Health of one rig device as its driver thread sees it, shared by the Aurora client, the flow
// sensors and the valve loop. ROS-free.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <string>
#include <utility>

namespace hydrojet {
namespace devices {

/// Connection state of a device driver.
enum class LinkState {
  kStopped,       ///< the driver thread is not running
  kDisconnected,  ///< port closed (never opened, unplugged, or dropped after silence); retrying
  kConnecting,    ///< port open, set-up in progress (reset, handshake) or waiting for first data
  kRunning,       ///< exchanging data
};

/// The link part of a device's status (AuroraStatus, FlowSensorStatus and ValveStatus extend it),
/// written by the client's DeviceWorker (device_worker.h).
struct LinkStatus {
  LinkState state = LinkState::kStopped;
  std::string message;     ///< what the driver is doing or, after a fault, why it failed ("; retrying every X s")
  std::string last_error;  ///< the last fault (kept after recovery)
};

/// Severity of a driver's log line: kInfo for connections, kWarn for faults.
enum class LogLevel { kInfo, kWarn };
/// Log lines of a driver thread (state changes, faults; a repeated fault is logged once).
using LogCallback = std::function<void(LogLevel, const std::string&)>;

/// Events per minute over a sliding window (diagnostics: CRC errors, reply time-outs, reconnects).
/// Times are passed in, so a test drives it with its own clock. Not thread-safe.
class RateCounter {
 public:
  using Time = std::chrono::steady_clock::time_point;
  /// `window_s` [s] > 0: events older than this no longer count.
  explicit RateCounter(double window_s = 60.0) : window_(std::chrono::duration<double>(window_s)) {}

  /// `n` events at `t` (times must not decrease).
  void add(Time t, uint64_t n = 1) {
    if (n == 0) return;
    events_.emplace_back(t, n);
    sum_ += n;
  }
  /// Feeds a cumulative counter: the growth since the previous call (from 0 on the first) is added
  /// at `t`; a counter that went down (restarted) counts from 0 again.
  void track(Time t, uint64_t total) {
    add(t, total >= last_total_ ? total - last_total_ : total);
    last_total_ = total;
  }
  /// Events in (now - window, now].
  uint64_t in_window(Time now) {
    while (!events_.empty() && now - events_.front().first >= window_) {
      sum_ -= events_.front().second;
      events_.pop_front();
    }
    return sum_;
  }
  /// in_window scaled to one minute [1/min] (the count itself for the default 60 s window).
  double per_minute(Time now) { return static_cast<double>(in_window(now)) * 60.0 / window_.count(); }

 private:
  std::chrono::duration<double> window_;
  std::deque<std::pair<Time, uint64_t>> events_;
  uint64_t sum_ = 0;
  uint64_t last_total_ = 0;
};

inline const char* to_string(LinkState s) {
  switch (s) {
    case LinkState::kStopped: return "stopped";
    case LinkState::kDisconnected: return "disconnected";
    case LinkState::kConnecting: return "connecting";
    case LinkState::kRunning: return "running";
  }
  return "?";
}

}  // namespace devices
}  // namespace hydrojet
