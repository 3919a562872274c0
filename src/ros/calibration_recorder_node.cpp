// calibration_recorder_node: the data collection of paper §6.2. Drives the rig driver or the
// simulated plant through N random jet-force combinations (the paper used 40), holding each with
// the controller's actuation (control/jet_actuation.h: desired flow from the thrust
// equation, eq. 26, and the per-jet PI flow regulators) for ~hold_time while the rod settles, records the driver's
// topics to a bag, and then runs the calibrator (the same code as the `calibrate` tool) on that bag.
//
// Topics: publishes jets/command (JetCommand); subscribes jets/state, tracker/tip_pose,
// tracker/base_pose (all written to ~bag with their header stamps). Timer at ~rate on ROS time, so
// a lockstep plant (which owns /clock and waits for a command per sample) advances with it.
// When done: ~result_file gets calibrate's last JSON line, ~report_file its whole report, and the
// JSON is also published (latched) on calibration/result. Parameters: see read_options() and
// docs/calibration.md.
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <std_msgs/String.h>
#include <geometry_msgs/PoseStamped.h>

#include <cstdio>
#include <fstream>
#include <iostream>
#include <optional>
#include <random>
#include <set>
#include <sstream>

#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/calibration/app.h"
#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/control/jet_actuation.h"
#include "hydrojet_control/ros/params.h"
#include "hydrojet_control/util/json_writer.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

