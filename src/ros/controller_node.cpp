// Wires the ROS topics of the topic contract (docs/ros_api.md) to the ROS-free controller
// (hydrojet::control::Controller, Algorithm 1 of the paper), and the operator's commands
// (docs/operating.md) to its reference: target_direction, look_at and /clicked_point, joy, view_rate
// and the follow_path action. One source drives at a time, the latest command wins.
#include <actionlib/server/simple_action_server.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/PointStamped.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TwistStamped.h>
#include <geometry_msgs/Vector3Stamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/Joy.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <future>
#include <iostream>
#include <mutex>
#include <optional>

#include "hydrojet_control/ControllerConfig.h"
#include "hydrojet_control/ControllerStatus.h"
#include "hydrojet_control/FollowPathAction.h"
#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/Contact.h"
#include "hydrojet_control/KeepOut.h"
#include "hydrojet_control/SetKeepOut.h"
#include "hydrojet_control/ReachableSet.h"
#include "hydrojet_control/RodState.h"
#include "hydrojet_control/TipTarget.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/control/look_at.h"
#include "hydrojet_control/control/path.h"
#include "hydrojet_control/ros/params.h"
#include "hydrojet_control/ros/names.h"
#include "hydrojet_control/ros/shutdown.h"
#include "hydrojet_control/util/format.h"
#include "hydrojet_control/util/text.h"
#include "background.h"
#include "surface_msg.h"
#include "reconfigure_server.h"

namespace names = hydrojet::names;

namespace hydrojet {
namespace {

Eigen::Matrix3d to_rotation(const geometry_msgs::Quaternion& q) {
  return Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
}

Eigen::Vector3d to_vector(const geometry_msgs::Point& p) { return {p.x, p.y, p.z}; }

geometry_msgs::Vector3 to_msg(const Eigen::Vector3d& v) {
  geometry_msgs::Vector3 m;
  m.x = v.x(), m.y = v.y(), m.z = v.z();
  return m;
}

/// Keep-out regions from their messages; an unknown type fails naming keep_out[i]/type (the rest is
/// checked where they are built: control::KeepOut).
std::string from_msg(const std::vector<hydrojet_control::KeepOutRegion>& msgs,
                     std::vector<control::KeepOutRegion>* regions) {
  for (size_t i = 0; i < msgs.size(); ++i) {
    const hydrojet_control::Surface& m = msgs[i].surface;
    control::KeepOutRegion r;
    if (m.type == "plane")
      r.surface.type = geometry::SurfaceType::kPlane;
    else if (m.type == "sphere")
      r.surface.type = geometry::SurfaceType::kSphere;
    else if (m.type == "ellipsoid")
      r.surface.type = geometry::SurfaceType::kEllipsoid;
    else
      return "keep_out[" + std::to_string(i) + "]/type: must be plane, sphere or ellipsoid (got '" + m.type + "')";
    const std::string at = "keep_out[" + std::to_string(i) + "]/";
    if (r.surface.type == geometry::SurfaceType::kSphere &&
        !((m.radii.y == 0.0 || m.radii.y == m.radii.x) && (m.radii.z == 0.0 || m.radii.z == m.radii.x)))
      return at + "radii: a sphere's radius is radii.x (y and z: 0 or the same)";
    r.surface.point = to_vector(m.point);
    r.surface.normal = {m.normal.x, m.normal.y, m.normal.z};
    r.surface.radii = r.surface.type == geometry::SurfaceType::kSphere
                          ? Eigen::Vector3d::Constant(m.radii.x)
                          : Eigen::Vector3d(m.radii.x, m.radii.y, m.radii.z);
    r.surface.inside = m.inside;
    r.margin = msgs[i].margin;
    regions->push_back(r);
  }
  return "";
}

bool finite_pose(const geometry_msgs::Pose& p) {
  for (double v :
       {p.position.x, p.position.y, p.position.z, p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z})
    if (!std::isfinite(v)) return false;
  const double n2 = p.orientation.w * p.orientation.w + p.orientation.x * p.orientation.x +
                    p.orientation.y * p.orientation.y + p.orientation.z * p.orientation.z;
  return n2 > 0.5 && n2 < 1.5;
}

/// One message entry per actuator.
std::vector<double> copy_jets(const rod::InputVector& from) {
  return std::vector<double>(from.data(), from.data() + from.size());
}

Eigen::Vector3d from_msg(const geometry_msgs::Vector3& v) { return Eigen::Vector3d(v.x, v.y, v.z); }
Eigen::Vector3d from_msg(const geometry_msgs::Point& p) { return Eigen::Vector3d(p.x, p.y, p.z); }

/// The goal as the core's PathGoal (every field, used or not: make_goal_path checks them all).
control::PathGoal to_path_goal(const hydrojet_control::FollowPathGoal& g) {
  control::PathGoal p;
  p.type = g.type;
  p.spiral.theta_start = g.theta_start, p.spiral.theta_end = g.theta_end;
  p.spiral.phi_start = g.phi_start, p.spiral.phi_end = g.phi_end, p.spiral.duration = g.duration;
  p.raster.theta_min = g.theta_min, p.raster.theta_max = g.theta_max, p.raster.rows = g.rows;
  p.raster.phi_start = g.raster_phi_start, p.raster.phi_end = g.raster_phi_end, p.raster.speed = g.speed;
  p.times.assign(g.times.begin(), g.times.end());
  for (const geometry_msgs::Vector3& d : g.directions) p.directions.push_back(from_msg(d));
  p.file = g.file;
  return p;
}

/// The follow_path action (action/FollowPath.action). A goal's path is built off the control loop
/// (control::make_goal_path on the Background thread: reading a file, checking every field against
/// control::PathLimits) and drives the controller from the first cycle after it is ready: approached
/// first (its clock starts once the tip has settled on its first direction; the error statistics
/// count from then), until it ends (succeeded), its approach fails (aborted), another source takes over or the
/// controller aborts (aborted), a new goal arrives or the client cancels (preempted; a cancel holds the current
/// direction). Its points are clipped to the reachable set as operator targets are; feedback and result say when
/// (`clipped`). Callbacks and cycle() run on the node's spinner thread, between control cycles.
class FollowPathServer {
 public:
  using Server = actionlib::SimpleActionServer<hydrojet_control::FollowPathAction>;

