// Tip-direction paths an operator or a script can ask the controller to follow (issue 13): the §7.1
// spiral of eq. (28), a raster (a gastric survey: rows of constant ϑ), waypoints (linear on the sphere
// between them) and a table from a file (t, ϑ, φ rows). Directions are unit tip z-axes in the base frame.
// ROS-free (Eigen, yaml-cpp for the file loader).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

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
  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};
std::unique_ptr<Path> make_raster(const RasterOptions& raster);

/// A direction to pass at time t.
struct Waypoint {
  double t = 0.0;                  ///< [s], strictly increasing along the list, first ≥ 0
  Vec3 direction = Vec3::UnitZ();  ///< unit (normalised on construction), base frame
};
/// Linear on the sphere (slerp) between consecutive waypoints; holds the first before its time.
/// @throws std::invalid_argument naming the waypoint ("waypoints[2].t: ...") on bad input.
std::unique_ptr<Path> make_waypoints(const std::vector<Waypoint>& waypoints);

/// A table of t [s], ϑ [rad], φ [rad] rows from a CSV (header line optional; comma or whitespace
/// separated) or a YAML file (a sequence of [t, theta, phi] or of {t, theta, phi} maps), by extension
/// (.csv / .yaml / .yml). Linear on the sphere between rows.
/// @throws std::invalid_argument naming the file and line or entry on bad input.
std::unique_ptr<Path> load_path_file(const std::string& file);

}  // namespace control
}  // namespace hydrojet
