// controller_node with a fake plant: it runs and drives the valves while tracker and flow data
// arrive, and zeroes the jets (and reports the abort) as soon as the tracker goes silent.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <cmath>

#include "hydrojet_control/ControllerStatus.h"
#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

namespace {

struct Recorder {
  hydrojet_control::JetCommand cmd;
  hydrojet_control::ControllerStatus status;
  ros::Time cmd_time, first_zero_after_cut;
  bool have_cmd = false, diag_error = false;
};

}  // namespace

TEST(ControllerStale, TrackerSilenceZeroesJets) {
  ros::NodeHandle nh;
  Recorder r;
  ros::Time cut;  // when the tracker stops
  ros::Subscriber cs = nh.subscribe<hydrojet_control::JetCommand>(
      names::kJetCommand, 100, [&](const hydrojet_control::JetCommand::ConstPtr& m) {
        r.cmd = *m;
        r.have_cmd = true;
        r.cmd_time = ros::Time::now();
        EXPECT_EQ(m->valve_command.size(), 3u) << "one duty per jet";
        bool zero = true;
        for (double d : m->valve_command) zero = zero && d == 0;
        if (!cut.isZero() && zero && r.first_zero_after_cut.isZero()) r.first_zero_after_cut = ros::Time::now();
      });
  ros::Subscriber ss = nh.subscribe<hydrojet_control::ControllerStatus>(
      names::kControllerStatus, 100, [&](const hydrojet_control::ControllerStatus::ConstPtr& m) { r.status = *m; });
  ros::Subscriber ds = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      names::kDiagnostics, 100, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
        for (const auto& s : m->status)
          if (s.level == diagnostic_msgs::DiagnosticStatus::ERROR && s.message.find("tracker") != std::string::npos)
            r.diag_error = true;
      });
  ros::Publisher tip = nh.advertise<geometry_msgs::PoseStamped>(names::kTipPose, 10);
  ros::Publisher base = nh.advertise<geometry_msgs::PoseStamped>(names::kBasePose, 10);
  ros::Publisher jets = nh.advertise<hydrojet_control::JetState>(names::kJetState, 10);

  ros::Rate rate(100.0);
  const ros::Time t0 = ros::Time::now();
  bool tracker_on = true;
  bool was_running_with_jets = false;
  while (ros::ok() && (ros::Time::now() - t0).toSec() < 20.0) {
    const ros::Time now = ros::Time::now();
    if (tracker_on) {
      geometry_msgs::PoseStamped p;
      p.header.stamp = now;
      p.header.frame_id = "tracker";
      // Tip 0.15 rad away from the spiral's start, so that the controller drives the jets.
      p.pose.orientation.w = std::cos(0.075);
      p.pose.orientation.x = std::sin(0.075);
      tip.publish(p);
      p.pose.orientation.w = 1.0;
      p.pose.orientation.x = 0.0;
      base.publish(p);
    }
    // The fake plant's valves: flow follows the last command (full duty = 1.6e-5 m^3/s).
    hydrojet_control::JetState js;
    js.header.stamp = now;
    js.flow_valid.assign(3, true);
    js.flow.assign(3, 0.0);
    for (size_t i = 0; i < 3 && i < r.cmd.valve_command.size(); ++i) js.flow[i] = 1.6e-5 * r.cmd.valve_command[i];
    jets.publish(js);
    ros::spinOnce();
    double valves = 0.0;
    for (double d : r.cmd.valve_command) valves += d;
    if (tracker_on && r.status.state == "running" && valves > 0.0 && (now - t0).toSec() > 3.0) {
      was_running_with_jets = true;  // running with the jets on: now cut the tracker
      tracker_on = false;
      cut = ros::Time::now();
    }
    if (!cut.isZero() && (now - cut).toSec() > 2.0) break;
    rate.sleep();
  }
  ASSERT_TRUE(was_running_with_jets) << "state " << r.status.state << " " << r.status.reason;
  ASSERT_FALSE(r.first_zero_after_cut.isZero());
  // 3 sample periods (30 ms) plus one control period and transport: well within 0.15 s.
  EXPECT_LT((r.first_zero_after_cut - cut).toSec(), 0.15);
  EXPECT_EQ(r.status.state, "aborted");
  EXPECT_NE(r.status.reason.find("tracker"), std::string::npos) << r.status.reason;
  ASSERT_EQ(r.cmd.valve_command.size(), 3u);
  EXPECT_EQ(r.cmd.valve_command[0] + r.cmd.valve_command[1] + r.cmd.valve_command[2], 0.0);
  EXPECT_TRUE(r.diag_error);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "controller_stale_test");
  return RUN_ALL_TESTS();
}
