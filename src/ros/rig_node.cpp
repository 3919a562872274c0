// Wires the HydroJet testbed's devices (ROS-free drivers in include/hydrojet_control/devices/: NDI
// Aurora, three flow sensors, valve board) to the topics of the topic contract (docs/ros_api.md),
// the same topics the simulated plant speaks. Health goes to /diagnostics; every device thread
// lives in the core, this file only converts and publishes.
#include <diagnostic_updater/diagnostic_updater.h>
#include <diagnostic_updater/update_functions.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <std_msgs/Float64.h>
#include <std_msgs/Header.h>
#include <tf2_ros/transform_broadcaster.h>

#include <cmath>
#include <iostream>
#include <memory>

#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/devices/rig_config.h"
#include "hydrojet_control/ros/params.h"
#include "hydrojet_control/ros/names.h"
#include "hydrojet_control/ros/shutdown.h"

namespace names = hydrojet::names;

namespace hydrojet {
namespace {

using devices::AuroraStatus;
using devices::HandlePose;
using devices::SteadyClock;
using devices::SteadyTime;

devices::RigOptions read_options(const ros::NodeHandle& pnh) {
  try {
    return devices::parse_rig_options(ros_bridge::private_params_as_yaml(pnh));
  } catch (const devices::RigOptionsError& e) {
    throw devices::RigOptionsError(std::string("~") + e.what());
  }
}

/// ROS time of a steady-clock instant in the (recent) past.
ros::Time to_ros(SteadyTime t) {
  const double age = devices::seconds_between(t, SteadyClock::now());
  return ros::Time::now() - ros::Duration(std::max(0.0, age));
}

const char* to_string(HandlePose::Status s) {
  switch (s) {
    case HandlePose::kValid: return "valid";
    case HandlePose::kMissing: return "missing";
    case HandlePose::kDisabled: return "disabled";
    case HandlePose::kOutOfVolume: return "out of volume";
  }
  return "?";
}

std::string fmt(const char* f, double x) {
  char b[96];
  std::snprintf(b, sizeof b, f, x);
  return b;
}

class RigNode {
 public:
  RigNode(ros::NodeHandle& nh, ros::NodeHandle& pnh)
      : cfg_(read_options(pnh)),
        nozzle_(config::load_scene(cfg_.scene).nozzle),
        diag_(nh, pnh),
        tracker_min_hz_(0.8 * cfg_.tracker.rate),
        tracker_max_hz_(1.1 * cfg_.tracker.rate),
        flow_min_hz_(0.8 * cfg_.flow_rate),
        flow_max_hz_(1.1 * cfg_.flow_rate),
        jets_min_hz_(0.8 * cfg_.flow_rate),
        jets_max_hz_(std::max(1.1 * cfg_.flow_rate, cfg_.flow_publish_rate * 1.1)),
        valve_min_hz_(0.8 * cfg_.valve_loop.rate),
        valve_max_hz_(1000.0),
        tip_freq_(diagnostic_updater::FrequencyStatusParam(&tracker_min_hz_, &tracker_max_hz_, 0.1, 10),
                  "tracker/tip_pose rate"),
        base_freq_(diagnostic_updater::FrequencyStatusParam(&tracker_min_hz_, &tracker_max_hz_, 0.1, 10),
                   "tracker/base_pose rate"),
        jets_freq_(diagnostic_updater::FrequencyStatusParam(&jets_min_hz_, &jets_max_hz_, 0.1, 10), "jets/state rate"),
        valve_freq_(diagnostic_updater::FrequencyStatusParam(&valve_min_hz_, &valve_max_hz_, 0.1, 10),
                    "valve acknowledgement rate"),
        flows_(cfg_.flow[0].timeout, cfg_.invalidate_on_reject) {
    if (!actuation::validate(nozzle_).empty())
      throw std::runtime_error("scene " + cfg_.scene + ": " + actuation::validate(nozzle_));
    advertise(nh);
    add_diagnostics();
    create_devices();
    cmd_sub_ = nh.subscribe(names::kJetCommand, 10, &RigNode::on_command, this, ros::TransportHints().tcpNoDelay());
    jets_timer_ = nh.createWallTimer(ros::WallDuration(1.0 / cfg_.flow_publish_rate), &RigNode::publish_jets, this);
    diag_timer_ = nh.createWallTimer(ros::WallDuration(0.05), &RigNode::update_diagnostics, this);

    valves_->start();
    tracker_->start();
    for (auto& f : flow_) f->start();
    ROS_INFO(
        "rig: tracker %s (tip %02X, base %02X, %.0f Hz), flow %s %s %s, valves %s; valves closed until "
        "every device is healthy and commands arrive",
        cfg_.tracker.port.c_str(), cfg_.tracker.tip_handle, cfg_.tracker.base_handle, cfg_.tracker.rate,
        cfg_.flow[0].port.c_str(), cfg_.flow[1].port.c_str(), cfg_.flow[2].port.c_str(), cfg_.valves.port.c_str());
  }

