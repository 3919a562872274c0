// Thread, stop, waits and reconnect loop of a device client (see device_worker.h).
#include "hydrojet_control/devices/device_worker.h"

#include <cstdio>

#include "hydrojet_control/devices/serial_port.h"

namespace hydrojet {
namespace devices {

DeviceWorker::DeviceWorker(DeviceSession& session, std::mutex& status_mutex, LinkStatus& link, std::string name,
                           double reconnect_period, LogCallback log)
    : session_(session),
      status_mu_(status_mutex),
      link_(link),
      name_(std::move(name)),
      reconnect_period_(reconnect_period),
      log_(std::move(log)) {}

DeviceWorker::~DeviceWorker() { stop(); }

void DeviceWorker::start() {
  if (thread_.joinable()) return;
  stop_ = false;
  set_link(LinkState::kDisconnected, "starting");
  thread_ = std::thread(&DeviceWorker::run, this);
}

void DeviceWorker::stop() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard<std::mutex> l(wait_mu_);
    stop_ = true;
  }
  wait_cv_.notify_all();
  thread_.join();
}

bool DeviceWorker::sleep_for(double s) {
  std::unique_lock<std::mutex> l(wait_mu_);
  return !wait_cv_.wait_for(l, seconds(s), [this] { return stop_.load(); });
}

bool DeviceWorker::wait_for_wake(double s) {
  std::unique_lock<std::mutex> l(wait_mu_);
  wait_cv_.wait_for(l, seconds(s), [this] { return stop_.load() || woken_; });
  woken_ = false;
  return !stop_;
}

void DeviceWorker::wake() {
  {
    std::lock_guard<std::mutex> l(wait_mu_);
    woken_ = true;
  }
  wait_cv_.notify_all();
}

void DeviceWorker::set_link(LinkState state, const std::string& message) {
  std::lock_guard<std::mutex> l(status_mu_);
  link_.state = state;
  link_.message = message;
}

void DeviceWorker::log(LogLevel level, const std::string& msg) const {
  if (log_) log_(level, name_ + ": " + msg);
}

void DeviceWorker::run() {
  std::string last_logged;
  while (!stopping()) {
    std::string fault;
    const bool connected = session_.run_session(&fault);
    if (stopping()) break;
    session_.close_port();
    if (fault.empty()) fault = "connection lost";
    record_fault(fault);
    // A fault after a connection is news; a repeated connection failure is logged once, not every period.
    if (connected || fault != last_logged) log(LogLevel::kWarn, fault);
    last_logged = fault;
    sleep_for(reconnect_period_);
  }
  session_.shut_down();
  record_stopped();
}

void DeviceWorker::record_fault(const std::string& fault) {
  char retry[64];
  std::snprintf(retry, sizeof retry, "; retrying every %.1f s", reconnect_period_);
  std::lock_guard<std::mutex> l(status_mu_);
  link_.state = LinkState::kDisconnected;
  link_.last_error = fault;
  link_.message = fault + retry;
  session_.mark_link_down();
}

void DeviceWorker::record_stopped() {
  std::lock_guard<std::mutex> l(status_mu_);
  link_.state = LinkState::kStopped;
  link_.message = "stopped";
  session_.mark_link_down();
}

}  // namespace devices
}  // namespace hydrojet