  FollowPathServer(ros::NodeHandle& nh, control::Controller& controller, std::string& message,
                   ros_bridge::Background& background)
      : server_(nh, names::kFollowPathAction, false),
        controller_(controller),
        message_(message),
        background_(background) {
    server_.registerGoalCallback([this] { on_goal(); });
    server_.registerPreemptCallback([this] { on_preempt(); });
    server_.start();
  }

  /// Before each control cycle: a path built since drives the controller (starting it when idle), so
  /// that the cycle's output, by which the goal is judged, is the path's.
  void before_cycle(const ros::Time& now) {
    if (std::optional<Built> built = built_.take()) adopt(*built, now);
  }

  /// After each control cycle: the error statistics, feedback at 10 Hz and the end of the goal.
  void cycle(const ros::Time& now, const control::ControllerOutput& out) {
    if (!server_.isActive() || !path_) return;
    if (out.state == control::ControllerState::kAborted) return finish(false, "controller aborted: " + out.reason);
    if (out.state == control::ControllerState::kIdle) return finish(false, "controller stopped");
    if (!out.path_failure.empty()) return finish(false, out.path_failure);
    const control::Reference& ref = controller_.reference();
    if (ref.path() != path_.get())
      return finish(false, std::string("superseded by the source '") + control::to_string(ref.source()) + "'");
    approach_time_ = out.approach_time;
    max_clip_ = std::max(max_clip_, out.clip_angle);
    time_scale_ = out.time_scale;
    if (out.reach_limited && !out.approaching) reach_limited_s_ += controller_.options().safety.sample_period;
    if (out.kept_out && !out.approaching) keep_out_s_ += controller_.options().safety.sample_period;
    if (!out.approaching) {  // the error of a path counts from its clock's start
      sum_sq_ += out.error_geodesic * out.error_geodesic;
      max_error_ = std::max(max_error_, out.error_geodesic);
      ++samples_;
    }
    if (now - last_feedback_ >= ros::Duration(0.1)) {
      hydrojet_control::FollowPathFeedback f;
      f.path_time = ref.path_time(now.toSec());
      f.progress = std::min(1.0, std::max(0.0, f.path_time / path_->duration()));
      f.error = out.error_geodesic;
      f.clipped = out.clipped;
      f.clip_angle = out.clip_angle;
      f.approaching = out.approaching;
      f.kept_out = out.kept_out;
      server_.publishFeedback(f);
      last_feedback_ = now;
    }
    if (ref.path_finished(now.toSec())) finish(true, "");
  }

 private:
  /// A goal's path, or why there is none, from the background thread.
  struct Built {
    uint64_t goal = 0;  ///< the goal it was built for (only the latest counts)
    std::shared_ptr<const control::Path> path;
    std::string error;
  };

  void on_goal() {
    const auto goal = server_.acceptNewGoal();
    path_.reset();
    sum_sq_ = max_error_ = max_clip_ = approach_time_ = reach_limited_s_ = keep_out_s_ = 0.0;
    time_scale_ = 1.0;
    samples_ = 0;
    building_ = ++goals_;
    if (controller_.state() == control::ControllerState::kAborted)
      return finish(false, "controller aborted: " + controller_.abort_reason());
    message_ = "follow_path: building the " + goal->type + " path";
    // The goal's copy for the path (its lists may be long) is made there too.
    background_.post(
        [this, id = building_, goal, configured = static_cast<const control::SpiralPath&>(controller_.options().path)] {
          Built b;
          b.goal = id;
          try {
            b.path = control::make_goal_path(to_path_goal(*goal), configured);
          } catch (const std::exception& e) {
            b.error = e.what();
          }
          built_.put(std::move(b));
        });
  }

  void adopt(const Built& b, const ros::Time& now) {
    if (b.goal != building_ || !server_.isActive()) return;  // cancelled or preempted meanwhile
    building_ = 0;
    if (!b.path) return finish(false, "bad goal: " + b.error);
    if (controller_.state() == control::ControllerState::kAborted)
      return finish(false, "controller aborted: " + controller_.abort_reason());
    path_ = b.path;
    controller_.follow(path_, now.toSec());
    if (controller_.state() == control::ControllerState::kIdle) controller_.start(now.toSec());
    message_ = std::string("follow_path: ") + path_->type() + " path of " + std::to_string(path_->duration()) + " s";
  }

  void on_preempt() {
    if (!server_.isActive()) return;
    building_ = 0;
    if (!server_.isNewGoalAvailable()) controller_.hold();  // a cancel holds the current direction
    server_.setPreempted(
        result(false, server_.isNewGoalAvailable() ? "preempted by a new goal" : "cancelled: holding"));
    path_.reset();
  }

  void finish(bool completed, const std::string& reason) {
    if (completed)
      server_.setSucceeded(result(true, ""));
    else
      server_.setAborted(result(false, reason), util::printable(reason));
    if (!completed) message_ = "follow_path: " + reason;
    path_.reset();
    building_ = 0;
  }

