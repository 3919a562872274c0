// Wires the simulated HydroJet (hydrojet::plant::Plant) to the same topics as the rig driver:
// tracker poses and jet states out, valve commands in. In lockstep mode it owns /clock and advances
// one sample period per controller command, so runs are deterministic for a seed and faster than
// real time; otherwise it runs paced to the wall clock.
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <tf2_ros/transform_broadcaster.h>

#include <iostream>

#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/RodState.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/ros/params.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

namespace hydrojet {
namespace {

struct PlantNodeOptions {
  std::string scene, plant_file;
  int seed = 1;
  double rate = 100.0;        ///< sensor sample rate [Hz]
  bool lockstep = true;       ///< own /clock, wait for each command
  double command_wait = 0.2;  ///< lockstep: wall time to wait for a command [s]
  double duration = 0.0;      ///< stop after this much simulated time [s] (0 = forever)
  std::string tracker_frame = "tracker";
  // Fault injection (simulated time [s]; < 0 = off)
  double tracker_dropout_at = -1.0, tracker_dropout_duration = 1.0;
  double flow_fault_at = -1.0;  ///< from then on jet 1 reads NaN and jet 2 negative
  double stuck_open_at = -1.0;
  int stuck_open_jet = 2;   ///< 1-based
  double stuck_duty = 1.0;  ///< the stuck valve's opening [0, 1]
};

PlantNodeOptions read_options(const ros::NodeHandle& pnh) {
  const YAML::Node y = ros_bridge::private_params_as_yaml(pnh);
  PlantNodeOptions o;
  config::YamlTree<config::ParamError> t(y, '/', "~");
  t.keys("", {"scene", "plant", "seed", "rate", "lockstep", "command_wait", "duration", "tracker_frame",
              "tracker_dropout_at", "tracker_dropout_duration", "flow_fault_at", "stuck_open_at", "stuck_open_jet",
              "stuck_duty"});
  o.scene = t.text("scene", "");
  if (o.scene.empty()) t.fail("scene", "missing (path of the scene YAML)");
  o.plant_file = t.text("plant", o.plant_file);
  o.seed = t.integer("seed", o.seed);
  o.rate = t.number("rate", o.rate);
  o.lockstep = t.boolean("lockstep", o.lockstep);
  o.command_wait = t.number("command_wait", o.command_wait);
  o.duration = t.number("duration", o.duration);
  o.tracker_frame = t.text("tracker_frame", o.tracker_frame);
  o.tracker_dropout_at = t.number("tracker_dropout_at", o.tracker_dropout_at);
  o.tracker_dropout_duration = t.number("tracker_dropout_duration", o.tracker_dropout_duration);
  o.flow_fault_at = t.number("flow_fault_at", o.flow_fault_at);
  o.stuck_open_at = t.number("stuck_open_at", o.stuck_open_at);
  o.stuck_open_jet = t.integer("stuck_open_jet", o.stuck_open_jet, 1, 3);
  o.stuck_duty = t.number("stuck_duty", o.stuck_duty);
  if (!(o.rate >= 1.0 && o.rate <= 1000.0)) t.fail("rate", "must lie in [1, 1000] Hz");
  return o;
}

geometry_msgs::Pose to_pose(const plant::SensorPose& s) {
  geometry_msgs::Pose p;
  p.position.x = s.position.x(), p.position.y = s.position.y(), p.position.z = s.position.z();
  p.orientation.w = s.orientation.w(), p.orientation.x = s.orientation.x();
  p.orientation.y = s.orientation.y(), p.orientation.z = s.orientation.z();
  return p;
}

class PlantNode {
 public:
  PlantNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) : o_(read_options(pnh)) {
    const config::Scene scene = config::load_scene(o_.scene);
    model_ = config::load_plant(scene, o_.plant_file);
    plant_.reset(new plant::Plant(model_, static_cast<unsigned>(o_.seed)));
    if (!plant_->error().empty()) throw std::runtime_error(plant_->error());
    if (o_.tracker_dropout_at >= 0) plant_->tracker().force_dropout(o_.tracker_dropout_at, o_.tracker_dropout_duration);
    if (o_.lockstep) clock_pub_ = nh.advertise<rosgraph_msgs::Clock>(names::kClock, 10);
    tip_pub_ = nh.advertise<geometry_msgs::PoseStamped>(names::kTipPose, 10);
    base_pub_ = nh.advertise<geometry_msgs::PoseStamped>(names::kBasePose, 10);
    jet_pub_ = nh.advertise<hydrojet_control::JetState>(names::kJetState, 10);
    truth_pub_ = nh.advertise<hydrojet_control::RodState>(names::kPlantRodState, 10);
    cmd_sub_ = nh.subscribe(names::kJetCommand, 10, &PlantNode::command, this, ros::TransportHints().tcpNoDelay());
    ROS_INFO("plant: scene %s, base tilt %.1f deg, seed %d, %s", o_.scene.c_str(), model_.base_tilt * 180 / M_PI,
             o_.seed, o_.lockstep ? "lockstep (owns /clock)" : "real time");
  }

