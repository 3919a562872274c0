// Health of one rig device as its driver thread sees it, shared by the Aurora client, the flow
// sensors and the valve loop. ROS-free.
#pragma once

#include <functional>
#include <string>

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
