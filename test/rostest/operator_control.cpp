// Operator control on the simulated plant in lockstep, one behaviour per .test file,
// selected by ~scenario. The controller starts with path/type none (holding) and autostart:
//   target_direction  0.4 rad away: error ≤ 0.02 rad within 0.4 / max_angular_rate + 3 s, then RMS
//                     ≤ 0.015 rad over 5 s of hold
//   look_at           a point 60 mm beyond the tip: the true tip axis passes within 3 mm of it
//   joy               deadman + axis moves the view the commanded way in the camera frame; release
//                     and timeout hold (drift ≤ 0.02 rad over 3 s)
//   follow_path       (autostart false) the first goal starts the idle controller; waypoints complete
//                     with RMS ≤ 0.02 rad; a second goal preempts; cancel holds
//   clipped           a target outside the reachable set is clipped, status says so, no abort
//   rejected          NaN, zero and unknown-frame targets: rejected, counted, nothing moves, no abort
//   reload_scene      controller/reload_scene: refused while running or for a bad file; stopped, the
//                     new scene's reachable set is published
// Times are simulated (the plant owns /clock); wall-clock limits only guard against hangs.
#include <actionlib/client/simple_action_client.h>
#include <geometry_msgs/PointStamped.h>
#include <geometry_msgs/Vector3Stamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/Joy.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>

#include <std_srvs/Trigger.h>

#include "hydrojet_control/ControllerStatus.h"
#include "hydrojet_control/FollowPathAction.h"
#include "hydrojet_control/ReachableSet.h"
#include "hydrojet_control/RodState.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;
using Eigen::Vector3d;

namespace {

Vector3d vec(const geometry_msgs::Vector3& v) { return Vector3d(v.x, v.y, v.z); }
double angle(const Vector3d& a, const Vector3d& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }
geometry_msgs::Vector3 msg(const Vector3d& v) {
  geometry_msgs::Vector3 m;
  m.x = v.x(), m.y = v.y(), m.z = v.z();
  return m;
}

/// The controller's status and the plant's true rod, as they arrive.
class Graph {
 public:
  Graph() {
    status_sub_ = nh_.subscribe<hydrojet_control::ControllerStatus>(
        names::kControllerStatus, 1000, [this](const hydrojet_control::ControllerStatus::ConstPtr& m) {
          status.push_back(*m);
          if (m->state == "aborted" && abort_reason.empty()) abort_reason = m->reason.empty() ? "?" : m->reason;
        });
    rod_sub_ = nh_.subscribe<hydrojet_control::RodState>(
        names::kPlantRodState, 10, [this](const hydrojet_control::RodState::ConstPtr& m) { rod = *m; });
    target_pub_ = nh_.advertise<geometry_msgs::Vector3Stamped>(names::kTargetDirection, 10);
    look_at_pub_ = nh_.advertise<geometry_msgs::PointStamped>(names::kLookAt, 10);
    joy_pub_ = nh_.advertise<sensor_msgs::Joy>(names::kJoy, 10);
  }

  /// Spins until the simulated time passes t [s] (or `until` holds); false on the wall-clock limit.
  bool wait_until(double t, const std::function<bool()>& until = nullptr, double wall_limit = 120.0) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(wall_limit);
    while (ros::ok() && ros::WallTime::now() < end) {
      ros::spinOnce();
      if (ros::Time::now().toSec() >= t || (until && until())) return true;
      ros::WallDuration(0.0005).sleep();
    }
    return false;
  }
  double now() const { return ros::Time::now().toSec(); }