  hydrojet_control::FollowPathResult result(bool completed, const std::string& reason) const {
    hydrojet_control::FollowPathResult r;
    r.completed = completed;
    r.reason = util::printable(reason);
    r.rms_error = samples_ > 0 ? std::sqrt(sum_sq_ / samples_) : 0.0;
    r.max_error = max_error_;
    r.clipped = max_clip_ > 0.0;
    r.max_clip_angle = max_clip_;
    r.approach_time = approach_time_;
    r.time_scale = time_scale_;
    r.reach_limited_s = reach_limited_s_;
    r.keep_out_s = keep_out_s_;
    return r;
  }

  Server server_;
  control::Controller& controller_;
  std::string& message_;  ///< the node's status message
  ros_bridge::Background& background_;
  ros_bridge::Mailbox<Built> built_;
  uint64_t goals_ = 0;     ///< goals received
  uint64_t building_ = 0;  ///< the goal whose path is being built (0: none)
  std::shared_ptr<const control::Path> path_;
  double sum_sq_ = 0.0, max_error_ = 0.0;  ///< [rad^2], [rad] over the goal's cycles
  double max_clip_ = 0.0;                  ///< [rad] the most a point of the path was clipped
  double approach_time_ = 0.0;             ///< [s] the path's approach (so far)
  double time_scale_ = 1.0;                ///< the path's time scaling so far
  double reach_limited_s_ = 0.0;           ///< [s] of the path clipped to the learned reach
  double keep_out_s_ = 0.0;                ///< [s] of the path moved out of a keep-out region
  int samples_ = 0;
  ros::Time last_feedback_;
};

class ControllerNode {
 public:
  ControllerNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) : nh_(nh), pnh_(pnh), tf_listener_(tf_) {
    opts_ = ros_bridge::read_controller_options(pnh, reconfigure_keys());
    for (const std::string& w : opts_.warnings) ROS_WARN("controller: %s", w.c_str());
    const config::Scene scene = config::load_scene(opts_.scene);
    const control::RobotModel model = config::make_controller_model(scene, opts_.flow_regulator);
    controller_.reset(new control::Controller(model, opts_.controller));
    controller_->set_fit_inline(false);                   // the probe's fit runs on the background thread (tick)
    background_.post([] { identification::warm_up(); });  // Ceres paged in now, not at the first probe
    look_at_.reset(new control::LookAtSolver(model));
    follow_path_.reset(new FollowPathServer(nh, *controller_, message_, background_));
    initial_params_ = opts_.controller;
    scene_in_force_ = opts_.scene;
    reachable_pub_ = nh.advertise<hydrojet_control::ReachableSet>(names::kReachableSet, 1, /*latch=*/true);
    publish_reachable_set();
    subscribe_operator(nh);

    tip_sub_ = nh.subscribe(names::kTipPose, 10, &ControllerNode::on_tip_pose, this);
    base_sub_ = nh.subscribe(names::kBasePose, 10, &ControllerNode::on_base_pose, this);
    jet_sub_ = nh.subscribe(names::kJetState, 10, &ControllerNode::on_jet_state, this);
    cmd_pub_ = nh.advertise<hydrojet_control::JetCommand>(names::kJetCommand, 10);
    status_pub_ = nh.advertise<hydrojet_control::ControllerStatus>(names::kControllerStatus, 10);
    rod_pub_ = nh.advertise<hydrojet_control::RodState>(names::kRodState, 10);
    target_pub_ = nh.advertise<hydrojet_control::TipTarget>(names::kControllerTarget, 10);
    force_pub_ = nh.advertise<geometry_msgs::WrenchStamped>(names::kExternalForce, 10);
    contact_pub_ = nh.advertise<hydrojet_control::Contact>(names::kContact, 10);
    keep_out_pub_ = nh.advertise<hydrojet_control::KeepOut>(names::kKeepOut, 1, /*latch=*/true);
    keep_out_regions_ = opts_.controller.keep_out;
    keep_out_basis_ = {controller_->shared_path_reachable_set(), controller_->tip_radius()};
    publish_keep_out();
    // Built off the control loop (a fit over the reachable set's sweep), adopted between two cycles.
    ros::AdvertiseServiceOptions keep_out = ros::AdvertiseServiceOptions::create<hydrojet_control::SetKeepOut>(
        names::kSetKeepOutService,
        [this](hydrojet_control::SetKeepOut::Request& req, hydrojet_control::SetKeepOut::Response& res) {
          return on_set_keep_out(req, res);
        },
        ros::VoidConstPtr(), background_.queue());
    keep_out_srv_ = nh.advertiseService(keep_out);
    start_srv_ = nh.advertiseService(names::kStartService, &ControllerNode::on_start, this);
    stop_srv_ = nh.advertiseService(names::kStopService, &ControllerNode::on_stop, this);
    mode_srv_ = nh.advertiseService(names::kClosedLoopService, &ControllerNode::on_closed_loop, this);
    // Loading a scene and sweeping its reachable set take long: on the background thread, whose
    // handler may wait; the control loop adopts the result between two cycles.
    ros::AdvertiseServiceOptions reload = ros::AdvertiseServiceOptions::create<std_srvs::Trigger>(
        names::kReloadSceneService,
        [this](std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res) { return on_reload_scene(req, res); },
        ros::VoidConstPtr(), background_.queue());
    reload_srv_ = nh.advertiseService(reload);
    start_reconfigure();

    diagnostics_.setHardwareID("hydrojet_controller");
    diagnostics_.add("controller", this, &ControllerNode::diagnose);
    timer_ = nh.createTimer(ros::Duration(1.0 / opts_.rate), &ControllerNode::tick, this);
    ROS_INFO("controller: scene %s, %s loop, %.0f Hz%s, at start: %s", opts_.scene.c_str(),
             control::to_string(opts_.controller.mode), opts_.rate, opts_.autostart ? ", autostart" : "",
             control::to_string(opts_.controller.path.type));
  }

