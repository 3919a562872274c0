// The full node graph on the simulated plant (lockstep, simulated time), one scenario per .test
// file, selected by ~scenario:
//   closed_loop       shortened spiral: completes without abort, RMS error below ~rms_bound
//   tracker_dropout   1 s tracker dropout: jets at zero within 3 sample periods, no restart
//   flow_fault        NaN / negative flow readings: rejected, aborted, reported on diagnostics
//   stuck_jet         a valve stuck open: detected from flow feedback, path aborted
//   wall              a wall across the spiral (~wall_point, ~wall_normal, ~wall_stiffness): each
//                     contact the truth shows (plant/rod_state against the wall) is flagged on
//                     controller/contact within 0.6 s, none before, and the wall is not pressed
//                     harder than contact/max_force allows once it is
//   keep_out          the same wall, and the same plane set as a keep-out region through
//                     controller/set_keep_out (a broken one refused first, naming the key): the truth
//                     never touches the wall, and controller/keep_out carries the region
#include <geometry_msgs/WrenchStamped.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <algorithm>
#include <cmath>

#include "hydrojet_control/Contact.h"
#include "hydrojet_control/ControllerStatus.h"
#include "hydrojet_control/Environment.h"
#include "hydrojet_control/JetCommand.h"
#include "hydrojet_control/KeepOut.h"
#include "hydrojet_control/SetKeepOut.h"
#include "hydrojet_control/RodState.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

namespace {

struct Log {
  std::vector<hydrojet_control::ControllerStatus> status;
  std::vector<hydrojet_control::JetCommand> commands;
  double last_tracker = -1.0;  ///< sim time of the last tracker sample before the dropout
  double dropout_from = -1.0;  ///< first gap > 1.5 sample periods in the tracker stream
  std::vector<std::string> diag_errors;
  std::vector<hydrojet_control::Contact> contact;
  std::vector<geometry_msgs::WrenchStamped> external_force;
  std::vector<std::pair<double, geometry_msgs::Point>> truth_tip;  ///< (stamp, the plant's true tip [m], base)
  std::vector<hydrojet_control::KeepOut> keep_out;
  std::vector<hydrojet_control::Environment> environment;
  double max_true_force = 0.0;  ///< the largest |external force| plant/rod_state carried [N]
};

bool zero(const hydrojet_control::JetCommand& c) {
  return c.valve_command.size() == 3 && c.valve_command[0] == 0.0 && c.valve_command[1] == 0.0 &&
         c.valve_command[2] == 0.0;
}

/// Spins until the controller reports finished/aborted (or the wall-clock limit).
void run(Log& log, double wall_limit) {
  ros::NodeHandle nh;
  ros::Subscriber s1 = nh.subscribe<hydrojet_control::ControllerStatus>(
      names::kControllerStatus, 10000,
      [&](const hydrojet_control::ControllerStatus::ConstPtr& m) { log.status.push_back(*m); });
  ros::Subscriber s2 = nh.subscribe<hydrojet_control::JetCommand>(
      names::kJetCommand, 10000, [&](const hydrojet_control::JetCommand::ConstPtr& m) { log.commands.push_back(*m); });
  ros::Subscriber s3 = nh.subscribe<geometry_msgs::PoseStamped>(
      names::kTipPose, 10000, [&](const geometry_msgs::PoseStamped::ConstPtr& m) {
        const double t = m->header.stamp.toSec();
        if (log.dropout_from < 0 && log.last_tracker >= 0 && t - log.last_tracker > 0.015)
          log.dropout_from = log.last_tracker;
        log.last_tracker = t;
      });
  ros::Subscriber s4 = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      names::kDiagnostics, 1000, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
        for (const auto& s : m->status)
          if (s.level == diagnostic_msgs::DiagnosticStatus::ERROR) log.diag_errors.push_back(s.message);
      });
  ros::Subscriber s5 = nh.subscribe<hydrojet_control::Contact>(
      names::kContact, 10000, [&](const hydrojet_control::Contact::ConstPtr& m) { log.contact.push_back(*m); });
  ros::Subscriber s6 = nh.subscribe<geometry_msgs::WrenchStamped>(
      names::kExternalForce, 10000,
      [&](const geometry_msgs::WrenchStamped::ConstPtr& m) { log.external_force.push_back(*m); });
  ros::Subscriber s7 = nh.subscribe<hydrojet_control::RodState>(
      names::kPlantRodState, 10000, [&](const hydrojet_control::RodState::ConstPtr& m) {
        log.truth_tip.emplace_back(m->header.stamp.toSec(), m->tip_pose.position);
        log.max_true_force = std::max(
            log.max_true_force, std::hypot(std::hypot(m->external_force.x, m->external_force.y), m->external_force.z));
      });
  ros::Subscriber s9 = nh.subscribe<hydrojet_control::Environment>(
      names::kPlantEnvironment, 10,
      [&](const hydrojet_control::Environment::ConstPtr& m) { log.environment.push_back(*m); });
  ros::Subscriber s8 = nh.subscribe<hydrojet_control::KeepOut>(
      names::kKeepOut, 10, [&](const hydrojet_control::KeepOut::ConstPtr& m) { log.keep_out.push_back(*m); });
  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(wall_limit);
  while (ros::ok() && ros::WallTime::now() < until) {
    ros::spinOnce();
    ros::WallDuration(0.001).sleep();
    if (!log.status.empty() && (log.status.back().state == "finished" || log.status.back().state == "aborted")) {
      // keep listening a little longer (simulated time keeps running) to see what follows
      const ros::WallTime more = ros::WallTime::now() + ros::WallDuration(2.0);
      while (ros::ok() && ros::WallTime::now() < more) {
        ros::spinOnce();
        ros::WallDuration(0.001).sleep();
      }
      break;
    }
  }
}

