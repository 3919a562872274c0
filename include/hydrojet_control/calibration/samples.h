// Calibration data: jet forces and the measured tip orientation, one static sample each; the CSV
// reader and the checks that turn bad data into an error naming the row or the problem.
// ROS-free (Eigen only).
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hydrojet {
namespace calibration {

/// One static equilibrium: jet forces q [N] and the measured orientation of the tip frame in the
/// base frame.
struct Sample {
  Eigen::Vector3d jet_force = Eigen::Vector3d::Zero();                  ///< q1, q2, q3 [N]
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

/// Parses CSV text. The header (first non-empty, non-'#' line) must name at least q1,q2,q3,
/// qw,qx,qy,qz (any order, case-insensitive, surrounding spaces ignored); other columns are
/// ignored. Empty lines and lines starting with '#' are skipped. Each sample's origin is
/// "<name>:<line>". Throws DataError naming the line and column for a missing column, a wrong
/// field count, an unparsable, non-finite or negative force, or a non-unit quaternion
/// (normalised otherwise).
std::vector<Sample> parse_csv(const std::string& text, const std::string& name = "data");
/// Reads and parses a CSV file; DataError when it cannot be read.
std::vector<Sample> read_csv(const std::string& path);

/// Throws DataError when the data cannot determine `fitted_params` parameters: fewer samples
/// than fitted parameters, all jet forces zero (no excitation), non-finite or negative values or
/// a non-unit quaternion in any sample (naming its origin).
void validate_samples(const std::vector<Sample>& samples, int fitted_params);

/// CSV text for samples (header q1,q2,q3,qw,qx,qy,qz; full precision).
std::string to_csv(const std::vector<Sample>& samples);

}  // namespace calibration
}  // namespace hydrojet