  /// On the way out after SIGINT or SIGTERM: an all-zero jets/command, one entry per actuator, so that
  /// the rig or the plant closes the valves now rather than at its command timeout. (After
  /// `rosnode kill` roscpp has already shut down and cannot send it: the receivers' command timeout
  /// closes the valves then.)
  void close_valves() {
    hydrojet_control::JetCommand cmd;
    cmd.header.stamp = ros::Time::now();
    const size_t n = static_cast<size_t>(controller_->input_count());
    cmd.valve_command.assign(n, 0.0);
    cmd.jet_force.assign(n, 0.0);
    cmd.flow.assign(n, 0.0);
    cmd_pub_.publish(cmd);
    ROS_INFO("controller: stopping (signal %d): jets/command all zero", ros_bridge::shutdown_signal());
  }

 private:
  // --- Operator commands (docs/operating.md): each becomes a command of the controller's reference.

  void subscribe_operator(ros::NodeHandle& nh) {
    target_sub_ = nh.subscribe(names::kTargetDirection, 10, &ControllerNode::on_target_direction, this);
    look_at_sub_ = nh.subscribe(names::kLookAt, 10, &ControllerNode::on_look_at, this);
    clicked_sub_ = nh.subscribe(names::kClickedPoint, 10, &ControllerNode::on_look_at, this);
    joy_sub_ = nh.subscribe(names::kJoy, 10, &ControllerNode::on_joy, this);
    view_rate_sub_ = nh.subscribe(names::kViewRate, 10, &ControllerNode::on_view_rate, this);
  }

  void on_target_direction(const geometry_msgs::Vector3Stamped::ConstPtr& m) {
    const Eigen::Vector3d raw = from_msg(m->vector);
    if (!raw.allFinite()) return reject("target_direction: not finite");
    Eigen::Vector3d v;
    if (!control::unit_direction(raw, &v)) return reject("target_direction: zero vector");
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation;
    if (!to_base(m->header.frame_id, rotation, translation)) return;
    if (!controller_->aim(rotation * v, control::Source::kDirection))
      return reject("target_direction: not a direction in the base frame");
    commanded("target_direction");
  }

  // A point to look at, from controller/look_at or rviz's /clicked_point: solved on the model once per
  // point (LookAtSolver, warm-started), then the closed loop tracks that direction. A point beyond the
  // jets' reach is not refused: the tip aims as close as it can (the closest aim, clipped as any
  // target); behind the camera, too close or not converged: rejected.
  void on_look_at(const geometry_msgs::PointStamped::ConstPtr& m) {
    const Eigen::Vector3d p = from_msg(m->point);
    if (!p.allFinite()) return reject("look_at: not finite");
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation;
    if (!to_base(m->header.frame_id, rotation, translation)) return;
    const control::LookAtResult r = look_at_->solve(rotation * p + translation);
    if (!r.ok && !r.out_of_reach) return reject("look_at: " + r.message);
    controller_->aim(r.direction, control::Source::kLookAt);  // out of reach: the closest aim, clipped
    commanded("look_at");
    if (r.out_of_reach) message_ = "look_at: " + r.message + "; aiming as close as the jets allow";
  }

  // Rate teleoperation by joystick (config/teleop.yaml): with the deadman held, the axes turn the
  // view; letting go of the deadman holds. Without the deadman the joystick commands nothing.
  void on_joy(const sensor_msgs::Joy::ConstPtr& m) {
    const config::TeleopOptions& t = opts_.teleop;
    auto axis = [&](int i) { return i < static_cast<int>(m->axes.size()) ? double(m->axes[i]) : 0.0; };
    const bool deadman = t.deadman_button < static_cast<int>(m->buttons.size()) && m->buttons[t.deadman_button];
    const bool driving = controller_->reference().source() == control::Source::kJoy;
    if (!deadman) {
      if (driving) controller_->hold();
      return;
    }
    const Eigen::Vector2d rates(t.scale_up * axis(t.axis_up), t.scale_right * axis(t.axis_right));
    if (!rates.allFinite()) return reject("joy: axes not finite");
    controller_->turn(rates, control::Source::kJoy, ros::Time::now().toSec() + t.timeout);
    commanded("joy");
    note_capped(rates);
  }

  // Keyboard rates (scripts/teleop): a zero twist holds.
  void on_view_rate(const geometry_msgs::TwistStamped::ConstPtr& m) {
    const Eigen::Vector2d rates(m->twist.angular.x, m->twist.angular.y);
    if (!rates.allFinite()) return reject("view_rate: not finite");
    if (rates.isZero(0.0))
      controller_->hold();
    else
      controller_->turn(rates, control::Source::kKeyboard, ros::Time::now().toSec() + opts_.teleop.timeout);
    commanded("view_rate");
    note_capped(rates);
  }

  // A rate faster than max_angular_rate turns at that rate (Reference::turn); the status says so.
  void note_capped(const Eigen::Vector2d& rates) {
    const double cap = controller_->options().limits.max_angular_rate;
    if (rates.cwiseAbs().maxCoeff() > cap || rates.norm() > cap)
      message_ += " (rate capped at " + std::to_string(cap) + " rad/s)";
  }

  /// The transform from `frame` to the base frame ("" or the base frame: identity). An unknown
  /// frame rejects the command (false).
  bool to_base(const std::string& frame, Eigen::Matrix3d& rotation, Eigen::Vector3d& translation) {
    rotation.setIdentity();
    translation.setZero();
    if (frame.empty() || frame == opts_.base_frame) return true;
    try {
      const geometry_msgs::TransformStamped tf = tf_.lookupTransform(opts_.base_frame, frame, ros::Time(0));
      rotation = to_rotation(tf.transform.rotation);
      translation = from_msg(tf.transform.translation);
      return true;
    } catch (const tf2::TransformException& e) {
      reject("unknown frame '" + frame + "': no transform from it to the base frame '" + opts_.base_frame +
             "' on tf2 (plant_node and view_node publish the lab's frames): " + e.what());
      return false;
    }
  }