  /// Waits for the controller to run for `settle` s of simulated time, the subscriptions connected.
  void settle(double settle = 2.0) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(60.0);
    while (ros::ok() && ros::WallTime::now() < end &&
           (status.empty() || status.back().state != "running" || status.back().path_time < settle ||
            target_pub_.getNumSubscribers() == 0 || joy_pub_.getNumSubscribers() == 0 || rod.backbone.empty())) {
      ros::spinOnce();
      ros::WallDuration(0.001).sleep();
    }
    ASSERT_FALSE(status.empty()) << "no controller status";
    ASSERT_EQ(status.back().state, "running") << status.back().reason;
    ASSERT_FALSE(rod.backbone.empty()) << "no plant/rod_state";
  }

  /// The controller idle (autostart false, as `sim.launch autostart:=false` starts it), the plant and the
  /// action server up, and 2 s of idle cycles: the controller has heard the tracker and the jets.
  template <class Client>
  void settle_idle(Client& client) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(60.0);
    while (ros::ok() && ros::WallTime::now() < end &&
           (status.empty() || rod.backbone.empty() || !client.isServerConnected())) {
      ros::spinOnce();
      ros::WallDuration(0.001).sleep();
    }
    ASSERT_FALSE(status.empty()) << "no controller status";
    ASSERT_FALSE(rod.backbone.empty()) << "no plant/rod_state";
    ASSERT_TRUE(client.isServerConnected()) << "no follow_path server";
    ASSERT_TRUE(wait_until(now() + 2.0));
    ASSERT_EQ(status.back().state, "idle") << "autostart false: nothing runs before the first goal";
  }

  /// Mean measured direction over the statuses stamped in [t0, t1] (the tracker's noise averaged).
  Vector3d mean_measured(double t0, double t1) const {
    Vector3d sum = Vector3d::Zero();
    for (const auto& s : status)
      if (s.header.stamp.toSec() >= t0 && s.header.stamp.toSec() <= t1) sum += vec(s.measured_direction);
    return sum.normalized();
  }
  const hydrojet_control::ControllerStatus& last() const { return status.back(); }

  void send_target(const Vector3d& d, const std::string& frame = "base") {
    geometry_msgs::Vector3Stamped m;
    m.header.frame_id = frame;
    m.vector = msg(d);
    target_pub_.publish(m);
  }
  void send_look_at(const Vector3d& p) {
    geometry_msgs::PointStamped m;
    m.header.frame_id = "base";
    m.point.x = p.x(), m.point.y = p.y(), m.point.z = p.z();
    look_at_pub_.publish(m);
  }
  /// Joy messages every 0.05 s of simulated time until t_end: axes as given, the deadman as given.
  void send_joy_until(double t_end, float up, float right, bool deadman) {
    ros::NodeHandle pnh("/controller/teleop");
    int axis_up = 1, axis_right = 0, button = 4;
    pnh.getParam("axis_up", axis_up), pnh.getParam("axis_right", axis_right), pnh.getParam("deadman_button", button);
    sensor_msgs::Joy j;
    j.axes.assign(std::max(axis_up, axis_right) + 1, 0.0f);
    j.buttons.assign(button + 1, 0);
    j.axes[axis_up] = up, j.axes[axis_right] = right, j.buttons[button] = deadman ? 1 : 0;
    while (ros::ok() && now() < t_end) {
      j.header.stamp = ros::Time::now();
      joy_pub_.publish(j);
      if (!wait_until(std::min(t_end, now() + 0.05))) break;
    }
  }

  std::vector<hydrojet_control::ControllerStatus> status;
  hydrojet_control::RodState rod;
  std::string abort_reason;

 private:
  ros::NodeHandle nh_;
  ros::Subscriber status_sub_, rod_sub_;
  ros::Publisher target_pub_, look_at_pub_, joy_pub_;
};

double max_angular_rate() {
  double rate = 0.0;
  EXPECT_TRUE(ros::param::get("/controller/limits/max_angular_rate", rate));
  return rate;
}

Eigen::Matrix3d tip_rotation(const hydrojet_control::RodState& rod) {
  const auto& q = rod.tip_pose.orientation;
  return Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
}

/// A direction `by` rad from d, toward the base +x side (or +y when d is along x).
Vector3d tilted(const Vector3d& d, double by) {
  Vector3d axis = d.cross(Vector3d::UnitX()).cross(d);
  if (axis.norm() < 1e-3) axis = Vector3d::UnitY();
  return Eigen::AngleAxisd(by, d.cross(axis).normalized()) * d;
}

/// The tip, held from simulated time t [s] on `held`: it settles on it (mean over the last 0.3 s of
/// 3 s within 0.02 rad) and does not wander once settled (≤ 0.02 rad from 1 s to 3 s). The first
/// second is the loop's settling, 3/K_p: a hold that begins while the tip still lags a reference that
/// moved finishes that motion first (≈ v/K_p, 0.015 rad at 0.1 rad/s), which is not drift.
void expect_settles_and_holds(Graph& g, const Vector3d& held, double t) {
  ASSERT_TRUE(g.wait_until(t + 3.0));
  const double error = angle(held, g.mean_measured(t + 2.7, t + 3.0));
  const double drift = angle(g.mean_measured(t + 1.0, t + 1.3), g.mean_measured(t + 2.7, t + 3.0));
  std::printf("held from %.2f s: error %.4f rad after 3 s, drift %.4f rad from 1 s to 3 s\n", t, error, drift);
  EXPECT_LE(error, 0.02) << "error";
  EXPECT_LE(drift, 0.02) << "drift";
}

