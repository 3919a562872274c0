#include "hydrojet_control/ros/shutdown.h"

#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <atomic>
#include <csignal>

namespace hydrojet {
namespace ros_bridge {
namespace {

std::atomic<int> g_signal{0};

extern "C" void on_signal(int sig) { g_signal.store(sig); }

}  // namespace

void install_shutdown_signals() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

int shutdown_signal() { return g_signal.load(); }

bool running() { return ros::ok() && g_signal.load() == 0; }

void spin_until_signal() {
  ros::CallbackQueue* queue = ros::getGlobalCallbackQueue();
  while (running()) queue->callAvailable(ros::WallDuration(0.01));
}

void flush_and_shutdown(double seconds) {
  if (ros::isStarted() && !ros::isShuttingDown()) {
    const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(seconds);
    while (ros::ok() && ros::WallTime::now() < until) ros::WallDuration(0.01).sleep();
  }
  ros::shutdown();
}

}  // namespace ros_bridge
}  // namespace hydrojet
