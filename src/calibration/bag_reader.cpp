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

/// The HydroJet's jets from a JetState: the current one (one entry per actuator; three jets), or one
/// recorded before that (float64[3] flow, force, valve_command, bool[3] flow_valid after the header,
/// whose md5 differs, so instantiate() refuses it): read from its bytes. False when neither.
bool read_jets(const rosbag::MessageInstance& m, JetRecord* r) {
  if (const auto j = m.instantiate<hydrojet_control::JetState>()) {
    if (j->flow.size() != 3 || j->flow_valid.size() != 3) return false;
    r->t = stamp_or(j->header.stamp, m.getTime());
    r->flow = Eigen::Vector3d(j->flow[0], j->flow[1], j->flow[2]);
    r->valid = j->flow_valid[0] && j->flow_valid[1] && j->flow_valid[2];
    return true;
  }
  if (m.getDataType() != "hydrojet_control/JetState") return false;
  namespace ser = ros::serialization;
  std::vector<uint8_t> bytes(m.size());
  try {
    ser::OStream out(bytes.data(), static_cast<uint32_t>(bytes.size()));
    m.write(out);
    ser::IStream in(bytes.data(), static_cast<uint32_t>(bytes.size()));
    std_msgs::Header header;
    ser::deserialize(in, header);
    double values[9];
    for (double& v : values) ser::deserialize(in, v);
    uint8_t valid[3];
    for (uint8_t& v : valid) ser::deserialize(in, v);
    if (in.getLength() != 0) return false;  // not that layout either
    r->t = stamp_or(header.stamp, m.getTime());
    r->flow = Eigen::Vector3d(values[0], values[1], values[2]);
    r->valid = valid[0] && valid[1] && valid[2];
    return true;
  } catch (const ros::Exception&) {
    return false;
  }
}

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
        JetRecord r;
        if (!read_jets(m, &r)) continue;
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