/// From simulated time t [s] on the source is hold: the reference stays put and the tip settles on
/// it and holds (expect_settles_and_holds).
void expect_holds_from(Graph& g, double t) {
  ASSERT_TRUE(g.wait_until(t));
  EXPECT_EQ(g.last().source, "hold");
  const Vector3d held = vec(g.last().desired_direction);
  expect_settles_and_holds(g, held, t);
  EXPECT_LE(angle(held, vec(g.last().desired_direction)), 1e-9);
}

}  // namespace

// 1: error ≤ 0.02 rad within 0.4 / max_angular_rate + 3 s, then RMS ≤ 0.015 rad over 5 s of hold.
void target_direction(Graph& g) {
  const double t0 = g.now();
  const Vector3d target = tilted(g.mean_measured(t0 - 0.5, t0), 0.4);
  g.send_target(2.0 * target);  // not unit: normalised
  const double deadline = t0 + 0.4 / max_angular_rate() + 3.0;
  ASSERT_TRUE(g.wait_until(deadline + 5.0));
  double reached = -1.0, sum2 = 0.0;
  int n = 0;
  for (const auto& s : g.status) {
    const double t = s.header.stamp.toSec(), e = angle(target, vec(s.measured_direction));
    if (t < t0) continue;
    if (reached < 0 && e <= 0.02) reached = t;
    if (t > deadline && t <= deadline + 5.0) sum2 += e * e, ++n;
  }
  ASSERT_GE(reached, 0.0) << "never within 0.02 rad";
  EXPECT_LE(reached, deadline) << "reached after " << reached - t0 << " s";
  ASSERT_GT(n, 100);
  const double rms = std::sqrt(sum2 / n);
  EXPECT_LE(rms, 0.015);
  EXPECT_EQ(g.last().source, "direction");
  std::printf("target_direction: within 0.02 rad after %.2f s (limit %.2f s), hold RMS %.4f rad\n", reached - t0,
              deadline - t0, rms);
}

// 2: the true tip axis passes within 3 mm of a point 60 mm beyond the tip.
void look_at(Graph& g) {
  const Vector3d tip(g.rod.tip_pose.position.x, g.rod.tip_pose.position.y, g.rod.tip_pose.position.z);
  const Vector3d point = tip + 0.06 * tilted(tip_rotation(g.rod).col(2), 0.3);
  g.send_look_at(point);
  ASSERT_TRUE(g.wait_until(g.now() + 12.0));
  // Mean over the last second of the true tip's line distance to the point (the plant's noise averaged).
  double sum = 0.0;
  int n = 0;
  const double t_end = g.now();
  while (g.now() < t_end + 1.0 && g.wait_until(g.now() + 0.02)) {
    const Vector3d p(g.rod.tip_pose.position.x, g.rod.tip_pose.position.y, g.rod.tip_pose.position.z);
    const Vector3d d = tip_rotation(g.rod).col(2), r = point - p;
    sum += (r - r.dot(d) * d).norm(), ++n;
  }
  ASSERT_GT(n, 10);
  EXPECT_LE(sum / n, 0.003) << "the tip axis misses the point by " << 1e3 * sum / n << " mm";
  EXPECT_EQ(g.last().source, "look_at");
  std::printf("look_at: the true tip axis misses the point by %.2f mm\n", 1e3 * sum / n);
}