const hydrojet_control::ControllerStatus* first_abort(const Log& log) {
  for (const auto& s : log.status)
    if (s.state == "aborted") return &s;
  return nullptr;
}

/// The wall scenario's checks: the truth is the plant's tip against the wall the test is given (the
/// static penalty force k δ of the capsule's sphere), independent of the controller's estimate.
void check_wall(const Log& log, ros::NodeHandle& pnh) {
  std::vector<double> point, normal;
  double stiffness = 0.0, radius = 0.0;
  ASSERT_TRUE(pnh.getParam("wall_point", point) && point.size() == 3);
  ASSERT_TRUE(pnh.getParam("wall_normal", normal) && normal.size() == 3);
  ASSERT_TRUE(pnh.getParam("wall_stiffness", stiffness) && pnh.getParam("tip_radius", radius));
  const auto* ab = first_abort(log);
  ASSERT_EQ(ab, nullptr) << "aborted at " << ab->path_time << " s: " << ab->reason;
  ASSERT_GT(log.truth_tip.size(), 100u) << "no plant/rod_state";
  ASSERT_GT(log.contact.size(), 100u) << "no controller/contact";
  ASSERT_GT(log.external_force.size(), 100u) << "no controller/external_force";
  EXPECT_EQ(log.external_force.back().header.frame_id, "base");
  auto force_at = [&](const geometry_msgs::Point& p) {
    const double d = (p.x - point[0]) * normal[0] + (p.y - point[1]) * normal[1] + (p.z - point[2]) * normal[2];
    return std::max(0.0, stiffness * (radius - d));
  };
  auto flagged_at = [&](double t) {  // the detector's flag at or before t
    bool flag = false;
    for (const auto& c : log.contact)
      if (c.header.stamp.toSec() <= t) flag = c.in_contact;
    return flag;
  };
  // Onsets as the experiment counts them: the true force past 20 mN after 0.5 s with none.
  std::vector<double> onsets;
  double quiet_since = log.truth_tip.front().first;
  bool armed = true;
  for (const auto& [t, p] : log.truth_tip) {
    const double f = force_at(p);
    if (f > 0.0) {
      if (armed && f > 0.02) onsets.push_back(t), armed = false;
      quiet_since = t;
    } else if (t - quiet_since >= 0.5) {
      armed = true;
    }
  }
  ASSERT_FALSE(onsets.empty()) << "the spiral never reached the wall";
  EXPECT_GT(log.max_true_force, 0.02) << "plant/rod_state carried no external force while the tip met the wall";
  for (const double onset : onsets) {
    double flagged = -1.0;
    for (const auto& c : log.contact)
      if (c.in_contact && c.header.stamp.toSec() >= onset - 0.5) {
        flagged = c.header.stamp.toSec();
        break;
      }
    EXPECT_GE(flagged, 0.0) << "the contact at " << onset << " s was never flagged";
    EXPECT_LE(flagged - onset, 0.6) << "the contact at " << onset << " s was flagged at " << flagged << " s";
  }
  // No flag before the first contact; once flagged (0.3 s on), the wall is pressed with at most
  // contact/max_force (0.04 N) and the 10 mN its damping and the estimate's lag add.
  double first_flag = -1.0, worst = 0.0;
  for (const auto& c : log.contact)
    if (c.in_contact) {
      first_flag = c.header.stamp.toSec();
      break;
    }
  if (first_flag >= 0.0) {
    EXPECT_GE(first_flag, onsets.front() - 0.5) << "flagged before the tip reached the wall";
  }
  for (const auto& [t, p] : log.truth_tip)
    if (flagged_at(t - 0.3) && flagged_at(t)) worst = std::max(worst, force_at(p));
  EXPECT_LE(worst, 0.05);
  std::printf("wall: %zu onsets, first flagged %.2f s after it, force after detection at most %.3f N\n", onsets.size(),
              first_flag - onsets.front(), worst);
}