  ~RigNode() {
    // Valves first (zero duty while the other devices still exist for its health check), then the
    // tracker (TSTOP), then the flow sensors.
    valves_->stop();
    tracker_->stop();
    for (auto& f : flow_) f->stop();
    ROS_INFO("rig: stopped (valves closed, tracking stopped)");
  }

 private:
  // -- set-up -----------------------------------------------------------------------------------

  void advertise(ros::NodeHandle& nh) {
    tip_pub_ = nh.advertise<geometry_msgs::PoseStamped>(names::kTipPose, 10);
    base_pub_ = nh.advertise<geometry_msgs::PoseStamped>(names::kBasePose, 10);
    tip_rms_pub_ = nh.advertise<std_msgs::Float64>(names::kTipRms, 10);
    tip_frame_pub_ = nh.advertise<std_msgs::Header>(names::kTipFrameNumber, 10);
    base_rms_pub_ = nh.advertise<std_msgs::Float64>(names::kBaseRms, 10);
    jet_pub_ = nh.advertise<hydrojet_control::JetState>(names::kJetState, 10);
  }

  void add_diagnostics() {
    for (int i = 0; i < 3; ++i)
      flow_freq_[i].reset(new diagnostic_updater::FrequencyStatus(
          diagnostic_updater::FrequencyStatusParam(&flow_min_hz_, &flow_max_hz_, 0.1, 10),
          cfg_.flow[i].name + " rate"));
    diag_.setHardwareID("hydrojet_rig");
    diag_.add("tracker", this, &RigNode::diagnose_tracker);
    diag_.add("tip sensor", [this](diagnostic_updater::DiagnosticStatusWrapper& s) { diagnose_handle(s, true); });
    diag_.add("base sensor", [this](diagnostic_updater::DiagnosticStatusWrapper& s) { diagnose_handle(s, false); });
    for (int i = 0; i < 3; ++i)
      diag_.add(cfg_.flow[i].name, [this, i](diagnostic_updater::DiagnosticStatusWrapper& s) { diagnose_flow(s, i); });
    diag_.add("valve board", this, &RigNode::diagnose_valve_board);
    diag_.add("valves", this, &RigNode::diagnose_gate);
    diag_.add(tip_freq_);
    diag_.add(base_freq_);
    diag_.add(jets_freq_);
    for (auto& f : flow_freq_) diag_.add(*f);
    diag_.add(valve_freq_);
  }

  /// The device clients (threads not started yet); they log through ROS.
  void create_devices() {
    auto log = [](devices::LogLevel level, const std::string& m) {
      if (level == devices::LogLevel::kInfo)
        ROS_INFO("rig: %s", m.c_str());
      else
        ROS_WARN("rig: %s", m.c_str());
    };
    tracker_.reset(new devices::AuroraClient(
        cfg_.tracker, [this](const devices::AuroraSample& s) { on_tracker(s); }, log));
    for (size_t i = 0; i < 3; ++i)
      flow_[i].reset(new devices::FlowSensor(
          cfg_.flow[i], [this, i](const devices::FlowReading& r) { on_flow(i, r); }, log));
    valves_.reset(new devices::ValveLoop(
        std::unique_ptr<devices::ValveDriver>(new devices::SerialValveBoard(cfg_.valves)), cfg_.valve_loop,
        [this](std::string* why) { return devices_healthy(SteadyClock::now(), why); },
        [this](const devices::Duty&, SteadyTime) { valve_freq_.tick(); }, log));
  }