  void reject(const std::string& why) {
    ++rejected_targets_;
    message_ = util::printable("rejected: " + why);
    ROS_WARN_THROTTLE(1.0, "controller: %s", message_.c_str());
  }

  void commanded(const char* what) {
    message_ = controller_->commands_pending()
                   ? std::string(what) + " stored: the controller is not running, it is used at start"
                   : std::string(what) + ": " + control::to_string(controller_->reference().source()) + " drives";
  }

  void publish_reachable_set() {
    const control::ReachableSet& set = controller_->reachable_set();
    hydrojet_control::ReachableSet m;
    m.header.stamp = ros::Time::now();
    m.header.frame_id = opts_.base_frame;
    m.center = to_msg(set.center());
    for (const Eigen::Vector3d& d : set.boundary()) m.boundary.push_back(to_msg(d));
    m.min_stability_margin = opts_.controller.safety.min_stability_margin;
    m.compute_time = set.compute_time();
    reachable_pub_.publish(m);
    ROS_INFO("controller: reachable set: %zu boundary directions, computed in %.3f s", set.boundary().size(),
             set.compute_time());
  }

  void on_tip_pose(const geometry_msgs::PoseStamped::ConstPtr& m) {
    tip_ = *m;
    have_tip_ = true;
  }
  void on_base_pose(const geometry_msgs::PoseStamped::ConstPtr& m) {
    base_ = *m;
    have_base_ = true;
  }
  void on_jet_state(const hydrojet_control::JetState::ConstPtr& m) {
    jets_ = *m;
    have_jets_ = true;
  }

  /// The parameters dynamic_reconfigure keeps under ~ (cfg/Controller.cfg): left there by an earlier
  /// run of a node of this name (a restart), they are not options; start_reconfigure() sets them anew.
  static std::vector<std::string> reconfigure_keys() {
    std::vector<std::string> keys;
    for (const auto& d : hydrojet_control::ControllerConfig::__getParamDescriptions__()) keys.push_back(d->name);
    return keys;
  }

  // Gains through dynamic_reconfigure (cfg/Controller.cfg), starting from the options read. The
  // server runs on the spinner thread, so a new configuration never lands in the middle of a control
  // cycle; it refuses values outside the .cfg's safe ranges and what ControllerOptions refuses, and
  // always reports the configuration in force (ros_bridge::ReconfigureServer).
  void start_reconfigure() {
    hydrojet_control::ControllerConfig initial = hydrojet_control::ControllerConfig::__getDefault__();
    const control::ControllerOptions& c = opts_.controller;
    initial.kp = c.pd.kp, initial.kd = c.pd.kd, initial.feedforward = c.pd.feedforward;
    initial.damping = c.allocation.damping;
    initial.max_force = c.limits.max_force, initial.max_force_rate = c.limits.max_force_rate;
    if (const std::string err = Reconfigure::out_of_bounds(initial); !err.empty())
      throw std::invalid_argument("gains and limits: " + err + " (cfg/Controller.cfg, docs/ros_api.md)");
    reconfigure_.reset(new Reconfigure(pnh_, initial, [this](const hydrojet_control::ControllerConfig& cfg) {
      control::ControllerOptions p = controller_->options();
      p.pd.kp = cfg.kp, p.pd.kd = cfg.kd, p.pd.feedforward = cfg.feedforward;
      p.allocation.damping = cfg.damping;
      p.limits.max_force = cfg.max_force, p.limits.max_force_rate = cfg.max_force_rate;
      std::string err = p.validate();
      if (err.empty()) controller_->set_options(p);
      return err;
    }));
  }

  bool on_start(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    controller_->start(ros::Time::now().toSec());
    res.success = true;
    res.message = std::string("started: ") + control::to_string(controller_->reference().source()) + " drives, " +
                  control::to_string(controller_->options().mode) + " loop";
    ROS_INFO("controller: %s", res.message.c_str());
    return true;
  }
  bool on_stop(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    controller_->stop();
    running_.store(false);  // now: a reload_scene right after this reply must not see the last cycle's state
    res.success = true;
    res.message = "stopped, jets off";
    ROS_INFO("controller: %s", res.message.c_str());
    return true;
  }
  bool on_closed_loop(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res) {
    controller_->set_mode(req.data ? control::LoopMode::kClosed : control::LoopMode::kOpen);
    res.success = true;
    res.message = std::string(control::to_string(controller_->options().mode)) + " loop";
    return true;
  }

  // A new scene (e.g. after a calibration): ~scene read again, the model rebuilt and its reachable set
  // swept here, on the background thread (the set in force serves meanwhile; a sweep longer than
  // ReachableSetOptions::max_time is refused); the control loop adopts it between two cycles with the
  // gains in force and publishes the new set. Refused while running (the jets would change model
  // mid-motion) and when the scene does not load (the old one stays).
  bool on_reload_scene(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    res.success = false;
    const auto refuse = [&](const std::string& why) {
      res.message = util::printable("refused: " + why + " (the scene " + scene_in_force_ + " stays)");
      ROS_WARN("controller: reload_scene %s", res.message.c_str());
      return true;
    };
    if (running_.load()) return refuse("the controller is running (call controller/stop first)");
    std::string path;
    if (!pnh_.getParam("scene", path) || path.empty())
      return refuse(std::string("~scene ") + (pnh_.hasParam("scene") ? "is not a file name" : "is not set"));
    SceneSwap swap;
    try {
      const control::RobotModel model = config::make_controller_model(config::load_scene(path), opts_.flow_regulator);
      control::ControllerOptions params = initial_params_;
      {
        std::lock_guard<std::mutex> lock(keep_out_mutex_);
        params.keep_out = keep_out_regions_;  // the regions in force, over the new robot's reach
      }
      swap.controller = std::make_unique<control::Controller>(model, params);
      swap.look_at = std::make_unique<control::LookAtSolver>(model);
    } catch (const std::exception& e) {
      return refuse(e.what());
    }
    std::future<std::string> verdict = swap.verdict.get_future();
    scene_box_.put(std::move(swap));
    if (verdict.wait_for(std::chrono::seconds(5)) != std::future_status::ready) {
      scene_box_.take();  // not adopted: withdrawn (or already taken: then it is in force)
      return refuse("the control loop did not take it within 5 s");
    }
    if (const std::string why = verdict.get(); !why.empty()) return refuse(why);
    scene_in_force_ = path;
    res.success = true;
    res.message =
        util::printable("scene " + path + " loaded; reachable set swept in " + std::to_string(sweep_time_) + " s");
    ROS_INFO("controller: %s", res.message.c_str());
    return true;
  }

