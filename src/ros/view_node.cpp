// What a person on the rig looks at: the model's backbone as a tube of the rod's real diameter, the
// capsule, the three jet forces, the desired and measured tip directions, the stability margin, the
// camera's field of view at the capsule's front and the reachable set of tip directions (a translucent
// cap on a sphere of twice the rod's length about the base origin), as a visualization_msgs/MarkerArray
// on view/markers; and the frames on tf2:
//   world → tracker (static), tracker → base_sensor (driver/plant), base_sensor → base (static,
//   the sensor is aligned with the base frame), base → tip_model (the model's tip).
// Fixed namespaces and ids. Each new subscriber (rviz starting or reconnecting to a restarted view)
// first gets a DELETEALL, to that subscriber alone, with the reachable set; all subscribers get one
// whenever the controller resets. The reachable set is sent once per controller/reachable_set message
// and again with each DELETEALL (it is large and rarely changes); everything else with each rod/state.
// Not latched: the per-subscriber welcome replaces the latch (a latched array would reach a late
// subscriber after, not before, its DELETEALL, and would hold only the last of the arrays).
#include <algorithm>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>

#include "hydrojet_control/Contact.h"
#include "hydrojet_control/Environment.h"
#include "hydrojet_control/KeepOut.h"
#include "hydrojet_control/ControllerStatus.h"
#include "hydrojet_control/JetState.h"
#include "hydrojet_control/ReachableSet.h"
#include "hydrojet_control/RodState.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/config/yaml_tree.h"
#include "hydrojet_control/ros/names.h"

namespace names = hydrojet::names;

namespace hydrojet {
namespace {

constexpr int kBackboneSegments = 20;  ///< fixed number of tube pieces (ids 0..19)
constexpr int kReachableRings = 8;     ///< rings of the reachable-set surface from its centre to its edge

/// The camera: field of view [rad] and length of the drawn pyramid [m].
constexpr double kCameraFieldOfView = M_PI / 2;
constexpr double kCameraFrustumLength = 0.015;

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

Eigen::Vector3d vector(const geometry_msgs::Vector3& v) { return Eigen::Vector3d(v.x, v.y, v.z); }

/// The unit direction a fraction t of the way from unit a to unit b along the great circle.
Eigen::Vector3d slerp(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double t) {
  const double angle = std::acos(std::max(-1.0, std::min(1.0, a.dot(b))));
  if (angle < 1e-9) return a;
  return (std::sin((1 - t) * angle) * a + std::sin(t * angle) * b) / std::sin(angle);
}

/// Unit, finite directions: the set's centre and its boundary loop (false when unusable).
bool reachable_directions(const hydrojet_control::ReachableSet& m, Eigen::Vector3d* center,
                          std::vector<Eigen::Vector3d>* boundary) {
  *center = vector(m.center);
  if (!center->allFinite() || center->norm() < 0.5 || m.boundary.size() < 3) return false;
  center->normalize();
  boundary->clear();
  for (const auto& b : m.boundary) {
    const Eigen::Vector3d d = vector(b);
    if (!d.allFinite() || d.norm() < 0.5) return false;
    boundary->push_back(d.normalized());
  }
  return true;
}

class ViewNode {
 public:
  ViewNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
    std::string scene_path;
    if (!pnh.getParam("scene", scene_path)) throw config::KeyError("~scene", "missing (path of the scene YAML)");
    const config::Scene scene = config::load_scene(scene_path);
    // Arrows for the actuators at the tip (the HydroJet's three jets): their directions, tip frame.
    const double L = scene.rod.length();
    for (size_t i = 0; i < scene.rod.actuators.size(); ++i)
      if (scene.rod.actuators[i].at >= L)
        tip_actuators_.push_back({static_cast<int>(i), scene.rod.actuators[i].direction});
    if (scene.rod.actuators.empty()) throw config::SceneError("jets", "the scene has no jets or actuators section");
    pnh.param("rod_diameter", rod_diameter_, 0.008);              // [m] (paper §6.2: 8 mm outer)
    pnh.param("capsule_length", capsule_length_, 0.028);          // [m] (§6.1: 28 mm)
    pnh.param("capsule_diameter", capsule_diameter_, 0.0098);     // [m] (§6.1: 9.8 mm)
    pnh.param("force_scale", force_scale_, 0.15);                 // arrow length per jet force [m/N]
    pnh.param("contact_force_scale", contact_force_scale_, 1.0);  // arrow length per external force [m/N]
    // The reachable set is drawn on a sphere beyond the camera (2 L: the capsule's front stays within
    // L + 28 mm of the base), so that rviz's Publish Point on it gives a point the camera can look at.
    pnh.param("reachable_radius", reachable_radius_, 2 * scene.rod.length());  // [m]
    pnh.param<std::string>("world_frame", world_frame_, "world");
    pnh.param<std::string>("tracker_frame", tracker_frame_, "tracker");
    pnh.param<std::string>("base_frame", base_frame_, "base");

