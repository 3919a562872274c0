// joystick_node on a FIFO fed with js_event records: the published sensor_msgs/Joy (axes scaled
// with the deadzone, buttons, frame id, stamp), autorepeat, diagnostics, one all-zero Joy when the
// device goes away (and nothing after it), and the reconnection when it comes back.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/joystick.h>
#include <ros/ros.h>
#include <sensor_msgs/Joy.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <string>
#include <vector>

#include "hydrojet_control/ros/names.h"
#include "../js_records.h"

namespace names = hydrojet::names;
using namespace hydrojet::test;  // js_record, axis, button, initial_axis, initial_button

namespace {

/// Spins until `cond` holds or `timeout_s` seconds (wall) have passed; its final value.
template <class F>
bool spin_until(F cond, double timeout_s) {
  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::ok() && ros::WallTime::now() < until) {
    ros::spinOnce();
    if (cond()) return true;
    ros::WallDuration(0.005).sleep();
  }
  ros::spinOnce();
  return cond();
}

/// The FIFO's write end: the joystick as joystick_node sees it.
class FifoWriter {
 public:
  explicit FifoWriter(std::string path) : path_(std::move(path)) {}
  ~FifoWriter() { close(); }
  /// Waits (bounded) until joystick_node has the FIFO open for reading (ENXIO until then).
  bool open(double timeout_s) {
    return spin_until([this] { return (fd_ = ::open(path_.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC)) >= 0; },
                      timeout_s);
  }
  bool write(const std::string& b) { return fd_ >= 0 && ::write(fd_, b.data(), b.size()) == ssize_t(b.size()); }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  std::string path_;
  int fd_ = -1;
};

struct Received {
  std::vector<sensor_msgs::Joy> joys;
  diagnostic_msgs::DiagnosticStatus diag;  ///< the latest status of joystick_node
  bool have_diag = false;

  bool last_is(const std::vector<float>& axes, const std::vector<int32_t>& buttons) const {
    return !joys.empty() && joys.back().axes == axes && joys.back().buttons == buttons;
  }
  bool diag_is(uint8_t level, const std::string& message) const {
    return have_diag && diag.level == level && diag.message.find(message) != std::string::npos;
  }
};

}  // namespace

TEST(JoystickFifo, PublishesJoyDisconnectsAndReconnects) {
  ros::NodeHandle nh, pnh("~");
  std::string path;
  ASSERT_TRUE(pnh.getParam("fifo", path));
  unlink(path.c_str());
  ASSERT_EQ(mkfifo(path.c_str(), 0600), 0) << path;
  signal(SIGPIPE, SIG_IGN);
  Received r;
  ros::Subscriber js = nh.subscribe<sensor_msgs::Joy>(
      names::kJoy, 100, [&](const sensor_msgs::Joy::ConstPtr& m) { r.joys.push_back(*m); });
  ros::Subscriber ds = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      names::kDiagnostics, 100, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
        for (const auto& s : m->status)
          if (s.hardware_id == "joystick " + path) r.diag = s, r.have_diag = true;
      });
  ASSERT_TRUE(spin_until([&] { return js.getNumPublishers() > 0; }, 10.0));

  // The joystick appears: initial state (axes created at 0), then moves. Deadzone 0.1 (the .test).
  FifoWriter w(path);
  ASSERT_TRUE(w.open(10.0)) << "joystick_node never opened " << path;
  ASSERT_TRUE(w.write(initial_button(0, 0) + initial_button(1, 0) + initial_axis(0, 5000) + initial_axis(1, 0)));
  ASSERT_TRUE(spin_until([&] { return r.last_is({0, 0}, {0, 0}); }, 5.0));
  ASSERT_TRUE(w.write(axis(0, 32767) + axis(1, -18021) + axis(2, 3000) + button(1, 1)));
  ASSERT_TRUE(spin_until([&] { return !r.joys.empty() && r.joys.back().axes.size() == 3; }, 5.0));
  sensor_msgs::Joy j = r.joys.back();
  EXPECT_EQ(j.axes[0], -1.0f);                                        // full deflection, negated (ROS joy)
  EXPECT_NEAR(j.axes[1], (18021 - 3276.7) / (32767 - 3276.7), 1e-6);  // ≈ 0.5: deadzone rescaled
  EXPECT_EQ(j.axes[2], 0.0f);                                         // inside the deadzone
  EXPECT_EQ(j.buttons, (std::vector<int32_t>{0, 1}));
  EXPECT_EQ(j.header.frame_id, "joy");
  EXPECT_LT(std::fabs((ros::Time::now() - j.header.stamp).toSec()), 5.0);
  ASSERT_TRUE(spin_until([&] { return r.diag_is(diagnostic_msgs::DiagnosticStatus::OK, "joystick connected"); }, 5.0));

  // Autorepeat (20 Hz in the .test): the same state keeps coming while nothing changes.
  const size_t n = r.joys.size();
  ASSERT_TRUE(spin_until([&] { return r.joys.size() >= n + 4; }, 5.0));
  EXPECT_EQ(r.joys.back().axes, j.axes);
  EXPECT_EQ(r.joys.back().buttons, j.buttons);

  // The joystick goes away: one all-zero Joy (same sizes), then silence, and an ERROR diagnostic.
  w.close();
  ASSERT_TRUE(spin_until([&] { return r.last_is({0, 0, 0}, {0, 0}); }, 5.0));
  const size_t after_zero = r.joys.size();
  spin_until([] { return false; }, 0.3);
  EXPECT_EQ(r.joys.size(), after_zero) << "published after the device went away";
  ASSERT_TRUE(
      spin_until([&] { return r.diag_is(diagnostic_msgs::DiagnosticStatus::ERROR, "no joystick at " + path); }, 5.0));

  // It comes back: published again, with a fresh state.
  ASSERT_TRUE(w.open(10.0));
  ASSERT_TRUE(w.write(initial_button(0, 1) + initial_axis(0, 0) + axis(0, -32767)));
  ASSERT_TRUE(spin_until([&] { return r.last_is({1}, {1}); }, 5.0));
  ASSERT_TRUE(spin_until([&] { return r.diag_is(diagnostic_msgs::DiagnosticStatus::OK, "joystick connected"); }, 5.0));
  w.close();
  unlink(path.c_str());
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "joystick_fifo_test");
  return RUN_ALL_TESTS();
}
