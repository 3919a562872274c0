// What a person on the rig looks at: the model's backbone as a tube of the rod's real diameter, the
// capsule, the three jet forces, the desired and measured tip directions and the stability margin,
// as a visualization_msgs/MarkerArray on view/markers; and the frames on tf2:
//   world → tracker (static), tracker → base_sensor (driver/plant), base_sensor → base (static,
//   the sensor is aligned with the base frame), base → tip_model (the model's tip).
// Fixed namespaces and ids; a DELETEALL goes out first and whenever the controller resets.
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include <Eigen/Geometry>
#include <cstdio>

#include "hydrojet_control/ControllerStatus.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/RodState.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/config/scene.h"

namespace hydrojet {
namespace {

constexpr int kBackboneSegments = 20;  ///< fixed number of tube pieces (ids 0..19)

geometry_msgs::Point point(const Eigen::Vector3d& v) {
  geometry_msgs::Point p;
  p.x = v.x(), p.y = v.y(), p.z = v.z();
  return p;
}

geometry_msgs::Quaternion quaternion(const Eigen::Quaterniond& q) {
  geometry_msgs::Quaternion m;
  m.w = q.w(), m.x = q.x(), m.y = q.y(), m.z = q.z();
  return m;
}

std_msgs::ColorRGBA color(double r, double g, double b, double a = 1.0) {
  std_msgs::ColorRGBA c;
  c.r = r, c.g = g, c.b = b, c.a = a;
  return c;
}

/// A cylinder from a to b (rviz cylinders are along their local z).
void cylinder_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double diameter,
                      visualization_msgs::Marker* m) {
  m->type = visualization_msgs::Marker::CYLINDER;
  const Eigen::Vector3d d = b - a;
  const double len = d.norm();
  m->pose.position = point(0.5 * (a + b));
  m->pose.orientation = quaternion(len > 0 ? Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), d / len)
                                           : Eigen::Quaterniond::Identity());
  m->scale.x = m->scale.y = diameter;
  m->scale.z = std::max(len, 1e-6);
}

class ViewNode {
 public:
  ViewNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
    std::string scene_path;
    if (!pnh.getParam("scene", scene_path)) throw std::runtime_error("~scene: missing (path of the scene YAML)");
    const config::Scene scene = config::load_scene(scene_path);
    if (!scene.has_jets) throw std::runtime_error("jets: the scene has no jets section");
    jets_ = actuation::JetMap(scene.jets).planar();
    pnh.param("rod_diameter", rod_diameter_, 0.008);           // [m] (paper §6.2: 8 mm outer)
    pnh.param("capsule_length", capsule_length_, 0.028);       // [m] (§6.1: 28 mm)
    pnh.param("capsule_diameter", capsule_diameter_, 0.0098);  // [m] (§6.1: 9.8 mm)
    pnh.param("force_scale", force_scale_, 0.15);              // arrow length per jet force [m/N]
    pnh.param<std::string>("world_frame", world_frame_, "world");
    pnh.param<std::string>("tracker_frame", tracker_frame_, "tracker");
    pnh.param<std::string>("base_frame", base_frame_, "base");

    markers_pub_ = nh.advertise<visualization_msgs::MarkerArray>("view/markers", 2, true);
    rod_sub_ = nh.subscribe("rod/state", 2, &ViewNode::rod, this);
    status_sub_ = nh.subscribe("controller/status", 2, &ViewNode::status, this);
    jets_sub_ = nh.subscribe("jets/state", 2, &ViewNode::jetState, this);

