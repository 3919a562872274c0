// What the simulated robot's tip meets (the plant's truth, `plant.environment` in a plant file):
// surfaces it touches (planes, spheres, ellipsoids: a wall, a fold, a stomach) and loads that act on
// it for a while (a tether's drag, a fold leaning on the tip). The capsule is a sphere of tip_radius
// about the tip point; each surface presses it with a penalty normal force k·δ − c·v_n (never
// pulling) and a regularised Coulomb friction μ·F_n against the sliding velocity. Base frame, SI.
// ROS-free (Eigen).
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hydrojet_control/geometry/surface.h"

namespace hydrojet {
namespace plant {

using geometry::nearest_point;
using geometry::SurfacePoint;
using geometry::SurfaceType;

/// A surface of the plant's environment: its shape (geometry/surface.h) and how it presses.
struct Surface : geometry::Surface {
  double stiffness = 1e3;  ///< [N/m]
  double damping = 0.0;    ///< [N s/m]
  double friction = 0.0;   ///< Coulomb coefficient [-]
  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};

/// A load that acts on the tip from start to end [s] (end infinite: for good): force [N] and moment [N m] in the tip
/// frame (a fold leaning with the capsule) or the base frame (a tether's drag).
struct ExternalLoad {
  double start = 0.0, end = 0.0;
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
  bool tip_frame = true;
};

/// The capsule against every surface at once.
struct Contact {
  bool touching = false;
  double normal_force = 0.0;                          ///< |Σ normal forces| [N]
  Eigen::Vector3d force = Eigen::Vector3d::Zero();    ///< on the capsule, friction included, base frame [N]
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    ///< the deepest contact's point on its surface [m]
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< the deepest contact's normal (free side)
  /// The capsule's least signed distance to any surface [m] (negative: pressed in; +inf: none).
  double clearance = std::numeric_limits<double>::infinity();
};

struct Environment {
  double tip_radius = 0.007;  ///< the capsule's contact sphere about the tip point [m]
  std::vector<Surface> surfaces;
  std::vector<ExternalLoad> loads;
  /// Sliding speed below which friction is proportional to it (the regularisation) [m/s].
  double friction_speed = 1e-3;
  bool empty() const { return surfaces.empty() && loads.empty(); }
  /// Empty when valid, else "<field>: <what is wrong>" (surfaces[i].…, loads[i].…).
  std::string validate() const;
};

/// The capsule at p moving at v (base frame) against every surface.
Contact contact(const Environment& e, const Eigen::Vector3d& p, const Eigen::Vector3d& v);

/// The loads acting at time t [s], as a force and moment in the base frame, given the tip's rotation.
void loads_at(const Environment& e, double t, const Eigen::Matrix3d& tip_rotation, Eigen::Vector3d* force,
              Eigen::Vector3d* moment);

/// The longest step [s] an explicit penalty contact with these surfaces stays stable and accurate at
/// for a capsule of this mass [kg]: a few steps per period of the stiffest wall, none too damped.
double contact_step(const Environment& e, double mass);

}  // namespace plant
}  // namespace hydrojet