/// The wall of ~wall_point, ~wall_normal as a keep-out region with `margin`.
hydrojet_control::KeepOutRegion wall_region(ros::NodeHandle& pnh, double margin) {
  std::vector<double> point, normal;
  pnh.getParam("wall_point", point);
  pnh.getParam("wall_normal", normal);
  hydrojet_control::KeepOutRegion r;
  r.surface.type = "plane";
  if (point.size() == 3) r.surface.point.x = point[0], r.surface.point.y = point[1], r.surface.point.z = point[2];
  if (normal.size() == 3)
    r.surface.normal.x = normal[0], r.surface.normal.y = normal[1], r.surface.normal.z = normal[2];
  r.margin = margin;
  return r;
}

/// Sets the keep-out region through the service before the run: a broken region first (refused,
/// naming the key), then the wall with a 2 mm margin.
void set_keep_out(ros::NodeHandle& pnh) {
  ASSERT_TRUE(ros::service::waitForService(names::kSetKeepOutService, ros::Duration(60.0)));
  hydrojet_control::SetKeepOut bad;
  bad.request.regions.push_back(wall_region(pnh, 0.002));
  bad.request.regions.back().surface.normal = geometry_msgs::Vector3();
  ASSERT_TRUE(ros::service::call(names::kSetKeepOutService, bad));
  EXPECT_FALSE(bad.response.success);
  EXPECT_NE(bad.response.message.find("keep_out[0]/normal"), std::string::npos) << bad.response.message;
  hydrojet_control::SetKeepOut good;
  good.request.regions.push_back(wall_region(pnh, 0.002));
  ASSERT_TRUE(ros::service::call(names::kSetKeepOutService, good));
  EXPECT_TRUE(good.response.success) << good.response.message;
}

/// The keep_out scenario's checks: the plant's tip (truth) keeps the capsule off the wall.
void check_keep_out(const Log& log, ros::NodeHandle& pnh) {
  std::vector<double> point, normal;
  double radius = 0.0;
  ASSERT_TRUE(pnh.getParam("wall_point", point) && pnh.getParam("wall_normal", normal) &&
              pnh.getParam("tip_radius", radius));
  const auto* ab = first_abort(log);
  ASSERT_EQ(ab, nullptr) << "aborted at " << ab->path_time << " s: " << ab->reason;
  EXPECT_EQ(log.status.back().state, "finished");
  ASSERT_FALSE(log.keep_out.empty()) << "no controller/keep_out";
  ASSERT_EQ(log.keep_out.back().regions.size(), 1u);
  EXPECT_EQ(log.keep_out.back().regions[0].surface.type, "plane");
  ASSERT_GT(log.truth_tip.size(), 100u) << "no plant/rod_state";
  double least = 1e9, farthest = -1e9;
  for (const auto& [t, p] : log.truth_tip) {
    const double d = (p.x - point[0]) * normal[0] + (p.y - point[1]) * normal[1] + (p.z - point[2]) * normal[2];
    least = std::min(least, d - radius);
    farthest = std::max(farthest, -d);
  }
  EXPECT_GE(least, 0.0) << "the capsule touched the wall the region keeps it from";
  EXPECT_LT(least, 0.006) << "the spiral never came near the wall";
  // The plant says what it simulates: its one wall, and no external force on a tip kept off it.
  ASSERT_FALSE(log.environment.empty()) << "no plant/environment";
  ASSERT_EQ(log.environment.back().surfaces.size(), 1u);
  EXPECT_EQ(log.environment.back().surfaces[0].type, "plane");
  EXPECT_DOUBLE_EQ(log.environment.back().tip_radius, radius);
  EXPECT_EQ(log.max_true_force, 0.0);
  std::printf("keep_out: the capsule's least clearance from the wall %.4f m\n", least);
}

}  // namespace

