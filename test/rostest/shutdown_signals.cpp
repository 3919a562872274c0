// SIGINT and SIGTERM end the rig, the plant and the controller with the valves closed
// (ros/shutdown.h). The test starts each node itself as a child process (its parameters are
// loaded by shutdown_signals_sim.test and shutdown_signals_rig.test under the node's name), waits until the jets are
// driven, sends the signal and checks what the node left behind:
//   - plant (lockstep, signalled while the controller still drives the jets): it exits 0 and its
//     last jets/state shows every valve closed;
//   - controller (signalled after that, its last command still non-zero because the clock stopped
//     with the plant): it exits 0 and its last jets/command is all zero;
//   - rig (against the pty emulators; the test drives the jets; the valve board's watchdog is off,
//     so only the driver can close them): it exits 0 and the board's applied duty is zero.
// Before this handling, SIGTERM killed each node on the spot and every check above failed.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "../emulator_process.h"
#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;
using hydrojet::test::Emulator;
using hydrojet::test::eventually;

namespace {

/// A node of this package run as a child: `<bin>/<type> __name:=<name>`.
class NodeProcess {
 public:
  NodeProcess(const std::string& type, const std::string& name) {
    const std::string exe = std::string(HYDROJET_BIN_DIR) + "/" + type;
    const std::string remap = "__name:=" + name;
    char* argv[] = {const_cast<char*>(exe.c_str()), const_cast<char*>(remap.c_str()), nullptr};
    if (posix_spawn(&pid_, exe.c_str(), nullptr, nullptr, argv, environ) != 0) pid_ = -1;
  }
  NodeProcess(const NodeProcess&) = delete;
  NodeProcess& operator=(const NodeProcess&) = delete;
  ~NodeProcess() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  bool started() const { return pid_ > 0; }
  void signal(int sig) const { ::kill(pid_, sig); }
  /// Waits ≤ timeout_s for the exit; true with the wait status in *status when it exited.
  bool wait_exit(double timeout_s, int* status) {
    const bool done = eventually([&] { return waitpid(pid_, status, WNOHANG) == pid_; }, timeout_s);
    if (done) pid_ = -1;
    return done;
  }