// 3: deadman + axis moves the view the commanded way in the camera frame; release and timeout hold.
void joy(Graph& g) {
  for (int stick = 0; stick < 2; ++stick) {  // 0: stick up (view up), 1: stick right (view right)
    const double t0 = g.now();
    const Eigen::Matrix3d tip = tip_rotation(g.rod);
    const Vector3d before = g.mean_measured(t0 - 0.3, t0);
    g.send_joy_until(t0 + 2.0, stick == 0 ? 1.0f : 0.0f, stick == 1 ? -1.0f : 0.0f, true);
    EXPECT_EQ(g.last().source, "joy");
    g.send_joy_until(g.now() + 1.0, 0.0f, 0.0f, false);  // deadman released: hold
    const double t1 = g.now();
    const Vector3d moved = g.mean_measured(t1 - 0.3, t1) - before;
    // View up: the tip z-axis turns toward the tip's −y; view right: toward its +x.
    const Vector3d wanted = stick == 0 ? Vector3d(-tip.col(1)) : Vector3d(tip.col(0));
    const Vector3d across = stick == 0 ? Vector3d(tip.col(0)) : Vector3d(tip.col(1));
    EXPECT_GT(moved.dot(wanted), 0.1) << "stick " << stick;  // 0.1 rad/s × 2 s = 0.2 rad commanded
    EXPECT_LT(std::abs(moved.dot(across)), 0.05) << "stick " << stick;
    EXPECT_EQ(g.last().source, "hold");
    expect_settles_and_holds(g, vec(g.last().desired_direction), t1);
  }
  // Timeout: deadman and axis, then no message at all; the target holds 0.5 s later.
  g.send_joy_until(g.now() + 1.0, 1.0f, 0.0f, true);
  expect_holds_from(g, g.now() + 0.5 + 0.1);
}

// 4: waypoints complete with RMS ≤ 0.02 rad; a path that begins elsewhere is approached first; a second
// goal preempts the first; cancel holds.
void follow_path(Graph& g) {
  using Client = actionlib::SimpleActionClient<hydrojet_control::FollowPathAction>;
  Client first(names::kFollowPathAction, false), second(names::kFollowPathAction, false);
  // The very first goal reaches an idle controller: it starts it, and its first cycle is the path's.
  g.settle_idle(first);
  if (::testing::Test::HasFatalFailure()) return;
  ASSERT_TRUE(g.wait_until(g.now() + 10.0, [&] { return second.isServerConnected(); })) << "no follow_path server";
  const double t0 = g.now();
  const Vector3d start = tip_rotation(g.rod).col(2);  // the rest direction (an idle status measures nothing)
  hydrojet_control::FollowPathGoal goal;
  goal.type = "waypoints";
  goal.times = {0.0, 6.0, 12.0};
  goal.directions = {msg(start), msg(tilted(start, 0.3)), msg(Eigen::AngleAxisd(0.6, start) * tilted(start, 0.3))};
  int feedback = 0;
  first.sendGoal(goal, Client::SimpleDoneCallback(), Client::SimpleActiveCallback(),
                 [&](const hydrojet_control::FollowPathFeedbackConstPtr&) { ++feedback; });
  ASSERT_TRUE(g.wait_until(t0 + 30.0, [&] { return first.getState().isDone(); }));
  ASSERT_EQ(first.getState(), actionlib::SimpleClientGoalState::SUCCEEDED) << first.getState().getText();
  const auto result = first.getResult();
  EXPECT_TRUE(result->completed) << result->reason;
  EXPECT_LE(result->rms_error, 0.02);
  EXPECT_GE(feedback, 5 * 12 - 5) << "feedback below 5 Hz";
  bool started = false;  // the goal started the controller on its path
  for (const auto& st : g.status)
    started |= st.header.stamp.toSec() >= t0 && st.state == "running" && st.source == "path";
  EXPECT_TRUE(started) << "no status running on the path after the first goal";
  std::printf("follow_path: waypoints RMS %.4f rad, max %.4f rad, %d feedbacks\n", result->rms_error, result->max_error,
              feedback);

  // A path that begins 0.3 rad away: approached first (feedback `approaching`, path_time 0), its clock
  // started once the tip has settled there, its error counted from then.
  const Vector3d here = g.mean_measured(g.now() - 0.3, g.now());
  const Vector3d begin = tilted(here, 0.3);
  hydrojet_control::FollowPathGoal away;
  away.type = "waypoints";
  away.times = {0.0, 6.0};
  away.directions = {msg(begin), msg(Eigen::AngleAxisd(0.4, here) * begin)};
  std::vector<hydrojet_control::FollowPathFeedback> fb;
  first.sendGoal(away, Client::SimpleDoneCallback(), Client::SimpleActiveCallback(),
                 [&](const hydrojet_control::FollowPathFeedbackConstPtr& f) { fb.push_back(*f); });
  ASSERT_TRUE(g.wait_until(g.now() + 30.0, [&] { return first.getState().isDone(); }));
  ASSERT_EQ(first.getState(), actionlib::SimpleClientGoalState::SUCCEEDED) << first.getState().getText();
  const auto approached = first.getResult();
  ASSERT_FALSE(fb.empty());
  EXPECT_TRUE(fb.front().approaching);
  size_t k = 0;
  for (; k < fb.size() && fb[k].approaching; ++k) EXPECT_EQ(fb[k].path_time, 0.0) << k;
  ASSERT_LT(k, fb.size()) << "the clock never started";
  EXPECT_LT(fb[k].error, 0.04) << "the clock started before the tip had settled";
  for (; k < fb.size(); ++k) EXPECT_FALSE(fb[k].approaching) << k;
  // The way there at ≤ 0.25 rad/s (max_angular_rate), then at least the 0.3 s window.
  EXPECT_GE(approached->approach_time, 0.3 / 0.25 + 0.3 - 0.05);
  EXPECT_LE(approached->approach_time, 0.3 / 0.25 + 5.0);
  EXPECT_LE(approached->rms_error, 0.02);  // the 0.3 rad of the approach are not in it
  std::printf("follow_path: approached in %.2f s, then RMS %.4f rad\n", approached->approach_time,
              approached->rms_error);

  // A second goal preempts the running one.
  goal.times = {0.0, 20.0, 40.0};
  first.sendGoal(goal);
  ASSERT_TRUE(g.wait_until(g.now() + 2.0));
  second.sendGoal(goal);
  ASSERT_TRUE(g.wait_until(g.now() + 5.0, [&] { return first.getState().isDone(); }));
  EXPECT_EQ(first.getState(), actionlib::SimpleClientGoalState::PREEMPTED) << first.getState().getText();
  ASSERT_TRUE(g.wait_until(g.now() + 2.0));
  EXPECT_EQ(second.getState(), actionlib::SimpleClientGoalState::ACTIVE);
  EXPECT_EQ(g.last().source, "path");

  // Cancel holds the current direction.
  second.cancelGoal();
  ASSERT_TRUE(g.wait_until(g.now() + 5.0, [&] { return second.getState().isDone(); }));
  EXPECT_EQ(second.getState(), actionlib::SimpleClientGoalState::PREEMPTED) << second.getState().getText();
  expect_holds_from(g, g.now() + 0.1);
}

