// Tip-direction paths an operator or a script can ask the controller to follow: the §7.1
// spiral of eq. (28), a raster (a gastric survey: rows of constant ϑ), waypoints (linear on the sphere
// between them) and a table from a file (t, ϑ, φ rows). Directions are unit tip z-axes in the base frame.
// ROS-free (Eigen, yaml-cpp for the file loader).
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "hydrojet_control/control/task_space.h"
#include "hydrojet_control/util/files.h"

namespace hydrojet {
namespace control {

/// Bounds every path is held to, whatever its source (a follow_path goal, a path file): building it
/// is bounded work, it ends, and it asks no motion faster than the robot can follow. Beyond them a
/// path is refused with std::invalid_argument naming the field (docs/operating.md lists them).
struct PathLimits {
  double max_duration = 3600.0;                      ///< [s] a path ends within an hour
  double max_speed = 2.0;                            ///< [rad/s] of arc on the sphere, anywhere along the path
  std::size_t max_points = 100000;                   ///< waypoints, rows of a file, rows of a raster
  std::size_t max_file_bytes = util::kMaxFileBytes;  ///< a path file is at most 16 MiB, and a regular file
};

/// A path of tip directions over time. Before 0 it is at its start, after duration() at its end.
class Path {
 public:
  virtual ~Path() = default;
  /// Desired tip z-axis (unit, base frame) at t [s] since the path started.
  virtual Vec3 direction_at(double t) const = 0;
  /// [s]; the path is finished at t ≥ duration().
  virtual double duration() const = 0;
  /// "spiral", "raster", "waypoints" or "file".
  virtual const char* type() const = 0;
};

/// Eq. (28) (SpiralPath holds its parameters).
std::unique_ptr<Path> make_spiral(const SpiralPath& spiral);

/// Empty when `spiral` is a path within `limits` (finite, ϑ in [0, π], duration in (0, max_duration],
/// speed at most max_speed), else "<field>: <what is wrong>".
std::string validate_spiral(const SpiralPath& spiral, const PathLimits& limits = {});

/// A gastric survey: `rows` rows of constant ϑ from theta_min to theta_max; each row sweeps φ from
/// phi_start to phi_end (alternating direction, boustrophedon) at `speed` [rad/s] of arc on the sphere;
/// consecutive rows are joined along the meridian at the same speed.
struct RasterOptions {
  double theta_min = 0.2;   ///< [rad]
  double theta_max = 0.8;   ///< [rad]
  int rows = 4;             ///< ≥ 1 (1: theta_min only)
  double phi_start = -1.0;  ///< [rad]
  double phi_end = 1.0;     ///< [rad]
  double speed = 0.05;      ///< angular speed along the path [rad/s], > 0
  /// Empty when valid and within `limits` (rows, speed, duration), else "<field>: <what is wrong>".
  std::string validate(const PathLimits& limits = {}) const;
};
/// @throws std::invalid_argument with validate()'s message.
std::unique_ptr<Path> make_raster(const RasterOptions& raster, const PathLimits& limits = {});

/// A direction to pass at time t.
struct Waypoint {
  double t = 0.0;                  ///< [s], strictly increasing along the list, first ≥ 0
  Vec3 direction = Vec3::UnitZ();  ///< unit (normalised on construction), base frame
};
/// Linear on the sphere (slerp) between consecutive waypoints; holds the first before its time.
/// @throws std::invalid_argument naming the waypoint ("waypoints[2].t: ...") on bad input or beyond
/// `limits` (count, last time, speed between two waypoints).
std::unique_ptr<Path> make_waypoints(const std::vector<Waypoint>& waypoints, const PathLimits& limits = {});

/// A table of t [s], ϑ [rad], φ [rad] rows from a CSV (header line optional; comma or whitespace
/// separated) or a YAML file (a sequence of [t, theta, phi] or of {t, theta, phi} maps), by extension
/// (.csv / .yaml / .yml). Linear on the sphere between rows. Only a regular file of at most
/// max_file_bytes is read (a FIFO or a device would block or never end).
/// @throws std::invalid_argument naming the file and line or entry on bad input or beyond `limits`.
std::unique_ptr<Path> load_path_file(const std::string& file, const PathLimits& limits = {});

/// A follow_path goal as action/FollowPath.action carries it, without ROS.
struct PathGoal {
  std::string type;                            ///< "spiral", "raster", "waypoints" or "file"
  SpiralPath spiral{0.0, 0.0, 0.0, 0.0, 0.0};  ///< duration <= 0: the configured spiral
  RasterOptions raster{0.0, 0.0, 0, 0.0, 0.0, 0.0};
  std::vector<double> times;     ///< waypoints [s]
  std::vector<Vec3> directions;  ///< waypoints, base frame, any length
  std::string file;              ///< a path file
};

/// The path a goal names. Every field is checked, whether or not the goal's type uses it (a NaN in
/// an unused field is a malformed goal, not a default); the path is held to `limits`.
/// @throws std::invalid_argument naming the field.
std::unique_ptr<Path> make_goal_path(const PathGoal& goal, const SpiralPath& configured, const PathLimits& limits = {});

}  // namespace control
}  // namespace hydrojet
