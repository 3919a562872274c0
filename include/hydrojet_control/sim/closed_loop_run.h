// One run of the §7 experiment in a single process, no transport: the controller (Algorithm 1)
// against the simulated plant, in lockstep at the control rate. Deterministic for a seed.
// ROS-free (the control and plant libraries).
#pragma once

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/plant/plant.h"

namespace hydrojet {
namespace sim {

/// How a run begins.
enum class RunStart {
  /// The paper's protocol: from rest, the controller jumps onto the path and its clock runs from start.
  kRest,
  /// The path is approached first (control/approach.h); its clock, and the error, start once the tip
  /// has settled on its first direction.
  kOnPath,
};
/// "rest", "on-path" (the experiment's --start values).
const char* to_string(RunStart s);
/// The RunStart that `name` names (to_string's names); false for any other.
bool parse_run_start(const std::string& name, RunStart* start);

/// What one run follows and how it begins.
struct RunPlan {
  std::shared_ptr<const control::Path> path;  ///< null: the controller's spiral (params.path)
  RunStart start = RunStart::kRest;
  double control_period = 0.01;  ///< [s]
  double settle = 1.0;           ///< [s] at rest before the controller starts
};

/// One control cycle as recorded.
struct RunSample {
  double t = 0.0;                ///< path time [s]
  Eigen::Vector3d desired;       ///< x_des, tip z-axis (base frame)
  Eigen::Vector3d measured;      ///< from the tracker
  Eigen::Vector3d truth;         ///< the plant's true tip z-axis (base frame)
  Eigen::Vector3d tip_position;  ///< true tip position [m], base frame
  double error_geodesic = 0.0;   ///< [rad]
  double error_pitch_yaw = 0.0;  ///< [rad]
  double error_true = 0.0;       ///< ∠(x_des, truth) [rad]: tracking without the tracker's noise
  rod::InputVector jet_force;    ///< true actuator forces [N], one per actuator
  double contact_force = 0.0;    ///< the true contact normal force on the capsule [N]
  /// The capsule's true least signed distance to a surface [m] (infinite: no surfaces).
  double clearance = std::numeric_limits<double>::infinity();
  Eigen::Vector3d external_force = Eigen::Vector3d::Zero();  ///< true: contact, loads, constant [N], base frame
  bool contact_flag = false;                                 ///< the controller's contact detector
  Eigen::Vector3d external_force_estimate = Eigen::Vector3d::Zero();  ///< the controller's [N], base frame
};

/// A run's contact, the truth against what the controller detected and estimated (the experiment's
/// contact fields). NaN where a figure has nothing to measure (written as null).
struct ContactSummary {
  int onsets = 0;  ///< the true normal force first above 0.02 N after ≥ 0.5 s with none
  /// [s] the worst delay from an onset to the detector's flag (an onset never flagged: to the run's
  /// end); NaN: no onset.
  double detection_delay_s = std::nan("");
  double missed_contact_s = 0.0;  ///< [s] true normal force > 0.03 N and no flag
  double false_contact_s = 0.0;   ///< [s] flagged while the true normal force has been zero ≥ 0.3 s
  double max_contact_force_n = 0.0;
  /// The largest true normal force from 0.3 s after each detection to the contact's end; NaN: no detection.
  double max_contact_force_after_detection_n = std::nan("");
  double external_force_rms_error_n = 0.0;                           ///< RMS of |estimated − true external tip force|
  double min_clearance_m = std::numeric_limits<double>::infinity();  ///< infinite: no surfaces
};

/// The contact figures of samples taken every dt [s].
ContactSummary summarise_contact(const std::vector<RunSample>& samples, double dt);

struct RunResult {
  bool completed = false;                                         ///< reached the end of the path without an abort
  double aborted_at = -1.0;                                       ///< path time of the abort [s], < 0 if none
  std::string reason;                                             ///< abort reason
  double rms = 0.0, median = 0.0, q1 = 0.0, q3 = 0.0, max = 0.0;  ///< of error_geodesic [rad]
  double rms_pitch_yaw = 0.0;                                     ///< of the paper's metric [rad]
  double rms_true = 0.0;                                          ///< of error_true [rad]
  /// The water the jets use: Σ_jets Q(q_i) by eq. (26) on the plant's jet forces, mean over the
  /// recorded samples [m^3/s].
  double water_flow = 0.0;
  RunStart start = RunStart::kRest;
  double approach_time = 0.0;  ///< [s] from the controller's start to the path clock's (0 for kRest)
  double wall_seconds = 0.0;
  double simulated_seconds = 0.0;
  std::vector<RunSample> samples;
  double time_scale = 1.0;       ///< how much longer than written the path took (its clock's time scaling)
  double reach_limited_s = 0.0;  ///< [s] of the path clipped to the reach the jets showed (LearnedReach)
  double keep_out_s = 0.0;       ///< [s] of the path moved out of a keep-out region (KeepOut)
  int supervisor_fallbacks = 0;  ///< times the law fell back to the paper's (the mode rang, a jet held at its bound)
  double supervised_s = 0.0;     ///< [s] of the path with the law's weight below 1
  control::PlantIdentity identified;  ///< what the controller ended with (Controller::identity)
  control::PlantIdentity truth;       ///< the plant's (plant_truth) at the run's end
  ContactSummary contact;             ///< (summarise_contact)
};

/// The plant's truth, to compare with what a controller identified: the first lateral mode about the
/// equilibrium at the plant's present jet forces (identification::free_vibration_mode on the plant's
/// own dynamic rod), each jet's valve lag and the tracker's latency. mode_hz stays 0 when the rod's
/// vibration could not be fitted.
control::PlantIdentity plant_truth(const plant::Plant& plant);

/// An identity as the experiment's and identify's JSON carry it (`identified`, `plant_truth`): mode_hz
/// and damping_ratio (null when not known), valve_time_constants_s (one per actuator, 0 for a force
/// actuator), tracker_latency_s; `identified` adds what was measured and what is still a first guess.
std::string identity_json(const control::PlantIdentity& id, bool identified);

/// The base tilt of a scene [deg, rounded] from its gravity in the base frame (0° hangs the rod
/// along +z): the experiment's tilt_deg.
inline int base_tilt_deg(const Eigen::Vector3d& gravity) {
  return static_cast<int>(std::lround(std::atan2(gravity.y(), gravity.z()) * 180.0 / M_PI));
}
/// A flow in mL/min from m^3/s (the experiment's water_ml_per_min).
inline double ml_per_min(double m3_per_s) { return m3_per_s * 6e7; }

/// The sensors at time t as the rig's driver delivers them into `in`: the tracker's tip frame in the
/// base frame (when its sample is valid; a dropout leaves the last pose and its stamp), the flows and
/// forces, stamped t.
void read_sensors(plant::Plant& plant, double t, control::ControllerInputs& in);

/// One episode on the simulated plant, the loop that the experiment's runs and hydrojet.gym share: the
/// plant built with its noise seeded, a clock of whole control periods (t = k·dt, no drift), the
/// valves shut while it settles, then one command per period; the sensors read as the rig's driver
/// delivers them after every advance.
class Episode {
 public:
  /// std::invalid_argument when `model` is not valid or control_period is not in [1e-4, 1] s.
  Episode(const plant::PlantModel& model, unsigned seed, double control_period);
  /// `seconds` at rest with the valves shut (rounded to whole periods): the clock stops on the first
  /// period after them, sensors read, nothing commanded there yet. False (error()) when the plant fails.
  bool settle(double seconds);
  /// `command` (valve duties and drives, plant::Plant::command) from now for one period, then the
  /// sensors. False (error()) when the plant fails.
  bool step(const rod::InputVector& command);
  double t() const { return steps_ * dt_; }
  long steps() const { return steps_; }  ///< control periods since the plant started
  plant::Plant& plant() { return plant_; }
  const plant::Plant& plant() const { return plant_; }
  const control::ControllerInputs& sensors() const { return in_; }
  const std::string& error() const { return plant_.error(); }

 private:
  bool advance();  ///< to t(), then the sensors

  plant::Plant plant_;
  double dt_;
  long steps_ = 0;
  control::ControllerInputs in_;
};

/// Runs the plan's path on the plant, `settle` seconds at rest, then the controller: until the path
/// ends, the controller aborts or an approach fails. The error statistics cover the path from its
/// clock's start.
RunResult run_path(const control::RobotModel& model, const control::ControllerOptions& params,
                   const plant::PlantModel& plant, unsigned seed, const RunPlan& plan);
/// The controller's spiral (params.path) from rest, as the paper ran it.
RunResult run_path(const control::RobotModel& model, const control::ControllerOptions& params,
                   const plant::PlantModel& plant, unsigned seed, double control_period = 0.01, double settle = 1.0);

}  // namespace sim
}  // namespace hydrojet
