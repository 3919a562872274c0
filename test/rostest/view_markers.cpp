// view_node for a known rod state: the MarkerArray has the fixed namespaces, ids and counts, every
// marker is in the base frame with finite values, the backbone tube ends at the tip, the camera
// frustum starts at the capsule's front, a published reachable set is drawn as a translucent cap on
// the sphere of twice the rod's length, and the tf tree world → tracker → base_sensor → base →
// tip_model is connected.
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
#include "hydrojet_control/ReachableSet.h"
#include "hydrojet_control/RodState.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

namespace {
bool finite(const visualization_msgs::Marker& m) {
  for (double v : {m.pose.position.x, m.pose.position.y, m.pose.position.z, m.pose.orientation.w, m.pose.orientation.x,
                   m.pose.orientation.y, m.pose.orientation.z, m.scale.x, m.scale.y, m.scale.z})
    if (!std::isfinite(v)) return false;
  for (const auto& p : m.points)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
  return true;
}

bool has_ns(const visualization_msgs::MarkerArray& arr, const std::string& ns) {
  for (const auto& m : arr.markers)
    if (m.ns == ns && m.action == visualization_msgs::Marker::ADD) return true;
  return false;
}

/// A cap of half-angle 0.6 rad about the base z-axis, 36 boundary directions counter-clockwise.
hydrojet_control::ReachableSet cap_set() {
  hydrojet_control::ReachableSet set;
  set.header.frame_id = "base";
  set.center.z = 1.0;
  for (int i = 0; i < 36; ++i) {
    const double az = 2 * M_PI * i / 36;
    geometry_msgs::Vector3 b;
    b.x = std::sin(0.6) * std::cos(az), b.y = std::sin(0.6) * std::sin(az), b.z = std::cos(0.6);
    set.boundary.push_back(b);
  }
  set.min_stability_margin = 0.5;
  return set;
}

double norm(const geometry_msgs::Point& p) { return std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z); }

// A circular arc of curvature κ = 10 1/m bending about the base x-axis, L = 0.09 m (closed form).
constexpr double kKappa = 10.0, kLength = 0.09;

hydrojet_control::RodState arc_rod_state() {
  hydrojet_control::RodState rs;
  rs.header.frame_id = "base";
  for (int i = 0; i <= 20; ++i) {
    const double s = kLength * i / 20.0;
    geometry_msgs::Point p;
    p.y = (std::cos(kKappa * s) - 1) / kKappa;
    p.z = std::sin(kKappa * s) / kKappa;
    rs.backbone.push_back(p);
  }
  rs.tip_pose.position = rs.backbone.back();
  rs.tip_pose.orientation.w = std::cos(kKappa * kLength / 2);
  rs.tip_pose.orientation.x = std::sin(kKappa * kLength / 2);
  rs.stability_margin = 2.8;
  rs.stability_eig_min = 2.8;
  rs.converged = true;
  return rs;
}

hydrojet_control::ControllerStatus running_status() {
  hydrojet_control::ControllerStatus status;
  status.state = "running";
  status.desired_direction.z = 1.0;
  status.measured_direction.y = -std::sin(kKappa * kLength), status.measured_direction.z = std::cos(kKappa * kLength);
  return status;
}

/// What the view sent while the test played controller and plant for the arc; collected once, checked
/// by every test below.
struct Received {
  std::vector<visualization_msgs::MarkerArray> got;
  size_t full = 0;      ///< 1 + index of the last array with the rod's markers (0: none)
  size_t with_set = 0;  ///< 1 + index of the last array with the reachable set (0: none)
  bool connected = false;
  std::string frames;                   ///< the tf tree, for the failure message
  geometry_msgs::TransformStamped tip;  ///< base → tip_model
};