TEST(SimGraph, Scenario) {
  ros::NodeHandle pnh("~");
  std::string scenario;
  pnh.param<std::string>("scenario", scenario, "");
  double rms_bound = 0.02;
  pnh.param("rms_bound", rms_bound, rms_bound);
  Log log;
  if (scenario == "keep_out") {
    ASSERT_NO_FATAL_FAILURE(set_keep_out(pnh));
  }
  run(log, 240.0);
  ASSERT_FALSE(log.status.empty()) << "no controller status received";

  if (scenario == "closed_loop") {
    const auto* ab = first_abort(log);
    ASSERT_EQ(ab, nullptr) << "aborted at " << ab->path_time << " s: " << ab->reason;
    EXPECT_EQ(log.status.back().state, "finished");
    double s2 = 0.0;
    int n = 0;
    for (const auto& s : log.status)
      if (s.state == "running") {
        s2 += s.error_geodesic * s.error_geodesic;
        ++n;
      }
    ASSERT_GT(n, 100);
    const double rms = std::sqrt(s2 / n);
    EXPECT_LT(rms, rms_bound);
    std::printf("closed loop on the simulated plant: RMS %.4f rad over %d cycles\n", rms, n);
    return;
  }

  if (scenario == "wall") {
    check_wall(log, pnh);
    return;
  }
  if (scenario == "keep_out") {
    check_keep_out(log, pnh);
    return;
  }

  const auto* ab = first_abort(log);
  ASSERT_NE(ab, nullptr) << "the controller did not abort";
  const double t_abort = ab->header.stamp.toSec();
  // Jets at zero from the abort on, and they stay there (no restart until commanded).
  bool zero_after = true;
  double first_zero = -1.0;
  for (const auto& c : log.commands) {
    if (c.header.stamp.toSec() >= t_abort) {
      zero_after = zero_after && zero(c);
      if (first_zero < 0 && zero(c)) first_zero = c.header.stamp.toSec();
    }
  }
  EXPECT_TRUE(zero_after);
  for (const auto& s : log.status) {
    if (s.header.stamp.toSec() > t_abort) {
      EXPECT_EQ(s.state, "aborted");
    }
  }

  if (scenario == "tracker_dropout") {
    EXPECT_NE(ab->reason.find("tracker"), std::string::npos) << ab->reason;
    ASSERT_GE(log.dropout_from, 0.0) << "no dropout seen in the tracker stream";
    // Stale after 3 sample periods: the jets are zero by the 4th control cycle after the last sample.
    EXPECT_LE(first_zero - log.dropout_from, 4 * 0.01 + 1e-6)
        << "last sample " << log.dropout_from << ", zero at " << first_zero;
    EXPECT_GT(first_zero - log.dropout_from, 0.0);
  } else if (scenario == "flow_fault") {
    EXPECT_NE(ab->reason.find("flow: jet 1 reading invalid"), std::string::npos) << ab->reason;
    bool reported = false;
    for (const auto& e : log.diag_errors) reported = reported || e.find("flow") != std::string::npos;
    EXPECT_TRUE(reported) << "no diagnostics ERROR about the flow";
  } else if (scenario == "stuck_jet") {
    EXPECT_NE(ab->reason.find("does not follow its command"), std::string::npos) << ab->reason;
  } else {
    FAIL() << "unknown ~scenario '" << scenario << "'";
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "sim_graph_test");
  return RUN_ALL_TESTS();
}