  // New keep-out regions (background thread): checked and built here against the reachable set in
  // force; refused naming the key (the regions in force stay), else adopted at the next cycle.
  bool on_set_keep_out(hydrojet_control::SetKeepOut::Request& req, hydrojet_control::SetKeepOut::Response& res) {
    std::vector<control::KeepOutRegion> regions;
    std::string error = from_msg(req.regions, &regions);
    std::shared_ptr<const control::KeepOut> keep_out;
    if (error.empty()) {
      KeepOutBasis basis;
      {
        std::lock_guard<std::mutex> lock(keep_out_mutex_);
        basis = keep_out_basis_;
      }
      try {
        keep_out = std::make_shared<const control::KeepOut>(regions, basis.tip_radius, basis.set);
      } catch (const std::exception& e) {
        error = e.what();
        // The message's fields: a centre is its `point`, a radius its `radii`.
        for (const auto& [file_key, field] :
             {std::pair<std::string, std::string>{"/centre:", "/point:"}, {"/radius:", "/radii:"}})
          if (const size_t p = error.find(file_key); p != std::string::npos) error.replace(p, file_key.size(), field);
      }
    }
    res.success = error.empty();
    if (!res.success) {
      res.message = util::printable("refused: " + error + " (the regions in force stay)");
      ROS_WARN("controller: set_keep_out %s", res.message.c_str());
      return true;
    }
    {
      std::lock_guard<std::mutex> lock(keep_out_mutex_);
      keep_out_regions_ = regions;
    }
    keep_out_box_.put(std::move(keep_out));
    res.message = std::to_string(regions.size()) + " keep-out region(s) from the next control cycle";
    ROS_INFO("controller: %s", res.message.c_str());
    return true;
  }

  /// Between two cycles: regions set_keep_out built, unless a scene reloaded since (then they were
  /// built over the old robot's reach: dropped, the caller told to set them again).
  void adopt_keep_out() {
    std::optional<std::shared_ptr<const control::KeepOut>> k = keep_out_box_.take();
    if (!k) return;
    if ((*k)->set() != controller_->shared_path_reachable_set()) {
      message_ = "keep_out: regions set during a scene reload were dropped; set them again";
      ROS_WARN("controller: %s", message_.c_str());
      return;
    }
    controller_->set_keep_out(std::move(*k));
    publish_keep_out();
  }

  /// The regions in force, latched (the view draws them).
  void publish_keep_out() {
    hydrojet_control::KeepOut m;
    m.header.stamp = ros::Time::now();
    m.header.frame_id = opts_.base_frame;
    for (const control::KeepOutRegion& r : controller_->options().keep_out) {
      hydrojet_control::KeepOutRegion k;
      k.surface = ros_bridge::to_msg(r.surface);
      k.margin = r.margin;
      m.regions.push_back(k);
    }
    keep_out_pub_.publish(m);
  }

  /// Between two cycles: a scene loaded by reload_scene replaces the model (unless the controller
  /// runs: then it is refused).
  void adopt_scene() {
    std::optional<SceneSwap> swap = scene_box_.take();
    if (!swap) return;
    if (controller_->state() == control::ControllerState::kRunning) {
      swap->verdict.set_value("the controller is running (call controller/stop first)");
      return;
    }
    control::ControllerOptions in_force = controller_->options();  // the gains in force ...
    in_force.keep_out = swap->controller->options().keep_out;      // ... and the regions it was built with
    swap->controller->set_options(in_force);
    *controller_ = std::move(*swap->controller);
    controller_->set_fit_inline(false);
    look_at_ = std::move(swap->look_at);
    sweep_time_ = controller_->reachable_set().compute_time();
    publish_reachable_set();
    {
      std::lock_guard<std::mutex> lock(keep_out_mutex_);
      keep_out_basis_ = {controller_->shared_path_reachable_set(), controller_->tip_radius()};
    }
    swap->verdict.set_value("");
  }