Received collect() {
  ros::NodeHandle nh;
  Received r;
  ros::Subscriber sub = nh.subscribe<visualization_msgs::MarkerArray>(
      names::kViewMarkers, 10, [&](const visualization_msgs::MarkerArray::ConstPtr& m) { r.got.push_back(*m); });
  ros::Publisher rod = nh.advertise<hydrojet_control::RodState>(names::kRodState, 2);
  ros::Publisher st = nh.advertise<hydrojet_control::ControllerStatus>(names::kControllerStatus, 2);
  ros::Publisher js = nh.advertise<hydrojet_control::JetState>(names::kJetState, 2);
  ros::Publisher reach = nh.advertise<hydrojet_control::ReachableSet>(names::kReachableSet, 1, true);
  reach.publish(cap_set());
  tf2_ros::TransformBroadcaster tfb;
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  hydrojet_control::RodState rs = arc_rod_state();
  hydrojet_control::JetState jets;
  jets.force = {0.1, 0.0, 0.2};

  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(20.0);
  int rounds = 0;  // at least 1 s, so that status and jet state have reached the view first
  while (ros::ok() && ros::WallTime::now() < until && !(r.connected && r.full > 0 && r.with_set > 0 && rounds > 20)) {
    ++rounds;
    const ros::Time now = ros::Time::now();
    geometry_msgs::TransformStamped t;  // tracker → base_sensor, as the driver or plant would send
    t.header.stamp = now;
    t.header.frame_id = "tracker";
    t.child_frame_id = "base_sensor";
    t.transform.translation.z = 0.25;
    t.transform.rotation.x = 1.0;  // Rx(π): the rod hangs down
    tfb.sendTransform(t);
    st.publish(running_status());
    js.publish(jets);
    rs.header.stamp = now;
    rod.publish(rs);
    ros::spinOnce();
    ros::WallDuration(0.05).sleep();
    ros::spinOnce();
    r.connected = buffer.canTransform("world", "tip_model", ros::Time(0));
    for (size_t i = 0; i < r.got.size(); ++i) {
      if (has_ns(r.got[i], "backbone")) r.full = i + 1;
      if (has_ns(r.got[i], "reachable_set")) r.with_set = i + 1;
    }
  }
  r.frames = buffer.allFramesAsString();
  if (r.connected) r.tip = buffer.lookupTransform("base", "tip_model", ros::Time(0));
  return r;
}

const Received& received() {
  static const Received r = collect();
  return r;
}

/// The last array with the rod's markers (the test fails first when there is none).
const visualization_msgs::MarkerArray& rod_markers() { return received().got[received().full - 1]; }
}  // namespace

TEST(ViewMarkers, TfTreeAndStartupReset) {
  const Received& r = received();
  ASSERT_TRUE(r.connected) << "tf tree world -> tip_model not connected:\n" << r.frames;
  ASSERT_GT(r.full, 0u) << "no marker array received";
  // The first message a subscriber gets is a DELETEALL (its welcome: a clean start in rviz).
  ASSERT_FALSE(r.got.front().markers.empty());
  EXPECT_EQ(r.got.front().markers[0].action, visualization_msgs::Marker::DELETEALL);
  // tip_model sits at the arc's tip, in the base frame.
  EXPECT_NEAR(r.tip.transform.translation.y, (std::cos(kKappa * kLength) - 1) / kKappa, 1e-9);
  EXPECT_NEAR(r.tip.transform.translation.z, std::sin(kKappa * kLength) / kKappa, 1e-9);
}

