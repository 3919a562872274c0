// Wires the simulated HydroJet (hydrojet::plant::Plant) to the same topics as the rig driver:
// tracker poses and jet states out, valve commands in. In lockstep mode it owns /clock and advances
// one sample period per controller command, so runs are deterministic for a seed and faster than
// real time; otherwise it runs paced to the wall clock.
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include <cmath>
#include <iostream>
#include <set>

#include "hydrojet_control/Environment.h"
#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/PlantFault.h"
#include "hydrojet_control/RodState.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/ros/params.h"
#include "hydrojet_control/ros/names.h"
#include "hydrojet_control/ros/shutdown.h"
#include "surface_msg.h"

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
  std::string world_frame = "world";  ///< the lab; the tracker is fixed in it
  // Fault injection (simulated time [s]; < 0 = off)
  double tracker_dropout_at = -1.0, tracker_dropout_duration = 1.0;
  double flow_fault_at = -1.0;  ///< from then on jet 1 reads NaN and jet 2 negative
  double stuck_open_at = -1.0;
  int stuck_open_actuator = 1;  ///< 0-based, as PlantFault's actuator (the old ~stuck_open_jet: 1-based)
  double stuck_duty = 1.0;      ///< the stuck valve's opening [0, 1]
  double start_time = 0.0;      ///< lockstep: /clock starts here [s] (a restarted plant, scripts/soak)
};

/// A fault received on plant/fault, active over [from, to) of the plant's own time [s].
struct ActiveFault {
  std::string kind;
  int actuator = 0;
  double from = 0.0, to = 0.0, value = 0.0;
  double frozen_flow = 0.0;  ///< flow_silent: the reading at the start, repeated
};

