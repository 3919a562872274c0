// What a node's control loop must never wait for (reading a path file, building a path, loading a
// scene and sweeping its reachable set) runs on a thread of its own, one job after another; results
// come back to the loop through a Mailbox, which the loop never waits on (the discipline of
// ros_control's realtime buffer: the loop only ever try_locks).
#pragma once

#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <boost/make_shared.hpp>
#include <functional>
#include <mutex>
#include <optional>
#include <utility>

namespace hydrojet {
namespace ros_bridge {

/// A callback queue served by one thread of its own: post() jobs to it, or give it to a service
/// (ros::AdvertiseServiceOptions::callback_queue) whose handler may take long.
class Background {
 public:
  Background() : spinner_(1, &queue_) { spinner_.start(); }
  ~Background() { spinner_.stop(); }
  Background(const Background&) = delete;
  Background& operator=(const Background&) = delete;

  ros::CallbackQueue* queue() { return &queue_; }
  /// Runs `job` on the background thread, after the jobs posted before it.
  void post(std::function<void()> job) { queue_.addCallback(boost::make_shared<Job>(std::move(job))); }

 private:
  class Job : public ros::CallbackInterface {
   public:
    explicit Job(std::function<void()> f) : f_(std::move(f)) {}
    CallResult call() override {
      f_();
      return Success;
    }

   private:
    std::function<void()> f_;
  };
  ros::CallbackQueue queue_;
  ros::AsyncSpinner spinner_;
};

/// One value handed from a background thread to the loop. put() waits only for the loop's pointer
/// swap; take() never waits: when the lock is busy it returns nothing, and the value is there at the
/// next cycle. A value put before the last one was taken replaces it.
template <class T>
class Mailbox {
 public:
  void put(T value) {
    std::lock_guard<std::mutex> lock(mutex_);
    value_ = std::move(value);
  }
  std::optional<T> take() {
    std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock() || !value_) return std::nullopt;
    std::optional<T> out = std::move(value_);
    value_.reset();
    return out;
  }

 private:
  std::mutex mutex_;
  std::optional<T> value_;
};

}  // namespace ros_bridge
}  // namespace hydrojet
