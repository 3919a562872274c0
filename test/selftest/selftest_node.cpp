// The self-test's node probe (scripts/ci_selftest through scripts/test --only selftest_rostest): a node
// that publishes selftest/alive at 10 Hz and ends on SIGINT/SIGTERM as every node of the package
// does (ros_bridge shutdown signals). HYDROJET_SELFTEST_INJECT=sanitizer_node leaks memory (a
// LeakSanitizer report at exit, which no test sees); =node_ignores_signals makes roslaunch kill it.
#include <ros/ros.h>
#include <std_msgs/UInt32.h>

#include <csignal>

#include "hydrojet_control/ros/shutdown.h"
#include "injection.h"

int main(int argc, char** argv) {
  namespace sd = hydrojet::selftest;
  ros::init(argc, argv, "selftest_probe", ros::init_options::NoSigintHandler);
  hydrojet::ros_bridge::install_shutdown_signals();
  if (sd::injected("sanitizer_node")) sd::leak(64);
  if (sd::injected("node_ignores_signals")) {
    std::signal(SIGINT, SIG_IGN);
    std::signal(SIGTERM, SIG_IGN);
  }
  ros::NodeHandle nh;
  ros::Publisher alive = nh.advertise<std_msgs::UInt32>("selftest/alive", 10);
  std_msgs::UInt32 count;
  ros::WallRate rate(10.0);
  while (hydrojet::ros_bridge::running()) {
    ++count.data;
    alive.publish(count);
    ros::spinOnce();
    rate.sleep();
  }
  hydrojet::ros_bridge::flush_and_shutdown(0.1);
  return 0;
}
