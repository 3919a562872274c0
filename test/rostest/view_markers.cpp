// view_node for a known rod state: the MarkerArray has the fixed namespaces, ids and counts, every
// marker is in the base frame with finite values, the backbone tube ends at the tip, and the tf
// tree world → tracker → base_sensor → base → tip_model is connected.
#include <geometry_msgs/TransformStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <cmath>
#include <map>

#include "hydrojet_control/ControllerStatus.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/RodState.h"

namespace {
bool finite(const visualization_msgs::Marker& m) {
  for (double v : {m.pose.position.x, m.pose.position.y, m.pose.position.z, m.pose.orientation.w, m.pose.orientation.x,
                   m.pose.orientation.y, m.pose.orientation.z, m.scale.x, m.scale.y, m.scale.z})
    if (!std::isfinite(v)) return false;
  for (const auto& p : m.points)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
  return true;
}
}  // namespace

TEST(ViewMarkers, KnownRodState) {
  ros::NodeHandle nh;
  std::vector<visualization_msgs::MarkerArray> got;
  ros::Subscriber sub = nh.subscribe<visualization_msgs::MarkerArray>(
      "view/markers", 10, [&](const visualization_msgs::MarkerArray::ConstPtr& m) { got.push_back(*m); });
  ros::Publisher rod = nh.advertise<hydrojet_control::RodState>("rod/state", 2);
  ros::Publisher st = nh.advertise<hydrojet_control::ControllerStatus>("controller/status", 2);
  ros::Publisher js = nh.advertise<hydrojet_control::JetState>("jets/state", 2);
  tf2_ros::TransformBroadcaster tfb;
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);

  // A circular arc of curvature κ = 10 1/m bending about the base x-axis, L = 0.09 m (closed form).
  const double kappa = 10.0, L = 0.09;
  hydrojet_control::RodState rs;
  rs.header.frame_id = "base";
  for (int i = 0; i <= 20; ++i) {
    const double s = L * i / 20.0;
    geometry_msgs::Point p;
    p.y = (std::cos(kappa * s) - 1) / kappa;
    p.z = std::sin(kappa * s) / kappa;
    rs.backbone.push_back(p);
  }
  rs.tip_pose.position = rs.backbone.back();
  rs.tip_pose.orientation.w = std::cos(kappa * L / 2);
  rs.tip_pose.orientation.x = std::sin(kappa * L / 2);
  rs.stability_margin = 2.8;
  rs.stability_eig_min = 2.8;
  rs.converged = true;
  hydrojet_control::ControllerStatus status;
  status.state = "running";
  status.desired_direction.z = 1.0;
  status.measured_direction.y = -std::sin(kappa * L), status.measured_direction.z = std::cos(kappa * L);
  hydrojet_control::JetState jets;
  jets.force = {0.1, 0.0, 0.2};

  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(20.0);
  bool connected = false;
  size_t full = 0;
  int rounds = 0;  // at least 1 s, so that status and jet state have reached the view first
  while (ros::ok() && ros::WallTime::now() < until && !(connected && full > 0 && rounds > 20)) {
    ++rounds;
    const ros::Time now = ros::Time::now();
    geometry_msgs::TransformStamped t;  // tracker → base_sensor, as the driver or plant would send
    t.header.stamp = now;
    t.header.frame_id = "tracker";
    t.child_frame_id = "base_sensor";
    t.transform.translation.z = 0.25;
    t.transform.rotation.x = 1.0;  // Rx(π): the rod hangs down
    tfb.sendTransform(t);
    st.publish(status);
    js.publish(jets);
    rs.header.stamp = now;
    rod.publish(rs);
    ros::spinOnce();
    ros::WallDuration(0.05).sleep();
    ros::spinOnce();
    connected = buffer.canTransform("world", "tip_model", ros::Time(0));
    for (size_t i = 0; i < got.size(); ++i)
      if (got[i].markers.size() > 1) full = i + 1;
  }
  ASSERT_TRUE(connected) << "tf tree world -> tip_model not connected:\n" << buffer.allFramesAsString();
  ASSERT_GT(full, 0u) << "no marker array received";
  // The first message is a DELETEALL (reset on start-up).
  ASSERT_FALSE(got.front().markers.empty());
  EXPECT_EQ(got.front().markers[0].action, visualization_msgs::Marker::DELETEALL);

  const auto& arr = got[full - 1];
  std::map<std::string, int> count;
  std::map<std::pair<std::string, int>, int> ids;
  for (const auto& m : arr.markers) {
    ++count[m.ns];
    ++ids[{m.ns, m.id}];
    EXPECT_EQ(m.header.frame_id, "base") << m.ns;
    EXPECT_TRUE(finite(m)) << m.ns << " " << m.id;
  }
  EXPECT_EQ(count["backbone"], 20);
  EXPECT_EQ(count["capsule"], 1);
  EXPECT_EQ(count["jets"], 3);
  EXPECT_EQ(count["direction"], 2);
  EXPECT_EQ(count["stability"], 1);
  for (const auto& kv : ids) EXPECT_EQ(kv.second, 1) << kv.first.first << " id " << kv.first.second << " repeated";
  // The tube has the rod's diameter and its last piece ends at the tip.
  for (const auto& m : arr.markers)
    if (m.ns == "backbone") EXPECT_NEAR(m.scale.x, 0.008, 1e-12);
  // Jet arrows are longer for larger forces (jet 3 carries twice jet 1's force, jet 2 none).
  double len[3] = {0, 0, 0};
  for (const auto& m : arr.markers)
    if (m.ns == "jets")
      len[m.id] = std::hypot(std::hypot(m.points[1].x - m.points[0].x, m.points[1].y - m.points[0].y),
                             m.points[1].z - m.points[0].z);
  EXPECT_GT(len[2], len[0]);
  EXPECT_GT(len[0], len[1]);
  // tip_model sits at the arc's tip, in the base frame.
  const auto tf = buffer.lookupTransform("base", "tip_model", ros::Time(0));
  EXPECT_NEAR(tf.transform.translation.y, (std::cos(kappa * L) - 1) / kappa, 1e-9);
  EXPECT_NEAR(tf.transform.translation.z, std::sin(kappa * L) / kappa, 1e-9);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "view_markers_test");
  return RUN_ALL_TESTS();
}
