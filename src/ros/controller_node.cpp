// Wires the ROS topics of the topic contract (docs/ros_api.md) to the ROS-free controller
// (hydrojet::control::Controller, Algorithm 1 of the paper).
#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <geometry_msgs/PoseStamped.h>
#include <ros/ros.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <iostream>

#include "hydrojet_control/ControllerConfig.h"
#include "hydrojet_control/ControllerStatus.h"
#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/RodState.h"
#include "hydrojet_control/TipTarget.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/ros/params.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

namespace hydrojet {
namespace {

Eigen::Matrix3d to_rotation(const geometry_msgs::Quaternion& q) {
  return Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
}

geometry_msgs::Vector3 to_msg(const Eigen::Vector3d& v) {
  geometry_msgs::Vector3 m;
  m.x = v.x(), m.y = v.y(), m.z = v.z();
  return m;
}

bool finite_pose(const geometry_msgs::Pose& p) {
  for (double v :
       {p.position.x, p.position.y, p.position.z, p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z})
    if (!std::isfinite(v)) return false;
  const double n2 = p.orientation.w * p.orientation.w + p.orientation.x * p.orientation.x +
                    p.orientation.y * p.orientation.y + p.orientation.z * p.orientation.z;
  return n2 > 0.5 && n2 < 1.5;
}

/// Copies the jets that fit into a message's fixed-size per-jet array (float64[3]); the rest stay 0.
template <class Array>
void copy_jets(const control::JetVector& from, Array& to) {
  for (int i = 0; i < from.size() && i < static_cast<int>(to.size()); ++i) to[i] = from[i];
}

class ControllerNode {
 public:
  ControllerNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) : nh_(nh), pnh_(pnh) {
    opts_ = ros_bridge::read_controller_options(pnh);
    const config::Scene scene = config::load_scene(opts_.scene);
    controller_.reset(
        new control::Controller(config::make_controller_model(scene, opts_.flow_regulator), opts_.controller));

    tip_sub_ = nh.subscribe(names::kTipPose, 10, &ControllerNode::on_tip_pose, this);
    base_sub_ = nh.subscribe(names::kBasePose, 10, &ControllerNode::on_base_pose, this);
    jet_sub_ = nh.subscribe(names::kJetState, 10, &ControllerNode::on_jet_state, this);
    cmd_pub_ = nh.advertise<hydrojet_control::JetCommand>(names::kJetCommand, 10);
    status_pub_ = nh.advertise<hydrojet_control::ControllerStatus>(names::kControllerStatus, 10);
    rod_pub_ = nh.advertise<hydrojet_control::RodState>(names::kRodState, 10);
    target_pub_ = nh.advertise<hydrojet_control::TipTarget>(names::kControllerTarget, 10);
    start_srv_ = nh.advertiseService(names::kStartService, &ControllerNode::on_start, this);
    stop_srv_ = nh.advertiseService(names::kStopService, &ControllerNode::on_stop, this);
    mode_srv_ = nh.advertiseService(names::kClosedLoopService, &ControllerNode::on_closed_loop, this);
    start_reconfigure();

    diagnostics_.setHardwareID("hydrojet_controller");
    diagnostics_.add("controller", this, &ControllerNode::diagnose);
    timer_ = nh.createTimer(ros::Duration(1.0 / opts_.rate), &ControllerNode::tick, this);
    ROS_INFO("controller: scene %s, %s loop, %.0f Hz%s", opts_.scene.c_str(), control::to_string(opts_.controller.mode),
             opts_.rate, opts_.autostart ? ", autostart" : "");
  }

 private:
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

  // Gains through dynamic_reconfigure, starting from the options read. Callbacks run on the single
  // spinner thread, so a new configuration never lands in the middle of a control cycle.
  void start_reconfigure() {
    reconfigure_.reset(new dynamic_reconfigure::Server<hydrojet_control::ControllerConfig>(reconfigure_mutex_, pnh_));
    hydrojet_control::ControllerConfig initial;
    const control::ControllerOptions& c = opts_.controller;
    initial.kp = c.kp, initial.kd = c.kd, initial.feedforward = c.feedforward, initial.damping = c.damping;
    initial.max_force = c.max_force, initial.max_force_rate = c.max_force_rate;
    reconfigure_->updateConfig(initial);
    reconfigure_->setCallback(
        [this](hydrojet_control::ControllerConfig& cfg, uint32_t level) { reconfigure(cfg, level); });
  }

  void reconfigure(hydrojet_control::ControllerConfig& cfg, uint32_t) {
    control::ControllerOptions p = controller_->params();
    p.kp = cfg.kp, p.kd = cfg.kd, p.feedforward = cfg.feedforward, p.damping = cfg.damping;
    p.max_force = cfg.max_force, p.max_force_rate = cfg.max_force_rate;
    const std::string err = p.validate();
    if (!err.empty()) {
      ROS_WARN("controller: rejected reconfiguration: %s", err.c_str());
      return;
    }
    controller_->set_params(p);
  }

  bool on_start(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    controller_->start(ros::Time::now().toSec());
    res.success = true;
    res.message = std::string("path started, ") + control::to_string(controller_->params().mode) + " loop";
    ROS_INFO("controller: %s", res.message.c_str());
    return true;
  }
  bool on_stop(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    controller_->stop();
    res.success = true;
    res.message = "stopped, jets off";
    ROS_INFO("controller: %s", res.message.c_str());
    return true;
  }
  bool on_closed_loop(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res) {
    controller_->set_mode(req.data ? control::LoopMode::kClosed : control::LoopMode::kOpen);
    res.success = true;
    res.message = std::string(control::to_string(controller_->params().mode)) + " loop";
    return true;
  }

