// A Linux joystick (/dev/input/js*, or any path that delivers js_event records) as sensor_msgs/Joy
// on `joy`, with the ROS joy conventions (axes in [-1, 1] with a deadzone, buttons 0/1, autorepeat;
// see include/hydrojet_control/devices/joystick.h). Debian bookworm ships no ROS joystick driver.
// The device thread lives in the core (JoystickReader); this file converts, publishes and
// diagnoses. When the device goes away it publishes one all-zero Joy, so that a listener holds.
#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>
#include <sensor_msgs/Joy.h>

#include <iostream>
#include <memory>

#include "hydrojet_control/config/yaml_tree.h"
#include "hydrojet_control/devices/joystick.h"
#include "hydrojet_control/ros/names.h"
#include "hydrojet_control/ros/params.h"

namespace names = hydrojet::names;

namespace hydrojet {
namespace {

constexpr char kFrameId[] = "joy";

/// ~device, ~deadzone, ~autorepeat_rate, ~coalesce_interval, ~reconnect_period; throws
/// config::ParamError naming the key.
devices::JoystickOptions read_options(const ros::NodeHandle& pnh) {
  config::YamlTree<config::ParamError> t(ros_bridge::private_params_as_yaml(pnh), '/', "~");
  t.keys("", {"device", "deadzone", "autorepeat_rate", "coalesce_interval", "reconnect_period",
              "diagnostic_period"});  // diagnostic_period: read by diagnostic_updater itself
  devices::JoystickOptions o;
  o.device = t.text("device", o.device);
  o.deadzone = t.number("deadzone", o.deadzone);
  o.autorepeat_rate = t.number("autorepeat_rate", o.autorepeat_rate);
  o.coalesce_interval = t.number("coalesce_interval", o.coalesce_interval);
  o.reconnect_period = t.number("reconnect_period", o.reconnect_period);
  const std::string err = o.validate();  // "<field>: <what>"
  if (!err.empty()) t.fail(err.substr(0, err.find(':')), err.substr(err.find(':') + 2));
  return o;
}

sensor_msgs::Joy to_joy(const devices::JoystickState& s) {
  sensor_msgs::Joy j;
  j.header.stamp = ros::Time::now();
  j.header.frame_id = kFrameId;
  j.axes.assign(s.axes.begin(), s.axes.end());
  j.buttons.assign(s.buttons.begin(), s.buttons.end());
  return j;
}

class JoystickNode {
 public:
  JoystickNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) : opt_(read_options(pnh)), diag_(nh, pnh) {
    pub_ = nh.advertise<sensor_msgs::Joy>(names::kJoy, 10);
    diag_.setHardwareID("joystick " + opt_.device);
    diag_.add("joystick", this, &JoystickNode::diagnose);
    auto log = [](devices::LogLevel level, const std::string& m) {
      if (level == devices::LogLevel::kInfo)
        ROS_INFO("%s", m.c_str());
      else
        ROS_WARN("%s", m.c_str());
    };
    reader_.reset(new devices::JoystickReader(
        opt_, [this](const devices::JoystickState& s) { publish(s); }, log));
    diag_timer_ = nh.createWallTimer(ros::WallDuration(0.1), &JoystickNode::update_diagnostics, this);
    reader_->start();
    ROS_INFO("joystick: %s, deadzone %.3f, autorepeat %.1f Hz, coalesce %.3f s; publishing %s", opt_.device.c_str(),
             opt_.deadzone, opt_.autorepeat_rate, opt_.coalesce_interval, pub_.getTopic().c_str());
  }

  ~JoystickNode() { reader_->stop(); }

 private:
  /// From the reader's thread (ros::Publisher is thread-safe).
  void publish(const devices::JoystickState& s) {
    pub_.publish(to_joy(s));
    if (!s.connected) ROS_WARN("joystick: %s gone: published an all-zero Joy", opt_.device.c_str());
  }

  void update_diagnostics(const ros::WallTimerEvent&) {
    // At once when the joystick comes or goes; otherwise at the updater's period.
    const bool connected = reader_->status().state == devices::LinkState::kRunning;
    if (connected != last_connected_) {
      last_connected_ = connected;
      diag_.force_update();
    } else {
      diag_.update();
    }
  }

  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& s) {
    using diagnostic_msgs::DiagnosticStatus;
    const devices::JoystickStatus st = reader_->status();
    if (st.state == devices::LinkState::kRunning)
      s.summary(DiagnosticStatus::OK,
                "joystick connected: " + opt_.device + (st.name.empty() ? "" : " (" + st.name + ")"));
    else
      s.summary(DiagnosticStatus::ERROR, "no joystick at " + opt_.device);
    s.add("device", opt_.device);
    s.add("name", st.name);
    s.add("state", devices::to_string(st.state));
    s.add("message", st.message);
    s.add("last_error", st.last_error);
    s.add("axes", st.axes);
    s.add("buttons", st.buttons);
    s.add("events", st.events);
    s.add("published", st.reports);
    s.add("connects", st.connects);
    s.add("connect_failures", st.connect_failures);
  }

  const devices::JoystickOptions opt_;
  diagnostic_updater::Updater diag_;
  ros::Publisher pub_;
  ros::WallTimer diag_timer_;
  bool last_connected_ = false;
  std::unique_ptr<devices::JoystickReader> reader_;  ///< last: its thread publishes with the members above
};

}  // namespace
}  // namespace hydrojet

int main(int argc, char** argv) {
  ros::init(argc, argv, "joystick");
  ros::NodeHandle nh, pnh("~");
  try {
    hydrojet::JoystickNode node(nh, pnh);
    ros::spin();
  } catch (const std::exception& e) {
    // Bad parameters: refuse to start, naming the key.
    ROS_FATAL("joystick: refusing to start: %s", e.what());
    std::cerr << "joystick: refusing to start: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