namespace hydrojet {
namespace {

struct RecorderOptions {
  std::string scene, bag, out, result_file, report_file;
  std::string fit = "ux,uy,E,G,da,db,dg";
  std::string calibrate_args;  ///< extra calibrate options, space separated
  int samples = 40;
  int seed = 1;
  double rate = 100.0;                  ///< command rate [Hz]
  double hold_time = 4.0;               ///< per combination [s]
  double start_hold = 2.0;              ///< jets off at the start [s] (also a zero-force sample)
  double max_jet_force_fraction = 0.9;  ///< q_i ≤ fraction · max_force_i of the scene
  double max_net_force = 0.12;          ///< |A q| ≤ this [N]: stays clear of follower-load flutter
  double min_net_force = 0.0;           ///< |A q| ≥ this [N]
  bool calibrate = true;
  bool exit_when_done = true;
  actuation::FlowRegulatorOptions flow;
};

RecorderOptions read_options(const ros::NodeHandle& pnh) {
  const YAML::Node y = ros_bridge::private_params_as_yaml(pnh);
  RecorderOptions o;
  o.flow = config::rig_flow_regulator();  // config/controller.yaml's flow_regulator (duty per m^3/s)
  config::YamlTree<config::ParamError> t(y, '/', "~");
  t.keys("", {"scene", "bag", "out", "result_file", "report_file", "fit", "calibrate_args", "samples", "seed", "rate",
              "hold_time", "start_hold", "max_jet_force_fraction", "max_net_force", "min_net_force", "calibrate",
              "exit_when_done", "flow_regulator"});
  o.scene = t.text("scene", o.scene);
  o.bag = t.text("bag", o.bag);
  o.out = t.text("out", o.out);
  o.result_file = t.text("result_file", o.result_file);
  o.report_file = t.text("report_file", o.report_file);
  o.fit = t.text("fit", o.fit);
  o.calibrate_args = t.text("calibrate_args", o.calibrate_args);
  o.samples = t.integer("samples", o.samples, 1, 100000);
  o.seed = t.integer("seed", o.seed);
  o.rate = t.number("rate", o.rate);
  o.hold_time = t.positive("hold_time", o.hold_time);
  o.start_hold = t.nonnegative("start_hold", o.start_hold);
  o.max_jet_force_fraction = t.number("max_jet_force_fraction", o.max_jet_force_fraction);
  o.max_net_force = t.number("max_net_force", o.max_net_force);
  o.min_net_force = t.number("min_net_force", o.min_net_force);
  o.calibrate = t.boolean("calibrate", o.calibrate);
  o.exit_when_done = t.boolean("exit_when_done", o.exit_when_done);
  config::read_flow_regulator(t, o.flow);
  t.reject_unknown("flow_regulator");
  if (o.scene.empty()) t.fail("scene", "missing (path of the nominal scene YAML)");
  if (o.bag.empty()) t.fail("bag", "missing (path of the bag to record)");
  if (o.calibrate && o.out.empty()) t.fail("out", "missing (path of the calibrated scene YAML)");
  if (!(o.rate >= 1.0 && o.rate <= 1000.0)) t.fail("rate", "must lie in [1, 1000] Hz");
  if (!(o.max_jet_force_fraction > 0.0 && o.max_jet_force_fraction <= 1.0))
    t.fail("max_jet_force_fraction", "must lie in (0, 1]");
  if (!(o.max_net_force > o.min_net_force && o.min_net_force >= 0.0))
    t.fail("max_net_force", "must exceed ~min_net_force >= 0");
  return o;
}

class Recorder {
 public:
  Recorder(ros::NodeHandle& nh, ros::NodeHandle& pnh) : o_(read_options(pnh)), rng_(o_.seed) {
    scene_ = config::load_scene(o_.scene);
    if (!scene_.jets) throw config::SceneError("jets", "missing (the recorder needs the jet geometry and nozzles)");
    jets_.emplace(scene_.rod, scene_.nozzle, o_.flow);
    make_targets();
    bag_.open(o_.bag, rosbag::bagmode::Write);
    cmd_pub_ = nh.advertise<hydrojet_control::JetCommand>(names::kJetCommand, 10);
    result_pub_ = nh.advertise<std_msgs::String>(names::kCalibrationResult, 1, true);
    jet_sub_ = nh.subscribe(names::kJetState, 100, &Recorder::jets, this, ros::TransportHints().tcpNoDelay());
    tip_sub_ = nh.subscribe<geometry_msgs::PoseStamped>(
        names::kTipPose, 100,
        [this](const geometry_msgs::PoseStamped::ConstPtr& m) { pose(m, names::kTipPose, &have_tip_); },
        ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
    base_sub_ = nh.subscribe<geometry_msgs::PoseStamped>(
        names::kBasePose, 100,
        [this](const geometry_msgs::PoseStamped::ConstPtr& m) { pose(m, names::kBasePose, &have_base_); },
        ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
    timer_ = nh.createTimer(ros::Duration(1.0 / o_.rate), &Recorder::tick, this);
    ROS_INFO("calibration recorder: %d jet-force combinations, %.1f s each, |net force| <= %.3f N, bag %s", o_.samples,
             o_.hold_time, o_.max_net_force, o_.bag.c_str());
  }

 private:
  /// Random jet forces q_i ∈ [0, fraction·q_max,i], kept when min ≤ |A q| ≤ max (nominal jet map).
  void make_targets() {
    const actuation::JetMap map(*scene_.jets);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    for (int k = 0; k < o_.samples; ++k) {
      for (int tries = 0;; ++tries) {
        if (tries > 100000) throw std::runtime_error("cannot draw jet forces within the net-force limits");
        Eigen::Vector3d q;
        for (int i = 0; i < 3; ++i) q[i] = o_.max_jet_force_fraction * scene_.rod.actuators[i].max_force * u01(rng_);
        const double net = (map.planar() * q).norm();
        if (net >= o_.min_net_force && net <= o_.max_net_force) {
          targets_.push_back(q);
          break;
        }
      }
    }
  }

  ros::Time bag_time(const ros::Time& stamp) const {
    const ros::Time t = stamp.isZero() ? ros::Time::now() : stamp;
    return t < ros::TIME_MIN ? ros::TIME_MIN : t;
  }

  void jets(const hydrojet_control::JetState::ConstPtr& m) {
    if (!recording_) return;
    if (m->flow.size() != 3) {  // the HydroJet's three jets (the calibration is eq. 24's)
      ROS_WARN_THROTTLE(1.0, "calibration recorder: jets/state with %zu flows for 3 jets: ignored", m->flow.size());
      return;
    }
    bag_.write(names::kJetState, bag_time(m->header.stamp), *m);
    flow_ = Eigen::Vector3d(m->flow[0], m->flow[1], m->flow[2]);
    have_jets_ = true;
  }

  void pose(const geometry_msgs::PoseStamped::ConstPtr& m, const std::string& topic, bool* flag) {
    if (!recording_) return;
    bag_.write(topic, bag_time(m->header.stamp), *m);
    *flag = true;
  }

  void tick(const ros::TimerEvent&) {
    if (done_) return;
    const ros::Time now = ros::Time::now();
    const double t = now.toSec();
    const double dt = have_last_t_ && t > last_t_ ? t - last_t_ : 1.0 / o_.rate;
    last_t_ = t;
    have_last_t_ = true;
    Eigen::Vector3d duty = Eigen::Vector3d::Zero();
    Eigen::Vector3d force = Eigen::Vector3d::Zero(), flow_des = Eigen::Vector3d::Zero();
    if (!(have_jets_ && have_tip_ && have_base_)) {
      // Jets off until the driver's data flow (a lockstep plant still advances on these commands).
    } else {
      if (phase_start_ < 0) {
        phase_start_ = t;
        ROS_INFO("calibration recorder: data arriving, starting (%.1f s jets off first)", o_.start_hold);
      }
      const double elapsed = t - phase_start_;
      const int k = elapsed < o_.start_hold ? -1 : static_cast<int>((elapsed - o_.start_hold) / o_.hold_time);
      if (k >= o_.samples) {
        finish();
        return;
      }
      if (k >= 0) {
        if (k != current_) {
          current_ = k;
          ROS_INFO("calibration recorder: combination %d/%d: q = [%.3f, %.3f, %.3f] N", k + 1, o_.samples,
                   targets_[k][0], targets_[k][1], targets_[k][2]);
        }
        force = targets_[k];
        const rod::InputVector q = force, flows = jets_->flows_for_forces(q);
        flow_des = flows;
        duty = jets_->regulate(q, flows, rod::InputVector(flow_), dt);
      }
    }
    publish(now, duty, force, flow_des);
  }

  void publish(const ros::Time& now, const Eigen::Vector3d& duty, const Eigen::Vector3d& force,
               const Eigen::Vector3d& flow) {
    hydrojet_control::JetCommand c;
    c.header.stamp = now;
    c.valve_command.assign(duty.data(), duty.data() + 3);
    c.jet_force.assign(force.data(), force.data() + 3);
    c.flow.assign(flow.data(), flow.data() + 3);
    cmd_pub_.publish(c);
    if (recording_) bag_.write(names::kJetCommand, bag_time(now), c);
  }

  void finish() {
    done_ = true;
    publish(ros::Time::now(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    recording_ = false;
    bag_.close();
    ROS_INFO("calibration recorder: recorded %s", o_.bag.c_str());
    std::string json = "{}";
    int& status = exit_status_;
    if (o_.calibrate) {
      std::vector<std::string> args = {"--scene", o_.scene, "--data", o_.bag, "--out", o_.out, "--fit", o_.fit};
      std::istringstream extra(o_.calibrate_args);
      for (std::string a; extra >> a;) args.push_back(a);
      std::ostringstream out, err;
      status = calibration::run_calibrate(args, out, err);
      std::cout << out.str() << std::flush;
      if (!err.str().empty()) std::cerr << err.str() << std::flush;
      const std::string report = out.str();
      std::istringstream lines(report);
      for (std::string line; std::getline(lines, line);)
        if (!line.empty()) json = line;  // the last line is calibrate's JSON object
      if (status == 2) json = error_json(err.str());
      if (!o_.report_file.empty()) write_atomically(o_.report_file, report + err.str());
      ROS_INFO("calibration recorder: calibrate exited %d; %s", status,
               status == 0 ? o_.out.c_str() : "see the report");
    }
    if (!o_.result_file.empty()) write_atomically(o_.result_file, json + "\n");
    std_msgs::String msg;
    msg.data = json;
    result_pub_.publish(msg);
    if (o_.exit_when_done) {
      ros::WallDuration(0.5).sleep();  // let the latched result go out
      ros::shutdown();
    }
  }

  /// A JSON object for a calibrate run that failed on its input (exit 2 prints no JSON).
  static std::string error_json(std::string err) {
    while (!err.empty() && err.back() == '\n') err.pop_back();
    util::JsonObject j;
    j.add("converged", false).add("error", err);
    return j.str();
  }

  static void write_atomically(const std::string& path, const std::string& text) {
    const std::string tmp = path + ".tmp";
    {
      std::ofstream f(tmp);
      f << text;
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) ROS_ERROR("calibration recorder: cannot write %s", path.c_str());
  }

  RecorderOptions o_;
  config::Scene scene_;
  std::mt19937 rng_;
  std::optional<control::JetActuation> jets_;  ///< eq. (26) and the jets' PI flow regulators
  std::vector<Eigen::Vector3d> targets_;
  rosbag::Bag bag_;
  ros::Publisher cmd_pub_, result_pub_;
  ros::Subscriber jet_sub_, tip_sub_, base_sub_;
  ros::Timer timer_;
  Eigen::Vector3d flow_ = Eigen::Vector3d::Zero();
  bool have_jets_ = false, have_tip_ = false, have_base_ = false;
  bool recording_ = true, done_ = false;
  double phase_start_ = -1.0, last_t_ = 0.0;
  bool have_last_t_ = false;
  int current_ = -1;

 public:
  int exit_status_ = 0;  ///< calibrate's exit status once done (0 converged, 1 not, 2 bad data)
};

}  // namespace
}  // namespace hydrojet

int main(int argc, char** argv) {
  ros::init(argc, argv, "calibration_recorder");
  ros::NodeHandle nh, pnh("~");
  try {
    hydrojet::Recorder r(nh, pnh);
    ros::spin();
    return r.exit_status_;
  } catch (const std::exception& e) {
    ROS_FATAL("calibration recorder: refusing to start: %s", e.what());
    std::cerr << "calibration recorder: refusing to start: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