 private:
  pid_t pid_ = -1;
};

bool any_nonzero(const std::vector<double>& v) {
  for (double x : v)
    if (x != 0.0) return true;
  return false;
}

bool all_zero(const std::vector<double>& v) { return !v.empty() && !any_nonzero(v); }

template <class F>
bool spin_until(F cond, double timeout_s) {
  return eventually(
      [&] {
        ros::spinOnce();
        return cond();
      },
      timeout_s);
}

/// Exit within 10 s, normally, status 0.
void expect_clean_exit(NodeProcess& node, const char* what) {
  int status = 0;
  ASSERT_TRUE(node.wait_exit(10.0, &status)) << what << " did not exit within 10 s of the signal";
  ASSERT_TRUE(WIFEXITED(status)) << what << " was killed by signal " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  EXPECT_EQ(WEXITSTATUS(status), 0) << what;
}

/// The valve emulator's applied duties ("duty": [a, b, c] in its JSON state file).
std::vector<double> board_duty(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string s = ss.str();
  const size_t d = s.find("\"duty\": [");
  double a[3];
  if (d == std::string::npos || std::sscanf(s.c_str() + d + 9, "%lf, %lf, %lf", &a[0], &a[1], &a[2]) != 3) return {};
  return {a[0], a[1], a[2]};
}

struct Signals {
  int plant, controller;
};

class PlantAndController : public ::testing::TestWithParam<Signals> {};

TEST_P(PlantAndController, CloseTheValvesOnTheSignal) {
  ros::NodeHandle nh;
  hydrojet_control::JetCommand last_cmd;
  hydrojet_control::JetState last_state;
  int cmds = 0, states = 0;
  ros::Subscriber c = nh.subscribe<hydrojet_control::JetCommand>(
      names::kJetCommand, 1000, [&](const hydrojet_control::JetCommand::ConstPtr& m) { last_cmd = *m, ++cmds; });
  ros::Subscriber s = nh.subscribe<hydrojet_control::JetState>(
      names::kJetState, 1000, [&](const hydrojet_control::JetState::ConstPtr& m) { last_state = *m, ++states; });
  NodeProcess plant("plant_node", "sig_plant");
  NodeProcess controller("controller_node", "sig_controller");
  ASSERT_TRUE(plant.started() && controller.started());
  ASSERT_TRUE(
      spin_until([&] { return any_nonzero(last_cmd.valve_command) && any_nonzero(last_state.valve_command); }, 60.0))
      << "the jets were never driven (" << cmds << " commands, " << states << " jet states)";

  plant.signal(GetParam().plant);
  expect_clean_exit(plant, "plant_node");
  spin_until([] { return false; }, 0.5);  // the last messages in flight
  EXPECT_TRUE(all_zero(last_state.valve_command)) << "the plant's last jets/state has an open valve";

  controller.signal(GetParam().controller);
  expect_clean_exit(controller, "controller_node");
  spin_until([] { return false; }, 0.5);
  EXPECT_EQ(last_cmd.valve_command.size(), 3u);
  EXPECT_TRUE(all_zero(last_cmd.valve_command)) << "the controller's last jets/command opens a valve";
  EXPECT_TRUE(all_zero(last_cmd.jet_force));
}

INSTANTIATE_TEST_SUITE_P(Signals, PlantAndController,
                         ::testing::Values(Signals{SIGTERM, SIGINT}, Signals{SIGINT, SIGTERM}));

class Rig : public ::testing::TestWithParam<int> {};

TEST_P(Rig, ClosesTheValvesOnTheSignal) {
  ros::NodeHandle nh, pnh("~");
  std::string dir;
  ASSERT_TRUE(pnh.getParam("dir", dir));
  std::filesystem::create_directories(dir);
  const std::string tag = std::to_string(GetParam());
  const std::string state = dir + "/valves" + tag + ".json";
  ros::param::set("/sig_rig/tracker/port", dir + "/aurora" + tag);
  ros::param::set("/sig_rig/valves/port", dir + "/valves" + tag);
  for (int j = 1; j <= 3; ++j)
    ros::param::set("/sig_rig/flow/ports/jet" + std::to_string(j), dir + "/flow" + tag + std::to_string(j));
  // No watchdog: once the driver has opened them, only the driver closes the valves.
  Emulator valves("valve_emulator.py", {"--symlink", dir + "/valves" + tag, "--state-file", state, "--watchdog", "0"});
  Emulator flow("flow_emulator.py", {"--sensor", dir + "/flow" + tag + "1", "--sensor", dir + "/flow" + tag + "2",
                                     "--sensor", dir + "/flow" + tag + "3", "--valve-state", state});
  Emulator tracker("aurora_emulator.py", {"--symlink", dir + "/aurora" + tag});
  ASSERT_TRUE(valves.started() && flow.started() && tracker.started());
  NodeProcess rig("rig_node", "sig_rig");
  ASSERT_TRUE(rig.started());

  ros::Publisher pub = nh.advertise<hydrojet_control::JetCommand>(names::kJetCommand, 10);
  hydrojet_control::JetCommand cmd;
  cmd.valve_command = {0.3, 0.2, 0.1};
  cmd.jet_force = {0.05, 0.03, 0.01};
  cmd.flow = {0.0, 0.0, 0.0};
  auto drive = [&] {
    cmd.header.stamp = ros::Time::now();
    pub.publish(cmd);
    ros::WallDuration(0.02).sleep();
    return any_nonzero(board_duty(state));
  };
  ASSERT_TRUE(spin_until(drive, 60.0)) << "the board never applied the commands";

  rig.signal(GetParam());
  // Commands keep coming while the driver stops: it must close the valves anyway.
  ASSERT_TRUE(eventually(
      [&] {
        drive();
        int status = 0;
        if (!rig.wait_exit(0.0, &status)) return false;
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "rig_node exit status " << status;
        return true;
      },
      10.0))
      << "rig_node did not exit within 10 s of the signal";
  EXPECT_TRUE(all_zero(board_duty(state))) << "the board still applies a duty after the driver stopped";
}

INSTANTIATE_TEST_SUITE_P(Signals, Rig, ::testing::Values(SIGTERM, SIGINT));

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "shutdown_signals_test");
  return RUN_ALL_TESTS();
}