// 5: a target outside the reachable set is clipped, the status says so, no abort; a look-at point the
// jets cannot aim at gives the closest aim, clipped as well, and the message says so.
void clipped(Graph& g) {
  const Vector3d impossible(std::sin(2.0) * std::cos(0.5), std::sin(2.0) * std::sin(0.5), std::cos(2.0));  // ϑ = 2 rad
  g.send_target(impossible);
  ASSERT_TRUE(g.wait_until(g.now() + 20.0));
  const auto& s = g.last();
  EXPECT_EQ(s.state, "running") << s.reason;
  EXPECT_EQ(s.source, "direction");
  EXPECT_TRUE(s.clipped);
  EXPECT_GT(s.clip_angle, 0.3);
  EXPECT_NEAR(angle(impossible, vec(s.desired_direction)), s.clip_angle, 1e-6);
  std::printf("clipped: moved by %.3f rad, error %.4f rad\n", s.clip_angle, s.error_geodesic);

  g.send_target(Vector3d::UnitZ());  // back to straight, then look at a point 1 m away, 100° to the side
  ASSERT_TRUE(g.wait_until(g.now() + 10.0));
  const uint32_t rejected = g.last().rejected_targets;
  const Vector3d tip(g.rod.tip_pose.position.x, g.rod.tip_pose.position.y, g.rod.tip_pose.position.z);
  g.send_look_at(tip + Vector3d(std::sin(1.75), 0.0, std::cos(1.75)));
  ASSERT_TRUE(g.wait_until(g.now() + 15.0));
  const auto& l = g.last();
  EXPECT_EQ(l.state, "running") << l.reason;
  EXPECT_EQ(l.source, "look_at");
  EXPECT_EQ(l.rejected_targets, rejected);
  EXPECT_NE(l.message.find("out of the jets' reach"), std::string::npos) << l.message;
  EXPECT_GT(angle(Vector3d::UnitZ(), vec(l.desired_direction)), 0.5) << "turned towards the point";
  EXPECT_LT(l.error_geodesic, 0.05);
  std::printf("clipped look_at: aims %.3f rad from straight (%s), error %.4f rad\n",
              angle(Vector3d::UnitZ(), vec(l.desired_direction)), l.clipped ? "clipped" : "not clipped",
              l.error_geodesic);
}