  void run() {
    const double dt = 1.0 / o_.rate;
    if (o_.lockstep) {
      // Wait (wall time) for a controller to subscribe, so the first steps are not lost.
      const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(30.0);
      while (ros::ok() && jet_pub_.getNumSubscribers() == 0 && ros::WallTime::now() < until) {
        publish_clock(0.0);
        ros::WallDuration(0.05).sleep();
        ros::spinOnce();
      }
    }
    ros::WallRate pace(o_.rate);
    for (long k = 0; ros::ok(); ++k) {
      const double t = k * dt;
      if (o_.duration > 0 && t > o_.duration) break;
      if (!plant_->advance_to(t)) {
        ROS_ERROR_THROTTLE(1.0, "plant: %s", plant_->error().c_str());
      }
      publish_sensors(t);
      if (o_.lockstep) {
        // Let the sensor messages go out before the clock that triggers the controller.
        ros::WallDuration(0.0005).sleep();
        publish_clock(t);
        const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(k == 0 ? 0.0 : o_.command_wait);
        while (ros::ok() && last_command_stamp_ < t - 1e-9 && ros::WallTime::now() < until) {
          ros::spinOnce();
          ros::WallDuration(0.0001).sleep();
        }
      } else {
        ros::spinOnce();
        pace.sleep();
      }
      ros::spinOnce();
    }
  }

 private:
  double now(double t) const { return o_.lockstep ? t : ros::Time::now().toSec(); }

  void publish_clock(double t) {
    rosgraph_msgs::Clock c;
    c.clock = ros::Time(t);
    clock_pub_.publish(c);
  }

  void command(const hydrojet_control::JetCommand::ConstPtr& m) {
    // One duty per actuator; a wrong count or a non-finite entry closes the valves (Plant::command).
    plant::Plant::Vector duty(std::min<int>(m->valve_command.size(), rod::kMaxActuators));
    for (int i = 0; i < duty.size(); ++i) duty[i] = m->valve_command[i];
    if (static_cast<int>(m->valve_command.size()) != plant_->actuator_count()) duty.setZero(0);
    const double t = o_.lockstep ? m->header.stamp.toSec() : plant_->time();
    plant_->command(duty, plant_->time());
    last_command_stamp_ = std::max(last_command_stamp_, t);
  }