  // One control cycle: latest samples in, Algorithm 1, command and status out.
  void tick(const ros::TimerEvent&) {
    const ros::Time now = ros::Time::now();
    control::ControllerInputs in;
    in.t = now.toSec();
    read_tracker(in);
    read_flows(in);
    if (opts_.autostart && !autostarted_ && in.tip_valid && in.flow_valid) {
      controller_->start(in.t);
      autostarted_ = true;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const control::ControllerOutput out = controller_->update(in);
    const double cycle_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (out.state == control::ControllerState::kAborted && last_state_ != control::ControllerState::kAborted)
      ROS_ERROR("controller: ABORT, jets off: %s", out.reason.c_str());
    last_state_ = out.state;
    last_ = out;

    publish_command(now, out);
    const hydrojet_control::ControllerStatus st = publish_status(now, out);
    if (out.state == control::ControllerState::kRunning || out.state == control::ControllerState::kFinished) {
      publish_target(st.header, out.desired_direction);
      publish_model(st.header, out, cycle_s);
    }
    diagnostics_.update();
  }

  // The tip orientation in the base frame from the two tracker sensors (both in the tracker frame).
  void read_tracker(control::ControllerInputs& in) const {
    if (!have_tip_ || !have_base_) return;
    in.tip_valid = true;
    if (finite_pose(tip_.pose) && finite_pose(base_.pose)) {
      in.tip_rotation = to_rotation(base_.pose.orientation).transpose() * to_rotation(tip_.pose.orientation);
      in.tip_stamp = std::min(tip_.header.stamp.toSec(), base_.header.stamp.toSec());
    } else {  // present but broken: let the core reject it as non-finite
      in.tip_rotation.setConstant(std::nan(""));
      in.tip_stamp = in.t;
    }
  }

  // The measured flows of the jets the message carries (float64[3]), valid when all of them are.
  void read_flows(control::ControllerInputs& in) const {
    if (!have_jets_) return;
    const int n = std::min(controller_->jet_count(), static_cast<int>(jets_.flow.size()));
    in.flow_valid = true;
    in.flows.resize(n);
    for (int i = 0; i < n; ++i) {
      in.flow_valid = in.flow_valid && jets_.flow_valid[i];
      in.flows[i] = jets_.flow[i];
    }
    in.flow_stamp = jets_.header.stamp.toSec();
  }

  void publish_command(const ros::Time& now, const control::ControllerOutput& out) {
    hydrojet_control::JetCommand cmd;
    cmd.header.stamp = now;
    copy_jets(out.valve_command, cmd.valve_command);
    copy_jets(out.jet_force_command, cmd.jet_force);
    copy_jets(out.flow_command, cmd.flow);
    cmd_pub_.publish(cmd);
  }

  hydrojet_control::ControllerStatus publish_status(const ros::Time& now, const control::ControllerOutput& out) {
    hydrojet_control::ControllerStatus st;
    st.header.stamp = now;
    st.header.frame_id = opts_.base_frame;
    st.state = control::to_string(out.state);
    st.mode = control::to_string(controller_->params().mode);
    st.reason = out.reason;
    st.path_time = out.path_time;
    st.desired_direction = to_msg(out.desired_direction);
    st.measured_direction = to_msg(out.measured_direction);
    st.model_direction = to_msg(out.model_tip_rotation.col(2));
    st.error_geodesic = out.error_geodesic;
    st.error_pitch_yaw = out.error_pitch_yaw;
    copy_jets(out.jet_force_command, st.jet_force_command);
    copy_jets(out.jet_force_observed, st.jet_force_observed);
    st.force_reachable = out.force_reachable;
    st.solver_converged = out.solver_converged;
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
    s.add("mode", control::to_string(controller_->params().mode));
    s.add("error_geodesic_rad", last_.error_geodesic);
    s.add("stability_margin", last_.stability_margin);
    s.add("solver_converged", last_.solver_converged);
  }

  ros::NodeHandle nh_, pnh_;
  config::ControllerNodeOptions opts_;
  std::unique_ptr<control::Controller> controller_;
  ros::Subscriber tip_sub_, base_sub_, jet_sub_;
  ros::Publisher cmd_pub_, status_pub_, rod_pub_, target_pub_;
  ros::ServiceServer start_srv_, stop_srv_, mode_srv_;
  ros::Timer timer_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<hydrojet_control::ControllerConfig>> reconfigure_;
  diagnostic_updater::Updater diagnostics_;
  geometry_msgs::PoseStamped tip_, base_;
  hydrojet_control::JetState jets_;
  bool have_tip_ = false, have_base_ = false, have_jets_ = false, autostarted_ = false;
  control::ControllerState last_state_ = control::ControllerState::kIdle;
  control::ControllerOutput last_;
};

}  // namespace
}  // namespace hydrojet

int main(int argc, char** argv) {
  ros::init(argc, argv, "controller");
  ros::NodeHandle nh, pnh("~");
  try {
    hydrojet::ControllerNode node(nh, pnh);
    ros::spin();
  } catch (const std::exception& e) {
    // Bad configuration: refuse to start, naming the key.
    ROS_FATAL("controller: refusing to start: %s", e.what());
    std::cerr << "controller: refusing to start: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