  // -- device threads -------------------------------------------------------------------------

  void on_tracker(const devices::AuroraSample& s) {
    // s.stamp is strictly increasing on the steady clock (receive time - latency); the conversion
    // to ROS time reads two clocks, so keep the published stamps strictly increasing too.
    ros::Time stamp = to_ros(s.stamp);
    if (!last_tracker_stamp_.isZero() && stamp <= last_tracker_stamp_)
      stamp = last_tracker_stamp_ + ros::Duration(0, 1000);
    last_tracker_stamp_ = stamp;
    std::vector<geometry_msgs::TransformStamped> tfs;
    if (s.tip_new && s.tip.status == HandlePose::kValid) {
      publish_pose(s.tip, stamp, tip_pub_, tip_rms_pub_, cfg_.tip_frame, &tfs);
      std_msgs::Header frame;
      frame.seq = s.tip.frame;
      frame.stamp = stamp;
      frame.frame_id = cfg_.tracker_frame;
      tip_frame_pub_.publish(frame);
      tip_freq_.tick();
    }
    if (s.base_new && s.base.status == HandlePose::kValid) {
      publish_pose(s.base, stamp, base_pub_, base_rms_pub_, cfg_.base_frame, &tfs);
      base_freq_.tick();
    }
    if (!tfs.empty()) tf_.sendTransform(tfs);
  }

  void publish_pose(const HandlePose& h, const ros::Time& stamp, ros::Publisher& pose_pub, ros::Publisher& rms_pub,
                    const std::string& child, std::vector<geometry_msgs::TransformStamped>* tfs) {
    geometry_msgs::PoseStamped p;
    p.header.stamp = stamp;
    p.header.frame_id = cfg_.tracker_frame;
    p.pose.position.x = h.t[0], p.pose.position.y = h.t[1], p.pose.position.z = h.t[2];
    p.pose.orientation.w = h.q[0], p.pose.orientation.x = h.q[1];
    p.pose.orientation.y = h.q[2], p.pose.orientation.z = h.q[3];
    pose_pub.publish(p);
    std_msgs::Float64 rms;
    rms.data = h.rms_m;
    rms_pub.publish(rms);
    geometry_msgs::TransformStamped t;
    t.header = p.header;
    t.child_frame_id = child;
    t.transform.translation.x = h.t[0], t.transform.translation.y = h.t[1], t.transform.translation.z = h.t[2];
    t.transform.rotation = p.pose.orientation;
    tfs->push_back(t);
  }

  void on_flow(size_t jet, const devices::FlowReading& r) {
    flows_.add(jet, r);
    if (r.accepted) flow_freq_[jet]->tick();
  }

  // -- ROS callbacks ----------------------------------------------------------------------------

  // The rig's three valves; a command for another number of actuators closes them.
  void on_command(const hydrojet_control::JetCommand::ConstPtr& m) {
    if (m->valve_command.size() != 3) {
      ROS_WARN_THROTTLE(1.0, "rig: jets/command with %zu entries for the rig's 3 valves: valves closed",
                        m->valve_command.size());
      valves_->command({0.0, 0.0, 0.0});
      return;
    }
    valves_->command({m->valve_command[0], m->valve_command[1], m->valve_command[2]});
  }

  void publish_jets(const ros::WallTimerEvent&) {
    devices::FlowAggregator::Sample s;
    if (!flows_.take(SteadyClock::now(), &s)) return;  // nothing new: never republish
    const devices::ValveStatus v = valves_->status();
    hydrojet_control::JetState js;
    js.header.stamp = to_ros(s.stamp);
    js.flow.resize(3);
    js.flow_valid.resize(3);
    js.force.resize(3);
    js.valve_command.resize(3);
    for (int i = 0; i < 3; ++i) {
      js.flow[i] = s.flow[i];
      js.flow_valid[i] = s.valid[i];
      js.force[i] = s.valid[i] ? actuation::force_from_flow(s.flow[i], nozzle_) : std::nan("");
      js.valve_command[i] = v.acknowledged[i];
    }
    jet_pub_.publish(js);
    jets_freq_.tick();
  }

