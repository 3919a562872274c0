// rig.launch against the device emulators: the test starts the Aurora, flow-sensor and valve-board
// emulators (test/emulators/, PTYs behind symbolic links in ~dir, which rig_node finds through its
// reconnect loop), then checks that
//  1. tracker poses reach the controller (it runs, autostarted, and reports a measured direction),
//  2. the controller's commands reach the valve emulator (non-zero duty applied by the board),
//  3. killing the tracker emulator closes the valves (board duty back to zero), and the driver's
//     diagnostics name the tracker, and no tip pose is published any more.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <signal.h>
#include <spawn.h>
#include <std_msgs/Float64.h>
#include <std_msgs/Header.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "hydrojet_control/ControllerStatus.h"
#include "hydrojet_control/JetState.h"
#include "../emulator_process.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

namespace {

using hydrojet::test::Emulator;

struct BoardState {
  double duty[3] = {NAN, NAN, NAN};
  long nonzero_commands = -1, acked = -1;
  bool ok = false;
};

/// The valve emulator's JSON state file (one object: "duty": [a, b, c], "nonzero_commands": n, ...).
BoardState read_board(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string s = ss.str();
  BoardState b;
  const size_t d = s.find("\"duty\": [");
  const size_t n = s.find("\"nonzero_commands\": ");
  const size_t a = s.find("\"acked\": ");
  if (d == std::string::npos || n == std::string::npos || a == std::string::npos) return b;
  b.ok = std::sscanf(s.c_str() + d + 9, "%lf, %lf, %lf", &b.duty[0], &b.duty[1], &b.duty[2]) == 3 &&
         std::sscanf(s.c_str() + n + 20, "%ld", &b.nonzero_commands) == 1 &&
         std::sscanf(s.c_str() + a + 9, "%ld", &b.acked) == 1;
  return b;
}

bool closed(const BoardState& b) { return b.ok && b.duty[0] == 0.0 && b.duty[1] == 0.0 && b.duty[2] == 0.0; }

template <class F>
bool spin_until(F cond, double timeout_s) {
  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::ok() && ros::WallTime::now() < until) {
    ros::spinOnce();
    if (cond()) return true;
    ros::WallDuration(0.005).sleep();
  }
  return cond();
}

}  // namespace