// 6: NaN, zero and unknown-frame targets are rejected and counted; nothing moves, no abort.
void rejected(Graph& g) {
  const Vector3d before = vec(g.last().desired_direction);
  const uint32_t count = g.last().rejected_targets;
  const struct {
    Vector3d v;
    const char* frame;
    const char* why;
  } bad[] = {{Vector3d(std::nan(""), 0, 1), "base", "not finite"},
             {Vector3d::Zero(), "base", "zero"},
             {Vector3d(0.3, 0, 1), "nowhere", "unknown frame 'nowhere'"}};
  for (const auto& b : bad) {
    g.send_target(b.v, b.frame);
    const uint32_t want = count + (&b - bad) + 1;
    ASSERT_TRUE(g.wait_until(g.now() + 5.0, [&] { return g.last().rejected_targets >= want; }));
    ASSERT_TRUE(g.wait_until(g.now() + 0.1));
    EXPECT_EQ(g.last().rejected_targets, want);
    EXPECT_NE(g.last().message.find(b.why), std::string::npos) << g.last().message;
  }
  ASSERT_TRUE(g.wait_until(g.now() + 2.0));
  EXPECT_EQ(g.last().source, "hold");
  EXPECT_LE(angle(before, vec(g.last().desired_direction)), 1e-9);
  EXPECT_EQ(g.last().state, "running");
}

/// Calls a std_srvs/Trigger service; its response (success false and the reason if the call failed).
std_srvs::Trigger::Response trigger(const std::string& name) {
  std_srvs::Trigger t;
  if (!ros::service::call(name, t)) t.response.message = "the call of " + name + " failed";
  return t.response;
}

// 7: a new scene: controller/reload_scene is refused while running and for a scene that does not
// load; stopped, it loads ~scene again and publishes the new scene's reachable set.
void reload_scene(Graph& g) {
  ros::NodeHandle nh;
  std::vector<hydrojet_control::ReachableSet> sets;
  ros::Subscriber sub = nh.subscribe<hydrojet_control::ReachableSet>(
      names::kReachableSet, 10, [&](const hydrojet_control::ReachableSet::ConstPtr& m) { sets.push_back(*m); });
  ASSERT_TRUE(g.wait_until(g.now() + 30.0, [&] { return !sets.empty(); }));
  const std::string service = names::kReloadSceneService;
  std_srvs::Trigger::Response r = trigger(service);
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("running"), std::string::npos) << r.message;
  ASSERT_TRUE(trigger(names::kStopService).success);
  std::string other;
  ASSERT_TRUE(ros::param::get("~other_scene", other));
  ros::param::set("/controller/scene", "/nonexistent/scene.yaml");
  r = trigger(service);
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("/nonexistent/scene.yaml"), std::string::npos) << r.message;
  ros::param::set("/controller/scene", other);
  r = trigger(service);
  EXPECT_TRUE(r.success) << r.message;
  ASSERT_TRUE(g.wait_until(g.now() + 30.0, [&] { return sets.size() >= 2; })) << "no new reachable set";
  // The new scene's set is centred on its own jets-off direction (the 30° base tilt moves it).
  EXPECT_GT(angle(vec(sets.front().center), vec(sets.back().center)), 0.05);
  ASSERT_TRUE(trigger(names::kStartService).success);
  ASSERT_TRUE(g.wait_until(g.now() + 2.0));
  EXPECT_EQ(g.last().state, "running") << g.last().reason;
  std::printf("reload_scene: the set's centre moved by %.3f rad\n",
              angle(vec(sets.front().center), vec(sets.back().center)));
}

TEST(OperatorControl, Scenario) {
  ros::NodeHandle pnh("~");
  std::string scenario;
  pnh.param<std::string>("scenario", scenario, "");
  Graph g;
  if (scenario != "follow_path") g.settle();  // follow_path: the controller idles until its first goal
  if (HasFatalFailure()) return;
  if (scenario == "target_direction")
    target_direction(g);
  else if (scenario == "look_at")
    look_at(g);
  else if (scenario == "joy")
    joy(g);
  else if (scenario == "follow_path")
    follow_path(g);
  else if (scenario == "clipped")
    clipped(g);
  else if (scenario == "rejected")
    rejected(g);
  else if (scenario == "reload_scene")
    reload_scene(g);
  else
    FAIL() << "unknown ~scenario '" << scenario << "'";
  EXPECT_EQ(g.abort_reason, "") << "the controller aborted";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "operator_control_test");
  return RUN_ALL_TESTS();
}