  void update_diagnostics(const ros::WallTimerEvent&) {
    track_tracker_rates(SteadyClock::now());
    // Publish at once when a device's health changes; otherwise at the updater's period.
    std::string why;
    const bool ok = devices_healthy(SteadyClock::now(), &why);
    const bool valves_ok = valves_->status().healthy;
    const std::string signature = (ok ? std::string("ok") : why.substr(0, why.find(':'))) + (valves_ok ? "+v" : "-v");
    if (signature != last_signature_) {
      if (ok && valves_ok) {
        ROS_INFO("rig: all devices healthy");
        ever_healthy_ = true;
      } else if (ever_healthy_) {
        ROS_ERROR("rig: valves closed: %s", ok ? "valve board unhealthy" : why.c_str());
      } else {
        ROS_INFO("rig: waiting for %s", ok ? "the valve board" : why.c_str());
      }
      last_signature_ = signature;
      diag_.force_update();
    } else {
      diag_.update();
    }
  }

  // -- health ----------------------------------------------------------------------------------

  std::string handle_problem(const devices::HandleStats& h, SteadyTime now) const {
    if (AuroraStatus::handle_ok(h, now, cfg_.tracker.timeout)) return "";
    if (!h.ever_valid && h.last_status == HandlePose::kValid) return "no pose yet";
    if (h.last_status != HandlePose::kValid) return to_string(h.last_status);
    return fmt("no new valid pose for %.2f s", devices::seconds_between(h.last_valid, now));
  }

  /// Whether every device other than the valve board is healthy; *why names the first that is not.
  bool devices_healthy(SteadyTime now, std::string* why) const {
    const AuroraStatus a = tracker_->status();
    if (!a.healthy(now, cfg_.tracker.timeout)) {
      *why = "tracker (NDI Aurora, " + cfg_.tracker.port + "): " + (a.message.empty() ? "not tracking" : a.message);
      return false;
    }
    std::string p = handle_problem(a.tip, now);
    if (!p.empty()) {
      *why = "tip sensor (handle " + hex(cfg_.tracker.tip_handle) + "): " + p;
      return false;
    }
    p = handle_problem(a.base, now);
    if (!p.empty()) {
      *why = "base sensor (handle " + hex(cfg_.tracker.base_handle) + "): " + p;
      return false;
    }
    for (size_t i = 0; i < 3; ++i) {
      p = flow_problem(i, now);
      if (!p.empty()) {
        *why = cfg_.flow[i].name + " (" + cfg_.flow[i].port + "): " + p;
        return false;
      }
    }
    why->clear();
    return true;
  }

  /// Why flow sensor `i` is unhealthy ("" when it is healthy).
  std::string flow_problem(size_t i, SteadyTime now) const {
    const devices::FlowSensorStatus f = flow_[i]->status();
    if (f.healthy(now, cfg_.flow[i].timeout)) return "";
    if (f.state != devices::LinkState::kRunning && f.state != devices::LinkState::kConnecting) return f.message;
    if (f.ever_accepted) return fmt("no valid reading for %.2f s", devices::seconds_between(f.last_accepted, now));
    return std::string("no valid reading yet") + (f.last_error.empty() ? "" : " (" + f.last_error + ")");
  }

  static std::string hex(uint8_t h) {
    char b[8];
    std::snprintf(b, sizeof b, "%02X", h);
    return b;
  }

  // -- diagnostics -----------------------------------------------------------------------------