  // One control cycle: latest samples in, Algorithm 1, command and status out.
  void tick(const ros::TimerEvent&) {
    adopt_keep_out();
    adopt_scene();
    const ros::Time now = ros::Time::now();
    control::ControllerInputs in;
    in.t = now.toSec();
    read_tracker(in);
    read_flows(in);
    if (opts_.autostart && !autostarted_ && in.tip_valid && in.flow_valid) {
      controller_->start(in.t);
      autostarted_ = true;
    }
    follow_path_->before_cycle(now);
    if (std::optional<control::ProbeJob::Result> fit = probe_results_.take()) controller_->deliver_probe_result(*fit);
    const auto t0 = std::chrono::steady_clock::now();
    const control::ControllerOutput out = controller_->update(in);
    const double cycle_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    control::ProbeJob job;
    if (controller_->take_probe_job(&job))  // the probe's fit, off the loop
      background_.post([this, job = std::move(job)] { probe_results_.put(job.run()); });
    if (out.state == control::ControllerState::kAborted && last_state_ != control::ControllerState::kAborted)
      ROS_ERROR("controller: ABORT, jets off: %s", out.reason.c_str());
    last_state_ = out.state;
    if (out.law_weight == 0.0 && last_.law_weight > 0.0) {
      message_ = out.mode_swing > controller_->options().modal.ring_amplitude
                     ? "supervisor: the mode rang (swing " + util::num(out.mode_swing) + " rad): the paper's law acts"
                     : std::string("supervisor: a jet is held at its bound: the paper's law acts");
      ROS_WARN("controller: %s", message_.c_str());
    } else if (out.law_weight == 1.0 && last_.law_weight < 1.0 && out.state == control::ControllerState::kRunning) {
      message_ = "supervisor: calm again, the modal law acts";
    }
    running_.store(out.state == control::ControllerState::kRunning);
    last_ = out;
    follow_path_->cycle(now, out);

    publish_command(now, out);
    const hydrojet_control::ControllerStatus st = publish_status(now, out);
    if (out.state == control::ControllerState::kRunning || out.state == control::ControllerState::kFinished) {
      publish_target(st.header, out.desired_direction);
      publish_model(st.header, out, cycle_s);
      publish_contact(st.header, out.contact);
    }
    diagnostics_.update();
  }

  // The tip orientation in the base frame from the two tracker sensors (both in the tracker frame).
  void read_tracker(control::ControllerInputs& in) const {
    if (!have_tip_ || !have_base_) return;
    in.tip_valid = true;
    if (finite_pose(tip_.pose) && finite_pose(base_.pose)) {
      const Eigen::Matrix3d base = to_rotation(base_.pose.orientation);
      in.tip_rotation = base.transpose() * to_rotation(tip_.pose.orientation);
      in.tip_position = base.transpose() * (to_vector(tip_.pose.position) - to_vector(base_.pose.position));
      in.tip_stamp = std::min(tip_.header.stamp.toSec(), base_.header.stamp.toSec());
    } else {  // present but broken: let the core reject it as non-finite
      in.tip_rotation.setConstant(std::nan(""));
      in.tip_stamp = in.t;
    }
  }

  // The measured flows and forces the message carries (one per actuator), valid when all of them
  // are. Extra entries are ignored; missing ones leave the vectors short (the core then aborts,
  // naming the counts).
  void read_flows(control::ControllerInputs& in) const {
    if (!have_jets_) return;
    const int n =
        std::min({static_cast<int>(rod::kMaxInputs), controller_->input_count(), static_cast<int>(jets_.flow.size())});
    in.flow_valid = true;
    in.flows.resize(n);
    for (int i = 0; i < n; ++i) {
      in.flow_valid = in.flow_valid && (i >= static_cast<int>(jets_.flow_valid.size()) || jets_.flow_valid[i]);
      in.flows[i] = jets_.flow[i];
    }
    const int m = std::min(n, static_cast<int>(jets_.force.size()));
    in.forces.resize(m);
    for (int i = 0; i < m; ++i) in.forces[i] = jets_.force[i];
    in.flow_stamp = jets_.header.stamp.toSec();
  }

  void publish_command(const ros::Time& now, const control::ControllerOutput& out) {
    hydrojet_control::JetCommand cmd;
    cmd.header.stamp = now;
    cmd.valve_command = copy_jets(out.valve_command);
    cmd.jet_force = copy_jets(out.jet_force_command);
    cmd.flow = copy_jets(out.flow_command);
    cmd_pub_.publish(cmd);
  }

  hydrojet_control::ControllerStatus publish_status(const ros::Time& now, const control::ControllerOutput& out) {
    hydrojet_control::ControllerStatus st;
    st.header.stamp = now;
    st.header.frame_id = opts_.base_frame;
    st.state = control::to_string(out.state);
    st.mode = control::to_string(controller_->options().mode);
    st.reason = util::printable(out.reason);
    st.path_time = out.path_time;
    st.desired_direction = to_msg(out.desired_direction);
    st.measured_direction = to_msg(out.measured_direction);
    st.model_direction = to_msg(out.model_tip_rotation.col(2));
    st.error_geodesic = out.error_geodesic;
    st.error_pitch_yaw = out.error_pitch_yaw;
    st.jet_force_command = copy_jets(out.jet_force_command);
    st.jet_force_observed = copy_jets(out.jet_force_observed);
    st.force_reachable = out.force_reachable;
    st.solver_converged = out.solver_converged;
    st.message = util::printable(message_);
    st.source = control::to_string(controller_->reference().source());
    st.clipped = out.clipped;
    st.clip_angle = out.clip_angle;
    st.rejected_targets = rejected_targets_;
    st.law_weight = out.law_weight;
    st.mode_swing = out.mode_swing;
    status_pub_.publish(st);
    return st;
  }

  void publish_target(const std_msgs::Header& header, const Eigen::Vector3d& desired) {
    hydrojet_control::TipTarget tgt;
    tgt.header = header;
    tgt.theta = control::bend_angle(desired);
    tgt.phi = control::azimuth(desired);
    tgt.direction = to_msg(desired);
    target_pub_.publish(tgt);
  }

  // The external force's estimate and the contact detector (base frame).
  void publish_contact(const std_msgs::Header& header, const control::ContactState& c) {
    geometry_msgs::WrenchStamped w;
    w.header = header;
    w.wrench.force = to_msg(c.force);
    force_pub_.publish(w);
    hydrojet_control::Contact m;
    m.header = header;
    m.in_contact = c.in_contact;
    m.normal = to_msg(c.normal);
    m.force = to_msg(c.force);
    if (c.in_contact && c.since > 0.0) m.since = ros::Time(c.since);
    contact_pub_.publish(m);
  }