    // Static frames: world → tracker (the tracker is fixed in the lab) and base_sensor → base.
    geometry_msgs::TransformStamped a, b;
    a.header.stamp = b.header.stamp = ros::Time::now();
    a.header.frame_id = world_frame_;
    a.child_frame_id = tracker_frame_;
    a.transform.rotation.w = 1.0;
    b.header.frame_id = "base_sensor";
    b.child_frame_id = base_frame_;
    b.transform.rotation.w = 1.0;
    static_tf_.sendTransform(std::vector<geometry_msgs::TransformStamped>{a, b});
    delete_all();
  }

 private:
  void delete_all() {
    visualization_msgs::MarkerArray arr;
    visualization_msgs::Marker m;
    m.action = visualization_msgs::Marker::DELETEALL;
    arr.markers.push_back(m);
    markers_pub_.publish(arr);
  }

  void status(const hydrojet_control::ControllerStatus::ConstPtr& m) {
    const bool reset = (m->state == "idle" || m->state == "aborted") && last_state_ != m->state;
    last_state_ = m->state;
    status_ = *m;
    if (reset) delete_all();
  }

  void jetState(const hydrojet_control::JetState::ConstPtr& m) {
    jet_force_ = Eigen::Vector3d(m->force[0], m->force[1], m->force[2]);
  }

  void rod(const hydrojet_control::RodState::ConstPtr& m) {
    if (m->backbone.size() < 2) return;
    const std::string frame = m->header.frame_id.empty() ? base_frame_ : m->header.frame_id;
    const Eigen::Quaterniond qt(m->tip_pose.orientation.w, m->tip_pose.orientation.x, m->tip_pose.orientation.y,
                                m->tip_pose.orientation.z);
    const Eigen::Vector3d pt(m->tip_pose.position.x, m->tip_pose.position.y, m->tip_pose.position.z);
    if (!qt.coeffs().allFinite() || !pt.allFinite() || qt.norm() < 0.5) return;
    const Eigen::Matrix3d Rt = qt.normalized().toRotationMatrix();

    // base → tip_model on tf2.
    geometry_msgs::TransformStamped tf;
    tf.header.stamp = m->header.stamp;
    tf.header.frame_id = frame;
    tf.child_frame_id = "tip_model";
    tf.transform.translation.x = pt.x(), tf.transform.translation.y = pt.y(), tf.transform.translation.z = pt.z();
    tf.transform.rotation = quaternion(qt.normalized());
    tf_.sendTransform(tf);

    visualization_msgs::MarkerArray arr;
    auto make = [&](const std::string& ns, int id) {
      visualization_msgs::Marker k;
      k.header.frame_id = frame;
      k.header.stamp = m->header.stamp;
      k.ns = ns;
      k.id = id;
      k.action = visualization_msgs::Marker::ADD;
      k.pose.orientation.w = 1.0;
      return k;
    };
    // Backbone: kBackboneSegments tube pieces, resampled from the published samples, coloured by
    // the stability margin (green: stiff, red: near instability).
    const double margin = m->stability_margin;
    const double g = std::max(0.0, std::min(1.0, margin / 3.0));
    const std_msgs::ColorRGBA tube = m->stability_eig_min > 0 ? color(1.0 - g, 0.4 + 0.6 * g, 0.2) : color(1, 0, 0);
    const size_t n = m->backbone.size();
    for (int i = 0; i < kBackboneSegments; ++i) {
      auto at = [&](double u) {  // piecewise-linear point at fraction u of the samples
        const double x = u * (n - 1);
        const size_t j = std::min(n - 2, static_cast<size_t>(x));
        const double f = x - j;
        const auto& a = m->backbone[j];
        const auto& b = m->backbone[j + 1];
        return Eigen::Vector3d(a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.z + f * (b.z - a.z));
      };
      visualization_msgs::Marker k = make("backbone", i);
      cylinder_between(at(double(i) / kBackboneSegments), at(double(i + 1) / kBackboneSegments), rod_diameter_, &k);
      k.color = tube;
      arr.markers.push_back(k);
    }
    // Capsule: a cylinder from the tip along the tip z-axis.
    {
      visualization_msgs::Marker k = make("capsule", 0);
      cylinder_between(pt, pt + capsule_length_ * Rt.col(2), capsule_diameter_, &k);
      k.color = color(0.85, 0.85, 0.9, 0.9);
      arr.markers.push_back(k);
    }
    // Jet forces: arrows from the capsule centre along each jet's force direction (eq. 24),
    // length proportional to the measured jet force.
    const Eigen::Vector3d centre = pt + 0.5 * capsule_length_ * Rt.col(2);
    for (int i = 0; i < 3; ++i) {
      visualization_msgs::Marker k = make("jets", i);
      k.type = visualization_msgs::Marker::ARROW;
      const Eigen::Vector3d dir = Rt * Eigen::Vector3d(jets_(0, i), jets_(1, i), 0.0);
      const double f = std::isfinite(jet_force_[i]) ? std::max(0.0, jet_force_[i]) : 0.0;
      k.points.push_back(point(centre));
      k.points.push_back(point(centre + (0.002 + force_scale_ * f) * dir));
      k.scale.x = 0.0015, k.scale.y = 0.003, k.scale.z = 0.004;
      k.color = i == 0 ? color(0.9, 0.3, 0.3) : (i == 1 ? color(0.3, 0.9, 0.3) : color(0.3, 0.4, 0.95));
      arr.markers.push_back(k);
    }
    // Desired (green) and measured (orange) tip directions, side by side from the tip.
    const Eigen::Vector3d des(status_.desired_direction.x, status_.desired_direction.y, status_.desired_direction.z);
    const Eigen::Vector3d mea(status_.measured_direction.x, status_.measured_direction.y, status_.measured_direction.z);
    const Eigen::Vector3d dirs[2] = {des.allFinite() && des.norm() > 0.5 ? des.normalized() : Rt.col(2),
                                     mea.allFinite() && mea.norm() > 0.5 ? mea.normalized() : Rt.col(2)};
    for (int i = 0; i < 2; ++i) {
      visualization_msgs::Marker k = make("direction", i);
      k.type = visualization_msgs::Marker::ARROW;
      k.points.push_back(point(pt));
      k.points.push_back(point(pt + 0.05 * dirs[i]));
      k.scale.x = 0.001, k.scale.y = 0.0025, k.scale.z = 0.004;
      k.color = i == 0 ? color(0.1, 0.8, 0.1) : color(1.0, 0.55, 0.0);
      arr.markers.push_back(k);
    }
    // Stability margin as text.
    {
      visualization_msgs::Marker k = make("stability", 0);
      k.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
      k.pose.position = point(pt + Eigen::Vector3d(0.0, 0.0, -0.02));
      k.scale.z = 0.006;
      char buf[160];
      std::snprintf(buf, sizeof(buf), "sigma_c %.2f N/m  %s  err %.3f rad", margin,
                    status_.state.empty() ? "" : status_.state.c_str(), status_.error_geodesic);
      k.text = buf;
      k.color = tube;
      arr.markers.push_back(k);
    }
    markers_pub_.publish(arr);
  }

  Eigen::Matrix<double, 2, 3> jets_;
  double rod_diameter_, capsule_length_, capsule_diameter_, force_scale_;
  std::string world_frame_, tracker_frame_, base_frame_, last_state_;
  hydrojet_control::ControllerStatus status_;
  Eigen::Vector3d jet_force_ = Eigen::Vector3d::Zero();
  ros::Publisher markers_pub_;
  ros::Subscriber rod_sub_, status_sub_, jets_sub_;
  tf2_ros::TransformBroadcaster tf_;
  tf2_ros::StaticTransformBroadcaster static_tf_;
};

}  // namespace
}  // namespace hydrojet

int main(int argc, char** argv) {
  ros::init(argc, argv, "view");
  ros::NodeHandle nh, pnh("~");
  try {
    hydrojet::ViewNode node(nh, pnh);
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("view: refusing to start: %s", e.what());
    return 1;
  }
  return 0;
}