  void publish_sensors(double t) {
    const ros::Time stamp(now(t));
    if (o_.stuck_open_at >= 0 && t >= o_.stuck_open_at)
      if (o_.stuck_open_jet <= plant_->hydraulics().size())
        plant_->hydraulics()[o_.stuck_open_jet - 1].set_stuck(o_.stuck_duty);
    const plant::TrackerSample ts = plant_->tracker_sample();
    if (ts.valid) {  // a missing sensor publishes nothing: stale data is never republished
      geometry_msgs::PoseStamped tip, base;
      tip.header.stamp = base.header.stamp = ros::Time(now(ts.stamp));
      tip.header.frame_id = base.header.frame_id = o_.tracker_frame;
      tip.pose = to_pose(ts.tip);
      base.pose = to_pose(ts.base);
      tip_pub_.publish(tip);
      base_pub_.publish(base);
      broadcast(tip, "tip_sensor");
      broadcast(base, "base_sensor");
    }
    plant::Plant::Vector q = plant_->flow_sample();
    const plant::Plant::Vector f = plant_->force_sample();
    if (o_.flow_fault_at >= 0 && t >= o_.flow_fault_at) {
      q[0] = std::nan("");
      if (q.size() > 1) q[1] = -1e-6;
    }
    hydrojet_control::JetState js;
    js.header.stamp = stamp;
    const int n = plant_->actuator_count();
    const plant::Plant::Vector duty = plant_->valves_closed_by_timeout()
                                          ? plant::Plant::Vector(plant::Plant::Vector::Zero(n))
                                          : plant_->valve_command();
    js.flow.resize(n);
    js.flow_valid.resize(n);
    js.force.resize(n);
    js.valve_command.resize(n);
    for (int i = 0; i < n; ++i) {
      js.flow[i] = q[i];
      js.flow_valid[i] = true;  // the plant reports what its sensors read; checks are the reader's job
      js.force[i] = plant_->is_jet(i) ? actuation::force_from_flow(q[i], model_.nozzle) : f[i];
      js.valve_command[i] = duty[i];
    }
    jet_pub_.publish(js);

    if (truth_pub_.getNumSubscribers() > 0) {
      hydrojet_control::RodState rs;
      rs.header.stamp = stamp;
      rs.header.frame_id = "base";
      for (const Eigen::Vector3d& p : plant_->backbone()) {
        geometry_msgs::Point pt;
        pt.x = p.x(), pt.y = p.y(), pt.z = p.z();
        rs.backbone.push_back(pt);
      }
      const Eigen::Quaterniond qt(plant_->tip_rotation());
      const Eigen::Vector3d pt = plant_->tip_position();
      rs.tip_pose.position.x = pt.x(), rs.tip_pose.position.y = pt.y(), rs.tip_pose.position.z = pt.z();
      rs.tip_pose.orientation.w = qt.w(), rs.tip_pose.orientation.x = qt.x();
      rs.tip_pose.orientation.y = qt.y(), rs.tip_pose.orientation.z = qt.z();
      rs.converged = plant_->error().empty();
      truth_pub_.publish(rs);
    }
  }

  void broadcast(const geometry_msgs::PoseStamped& p, const std::string& child) {
    geometry_msgs::TransformStamped t;
    t.header = p.header;
    t.child_frame_id = child;
    t.transform.translation.x = p.pose.position.x;
    t.transform.translation.y = p.pose.position.y;
    t.transform.translation.z = p.pose.position.z;
    t.transform.rotation = p.pose.orientation;
    tf_.sendTransform(t);
  }

  PlantNodeOptions o_;
  plant::PlantModel model_;
  std::unique_ptr<plant::Plant> plant_;
  ros::Publisher clock_pub_, tip_pub_, base_pub_, jet_pub_, truth_pub_;
  ros::Subscriber cmd_sub_;
  tf2_ros::TransformBroadcaster tf_;
  double last_command_stamp_ = -1.0;
};

}  // namespace
}  // namespace hydrojet

int main(int argc, char** argv) {
  ros::init(argc, argv, "plant");
  ros::NodeHandle nh, pnh("~");
  try {
    hydrojet::PlantNode node(nh, pnh);
    node.run();
  } catch (const std::exception& e) {
    ROS_FATAL("plant: refusing to start: %s", e.what());
    std::cerr << "plant: refusing to start: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