TEST(ViewMarkers, NamespacesIdsAndFrames) {
  ASSERT_GT(received().full, 0u) << "no marker array received";
  std::map<std::string, int> count;
  std::map<std::pair<std::string, int>, int> ids;
  for (const auto& m : rod_markers().markers) {
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
  EXPECT_EQ(count["camera"], 1);
  for (const auto& kv : ids) EXPECT_EQ(kv.second, 1) << kv.first.first << " id " << kv.first.second << " repeated";
}

TEST(ViewMarkers, TubeAndJetArrows) {
  ASSERT_GT(received().full, 0u) << "no marker array received";
  // The tube has the rod's diameter and its last piece ends at the tip.
  for (const auto& m : rod_markers().markers)
    if (m.ns == "backbone") {
      EXPECT_NEAR(m.scale.x, 0.008, 1e-12);
    }
  // Jet arrows are longer for larger forces (jet 3 carries twice jet 1's force, jet 2 none).
  double len[3] = {0, 0, 0};
  for (const auto& m : rod_markers().markers)
    if (m.ns == "jets")
      len[m.id] = std::hypot(std::hypot(m.points[1].x - m.points[0].x, m.points[1].y - m.points[0].y),
                             m.points[1].z - m.points[0].z);
  EXPECT_GT(len[2], len[0]);
  EXPECT_GT(len[0], len[1]);
}

TEST(ViewMarkers, CameraFrustum) {
  ASSERT_GT(received().full, 0u) << "no marker array received";
  // A line list whose first point is the capsule's front (tip + 28 mm along the tip z-axis).
  const double c = std::cos(kKappa * kLength), s = std::sin(kKappa * kLength);  // tip z-axis = (0, −s, c)
  for (const auto& m : rod_markers().markers)
    if (m.ns == "camera") {
      EXPECT_EQ(m.type, visualization_msgs::Marker::LINE_LIST);
      ASSERT_GE(m.points.size(), 16u);
      EXPECT_EQ(m.points.size() % 2, 0u);
      EXPECT_NEAR(m.points[0].y, (c - 1) / kKappa - 0.028 * s, 1e-9);
      EXPECT_NEAR(m.points[0].z, s / kKappa + 0.028 * c, 1e-9);
    }
}

TEST(ViewMarkers, ReachableSet) {
  // A translucent triangle list on the sphere of twice the rod's length (0.18 m) and its edge, in the
  // set's frame.
  const Received& r = received();
  ASSERT_GT(r.with_set, 0u) << "no reachable_set marker received";
  std::map<int, visualization_msgs::Marker> set_markers;
  for (const auto& m : r.got[r.with_set - 1].markers)
    if (m.ns == "reachable_set") set_markers[m.id] = m;
  ASSERT_EQ(set_markers.size(), 2u);
  const auto& surface = set_markers[0];
  EXPECT_EQ(surface.header.frame_id, "base");
  EXPECT_EQ(surface.type, visualization_msgs::Marker::TRIANGLE_LIST);
  ASSERT_GT(surface.points.size(), 0u);
  EXPECT_EQ(surface.points.size() % 3, 0u);
  EXPECT_GT(surface.color.a, 0.1);
  EXPECT_LT(surface.color.a, 0.5);
  EXPECT_TRUE(finite(surface));
  for (const auto& p : surface.points) {
    EXPECT_NEAR(norm(p), 0.18, 1e-9);
    EXPECT_GE(p.z / norm(p), std::cos(0.6) - 1e-9);  // inside the cap
  }
  EXPECT_EQ(set_markers[1].type, visualization_msgs::Marker::LINE_STRIP);
  EXPECT_EQ(set_markers[1].points.size(), 37u);  // the 36 boundary directions, closed
}

// rviz connecting later (or again) gets a clean start too: its first array is a DELETEALL carrying the
// reachable set, whatever was published before.
TEST(ViewMarkers, ALateSubscriberFirstGetsADeleteAllWithTheReachableSet) {
  ASSERT_GT(received().with_set, 0u) << "no reachable_set marker received";
  ros::NodeHandle nh;
  std::vector<visualization_msgs::MarkerArray> got;
  ros::Subscriber sub = nh.subscribe<visualization_msgs::MarkerArray>(
      names::kViewMarkers, 10, [&](const visualization_msgs::MarkerArray::ConstPtr& m) { got.push_back(*m); });
  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(10.0);
  while (ros::ok() && got.empty() && ros::WallTime::now() < until) {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
  ASSERT_FALSE(got.empty());
  ASSERT_FALSE(got.front().markers.empty());
  EXPECT_EQ(got.front().markers[0].action, visualization_msgs::Marker::DELETEALL);
  EXPECT_TRUE(has_ns(got.front(), "reachable_set"));
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "view_markers_test");
  return RUN_ALL_TESTS();
}