    markers_pub_ = nh.advertise<visualization_msgs::MarkerArray>(
        names::kViewMarkers, 2,
        [this](const ros::SingleSubscriberPublisher& p) {
          p.publish(reset_markers());
          ++welcomed_;
        },
        [this](const ros::SingleSubscriberPublisher&) { welcomed_ = std::max(0, welcomed_ - 1); });
    rod_sub_ = nh.subscribe(names::kRodState, 2, &ViewNode::on_rod_state, this);
    status_sub_ = nh.subscribe(names::kControllerStatus, 2, &ViewNode::on_status, this);
    jets_sub_ = nh.subscribe(names::kJetState, 2, &ViewNode::on_jet_state, this);
    reachable_sub_ = nh.subscribe(names::kReachableSet, 1, &ViewNode::on_reachable_set, this);
    contact_sub_ = nh.subscribe(names::kContact, 2, &ViewNode::on_contact, this);
    keep_out_sub_ = nh.subscribe(names::kKeepOut, 1, &ViewNode::on_keep_out, this);
    environment_sub_ = nh.subscribe(names::kPlantEnvironment, 1, &ViewNode::on_environment, this);
    truth_sub_ = nh.subscribe(names::kPlantRodState, 2, &ViewNode::on_plant_rod_state, this);

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
  }

 private:
  /// Frame and stamp of every marker of one rod message.
  struct MarkerStamp {
    std::string frame;
    ros::Time stamp;
    visualization_msgs::Marker make(const std::string& ns, int id) const {
      visualization_msgs::Marker k;
      k.header.frame_id = frame;
      k.header.stamp = stamp;
      k.ns = ns;
      k.id = id;
      k.action = visualization_msgs::Marker::ADD;
      k.pose.orientation.w = 1.0;
      return k;
    }
  };

  /// Clears every marker, then draws the reachable set again (in the same message, so rviz keeps it).
  visualization_msgs::MarkerArray reset_markers() const {
    visualization_msgs::MarkerArray arr;
    visualization_msgs::Marker m;
    m.action = visualization_msgs::Marker::DELETEALL;
    arr.markers.push_back(m);
    arr.markers.insert(arr.markers.end(), reachable_markers_.begin(), reachable_markers_.end());
    arr.markers.insert(arr.markers.end(), keep_out_markers_.begin(), keep_out_markers_.end());
    arr.markers.insert(arr.markers.end(), environment_markers_.begin(), environment_markers_.end());
    return arr;
  }
  void delete_all() { broadcast(reset_markers()); }
  /// Publishes to every subscriber once each has had its welcome. roscpp links a new subscriber
  /// before its connect callback runs (that is queued), so a broadcast in between would reach it
  /// before its DELETEALL; such a broadcast is skipped: the welcome carries the reachable set, and
  /// the rod's markers come again with the next rod state.
  void broadcast(const visualization_msgs::MarkerArray& arr) {
    if (static_cast<int>(markers_pub_.getNumSubscribers()) <= welcomed_) markers_pub_.publish(arr);
  }