  // The controller's model at this cycle: tip pose, backbone, wrench, stability and solve time.
  void publish_model(const std_msgs::Header& header, const control::ControllerOutput& out, double cycle_s) {
    hydrojet_control::RodState rs;
    rs.header = header;
    const Eigen::Quaterniond q(out.model_tip_rotation);
    rs.tip_pose.orientation.w = q.w(), rs.tip_pose.orientation.x = q.x();
    rs.tip_pose.orientation.y = q.y(), rs.tip_pose.orientation.z = q.z();
    for (int i = 0; i < 6; ++i) rs.tip_wrench[i] = out.wrench_observed[i];
    for (const Eigen::Vector3d& p : controller_->model_shape(20)) {
      geometry_msgs::Point pt;
      pt.x = p.x(), pt.y = p.y(), pt.z = p.z();
      rs.backbone.push_back(pt);
    }
    if (!rs.backbone.empty()) rs.tip_pose.position = rs.backbone.back();
    rs.stability_margin = out.stability_margin;
    rs.stability_eig_min = out.stability_eig_min;
    rs.converged = out.solver_converged;
    rs.solve_time = cycle_s;
    rod_pub_.publish(rs);
  }

  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& s) {
    using diagnostic_msgs::DiagnosticStatus;
    if (last_.state == control::ControllerState::kAborted)
      s.summary(DiagnosticStatus::ERROR, "aborted: " + last_.reason);
    else if (!have_tip_ || !have_base_)
      s.summary(DiagnosticStatus::WARN, "no tracker data");
    else if (!have_jets_)
      s.summary(DiagnosticStatus::WARN, "no jet state");
    else
      s.summary(DiagnosticStatus::OK, control::to_string(last_.state));
    s.add("mode", control::to_string(controller_->options().mode));
    s.add("error_geodesic_rad", last_.error_geodesic);
    s.add("stability_margin", last_.stability_margin);
    s.add("solver_converged", last_.solver_converged);
  }

  ros::NodeHandle nh_, pnh_;
  config::ControllerNodeOptions opts_;
  tf2_ros::Buffer tf_;
  tf2_ros::TransformListener tf_listener_;
  std::unique_ptr<control::Controller> controller_;
  std::unique_ptr<control::LookAtSolver> look_at_;
  std::unique_ptr<FollowPathServer> follow_path_;
  std::string message_;            ///< the status message: the last command, rejection or goal event
  uint32_t rejected_targets_ = 0;  ///< since the node started
  ros::Subscriber tip_sub_, base_sub_, jet_sub_;
  ros::Subscriber target_sub_, look_at_sub_, clicked_sub_, joy_sub_, view_rate_sub_;
  ros::Publisher cmd_pub_, status_pub_, rod_pub_, target_pub_, reachable_pub_, force_pub_, contact_pub_;
  ros::ServiceServer start_srv_, stop_srv_, mode_srv_, reload_srv_;
  ros::Timer timer_;
  using Reconfigure = ros_bridge::ReconfigureServer<hydrojet_control::ControllerConfig>;
  std::unique_ptr<Reconfigure> reconfigure_;
  diagnostic_updater::Updater diagnostics_;
  geometry_msgs::PoseStamped tip_, base_;
  hydrojet_control::JetState jets_;
  bool have_tip_ = false, have_base_ = false, have_jets_ = false, autostarted_ = false;
  control::ControllerState last_state_ = control::ControllerState::kIdle;
  control::ControllerOutput last_;

  /// A scene loaded off the loop, and the loop's answer ("" adopted, else why not).
  struct SceneSwap {
    std::unique_ptr<control::Controller> controller;
    std::unique_ptr<control::LookAtSolver> look_at;
    std::promise<std::string> verdict;
  };
  control::ControllerOptions initial_params_;  ///< as read at start: a reloaded scene's sets are swept with them
  std::string scene_in_force_;                 ///< reload_scene's (background thread) record of the scene
  double sweep_time_ = 0.0;                    ///< [s] the adopted scene's sweep, for reload_scene's reply
  /// The controller runs, for reload_scene's early refusal (the loop's verdict at adoption is final):
  /// set by each cycle and by controller/stop.
  std::atomic<bool> running_{false};
  ros_bridge::Mailbox<SceneSwap> scene_box_;
  /// What set_keep_out builds regions over (the loop sets it; the background thread reads it).
  struct KeepOutBasis {
    std::shared_ptr<const control::ReachableSet> set;
    double tip_radius = 0.0;
  };
  std::mutex keep_out_mutex_;  ///< guards the two below
  KeepOutBasis keep_out_basis_;
  std::vector<control::KeepOutRegion> keep_out_regions_;  ///< in force, or on their way to the loop
  ros_bridge::Mailbox<std::shared_ptr<const control::KeepOut>> keep_out_box_;
  ros::Publisher keep_out_pub_;
  ros::ServiceServer keep_out_srv_;
  // Last: destroyed first, so that no background job outlives what it uses.
  /// The probe's fit, from the background thread (declared before it: the thread stops first).
  ros_bridge::Mailbox<control::ProbeJob::Result> probe_results_;
  ros_bridge::Background background_;
};

}  // namespace
}  // namespace hydrojet

int main(int argc, char** argv) {
  ros::init(argc, argv, "controller", ros::init_options::NoSigintHandler);
  hydrojet::ros_bridge::install_shutdown_signals();
  ros::NodeHandle nh, pnh("~");
  try {
    hydrojet::ControllerNode node(nh, pnh);
    hydrojet::ros_bridge::spin_until_signal();
    node.close_valves();
    hydrojet::ros_bridge::flush_and_shutdown();
  } catch (const std::exception& e) {
    // Bad configuration: refuse to start, naming the key.
    ROS_FATAL("controller: refusing to start: %s", e.what());
    std::cerr << "controller: refusing to start: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