  void diagnose_tracker(diagnostic_updater::DiagnosticStatusWrapper& s) {
    using diagnostic_msgs::DiagnosticStatus;
    const SteadyTime now = SteadyClock::now();
    const AuroraStatus a = tracker_->status();
    if (a.healthy(now, cfg_.tracker.timeout))
      s.summary(DiagnosticStatus::OK, "tracker (NDI Aurora): tracking");
    else
      s.summary(DiagnosticStatus::ERROR, "tracker (NDI Aurora, " + cfg_.tracker.port + "): " + a.message);
    s.add("port", cfg_.tracker.port);
    s.add("state", devices::to_string(a.state));
    s.add("last_error", a.last_error);
    s.add("connected_by", devices::to_string(a.connected_by));
    s.add("reply_format", a.tx_mode ? "TX (ASCII)" : "BX (binary)");
    s.add("tx_fallbacks", a.tx_fallbacks);
    s.add("frames", a.frames);
    s.add("duplicate_frames", a.duplicate_frames);
    s.add("crc_errors", a.crc_errors);
    s.add("garbage_bytes", a.garbage_bytes);
    s.add("format_errors", a.format_errors);
    s.add("truncated_frames", a.truncated_frames);
    s.add("reply_timeouts", a.reply_timeouts);
    s.add("device_errors", a.device_errors);
    s.add("sessions", a.sessions);
    s.add("connect_failures", a.connect_failures);
    s.add("crc_errors_per_min", crc_rate_.per_minute(now));
    s.add("reply_timeouts_per_min", timeout_rate_.per_minute(now));
    s.add("reconnects_per_min", reconnect_rate_.per_minute(now));
  }

  /// Feeds the per-minute windows from the tracker's cumulative counters (diagnostics timer).
  void track_tracker_rates(SteadyTime now) {
    const AuroraStatus a = tracker_->status();
    crc_rate_.track(now, a.crc_errors);
    timeout_rate_.track(now, a.reply_timeouts);
    // Reconnects: every session after the first, and every failed connection attempt.
    reconnect_rate_.track(now, (a.sessions > 0 ? a.sessions - 1 : 0) + a.connect_failures);
  }

  void diagnose_handle(diagnostic_updater::DiagnosticStatusWrapper& s, bool tip) {
    using diagnostic_msgs::DiagnosticStatus;
    const SteadyTime now = SteadyClock::now();
    const AuroraStatus a = tracker_->status();
    const devices::HandleStats& h = tip ? a.tip : a.base;
    const std::string name = std::string(tip ? "tip" : "base") + " sensor (handle " +
                             hex(tip ? cfg_.tracker.tip_handle : cfg_.tracker.base_handle) + ")";
    const std::string p = handle_problem(h, now);
    if (p.empty())
      s.summary(DiagnosticStatus::OK, name + ": valid");
    else if (!a.healthy(now, cfg_.tracker.timeout))
      s.summary(DiagnosticStatus::ERROR, name + ": no data (tracker not tracking)");
    else
      s.summary(DiagnosticStatus::ERROR, name + ": " + p);
    s.add("status", to_string(h.last_status));
    s.add("rms_error_m", h.last_rms_m);
    s.add("valid", h.valid);
    s.add("missing", h.missing);
    s.add("out_of_volume", h.out_of_volume);
    s.add("disabled", h.disabled);
  }

  void diagnose_flow(diagnostic_updater::DiagnosticStatusWrapper& s, int i) {
    using diagnostic_msgs::DiagnosticStatus;
    const SteadyTime now = SteadyClock::now();
    const devices::FlowSensorStatus f = flow_[i]->status();
    const std::string name = cfg_.flow[i].name + " (" + cfg_.flow[i].port + ")";
    if (f.healthy(now, cfg_.flow[i].timeout))
      s.summary(DiagnosticStatus::OK, name + ": streaming");
    else if (f.state == devices::LinkState::kDisconnected)
      s.summary(DiagnosticStatus::ERROR, name + ": " + f.message);
    else
      s.summary(DiagnosticStatus::ERROR,
                name + ": no valid reading" +
                    (f.ever_accepted ? fmt(" for %.2f s", devices::seconds_between(f.last_accepted, now))
                                     : std::string(" yet")));
    s.add("state", devices::to_string(f.state));
    s.add("last_error", f.last_error);
    s.add("flow_m3_per_s", f.last_flow);
    s.add("lines", f.lines);
    s.add("accepted", f.accepted);
    s.add("rejected", f.rejected);
    s.add("discarded_garbage", f.discarded);
    s.add("connects", f.connects);
  }

