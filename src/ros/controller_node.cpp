// Wires the ROS topics of the topic contract (README, "Topics") to the ROS-free controller
// (hydrojet::control::Controller, Algorithm 1 of the paper).
#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <geometry_msgs/PoseStamped.h>
#include <ros/ros.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>

#include <Eigen/Geometry>
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

class ControllerNode {
 public:
  ControllerNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) : nh_(nh), pnh_(pnh) {
    opts_ = ros_bridge::read_controller_options(pnh);
    const config::Scene scene = config::load_scene(opts_.scene);
    controller_.reset(new control::Controller(config::make_controller_model(scene, opts_.flow), opts_.controller));

    tip_sub_ = nh.subscribe("tracker/tip_pose", 10, &ControllerNode::tipCallback, this);
    base_sub_ = nh.subscribe("tracker/base_pose", 10, &ControllerNode::baseCallback, this);
    jet_sub_ = nh.subscribe("jets/state", 10, &ControllerNode::jetCallback, this);
    cmd_pub_ = nh.advertise<hydrojet_control::JetCommand>("jets/command", 10);
    status_pub_ = nh.advertise<hydrojet_control::ControllerStatus>("controller/status", 10);
    rod_pub_ = nh.advertise<hydrojet_control::RodState>("rod/state", 10);
    target_pub_ = nh.advertise<hydrojet_control::TipTarget>("controller/target", 10);
    start_srv_ = nh.advertiseService("controller/start", &ControllerNode::startService, this);
    stop_srv_ = nh.advertiseService("controller/stop", &ControllerNode::stopService, this);
    mode_srv_ = nh.advertiseService("controller/closed_loop", &ControllerNode::modeService, this);

    // Gains through dynamic_reconfigure. Callbacks run on the single spinner thread, so a new
    // configuration never lands in the middle of a control cycle.
    reconfigure_.reset(new dynamic_reconfigure::Server<hydrojet_control::ControllerConfig>(reconfigure_mutex_, pnh_));
    hydrojet_control::ControllerConfig initial;
    const control::ControllerParams& c = opts_.controller;
    initial.kp = c.kp, initial.kd = c.kd, initial.feedforward = c.feedforward, initial.damping = c.damping;
    initial.max_force = c.max_force, initial.max_force_rate = c.max_force_rate;
    reconfigure_->updateConfig(initial);
    reconfigure_->setCallback(
        [this](hydrojet_control::ControllerConfig& cfg, uint32_t level) { reconfigure(cfg, level); });

    diagnostics_.setHardwareID("hydrojet_controller");
    diagnostics_.add("controller", this, &ControllerNode::diagnose);
    timer_ = nh.createTimer(ros::Duration(1.0 / opts_.rate), &ControllerNode::tick, this);
    ROS_INFO("controller: scene %s, %s loop, %.0f Hz%s", opts_.scene.c_str(), control::to_string(opts_.controller.mode),
             opts_.rate, opts_.autostart ? ", autostart" : "");
  }

 private:
  void tipCallback(const geometry_msgs::PoseStamped::ConstPtr& m) {
    tip_ = *m;
    have_tip_ = true;
  }
  void baseCallback(const geometry_msgs::PoseStamped::ConstPtr& m) {
    base_ = *m;
    have_base_ = true;
  }
  void jetCallback(const hydrojet_control::JetState::ConstPtr& m) {
    jets_ = *m;
    have_jets_ = true;
  }

  void reconfigure(hydrojet_control::ControllerConfig& cfg, uint32_t) {
    control::ControllerParams p = controller_->params();
    p.kp = cfg.kp, p.kd = cfg.kd, p.feedforward = cfg.feedforward, p.damping = cfg.damping;
    p.max_force = cfg.max_force, p.max_force_rate = cfg.max_force_rate;
    const std::string err = p.validate();
    if (!err.empty()) {
      ROS_WARN("controller: rejected reconfiguration: %s", err.c_str());
      return;
    }
    controller_->set_params(p);
  }

  bool startService(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    controller_->start(ros::Time::now().toSec());
    res.success = true;
    res.message = std::string("path started, ") + control::to_string(controller_->params().mode) + " loop";
    ROS_INFO("controller: %s", res.message.c_str());
    return true;
  }
  bool stopService(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    controller_->stop();
    res.success = true;
    res.message = "stopped, jets off";
    ROS_INFO("controller: %s", res.message.c_str());
    return true;
  }
  bool modeService(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res) {
    controller_->set_mode(req.data ? control::LoopMode::kClosed : control::LoopMode::kOpen);
    res.success = true;
    res.message = std::string(control::to_string(controller_->params().mode)) + " loop";
    return true;
  }

  void tick(const ros::TimerEvent&) {
    const ros::Time now = ros::Time::now();
    control::ControllerInputs in;
    in.t = now.toSec();
    if (have_tip_ && have_base_ && finite_pose(tip_.pose) && finite_pose(base_.pose)) {
      in.tip_valid = true;
      // Tip orientation in the base frame from the two tracker sensors (both in the tracker frame).
      in.tip_rotation = to_rotation(base_.pose.orientation).transpose() * to_rotation(tip_.pose.orientation);
      in.tip_stamp = std::min(tip_.header.stamp.toSec(), base_.header.stamp.toSec());
    } else if (have_tip_ && have_base_) {
      in.tip_valid = true;  // present but broken: let the core reject it as non-finite
      in.tip_rotation.setConstant(std::nan(""));
      in.tip_stamp = in.t;
    }
    if (have_jets_) {
      in.flow_valid = jets_.flow_valid[0] && jets_.flow_valid[1] && jets_.flow_valid[2];
      in.flow_stamp = jets_.header.stamp.toSec();
      in.flows = Eigen::Vector3d(jets_.flow[0], jets_.flow[1], jets_.flow[2]);
    }
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

    hydrojet_control::JetCommand cmd;
    cmd.header.stamp = now;
    for (int i = 0; i < 3; ++i) {
      cmd.valve_command[i] = out.valve_command[i];
      cmd.jet_force[i] = out.jet_force_command[i];
      cmd.flow[i] = out.flow_command[i];
    }
    cmd_pub_.publish(cmd);

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
    for (int i = 0; i < 3; ++i) {
      st.jet_force_command[i] = out.jet_force_command[i];
      st.jet_force_observed[i] = out.jet_force_observed[i];
    }
    st.force_reachable = out.force_reachable;
    st.solver_converged = out.solver_converged;
    status_pub_.publish(st);

    if (out.state == control::ControllerState::kRunning || out.state == control::ControllerState::kFinished) {
      hydrojet_control::TipTarget tgt;
      tgt.header = st.header;
      tgt.theta = control::bend_angle(out.desired_direction);
      tgt.phi = control::azimuth(out.desired_direction);
      tgt.direction = st.desired_direction;
      target_pub_.publish(tgt);

      hydrojet_control::RodState rs;
      rs.header = st.header;
      const Eigen::Quaterniond q(out.model_tip_rotation);
      rs.tip_pose.orientation.w = q.w(), rs.tip_pose.orientation.x = q.x();
      rs.tip_pose.orientation.y = q.y(), rs.tip_pose.orientation.z = q.z();
      for (int i = 0; i < 6; ++i) rs.tip_wrench[i] = out.wrench_observed[i];
      for (const Eigen::Vector3d& p : controller_->model_shape(20)) {
        geometry_msgs::Point pt;
        pt.x = p.x(), pt.y = p.y(), pt.z = p.z();
        rs.backbone.push_back(pt);
      }
      if (!rs.backbone.empty()) {
        rs.tip_pose.position.x = rs.backbone.back().x;
        rs.tip_pose.position.y = rs.backbone.back().y;
        rs.tip_pose.position.z = rs.backbone.back().z;
      }
      rs.stability_margin = out.stability_margin;
      rs.stability_eig_min = out.stability_eig_min;
      rs.converged = out.solver_converged;
      rs.solve_time = cycle_s;
      rod_pub_.publish(rs);
    }
    diagnostics_.update();
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
  config::ControllerOptions opts_;
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