PlantNodeOptions read_options(const ros::NodeHandle& pnh) {
  const YAML::Node y = ros_bridge::private_params_as_yaml(pnh);
  PlantNodeOptions o;
  config::YamlTree<config::ParamError> t(y, '/', "~");
  t.keys("", {"scene", "plant", "seed", "rate", "lockstep", "command_wait", "duration", "tracker_frame", "world_frame",
              "tracker_dropout_at", "tracker_dropout_duration", "flow_fault_at", "stuck_open_at", "stuck_open_jet",
              "stuck_open_actuator", "stuck_duty", "start_time"});
  o.scene = t.text("scene", "");
  if (o.scene.empty()) t.fail("scene", "missing (path of the scene YAML)");
  o.plant_file = t.text("plant", o.plant_file);
  o.seed = t.integer("seed", o.seed);
  o.rate = t.number("rate", o.rate);
  o.lockstep = t.boolean("lockstep", o.lockstep);
  o.command_wait = t.number("command_wait", o.command_wait);
  o.duration = t.number("duration", o.duration);
  o.tracker_frame = t.text("tracker_frame", o.tracker_frame);
  o.world_frame = t.text("world_frame", o.world_frame);
  o.tracker_dropout_at = t.number("tracker_dropout_at", o.tracker_dropout_at);
  o.tracker_dropout_duration = t.number("tracker_dropout_duration", o.tracker_dropout_duration);
  o.flow_fault_at = t.number("flow_fault_at", o.flow_fault_at);
  o.stuck_open_at = t.number("stuck_open_at", o.stuck_open_at);
  if (t.has("stuck_open_jet") && t.has("stuck_open_actuator"))
    t.fail("stuck_open_jet", "give stuck_open_actuator (0-based) or the older stuck_open_jet (1-based), not both");
  if (t.has("stuck_open_jet"))
    o.stuck_open_actuator = t.integer("stuck_open_jet", o.stuck_open_actuator + 1, 1, rod::kMaxInputs) - 1;
  o.stuck_open_actuator = t.integer("stuck_open_actuator", o.stuck_open_actuator, 0, rod::kMaxInputs - 1);
  o.stuck_duty = t.number("stuck_duty", o.stuck_duty);
  o.start_time = t.number("start_time", o.start_time);
  if (!(o.start_time >= 0.0)) t.fail("start_time", "must be >= 0 s");
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
    if (o_.stuck_open_at >= 0 &&
        (o_.stuck_open_actuator >= plant_->input_count() || !plant_->is_jet(o_.stuck_open_actuator)))
      throw config::ParamError("~stuck_open_actuator: " + std::to_string(o_.stuck_open_actuator) +
                               " is not a jet of this robot (only a jet has a valve to stick)");
    if (o_.tracker_dropout_at >= 0) plant_->tracker().force_dropout(o_.tracker_dropout_at, o_.tracker_dropout_duration);
    if (o_.lockstep) clock_pub_ = nh.advertise<rosgraph_msgs::Clock>(names::kClock, 10);
    tip_pub_ = nh.advertise<geometry_msgs::PoseStamped>(names::kTipPose, 10);
    base_pub_ = nh.advertise<geometry_msgs::PoseStamped>(names::kBasePose, 10);
    jet_pub_ = nh.advertise<hydrojet_control::JetState>(names::kJetState, 10);
    truth_pub_ = nh.advertise<hydrojet_control::RodState>(names::kPlantRodState, 10);
    environment_pub_ = nh.advertise<hydrojet_control::Environment>(names::kPlantEnvironment, 1, /*latch=*/true);
    publish_environment();
    cmd_sub_ = nh.subscribe(names::kJetCommand, 10, &PlantNode::command, this, ros::TransportHints().tcpNoDelay());
    fault_sub_ = nh.subscribe(names::kPlantFault, 10, &PlantNode::on_fault, this);
    fault_pub_ = nh.advertise<hydrojet_control::PlantFault>(names::kPlantFaultApplied, 10);
    publish_static_frames();
    ROS_INFO("plant: scene %s, base tilt %.1f deg, seed %d, %s", o_.scene.c_str(), model_.base_tilt * 180 / M_PI,
             o_.seed, o_.lockstep ? "lockstep (owns /clock)" : "real time");
  }

  void run() {
    const double dt = 1.0 / o_.rate;
    if (o_.lockstep) {
      // Wait (wall time) for a controller to subscribe, to the sensors and to the clock, so that
      // the first steps are not lost.
      const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(30.0);
      while (ros_bridge::running() && (jet_pub_.getNumSubscribers() == 0 || clock_pub_.getNumSubscribers() == 0) &&
             ros::WallTime::now() < until) {
        publish_clock(0.0);
        ros::WallDuration(0.05).sleep();
        ros::spinOnce();
      }
    }
    if (o_.lockstep && o_.start_time > 0.0) {
      // A restarted plant (scripts/soak): its clock resumes, and the controller runs one cycle on it,
      // before its first sensor sample: as a real rig's data come back after the time that passed,
      // the controller sees the gap.
      // The clock again until that cycle's command is back (a single message could still be on its
      // way to a controller that has just connected), at most 5 s of wall time.
      const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(5.0);
      while (ros_bridge::running() && last_command_stamp_ < -1e-9 && ros::WallTime::now() < until) {
        publish_clock(0.0);
        wait_for_command(0.0, 0.01);
      }
    }
    ros::WallRate pace(o_.rate);
    for (long k = 0; ros_bridge::running(); ++k) {
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
        wait_for_command(t, k == 0 ? 0.0 : o_.command_wait);
      } else {
        ros::spinOnce();
        pace.sleep();
      }
      ros::spinOnce();
    }
  }

  /// On the way out (a signal, the end of `duration`): the simulated valves shut, and a last
  /// jets/state shows it (valve_command all zero unless a valve is stuck).
  void close_valves() {
    plant_->command(rod::InputVector::Zero(plant_->input_count()), plant_->time());
    publish_sensors(plant_->time());
    ROS_INFO("plant: stopping (signal %d): valves closed", ros_bridge::shutdown_signal());
  }

 private:
  /// Lockstep: spins until the command of time t [s] arrived, at most `wall_s` of wall time.
  void wait_for_command(double t, double wall_s) {
    const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(wall_s);
    while (ros_bridge::running() && last_command_stamp_ < t - 1e-9 && ros::WallTime::now() < until) {
      ros::spinOnce();
      ros::WallDuration(0.0001).sleep();
    }
  }

  /// The ROS time of the plant's own time t [s]: offset by start_time in lockstep.
  double now(double t) const { return o_.lockstep ? t + o_.start_time : ros::Time::now().toSec(); }

  void publish_clock(double t) {
    rosgraph_msgs::Clock c;
    c.clock = ros::Time(now(t));
    clock_pub_.publish(c);
  }

  /// plant/fault: checked field by field, applied from the plant's current time, echoed on
  /// plant/fault_applied with its ROS time.
  void on_fault(const hydrojet_control::PlantFault::ConstPtr& m) {
    static const std::set<std::string> kinds = {"tracker_dropout", "flow_nan", "flow_negative", "flow_silent",
                                                "stuck_valve"};
    std::string err;
    if (!kinds.count(m->kind))
      err = "kind: '" + m->kind + "' is not tracker_dropout, flow_nan, flow_negative, flow_silent or stuck_valve";
    else if (!(std::isfinite(m->duration) && m->duration > 0.0))
      err = "duration: must be finite and > 0 s";
    else if (m->kind != "tracker_dropout" && (m->actuator < 0 || m->actuator >= plant_->input_count()))
      err =
          "actuator: " + std::to_string(m->actuator) + " is not in [0, " + std::to_string(plant_->input_count()) + ")";
    else if (m->kind == "stuck_valve" && !plant_->is_jet(m->actuator))
      err = "actuator: " + std::to_string(m->actuator) + " is not a jet (only a jet has a valve to stick)";
    else if (m->kind == "stuck_valve" && !(m->value >= 0.0 && m->value <= 1.0))
      err = "value: a stuck valve's opening must lie in [0, 1]";
    if (!err.empty()) {
      ROS_ERROR("plant: refused plant/fault: %s", err.c_str());
      return;
    }
    ActiveFault f;
    f.kind = m->kind, f.actuator = m->actuator, f.value = m->value;
    f.from = plant_->time();
    f.to = f.from + m->duration;
    if (f.kind == "tracker_dropout") plant_->tracker().force_dropout(f.from, m->duration);
    if (f.kind == "stuck_valve") plant_->hydraulics()[plant_->valve_of(f.actuator)].set_stuck(f.value);
    if (f.kind == "flow_silent") f.frozen_flow = plant_->flow_sample()[f.actuator];
    faults_.push_back(f);
    hydrojet_control::PlantFault echo = *m;
    echo.header.stamp = ros::Time(now(f.from));
    fault_pub_.publish(echo);
    ROS_WARN("plant: fault %s on actuator %d for %.3f s from t = %.3f s", f.kind.c_str(), f.actuator, m->duration,
             now(f.from));
  }

  /// The faults of plant/fault on this sample's readings; an ended stuck valve is freed.
  void apply_faults(double t, rod::InputVector* q, std::vector<uint8_t>* valid) {
    for (auto it = faults_.begin(); it != faults_.end();) {
      if (t >= it->to) {
        if (it->kind == "stuck_valve") plant_->hydraulics()[plant_->valve_of(it->actuator)].set_stuck(-1.0);
        it = faults_.erase(it);
        continue;
      }
      if (it->kind == "flow_nan") (*q)[it->actuator] = std::nan("");
      if (it->kind == "flow_negative") (*q)[it->actuator] = -1e-6;
      if (it->kind == "flow_silent") (*q)[it->actuator] = it->frozen_flow, (*valid)[it->actuator] = false;
      ++it;
    }
  }

  void command(const hydrojet_control::JetCommand::ConstPtr& m) {
    // One duty per actuator; a wrong count or a non-finite entry closes the valves (Plant::command).
    rod::InputVector duty(std::min<int>(m->valve_command.size(), rod::kMaxInputs));
    for (int i = 0; i < duty.size(); ++i) duty[i] = m->valve_command[i];
    if (static_cast<int>(m->valve_command.size()) != plant_->input_count()) duty.setZero(0);
    const double t = o_.lockstep ? m->header.stamp.toSec() - o_.start_time : plant_->time();
    plant_->command(duty, plant_->time());
    last_command_stamp_ = std::max(last_command_stamp_, t);
  }

  void publish_sensors(double t) {
    const ros::Time stamp(now(t));
    if (o_.stuck_open_at >= 0 && t >= o_.stuck_open_at)
      plant_->hydraulics()[plant_->valve_of(o_.stuck_open_actuator)].set_stuck(o_.stuck_duty);
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
    rod::InputVector q = plant_->flow_sample();
    const rod::InputVector f = plant_->force_sample();
    if (o_.flow_fault_at >= 0 && t >= o_.flow_fault_at) {
      q[0] = std::nan("");
      if (q.size() > 1) q[1] = -1e-6;
    }
    const int n = plant_->input_count();
    std::vector<uint8_t> valid(n, true);  // the plant reports what its sensors read; checks are the reader's job
    apply_faults(t, &q, &valid);
    hydrojet_control::JetState js;
    js.header.stamp = stamp;
    const rod::InputVector duty =
        plant_->valves_closed_by_timeout() ? rod::InputVector(rod::InputVector::Zero(n)) : plant_->valve_command();
    js.flow.resize(n);
    js.flow_valid.resize(n);
    js.force.resize(n);
    js.valve_command.resize(n);
    for (int i = 0; i < n; ++i) {
      js.flow[i] = q[i];
      js.flow_valid[i] = valid[i];
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
      const Eigen::Vector3d f = plant_->external_force();
      rs.external_force.x = f.x(), rs.external_force.y = f.y(), rs.external_force.z = f.z();
      truth_pub_.publish(rs);
    }
  }

  /// The plant's surfaces (the truth), latched: the view draws them.
  void publish_environment() {
    hydrojet_control::Environment m;
    m.header.stamp = ros::Time::now();
    m.header.frame_id = "base";
    for (const plant::Surface& s : model_.environment.surfaces) {
      m.surfaces.push_back(ros_bridge::to_msg(s));
      m.stiffness.push_back(s.stiffness);
    }
    m.tip_radius = model_.environment.tip_radius;
    environment_pub_.publish(m);
  }

  // The simulated lab's fixed frames, so that a point clicked in rviz (fixed frame world) reaches the
  // controller without view_node: world → tracker (the tracker is fixed in the lab) and base_sensor →
  // base (the sensor is aligned with the base). view_node sends the same when it runs.
  void publish_static_frames() {
    geometry_msgs::TransformStamped a, b;
    a.header.stamp = b.header.stamp = ros::Time::now();
    a.header.frame_id = o_.world_frame;
    a.child_frame_id = o_.tracker_frame;
    a.transform.rotation.w = 1.0;
    b.header.frame_id = "base_sensor";
    b.child_frame_id = "base";
    b.transform.rotation.w = 1.0;
    static_tf_.sendTransform(std::vector<geometry_msgs::TransformStamped>{a, b});
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
  ros::Publisher clock_pub_, tip_pub_, base_pub_, jet_pub_, truth_pub_, environment_pub_;
  ros::Subscriber cmd_sub_, fault_sub_;
  ros::Publisher fault_pub_;
  std::vector<ActiveFault> faults_;
  tf2_ros::TransformBroadcaster tf_;
  tf2_ros::StaticTransformBroadcaster static_tf_;
  double last_command_stamp_ = -1.0;
};

}  // namespace
}  // namespace hydrojet

int main(int argc, char** argv) {
  ros::init(argc, argv, "plant", ros::init_options::NoSigintHandler);
  hydrojet::ros_bridge::install_shutdown_signals();
  ros::NodeHandle nh, pnh("~");
  try {
    hydrojet::PlantNode node(nh, pnh);
    node.run();
    node.close_valves();
    hydrojet::ros_bridge::flush_and_shutdown();
  } catch (const std::exception& e) {
    ROS_FATAL("plant: refusing to start: %s", e.what());
    std::cerr << "plant: refusing to start: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
