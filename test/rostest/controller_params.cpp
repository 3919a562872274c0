// controller_node refuses to start on a bad parameter file, naming the key; with good parameters it
// runs and keeps the jets at zero until started.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <string>

#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

namespace {

const std::string kScene = std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/hydrojet_0deg.yaml";

struct Exit {
  int status;
  std::string err;
};

/// Runs controller_node as `name` for at most `seconds`; returns its exit status (-1 if still
/// running, then killed) and stderr.
Exit run_node(const std::string& name, double seconds) {
  const std::string err = "/tmp/hydrojet_" + name + ".err";
  const std::string cmd = "timeout -s INT " + std::to_string(seconds) + " " + std::string(HYDROJET_BIN_DIR) +
                          "/controller_node __name:=" + name + " 2> " + err + " > /dev/null";
  const int st = std::system(cmd.c_str());
  std::ifstream f(err);
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const int code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return {code == 124 ? -1 : code, text};
}

void set_good(ros::NodeHandle& nh, const std::string& name) {
  nh.setParam("/" + name + "/scene", kScene);
  nh.setParam("/" + name + "/rate", 100.0);
  nh.setParam("/" + name + "/pd/kp", 4.0);
}

}  // namespace

TEST(ControllerOptions, BadParametersAreRejectedByName) {
  ros::NodeHandle nh;
  struct Case {
    std::string name, key;
    XmlRpc::XmlRpcValue value;
    std::string expect;
  };
  const std::vector<Case> cases = {
      {"bad_kp", "pd/kp", XmlRpc::XmlRpcValue(-1.0), "~pd/kp"},
      {"bad_unknown", "pd/kq", XmlRpc::XmlRpcValue(1.0), "~pd/kq: unknown"},
      {"moved_twice", "gains/kp", XmlRpc::XmlRpcValue(1.0), "~gains/kp: moved to pd/kp"},
      {"bad_mode", "mode", XmlRpc::XmlRpcValue("sideways"), "~mode"},
      {"bad_type", "safety/stale_periods", XmlRpc::XmlRpcValue("three"), "~safety/stale_periods"},
      {"bad_rate", "rate", XmlRpc::XmlRpcValue(5000.0), "~rate"},
      {"bad_theta", "path/theta_end", XmlRpc::XmlRpcValue(3.0), "~path/theta_end"},
      {"bad_flow", "flow_regulator/ki", XmlRpc::XmlRpcValue(-2.0), "~flow_regulator/ki"},
      {"bad_scene", "scene", XmlRpc::XmlRpcValue("/nonexistent/scene.yaml"), "cannot read"},
  };
  for (auto c : cases) {
    set_good(nh, c.name);
    nh.setParam("/" + c.name + "/" + c.key, c.value);
    const Exit e = run_node(c.name, 20.0);
    EXPECT_EQ(e.status, 1) << c.name << ": " << e.err;
    EXPECT_NE(e.err.find(c.expect), std::string::npos) << c.name << ": " << e.err;
    EXPECT_NE(e.err.find("refusing to start"), std::string::npos) << e.err;
  }
  // Missing scene.
  nh.setParam("/no_scene/rate", 100.0);
  const Exit e = run_node("no_scene", 20.0);
  EXPECT_EQ(e.status, 1);
  EXPECT_NE(e.err.find("~scene: missing"), std::string::npos) << e.err;
  // A scene with an unknown key names it.
  const std::string bad_scene = "/tmp/hydrojet_bad_scene.yaml";
  std::ofstream(bad_scene)
      << "rod: {length: 0.09, lenght: 1, bending_stiffness: [1e-3, 1e-3], torsional_stiffness: 1e-3}\n"
         "tip: {mass: 0}\ngravity: [0, 0, 0]\n";
  set_good(nh, "bad_scene_key");
  nh.setParam("/bad_scene_key/scene", bad_scene);
  const Exit e2 = run_node("bad_scene_key", 20.0);
  EXPECT_EQ(e2.status, 1);
  EXPECT_NE(e2.err.find("rod.lenght"), std::string::npos) << e2.err;
}

TEST(ControllerOptions, GoodParametersRunWithJetsAtZero) {
  ros::NodeHandle nh;
  set_good(nh, "good");
  int n = 0;
  bool all_zero = true;
  ros::Subscriber sub = nh.subscribe<hydrojet_control::JetCommand>(
      names::kJetCommand, 100, [&](const hydrojet_control::JetCommand::ConstPtr& m) {
        ++n;
        for (double v : m->valve_command) all_zero = all_zero && v == 0.0;
      });
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const Exit e = run_node("good", 4.0);
  EXPECT_EQ(e.status, -1) << "node exited early: " << e.err;  // still running when timed out
  EXPECT_GT(n, 50);                                           // ~100 Hz for a few seconds
  EXPECT_TRUE(all_zero);                                      // idle: jets off
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "controller_params_test");
  return RUN_ALL_TESTS();
}
