// The plant closes its valves when the controller goes silent (killed): the test plays the
// controller, commanding the valves half open for 2 s of simulated time, then stops publishing.
// The plant must report zero valve command within its command timeout and the flows must decay.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>

#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

TEST(SimControllerKilled, PlantClosesValvesOnCommandTimeout) {
  ros::NodeHandle nh;
  std::vector<hydrojet_control::JetState> states;
  ros::Publisher cmd = nh.advertise<hydrojet_control::JetCommand>(names::kJetCommand, 10);
  const double stop_at = 2.0;
  double now = 0.0;
  ros::Subscriber clock =
      nh.subscribe<rosgraph_msgs::Clock>(names::kClock, 100, [&](const rosgraph_msgs::Clock::ConstPtr& c) {
        now = c->clock.toSec();
        if (now > 0.0 && now <= stop_at) {  // the "controller": answer every step until it dies
          hydrojet_control::JetCommand m;
          m.header.stamp = c->clock;
          m.valve_command = {0.6, 0.6, 0.6};
          cmd.publish(m);
        }
      });
  ros::Subscriber js = nh.subscribe<hydrojet_control::JetState>(
      names::kJetState, 1000, [&](const hydrojet_control::JetState::ConstPtr& m) { states.push_back(*m); });
  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(120.0);
  while (ros::ok() && ros::WallTime::now() < until && now < stop_at + 1.0) {
    ros::spinOnce();
    ros::WallDuration(0.0002).sleep();
  }
  ASSERT_GT(now, stop_at + 0.5) << "simulated time did not advance";
  double flow_at_stop = 0.0, first_closed = -1.0, flow_late = 1.0;
  for (const auto& s : states) {
    ASSERT_EQ(s.flow.size(), 3u);
    ASSERT_EQ(s.valve_command.size(), 3u);
    const double t = s.header.stamp.toSec();
    if (t <= stop_at) {
      EXPECT_GT(s.valve_command[0] + (t < 0.1 ? 1.0 : 0.0), 0.0) << "valves should be open at " << t;
      flow_at_stop = s.flow[0];
    } else if (first_closed < 0 && s.valve_command[0] == 0 && s.valve_command[1] == 0 && s.valve_command[2] == 0) {
      first_closed = t;
    }
    if (t > stop_at + 0.5) flow_late = std::min(flow_late, s.flow[0] + s.flow[1] + s.flow[2]);
  }
  ASSERT_GT(flow_at_stop, 1e-6) << "the jets never ran";
  ASSERT_GT(first_closed, 0.0) << "valves never closed";
  // command_timeout (0.05 s in config/plant.yaml) plus one sample period.
  EXPECT_LE(first_closed - stop_at, 0.05 + 0.01 + 1e-6);
  EXPECT_LT(flow_late, 0.05 * flow_at_stop);  // the flows have died away
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "sim_controller_killed_test");
  return RUN_ALL_TESTS();
}
