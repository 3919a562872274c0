// rosbag → ROS-free records (see bag_reader.h).
#include "hydrojet_control/calibration/bag_reader.h"

#include <geometry_msgs/PoseStamped.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <fstream>
#include <set>

#include "hydrojet_control/JetState.h"

namespace hydrojet {
namespace calibration {
namespace {

bool matches(const std::string& topic, const std::string& name) {
  if (topic == name) return true;
  const std::string n = name.empty() || name[0] == '/' ? name : "/" + name;
  return topic.size() >= n.size() && topic.compare(topic.size() - n.size(), n.size(), n) == 0;
}

double stamp_or(const ros::Time& stamp, const ros::Time& recv) { return stamp.isZero() ? recv.toSec() : stamp.toSec(); }

}  // namespace

bool is_rosbag(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  char magic[13] = {0};
  f.read(magic, 12);
  return f.gcount() == 12 && std::string(magic, 12) == "#ROSBAG V2.0";
}

BagRecords read_bag(const std::string& path, const BagTopics& topics) {
  rosbag::Bag bag;
  try {
    bag.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& e) {
    throw DataError("cannot open bag '" + path + "': " + e.what());
  }
  BagRecords out;
  std::set<std::string> found;
  bool have_tip = false, have_base = false, have_jets = false;
  try {
    rosbag::View view(bag);
    for (const rosbag::MessageInstance& m : view) {
      const std::string& topic = m.getTopic();
      found.insert(topic + " (" + m.getDataType() + ")");
      const bool is_tip = matches(topic, topics.tip), is_base = matches(topic, topics.base);
      if (is_tip || is_base) {
        const auto p = m.instantiate<geometry_msgs::PoseStamped>();
        if (!p) continue;
        PoseRecord r;
        r.t = stamp_or(p->header.stamp, m.getTime());
        const auto& q = p->pose.orientation;
        r.orientation = Eigen::Quaterniond(q.w, q.x, q.y, q.z);
        (is_tip ? out.tip : out.base).push_back(r);
        (is_tip ? have_tip : have_base) = true;
      } else if (matches(topic, topics.jets)) {
        const auto j = m.instantiate<hydrojet_control::JetState>();
        if (!j || j->flow.size() != 3 || j->flow_valid.size() != 3) continue;  // the HydroJet's three jets
        JetRecord r;
        r.t = stamp_or(j->header.stamp, m.getTime());
        r.flow = Eigen::Vector3d(j->flow[0], j->flow[1], j->flow[2]);
        r.valid = j->flow_valid[0] && j->flow_valid[1] && j->flow_valid[2];
        out.jets.push_back(r);
        have_jets = true;
      }
    }
  } catch (const rosbag::BagException& e) {
    throw DataError("cannot read bag '" + path + "': " + e.what());
  }
  bag.close();
  auto missing = [&](const std::string& name, const std::string& type) {
    std::string list;
    for (const std::string& t : found) list += (list.empty() ? "" : ", ") + t;
    throw DataError("bag '" + path + "': no " + type + " messages on a topic '" + name +
                    "' (topics: " + (list.empty() ? "none" : list) + ")");
  };
  if (!have_tip) missing(topics.tip, "geometry_msgs/PoseStamped");
  if (!have_base) missing(topics.base, "geometry_msgs/PoseStamped");
  if (!have_jets) missing(topics.jets, "hydrojet_control/JetState");
  return out;
}

}  // namespace calibration
}  // namespace hydrojet