  /// A new reachable set: its markers replace the previous ones (or delete them when it is empty).
  void on_reachable_set(const hydrojet_control::ReachableSet::ConstPtr& m) {
    // Stamp 0: the latest transform (the set is latched and re-sent long after its stamp).
    const MarkerStamp stamp{m->header.frame_id.empty() ? base_frame_ : m->header.frame_id, ros::Time()};
    Eigen::Vector3d center;
    std::vector<Eigen::Vector3d> boundary;
    visualization_msgs::MarkerArray arr;
    reachable_markers_.clear();
    if (reachable_directions(*m, &center, &boundary)) {
      reachable_markers_.push_back(reachable_surface(stamp, center, boundary));
      reachable_markers_.push_back(reachable_edge(stamp, boundary));
      arr.markers = reachable_markers_;
    } else {
      for (int id = 0; id < 2; ++id) {
        visualization_msgs::Marker k = stamp.make("reachable_set", id);
        k.action = visualization_msgs::Marker::DELETE;
        arr.markers.push_back(k);
      }
    }
    broadcast(arr);
  }

  /// A surface as a marker: a plane as a thin square about its point, spheres and ellipsoids as
  /// themselves.
  visualization_msgs::Marker surface_marker(const MarkerStamp& stamp, const char* ns, int id,
                                            const hydrojet_control::Surface& r) const {
    visualization_msgs::Marker k = stamp.make(ns, id);
    k.pose.position = r.point;
    k.pose.orientation.w = 1.0;
    if (r.type == "plane") {
      k.type = visualization_msgs::Marker::CUBE;
      const Eigen::Vector3d n(r.normal.x, r.normal.y, r.normal.z);
      const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), n);
      k.pose.orientation.w = q.w(), k.pose.orientation.x = q.x(), k.pose.orientation.y = q.y(),
      k.pose.orientation.z = q.z();
      k.scale.x = k.scale.y = reachable_radius_, k.scale.z = 0.0005;
    } else {
      k.type = visualization_msgs::Marker::SPHERE;
      const bool sphere = r.type == "sphere";
      k.scale.x = 2.0 * r.radii.x, k.scale.y = 2.0 * (sphere ? r.radii.x : r.radii.y);
      k.scale.z = 2.0 * (sphere ? r.radii.x : r.radii.z);
    }
    return k;
  }

  /// Surfaces replacing the previous ones of namespace `ns` (*kept: what a reset draws again).
  void replace_surfaces(const MarkerStamp& stamp, const char* ns,
                        const std::vector<hydrojet_control::Surface>& surfaces, const std_msgs::ColorRGBA& outside,
                        const std_msgs::ColorRGBA& inside, std::vector<visualization_msgs::Marker>* kept) {
    visualization_msgs::MarkerArray arr;
    for (size_t i = surfaces.size(); i < kept->size(); ++i) {
      visualization_msgs::Marker k = stamp.make(ns, static_cast<int>(i));
      k.action = visualization_msgs::Marker::DELETE;
      arr.markers.push_back(k);
    }
    kept->clear();
    for (size_t i = 0; i < surfaces.size(); ++i) {
      visualization_msgs::Marker k = surface_marker(stamp, ns, static_cast<int>(i), surfaces[i]);
      k.color = surfaces[i].inside ? inside : outside;
      kept->push_back(k);
      arr.markers.push_back(k);
    }
    broadcast(arr);
  }

  /// The keep-out regions in force: orange, translucent.
  void on_keep_out(const hydrojet_control::KeepOut::ConstPtr& m) {
    std::vector<hydrojet_control::Surface> surfaces;
    for (const hydrojet_control::KeepOutRegion& r : m->regions) surfaces.push_back(r.surface);
    replace_surfaces({m->header.frame_id.empty() ? base_frame_ : m->header.frame_id, ros::Time()}, "keep_out", surfaces,
                     color(1.0, 0.55, 0.1, 0.3), color(1.0, 0.55, 0.1, 0.12), &keep_out_markers_);
  }

  /// The simulated plant's surfaces (the truth): grey, translucent.
  void on_environment(const hydrojet_control::Environment::ConstPtr& m) {
    replace_surfaces({m->header.frame_id.empty() ? base_frame_ : m->header.frame_id, ros::Time()}, "plant_surfaces",
                     m->surfaces, color(0.6, 0.6, 0.65, 0.35), color(0.6, 0.6, 0.65, 0.12), &environment_markers_);
  }

  /// The plant's true tip and external force (simulation only).
  void on_plant_rod_state(const hydrojet_control::RodState::ConstPtr& m) { truth_ = *m; }

  void on_status(const hydrojet_control::ControllerStatus::ConstPtr& m) {
    const bool reset = (m->state == "idle" || m->state == "aborted") && last_state_ != m->state;
    last_state_ = m->state;
    status_ = *m;
    if (reset) delete_all();
  }

  void on_jet_state(const hydrojet_control::JetState::ConstPtr& m) { jet_force_ = m->force; }
  void on_contact(const hydrojet_control::Contact::ConstPtr& m) { contact_ = *m; }
  /// The model's tip: position [m] and orientation in the base frame.
  struct Tip {
    Eigen::Vector3d p;
    Eigen::Matrix3d R;
  };

  /// The model's rod: tip frame on tf2, then the markers drawn from it.
  void on_rod_state(const hydrojet_control::RodState::ConstPtr& m) {
    if (m->backbone.size() < 2) return;
    const Eigen::Quaterniond qt(m->tip_pose.orientation.w, m->tip_pose.orientation.x, m->tip_pose.orientation.y,
                                m->tip_pose.orientation.z);
    const Eigen::Vector3d pt(m->tip_pose.position.x, m->tip_pose.position.y, m->tip_pose.position.z);
    if (!qt.coeffs().allFinite() || !pt.allFinite() || qt.norm() < 0.5) return;
    const MarkerStamp stamp{m->header.frame_id.empty() ? base_frame_ : m->header.frame_id, m->header.stamp};
    publish_tip_frame(stamp, pt, qt.normalized());

    const Tip tip{pt, qt.normalized().toRotationMatrix()};
    const std_msgs::ColorRGBA tube = stability_color(*m);
    visualization_msgs::MarkerArray arr;
    add_backbone(stamp, *m, tube, &arr);
    add_capsule(stamp, tip, &arr);
    add_jet_forces(stamp, tip, &arr);
    add_directions(stamp, tip, &arr);
    add_stability_text(stamp, tip, m->stability_margin, tube, &arr);
    add_camera_frustum(stamp, tip, &arr);
    add_contact(stamp, tip, &arr);
    broadcast(arr);
  }

  /// base → tip_model on tf2.
  void publish_tip_frame(const MarkerStamp& s, const Eigen::Vector3d& pt, const Eigen::Quaterniond& q) {
    geometry_msgs::TransformStamped tf;
    tf.header.stamp = s.stamp;
    tf.header.frame_id = s.frame;
    tf.child_frame_id = "tip_model";
    tf.transform.translation.x = pt.x(), tf.transform.translation.y = pt.y(), tf.transform.translation.z = pt.z();
    tf.transform.rotation = quaternion(q);
    tf_.sendTransform(tf);
  }

  /// Green: stiff, red: near instability (red as well when the smallest eigenvalue is not positive).
  static std_msgs::ColorRGBA stability_color(const hydrojet_control::RodState& m) {
    const double g = std::max(0.0, std::min(1.0, m.stability_margin / 3.0));
    return m.stability_eig_min > 0 ? color(1.0 - g, 0.4 + 0.6 * g, 0.2) : color(1, 0, 0);
  }

  /// kBackboneSegments tube pieces, resampled from the published samples, coloured by the margin.
  void add_backbone(const MarkerStamp& s, const hydrojet_control::RodState& m, const std_msgs::ColorRGBA& tube,
                    visualization_msgs::MarkerArray* arr) const {
    const size_t n = m.backbone.size();
    auto at = [&](double u) {  // piecewise-linear point at fraction u of the samples
      const double x = u * (n - 1);
      const size_t j = std::min(n - 2, static_cast<size_t>(x));
      const double f = x - j;
      const auto& a = m.backbone[j];
      const auto& b = m.backbone[j + 1];
      return Eigen::Vector3d(a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.z + f * (b.z - a.z));
    };
    for (int i = 0; i < kBackboneSegments; ++i) {
      visualization_msgs::Marker k = s.make("backbone", i);
      cylinder_between(at(double(i) / kBackboneSegments), at(double(i + 1) / kBackboneSegments), rod_diameter_, &k);
      k.color = tube;
      arr->markers.push_back(k);
    }
  }

  /// The capsule: a cylinder from the tip along the tip z-axis.
  void add_capsule(const MarkerStamp& s, const Tip& tip, visualization_msgs::MarkerArray* arr) const {
    visualization_msgs::Marker k = s.make("capsule", 0);
    cylinder_between(tip.p, tip.p + capsule_length_ * tip.R.col(2), capsule_diameter_, &k);
    k.color = color(0.85, 0.85, 0.9, 0.9);
    arr->markers.push_back(k);
  }

  /// Arrows from the capsule centre along each tip actuator's force direction (eq. 24 for the
  /// jets), length proportional to its measured force (actuators along the body are not drawn).
  void add_jet_forces(const MarkerStamp& s, const Tip& tip, visualization_msgs::MarkerArray* arr) const {
    const Eigen::Vector3d centre = tip.p + 0.5 * capsule_length_ * tip.R.col(2);
    for (size_t i = 0; i < tip_actuators_.size(); ++i) {
      visualization_msgs::Marker k = s.make("jets", static_cast<int>(i));
      k.type = visualization_msgs::Marker::ARROW;
      const Eigen::Vector3d dir = tip.R * tip_actuators_[i].direction;
      const size_t input = static_cast<size_t>(tip_actuators_[i].index);
      const double raw = input < jet_force_.size() ? jet_force_[input] : 0.0;
      const double f = std::isfinite(raw) ? std::abs(raw) : 0.0;
      k.points.push_back(point(centre));
      k.points.push_back(point(centre + (0.002 + force_scale_ * f) * dir));
      k.scale.x = 0.0015, k.scale.y = 0.003, k.scale.z = 0.004;
      k.color = i % 3 == 0 ? color(0.9, 0.3, 0.3) : (i % 3 == 1 ? color(0.3, 0.9, 0.3) : color(0.3, 0.4, 0.95));
      arr->markers.push_back(k);
    }
  }

  /// Desired (green) and measured (orange) tip directions, side by side from the tip.
  void add_directions(const MarkerStamp& s, const Tip& tip, visualization_msgs::MarkerArray* arr) const {
    const Eigen::Vector3d des(status_.desired_direction.x, status_.desired_direction.y, status_.desired_direction.z);
    const Eigen::Vector3d mea(status_.measured_direction.x, status_.measured_direction.y, status_.measured_direction.z);
    const Eigen::Vector3d dirs[2] = {des.allFinite() && des.norm() > 0.5 ? des.normalized() : tip.R.col(2),
                                     mea.allFinite() && mea.norm() > 0.5 ? mea.normalized() : tip.R.col(2)};
    for (int i = 0; i < 2; ++i) {
      visualization_msgs::Marker k = s.make("direction", i);
      k.type = visualization_msgs::Marker::ARROW;
      k.points.push_back(point(tip.p));
      k.points.push_back(point(tip.p + 0.05 * dirs[i]));
      k.scale.x = 0.001, k.scale.y = 0.0025, k.scale.z = 0.004;
      k.color = i == 0 ? color(0.1, 0.8, 0.1) : color(1.0, 0.55, 0.0);
      arr->markers.push_back(k);
    }
  }

  /// The estimated external force (magenta arrow at the capsule's front, contact_force_scale [m/N]) and,
  /// in contact, a red sphere where the capsule meets the surface (its front against the normal).
  void add_contact(const MarkerStamp& s, const Tip& tip, visualization_msgs::MarkerArray* arr) const {
    const Eigen::Vector3d f(contact_.force.x, contact_.force.y, contact_.force.z);
    const Eigen::Vector3d n(contact_.normal.x, contact_.normal.y, contact_.normal.z);
    const Eigen::Vector3d front = tip.p + capsule_length_ * tip.R.col(2);
    visualization_msgs::Marker k = s.make("external_force", 0);
    k.type = visualization_msgs::Marker::ARROW;
    k.points.push_back(point(front));
    k.points.push_back(point(front + contact_force_scale_ * (f.allFinite() ? f : Eigen::Vector3d::Zero())));
    k.scale.x = 0.0012, k.scale.y = 0.0025, k.scale.z = 0.003;
    k.color = color(0.9, 0.1, 0.9);
    arr->markers.push_back(k);
    visualization_msgs::Marker c = s.make("contact", 0);
    c.type = visualization_msgs::Marker::SPHERE;
    const bool touching = contact_.in_contact && n.allFinite() && n.norm() > 0.5;
    c.action = touching ? visualization_msgs::Marker::ADD : visualization_msgs::Marker::DELETE;
    c.pose.position = point(front - 0.5 * capsule_diameter_ * (touching ? n.normalized() : Eigen::Vector3d::Zero()));
    c.scale.x = c.scale.y = c.scale.z = 0.004;
    c.color = color(1.0, 0.1, 0.1);
    arr->markers.push_back(c);
    // In simulation: the plant's true external force (green) from its own capsule's front, at most
    // 1 s old (else deleted).
    visualization_msgs::Marker t = s.make("true_force", 0);
    t.type = visualization_msgs::Marker::ARROW;
    const bool fresh = !truth_.header.stamp.isZero() && std::abs((s.stamp - truth_.header.stamp).toSec()) < 1.0;
    t.action = fresh ? visualization_msgs::Marker::ADD : visualization_msgs::Marker::DELETE;
    const Eigen::Quaterniond q(truth_.tip_pose.orientation.w, truth_.tip_pose.orientation.x,
                               truth_.tip_pose.orientation.y, truth_.tip_pose.orientation.z);
    const Eigen::Vector3d p(truth_.tip_pose.position.x, truth_.tip_pose.position.y, truth_.tip_pose.position.z);
    const Eigen::Vector3d tf(truth_.external_force.x, truth_.external_force.y, truth_.external_force.z);
    const Eigen::Vector3d true_front =
        p +
        capsule_length_ * (q.norm() > 0.5 ? q.normalized() : Eigen::Quaterniond::Identity()).toRotationMatrix().col(2);
    t.points.push_back(point(true_front));
    t.points.push_back(point(true_front + contact_force_scale_ * (tf.allFinite() ? tf : Eigen::Vector3d::Zero())));
    t.scale.x = 0.0012, t.scale.y = 0.0025, t.scale.z = 0.003;
    t.color = color(0.1, 0.8, 0.2);
    arr->markers.push_back(t);
  }

  /// The stability margin, the controller's state and its error as text below the tip.
  void add_stability_text(const MarkerStamp& s, const Tip& tip, double margin, const std_msgs::ColorRGBA& tube,
                          visualization_msgs::MarkerArray* arr) const {
    visualization_msgs::Marker k = s.make("stability", 0);
    k.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
    k.pose.position = point(tip.p + Eigen::Vector3d(0.0, 0.0, -0.02));
    k.scale.z = 0.006;
    char buf[160];
    std::snprintf(buf, sizeof(buf), "sigma_c %.2f N/m  %s  err %.3f rad", margin,
                  status_.state.empty() ? "" : status_.state.c_str(), status_.error_geodesic);
    k.text = buf;
    k.color = tube;
    arr->markers.push_back(k);
  }

  /// The camera's field of view: a pyramid from the capsule's front along the tip z-axis, its image
  /// axes those of a camera optical frame (tip x right, tip y down), with a small roof on the top
  /// edge (tip −y) so that "up" on the screen can be told in rviz.
  void add_camera_frustum(const MarkerStamp& s, const Tip& tip, visualization_msgs::MarkerArray* arr) const {
    visualization_msgs::Marker k = s.make("camera", 0);
    k.type = visualization_msgs::Marker::LINE_LIST;
    const Eigen::Vector3d apex = tip.p + capsule_length_ * tip.R.col(2);
    const double h = kCameraFrustumLength * std::tan(0.5 * kCameraFieldOfView);
    const double L = kCameraFrustumLength;
    auto at = [&](double x, double y, double z) -> Eigen::Vector3d { return apex + tip.R * Eigen::Vector3d(x, y, z); };
    const Eigen::Vector3d corner[4] = {at(-h, -h, L), at(h, -h, L), at(h, h, L), at(-h, h, L)};
    auto line = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
      k.points.push_back(point(a));
      k.points.push_back(point(b));
    };
    for (int i = 0; i < 4; ++i) {
      line(apex, corner[i]);
      line(corner[i], corner[(i + 1) % 4]);
    }
    line(corner[0], at(0, -1.4 * h, L));  // the roof: image up is the tip's −y
    line(at(0, -1.4 * h, L), corner[1]);
    k.scale.x = 0.0005;
    k.color = color(0.2, 0.9, 0.9, 0.9);
    arr->markers.push_back(k);
  }

  /// The set as a translucent cap on the sphere of radius reachable_radius_ about the base origin: a
  /// triangle fan from the centre to the boundary, each spoke cut into kReachableRings pieces along its
  /// great circle so that the cap follows the sphere. The triangles face the base (clockwise seen from
  /// outside): rviz lights the front face, and one looks into the cap from the robot's side.
  visualization_msgs::Marker reachable_surface(const MarkerStamp& s, const Eigen::Vector3d& center,
                                               const std::vector<Eigen::Vector3d>& boundary) const {
    visualization_msgs::Marker k = s.make("reachable_set", 0);
    k.type = visualization_msgs::Marker::TRIANGLE_LIST;
    k.scale.x = k.scale.y = k.scale.z = 1.0;
    k.color = color(0.3, 0.6, 1.0, 0.25);
    auto at = [&](const Eigen::Vector3d& b, int ring) {
      return point(reachable_radius_ * slerp(center, b, double(ring) / kReachableRings));
    };
    const size_t n = boundary.size();
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d& a = boundary[i];
      const Eigen::Vector3d& b = boundary[(i + 1) % n];
      k.points.insert(k.points.end(), {at(a, 0), at(b, 1), at(a, 1)});
      for (int r = 1; r < kReachableRings; ++r)
        k.points.insert(k.points.end(), {at(a, r), at(b, r + 1), at(a, r + 1), at(a, r), at(b, r), at(b, r + 1)});
    }
    return k;
  }

  /// The set's edge: the boundary loop, closed, on the same sphere.
  visualization_msgs::Marker reachable_edge(const MarkerStamp& s, const std::vector<Eigen::Vector3d>& boundary) const {
    visualization_msgs::Marker k = s.make("reachable_set", 1);
    k.type = visualization_msgs::Marker::LINE_STRIP;
    k.scale.x = 0.0008;
    k.color = color(0.3, 0.6, 1.0, 0.8);
    for (const auto& b : boundary) k.points.push_back(point(reachable_radius_ * b));
    k.points.push_back(k.points.front());
    return k;
  }

  struct TipActuator {
    int index;                  ///< its entry in jets/state
    Eigen::Vector3d direction;  ///< tip frame
  };
  std::vector<TipActuator> tip_actuators_;
  double rod_diameter_, capsule_length_, capsule_diameter_, force_scale_, contact_force_scale_, reachable_radius_;
  std::string world_frame_, tracker_frame_, base_frame_, last_state_;
  hydrojet_control::ControllerStatus status_;
  hydrojet_control::Contact contact_;  ///< the controller's detector (controller/contact)
  std::vector<double> jet_force_;      ///< measured force per actuator [N] (jets/state)
  ros::Publisher markers_pub_;
  int welcomed_ = 0;  ///< subscribers of markers_pub_ that have had their welcome DELETEALL
  std::vector<visualization_msgs::Marker> reachable_markers_;    ///< the last set's markers (empty: none)
  std::vector<visualization_msgs::Marker> keep_out_markers_;     ///< the keep-out regions in force
  std::vector<visualization_msgs::Marker> environment_markers_;  ///< the simulated plant's surfaces
  hydrojet_control::RodState truth_;                             ///< the plant's last (simulation only)
  ros::Subscriber rod_sub_, status_sub_, jets_sub_, reachable_sub_, contact_sub_, keep_out_sub_, environment_sub_,
      truth_sub_;
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
