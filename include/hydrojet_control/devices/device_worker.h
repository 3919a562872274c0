// The thread of one rig device client (the Aurora client, each flow sensor, the valve loop): start,
// stop, interruptible sleeps, the reconnect loop and the link fields of the client's status. ROS-free.
//
// Reconnect loop (one per client):
//   until stop:
//     session = connect, then exchange data until a fault or stop     (the client: run_session)
//     on a fault: close the port                                        (the client: close_port)
//                 status: state kDisconnected, last_error = fault,
//                         message = fault + "; retrying every <reconnect_period> s"
//                 log the fault (a repeated connection failure once, not every period)
//                 wait reconnect_period (stop interrupts)
//   on stop: last words to the device and close (TSTOP, zero duty)     (the client: shut_down)
//            status: state kStopped, message "stopped"
#pragma once

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

#include "hydrojet_control/devices/device_status.h"

namespace hydrojet {
namespace devices {

/// What a device client implements for its DeviceWorker. Called from the worker's thread only.
class DeviceSession {
 public:
  virtual ~DeviceSession() = default;
  /// Connects and exchanges data until a fault or until the worker is stopping. Returns whether
  /// the connection was made (a fault after a connection is always logged); *fault says why the
  /// session ended ("" counts as "connection lost"; ignored when stopping).
  virtual bool run_session(std::string* fault) = 0;
  /// Closes the port after a fault (not on stop: shut_down may still talk to the device).
  virtual void close_port() = 0;
  /// On stop: last words to the device (best effort), then closes the port.
  virtual void shut_down() = 0;
  /// Called with the status mutex held whenever the link goes down (a fault or stop): clears what
  /// only a live link has (e.g. "tracking").
  virtual void mark_link_down() {}
};

class DeviceWorker {
 public:
  /// `status_mutex` guards `link`, the link fields of the client's status (the worker writes them
  /// under that mutex). Log lines are "<name>: <what>".
  DeviceWorker(DeviceSession& session, std::mutex& status_mutex, LinkStatus& link, std::string name,
               double reconnect_period, LogCallback log);
  ~DeviceWorker();  ///< stops; the client must stop() first when its session uses its own members
  DeviceWorker(const DeviceWorker&) = delete;
  DeviceWorker& operator=(const DeviceWorker&) = delete;

  /// Starts the thread (state kDisconnected, message "starting"); no-op when running.
  void start();
  /// Stops the thread: interrupts sleeps and waits, lets the session end, joins. No-op when stopped.
  void stop();
  bool stopping() const { return stop_.load(); }

  /// Sleeps up to `s` seconds; false (early) when stopping.
  bool sleep_for(double s);
  /// Waits up to `s` seconds or until wake(); false when stopping. Consumes the wake-up.
  bool wait_for_wake(double s);
  /// Ends the current (or the next) wait_for_wake at once (thread-safe).
  void wake();

  /// Sets the link state and message (under the status mutex).
  void set_link(LinkState state, const std::string& message);
  /// Log line "<name>: <msg>".
  void log(LogLevel level, const std::string& msg) const;

 private:
  void run();
  void record_fault(const std::string& fault);
  void record_stopped();

  DeviceSession& session_;
  std::mutex& status_mu_;
  LinkStatus& link_;
  const std::string name_;
  const double reconnect_period_;
  const LogCallback log_;

  std::atomic<bool> stop_{false};
  std::mutex wait_mu_;
  std::condition_variable wait_cv_;
  bool woken_ = false;  ///< wake() since the last wait_for_wake
  std::thread thread_;
};

}  // namespace devices
}  // namespace hydrojet