  void diagnose_valve_board(diagnostic_updater::DiagnosticStatusWrapper& s) {
    using diagnostic_msgs::DiagnosticStatus;
    const devices::ValveStatus v = valves_->status();
    const std::string name = "valve board (" + cfg_.valves.port + ")";
    if (v.healthy)
      s.summary(DiagnosticStatus::OK, name + ": acknowledging");
    else
      s.summary(DiagnosticStatus::ERROR, name + ": " + v.message);
    s.add("state", devices::to_string(v.state));
    s.add("last_error", v.last_error);
    s.add("acknowledged_duty", fmt("%.4f", v.acknowledged[0]) + ", " + fmt("%.4f", v.acknowledged[1]) + ", " +
                                   fmt("%.4f", v.acknowledged[2]));
    s.add("sent", v.sent);
    s.add("acknowledged", v.acknowledged_count);
    s.add("no_reply", v.no_reply);
    s.add("rejected", v.rejected);
    s.add("hangups", v.hangups);
    s.add("connects", v.connects);
  }

  void diagnose_gate(diagnostic_updater::DiagnosticStatusWrapper& s) {
    using diagnostic_msgs::DiagnosticStatus;
    const devices::ValveStatus v = valves_->status();
    std::string why;
    const bool ok = devices_healthy(SteadyClock::now(), &why);
    if (!v.healthy)
      s.summary(DiagnosticStatus::ERROR, "valves: state unknown, valve board unhealthy");
    else if (!ok)
      s.summary(DiagnosticStatus::ERROR, "valves closed: " + why);
    else if (!v.gate_open)
      s.summary(DiagnosticStatus::WARN, "valves closed: " + v.gate_reason);
    else
      s.summary(DiagnosticStatus::OK, "valves follow jets/command");
    s.add("bad_commands", v.bad_commands);
  }

  const devices::RigOptions cfg_;
  const actuation::Nozzle nozzle_;
  diagnostic_updater::Updater diag_;
  double tracker_min_hz_, tracker_max_hz_, flow_min_hz_, flow_max_hz_, jets_min_hz_, jets_max_hz_, valve_min_hz_,
      valve_max_hz_;
  diagnostic_updater::FrequencyStatus tip_freq_, base_freq_, jets_freq_, valve_freq_;
  std::unique_ptr<diagnostic_updater::FrequencyStatus> flow_freq_[3];
  devices::FlowAggregator flows_;

  ros::Publisher tip_pub_, base_pub_, tip_rms_pub_, base_rms_pub_, tip_frame_pub_, jet_pub_;
  ros::Time last_tracker_stamp_;                                   ///< written by the tracker thread only
  devices::RateCounter crc_rate_, timeout_rate_, reconnect_rate_;  ///< diagnostics timer only
  ros::Subscriber cmd_sub_;
  ros::WallTimer jets_timer_, diag_timer_;
  tf2_ros::TransformBroadcaster tf_;
  std::string last_signature_;
  bool ever_healthy_ = false;

  std::unique_ptr<devices::AuroraClient> tracker_;
  std::unique_ptr<devices::FlowSensor> flow_[3];
  std::unique_ptr<devices::ValveLoop> valves_;
};

}  // namespace
}  // namespace hydrojet

int main(int argc, char** argv) {
  ros::init(argc, argv, "rig", ros::init_options::NoSigintHandler);
  hydrojet::ros_bridge::install_shutdown_signals();
  ros::NodeHandle nh, pnh("~");
  try {
    hydrojet::RigNode node(nh, pnh);
    hydrojet::ros_bridge::spin_until_signal();
    if (hydrojet::ros_bridge::shutdown_signal() != 0)
      ROS_INFO("rig: signal %d: closing the valves", hydrojet::ros_bridge::shutdown_signal());
  }  // ~RigNode: valves closed (duty 0 acknowledged by the board, or the port closed), TSTOP
  catch (const std::exception& e) {
    // Bad configuration: refuse to start, naming the key.
    ROS_FATAL("rig: refusing to start: %s", e.what());
    std::cerr << "rig: refusing to start: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
