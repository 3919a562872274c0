// The ROS bridge of the calibrator: reads a rosbag of the driver's topics into the ROS-free records
// of quasistatic.h. This header has no ROS includes; its implementation (bag_reader.cpp, library
// hydrojet_calibration_ros) links rosbag and the package's messages.
#pragma once

#include <string>
#include <vector>

#include "hydrojet_control/calibration/quasistatic.h"

namespace hydrojet {
namespace calibration {

/// Topic names. A bag topic matches when it equals the name or ends with "/" + name (so
/// "/hydrojet/tracker/tip_pose" matches "tracker/tip_pose").
struct BagTopics {
  std::string tip = "tracker/tip_pose";    ///< geometry_msgs/PoseStamped, tracker frame
  std::string base = "tracker/base_pose";  ///< geometry_msgs/PoseStamped, tracker frame
  std::string jets = "jets/state";         ///< hydrojet_control/JetState (flow [m^3/s] per jet)
};

struct BagRecords {
  std::vector<JetRecord> jets;
  std::vector<PoseRecord> tip, base;
};

/// True when the file starts with the rosbag 2.0 magic "#ROSBAG V2.0".
bool is_rosbag(const std::string& path);

/// Reads the three topics (header stamps; the bag's receive time when a stamp is zero). Throws
/// DataError when the bag cannot be opened or a topic is missing (naming it and the topics found).
BagRecords read_bag(const std::string& path, const BagTopics& topics = BagTopics());

}  // namespace calibration
}  // namespace hydrojet
