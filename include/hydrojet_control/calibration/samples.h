// Calibration data: actuator inputs and the measured tip orientation, one static sample each; the
// CSV reader and the checks that turn bad data into an error naming the row or the problem.
// ROS-free (Eigen and the rod model's actuators).
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hydrojet_control/rod/rod_model.h"

namespace hydrojet {
namespace calibration {

/// One static equilibrium: actuator inputs q [N] and the measured orientation of the tip frame in
/// the base frame.
struct Sample {
  rod::InputVector inputs;                                              ///< q1..qN [N], the scene's actuator order
  Eigen::Quaterniond tip_orientation = Eigen::Quaterniond::Identity();  ///< unit, tip in base
  std::string origin;  ///< where it came from, for messages: "line 7", "bag t=12.40 s"
};

/// The data are unusable; what() names the row or the problem.
class DataError : public std::runtime_error {
 public:
  explicit DataError(const std::string& what) : std::runtime_error(what) {}
};

/// |‖q‖ − 1| above this rejects a quaternion as non-unit (rows written with 6 significant
/// digits are unit to ~1e-6).
constexpr double kUnitQuaternionTolerance = 1e-3;

/// Parses CSV text for a robot with these actuators (N of them). The header (first non-empty,
/// non-'#' line) must name q1..qN and qw,qx,qy,qz (any order, case-insensitive, surrounding spaces
/// ignored) and no q<k> beyond N (data of another robot); other columns are ignored. Empty lines
/// and lines starting with '#' are skipped. Each sample's origin is "<name>:<line>". Throws
/// DataError naming the line and column for a missing column, a wrong field count, an unparsable
/// or non-finite input, a negative input of an actuator that cannot pull (min_force ≥ 0), or a
/// non-unit quaternion (normalised otherwise).
std::vector<Sample> parse_csv(const std::string& text, const std::vector<rod::Actuator>& actuators,
                              const std::string& name = "data");
/// Reads and parses a CSV file; DataError when it cannot be read.
std::vector<Sample> read_csv(const std::string& path, const std::vector<rod::Actuator>& actuators);

/// Throws DataError when the data cannot determine `fitted_params` parameters of a robot with
/// these actuators: fewer samples than fitted parameters, every input zero (no excitation), a
/// sample with the wrong number of inputs, a non-finite input, a negative input of an actuator
/// that cannot pull, or a non-unit quaternion (naming the sample's origin).
void validate_samples(const std::vector<Sample>& samples, const std::vector<rod::Actuator>& actuators,
                      int fitted_params);

/// CSV text for samples (header q1..qN,qw,qx,qy,qz; full precision).
std::string to_csv(const std::vector<Sample>& samples);

}  // namespace calibration
}  // namespace hydrojet
