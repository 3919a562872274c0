// The full node graph on the simulated plant (lockstep, simulated time), one scenario per .test
// file, selected by ~scenario:
//   closed_loop       shortened spiral: completes without abort, RMS error below ~rms_bound
//   tracker_dropout   1 s tracker dropout: jets at zero within 3 sample periods, no restart
//   flow_fault        NaN / negative flow readings: rejected, aborted, reported on diagnostics
//   stuck_jet         a valve stuck open: detected from flow feedback, path aborted
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <cmath>

#include "hydrojet_control/ControllerStatus.h"
#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

namespace {

struct Log {
  std::vector<hydrojet_control::ControllerStatus> status;
  std::vector<hydrojet_control::JetCommand> commands;
  double last_tracker = -1.0;  ///< sim time of the last tracker sample before the dropout
  double dropout_from = -1.0;  ///< first gap > 1.5 sample periods in the tracker stream
  std::vector<std::string> diag_errors;
};

bool zero(const hydrojet_control::JetCommand& c) {
  return c.valve_command.size() == 3 && c.valve_command[0] == 0.0 && c.valve_command[1] == 0.0 &&
         c.valve_command[2] == 0.0;
}

/// Spins until the controller reports finished/aborted (or the wall-clock limit).
void run(Log& log, double wall_limit) {
  ros::NodeHandle nh;
  ros::Subscriber s1 = nh.subscribe<hydrojet_control::ControllerStatus>(
      names::kControllerStatus, 10000,
      [&](const hydrojet_control::ControllerStatus::ConstPtr& m) { log.status.push_back(*m); });
  ros::Subscriber s2 = nh.subscribe<hydrojet_control::JetCommand>(
      names::kJetCommand, 10000, [&](const hydrojet_control::JetCommand::ConstPtr& m) { log.commands.push_back(*m); });
  ros::Subscriber s3 = nh.subscribe<geometry_msgs::PoseStamped>(
      names::kTipPose, 10000, [&](const geometry_msgs::PoseStamped::ConstPtr& m) {
        const double t = m->header.stamp.toSec();
        if (log.dropout_from < 0 && log.last_tracker >= 0 && t - log.last_tracker > 0.015)
          log.dropout_from = log.last_tracker;
        log.last_tracker = t;
      });
  ros::Subscriber s4 = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      names::kDiagnostics, 1000, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
        for (const auto& s : m->status)
          if (s.level == diagnostic_msgs::DiagnosticStatus::ERROR) log.diag_errors.push_back(s.message);
      });
  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(wall_limit);
  while (ros::ok() && ros::WallTime::now() < until) {
    ros::spinOnce();
    ros::WallDuration(0.001).sleep();
    if (!log.status.empty() && (log.status.back().state == "finished" || log.status.back().state == "aborted")) {
      // keep listening a little longer (simulated time keeps running) to see what follows
      const ros::WallTime more = ros::WallTime::now() + ros::WallDuration(2.0);
      while (ros::ok() && ros::WallTime::now() < more) {
        ros::spinOnce();
        ros::WallDuration(0.001).sleep();
      }
      break;
    }
  }
}

const hydrojet_control::ControllerStatus* first_abort(const Log& log) {
  for (const auto& s : log.status)
    if (s.state == "aborted") return &s;
  return nullptr;
}

}  // namespace

TEST(SimGraph, Scenario) {
  ros::NodeHandle pnh("~");
  std::string scenario;
  pnh.param<std::string>("scenario", scenario, "");
  double rms_bound = 0.02;
  pnh.param("rms_bound", rms_bound, rms_bound);
  Log log;
  run(log, 240.0);
  ASSERT_FALSE(log.status.empty()) << "no controller status received";

  if (scenario == "closed_loop") {
    const auto* ab = first_abort(log);
    ASSERT_EQ(ab, nullptr) << "aborted at " << ab->path_time << " s: " << ab->reason;
    EXPECT_EQ(log.status.back().state, "finished");
    double s2 = 0.0;
    int n = 0;
    for (const auto& s : log.status)
      if (s.state == "running") {
        s2 += s.error_geodesic * s.error_geodesic;
        ++n;
      }
    ASSERT_GT(n, 100);
    const double rms = std::sqrt(s2 / n);
    EXPECT_LT(rms, rms_bound);
    std::printf("closed loop on the simulated plant: RMS %.4f rad over %d cycles\n", rms, n);
    return;
  }

  const auto* ab = first_abort(log);
  ASSERT_NE(ab, nullptr) << "the controller did not abort";
  const double t_abort = ab->header.stamp.toSec();
  // Jets at zero from the abort on, and they stay there (no restart until commanded).
  bool zero_after = true;
  double first_zero = -1.0;
  for (const auto& c : log.commands) {
    if (c.header.stamp.toSec() >= t_abort) {
      zero_after = zero_after && zero(c);
      if (first_zero < 0 && zero(c)) first_zero = c.header.stamp.toSec();
    }
  }
  EXPECT_TRUE(zero_after);
  for (const auto& s : log.status) {
    if (s.header.stamp.toSec() > t_abort) {
      EXPECT_EQ(s.state, "aborted");
    }
  }

  if (scenario == "tracker_dropout") {
    EXPECT_NE(ab->reason.find("tracker"), std::string::npos) << ab->reason;
    ASSERT_GE(log.dropout_from, 0.0) << "no dropout seen in the tracker stream";
    // Stale after 3 sample periods: the jets are zero by the 4th control cycle after the last sample.
    EXPECT_LE(first_zero - log.dropout_from, 4 * 0.01 + 1e-6)
        << "last sample " << log.dropout_from << ", zero at " << first_zero;
    EXPECT_GT(first_zero - log.dropout_from, 0.0);
  } else if (scenario == "flow_fault") {
    EXPECT_NE(ab->reason.find("flow: jet 1 reading invalid"), std::string::npos) << ab->reason;
    bool reported = false;
    for (const auto& e : log.diag_errors) reported = reported || e.find("flow") != std::string::npos;
    EXPECT_TRUE(reported) << "no diagnostics ERROR about the flow";
  } else if (scenario == "stuck_jet") {
    EXPECT_NE(ab->reason.find("does not follow its command"), std::string::npos) << ab->reason;
  } else {
    FAIL() << "unknown ~scenario '" << scenario << "'";
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "sim_graph_test");
  return RUN_ALL_TESTS();
}