TEST(RigEmulated, PoseToControllerCommandToBoardTrackerLossClosesValves) {
  ros::NodeHandle nh, pnh("~");
  std::string dir;
  ASSERT_TRUE(pnh.getParam("dir", dir));
  std::filesystem::create_directories(dir);
  struct Cleanup {
    std::string dir;
    ~Cleanup() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  } cleanup{dir};

  double sample_period = 0;
  ASSERT_TRUE(ros::param::get("/controller/safety/sample_period", sample_period));
  EXPECT_DOUBLE_EQ(sample_period, 0.05);  // rig.launch's override of controller.yaml

  hydrojet_control::ControllerStatus status;
  hydrojet_control::JetState jets;
  int tip_poses = 0, rms_msgs = 0, jet_msgs = 0, jets_all_valid = 0;
  // (header seq, stamp) of each tip pose and jet state: the publisher numbers and stamps them, so that
  // a rate from them is the rig node's, whatever this process's scheduling or queue drops.
  std::vector<std::pair<uint32_t, ros::Time>> tip_seq, jet_seq;
  ros::WallTime last_tip;
  std::string tracker_error, valves_error;
  ros::Subscriber s1 = nh.subscribe<hydrojet_control::ControllerStatus>(
      names::kControllerStatus, 100, [&](const hydrojet_control::ControllerStatus::ConstPtr& m) { status = *m; });
  // Tip pose stamps and the device frame numbers.
  std::vector<ros::Time> tip_stamps, frame_stamps;
  std::vector<uint32_t> frames;
  bool tip_stamps_increase = true;
  ros::Subscriber s2 = nh.subscribe<geometry_msgs::PoseStamped>(
      names::kTipPose, 100, [&](const geometry_msgs::PoseStamped::ConstPtr& m) {
        ++tip_poses;
        tip_seq.emplace_back(m->header.seq, m->header.stamp);
        last_tip = ros::WallTime::now();
        tip_stamps_increase = tip_stamps_increase && (tip_stamps.empty() || m->header.stamp > tip_stamps.back());
        tip_stamps.push_back(m->header.stamp);
        EXPECT_EQ(m->header.frame_id, "tracker");
        EXPECT_NEAR(m->pose.position.z, -0.150, 1e-5);  // the emulator's tip [mm -> m]
      });
  ros::Subscriber s3 = nh.subscribe<std_msgs::Float64>(names::kTipRms, 100, [&](const std_msgs::Float64::ConstPtr& m) {
    ++rms_msgs;
    EXPECT_NEAR(m->data, 0.30e-3, 1e-8);
  });
  ros::Subscriber s4 = nh.subscribe<hydrojet_control::JetState>(
      names::kJetState, 100, [&](const hydrojet_control::JetState::ConstPtr& m) {
        jets = *m;
        ++jet_msgs;
        jet_seq.emplace_back(m->header.seq, m->header.stamp);
        jets_all_valid += m->flow_valid.size() == 3 && m->flow_valid[0] && m->flow_valid[1] && m->flow_valid[2];
      });
  // The device's frame number of each tip pose, on its own topic with the pose's stamp.
  ros::Subscriber s6 =
      nh.subscribe<std_msgs::Header>(names::kTipFrameNumber, 100, [&](const std_msgs::Header::ConstPtr& m) {
        frames.push_back(m->seq);
        frame_stamps.push_back(m->stamp);
      });
  ros::Subscriber s5 = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      names::kDiagnostics, 100, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
        for (const auto& s : m->status) {
          if (s.level != diagnostic_msgs::DiagnosticStatus::ERROR) continue;
          if (s.name.find("tracker") != std::string::npos && s.message.find("tracker") != std::string::npos)
            tracker_error = s.message;
          if (s.name.find("valves") != std::string::npos && s.message.find("tracker") != std::string::npos)
            valves_error = s.message;
        }
      });

  // The devices appear (rig_node is already retrying every second).
  const std::string state = dir + "/valves.json";
  Emulator valves("valve_emulator.py", {"--symlink", dir + "/valves", "--state-file", state});
  Emulator flow("flow_emulator.py", {"--sensor", dir + "/flow1", "--sensor", dir + "/flow2", "--sensor", dir + "/flow3",
                                     "--valve-state", state});
  // The tip is tilted 0.15 rad from the base, so the controller (path starting at ϑ = 0) drives the jets.
  auto tracker = std::make_unique<Emulator>(
      "aurora_emulator.py", std::vector<std::string>{"--symlink", dir + "/aurora", "--strict-baud", "--tip-tilt",
                                                     "0.15", "--events-file", dir + "/aurora.events"});
  ASSERT_TRUE(valves.started() && flow.started() && tracker->started());

  // 1. A pose reaches the controller: it runs (autostart needs tracker and flow data) and measures.
  ASSERT_TRUE(
      spin_until([&] { return status.state == "running" && std::fabs(status.measured_direction.z) > 0.5; }, 40.0))
      << "controller state '" << status.state << "' reason '" << status.reason << "', tip poses " << tip_poses
      << ", jet states " << jet_msgs;
  EXPECT_NEAR(std::acos(status.measured_direction.z), 0.15, 0.01);  // the emulator's tilt, through the whole chain

  // 2. A command reaches the valve emulator (and the board applies it).
  ASSERT_TRUE(spin_until(
      [&] {
        const BoardState b = read_board(state);
        return b.ok && b.nonzero_commands > 0 && std::max({b.duty[0], b.duty[1], b.duty[2]}) > 0.01;
      },
      15.0))
      << "controller '" << status.state << "' " << status.reason;
  ASSERT_EQ(status.state, "running") << status.reason;

  // The loop keeps running on the driver's data for 3 s (no stale-data or flow-fault abort: poses,
  // flows and valve acknowledgements keep up), and the stream rates are measured.
  const size_t tip0 = tip_seq.size(), jets0 = jet_seq.size();
  const long acked0 = read_board(state).acked;
  const ros::WallTime w0 = ros::WallTime::now();
  spin_until([&] { return status.state != "running"; }, 3.0);
  const double window = (ros::WallTime::now() - w0).toSec();
  EXPECT_EQ(status.state, "running") << status.reason;
  // Messages published per second of the publisher's own stamps (seq counts every publish).
  const auto published_hz = [](const std::vector<std::pair<uint32_t, ros::Time>>& v, size_t from) {
    if (v.size() < from + 2) return 0.0;
    const double span = (v.back().second - v[from].second).toSec();
    return span > 0.0 ? (v.back().first - v[from].first) / span : 0.0;
  };
  const double tip_hz = published_hz(tip_seq, tip0), jets_hz = published_hz(jet_seq, jets0);
  // Acknowledgements counted by the valve emulator over this window (both go on while this process waits).
  const double ack_hz = (read_board(state).acked - acked0) / window;
  EXPECT_GT(tip_hz, 30.0);   // the Aurora's 40 Hz
  EXPECT_GT(jets_hz, 40.0);  // three sensors at 50 Hz each
  EXPECT_GT(ack_hz, 60.0);   // the controller's 100 Hz commands
  EXPECT_GT(rms_msgs, 0);
  EXPECT_GT(jets_all_valid, 0);
  EXPECT_GT(jets.valve_command[0] + jets.valve_command[1] + jets.valve_command[2], 0.0);  // acknowledged duty
  // Stamps strictly increase; each frame number is new (repeats dropped) and comes with a tip pose's stamp.
  EXPECT_TRUE(tip_stamps_increase);
  ASSERT_GT(frames.size(), 10u);
  for (size_t i = 1; i < frames.size(); ++i) EXPECT_GT(frames[i], frames[i - 1]) << "frame number " << i;
  for (const ros::Time& t : frame_stamps)  // (a frame number whose pose is still in flight is not checked)
    if (t <= tip_stamps.back())
      EXPECT_TRUE(std::find(tip_stamps.begin(), tip_stamps.end(), t) != tip_stamps.end()) << "no tip pose at " << t;

  // 3. The tracker emulator dies: valves closed, diagnostics name the tracker, no more poses.
  const ros::WallTime cut = ros::WallTime::now();
  tracker->kill();
  ASSERT_TRUE(spin_until([&] { return closed(read_board(state)); }, 5.0));
  const double latency = (ros::WallTime::now() - cut).toSec();
  EXPECT_LT(latency, 1.0);
  ASSERT_TRUE(spin_until([&] { return !tracker_error.empty() && !valves_error.empty(); }, 5.0))
      << "tracker '" << tracker_error << "' valves '" << valves_error << "'";
  spin_until([] { return false; }, 1.0);
  EXPECT_TRUE(closed(read_board(state)));  // and they stay closed
  EXPECT_LT((last_tip - cut).toSec(), 0.1) << "a tip pose was published after the tracker died";
  ROS_INFO(
      "rig_emulated: tip poses %.1f Hz, jet states %.1f Hz, valve acks %.1f Hz over %.1f s; valves closed "
      "%.3f s after the tracker died; '%s'",
      tip_hz, jets_hz, ack_hz, window, latency, valves_error.c_str());
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "rig_emulated_test");
  return RUN_ALL_TESTS();
}
