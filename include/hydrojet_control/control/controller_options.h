// Options of the controller (paper §4, Algorithm 1), in groups that mirror their owners: the YAML key
// of config/controller.yaml is each field's path (pd/kp is pd.kp). Each group validates itself; the
// defaults equal config/controller.yaml (test_controller). ROS-free (Eigen only).
#pragma once

#include <vector>

#include <string>

#include "hydrojet_control/control/approach.h"
#include "hydrojet_control/control/contact.h"
#include "hydrojet_control/control/keep_out.h"
#include "hydrojet_control/control/direction_law.h"
#include "hydrojet_control/control/modal_law.h"
#include "hydrojet_control/control/plant_identification.h"
#include "hydrojet_control/control/resolved_rates.h"
#include "hydrojet_control/control/safety_monitor.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

enum class LoopMode { kClosed, kOpen };
const char* to_string(LoopMode m);

/// What the controller does at start: follow the spiral of `path` (§7.1), or hold the measured direction.
enum class PathType { kSpiral, kNone };
const char* to_string(PathType t);

/// The controller's limits (`limits/`): on the commanded tip force and on the reference.
struct LimitOptions {
  double max_force = 0.30;         ///< magnitude limit of the commanded tip force [N]
  double max_force_rate = 1.0;     ///< rate limit of the commanded tip force [N/s]
  double max_angular_rate = 0.25;  ///< the reference moves toward a new target at most this fast [rad/s]
  /// A path's clock slows where the path would turn the reference faster than this [rad/s] (time
  /// scaling: the path as written, later; Reference::time_scale).
  double max_path_rate = 1.5;
  /// Operator targets are clipped to the set that this fraction of each jet's q_max reaches (authority
  /// kept for the closed loop); paths to the set of q_max [-], in (0, 1].
  double reachable_force_fraction = 0.8;
  /// Empty when valid, else "<field>: <what is wrong>"; the live limits within cfg/Controller.cfg's bounds.
  std::string validate() const;
};

/// The path at start (`path/`): the spiral of eq. (28), or none (hold the measured direction).
struct PathOptions : SpiralPath {
  PathType type = PathType::kSpiral;
  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};

struct ControllerOptions {
  LoopMode mode = LoopMode::kClosed;
  ControlLaw control_law = ControlLaw::kModal;  ///< the law that acts (make_direction_law)
  PdOptions pd;                                 ///< eq. (17)'s gains (DirectionPd)
  ModalLawOptions modal;                        ///< the modal law's (ModalLaw)
  LimitOptions limits;
  AllocationOptions allocation;  ///< eqs. (19)–(20) and the rounded corners (CornerRounding)
  SafetyOptions safety;          ///< SafetyMonitor's thresholds
  ApproachOptions approach;      ///< when an approached path's clock starts (ApproachMonitor)
  PathOptions path;
  IdentificationOptions identification;  ///< what is measured of the plant present (PlantIdentity)
  ContactOptions contact;                ///< the external force's estimate, the detector, the reaction
  /// Regions the reference never takes the capsule into (keep_out.h); `keep_out` in the controller file.
  std::vector<KeepOutRegion> keep_out;

  /// Empty when valid, else "<group>/<field>: <what is wrong>" (the YAML key).
  std::string validate() const;
};

}  // namespace control
}  // namespace hydrojet
