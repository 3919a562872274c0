// Static samples from recorded time series (a rosbag of the driver's topics, read by the tool):
// pairs tracker poses with jet states by time and keeps only quasistatic intervals, one averaged
// sample per interval. ROS-free (Eigen + the thrust equation).
//
// Every paired time point carries the jet forces F = force_from_flow(measured flow) (eq. 26, the
// scene's nozzles) and the tip orientation in the base frame, R = R_baseᵀ R_tip (both sensors in the
// tracker frame). A window of `window` seconds ending at a point is quasistatic when, within it,
//   - each jet force's standard deviation ≤ max_force_std and its drift (mean of the second half −
//     mean of the first half) ≤ max_force_drift, and
//   - the RMS angle of the orientations about their mean ≤ max_angle_std and the angle between the
//     two halves' mean orientations ≤ max_angle_drift
// (a rod still ringing or creeping fails the spread or the drift test). Consecutive quasistatic
// windows form an interval; each interval gives one sample: the means over its last window that
// ends end_guard before the interval does (the most settled part, clear of the next step). When
// consecutive intervals' samples have the same jet forces within max_force_drift (a noise spike
// or a slow creep split one hold), only the later, more settled one is kept. Defaults suit 100 Hz data with the
// Aurora's ~0.3° and the flow sensors' ~3 mL/min noise (see docs/calibration.md).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/calibration/samples.h"

namespace hydrojet {
namespace calibration {

/// One jet-state message: measured flows [m^3/s] at time t [s].
struct JetRecord {
  double t = 0.0;
  Eigen::Vector3d flow = Eigen::Vector3d::Zero();
  bool valid = true;  ///< false when the driver flagged any of the three readings
};

/// One tracker pose of a sensor (orientation in the tracker frame) at time t [s].
struct PoseRecord {
  double t = 0.0;
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

struct QuasistaticOptions {
  double window = 0.5;             ///< averaging window [s]
  double max_force_std = 0.005;    ///< [N] per jet, within the window
  double max_force_drift = 0.003;  ///< [N] per jet, second-half mean − first-half mean
  double max_angle_std = 0.02;     ///< [rad] RMS angle about the window's mean orientation (≈1.15°)
  double max_angle_drift = 0.01;   ///< [rad] between the two halves' mean orientations (≈0.57°)
  double max_pair_dt = 0.006;      ///< [s] largest stamp difference paired (tip↔base, pose↔jets)
  int min_points = 5;              ///< fewest paired points in a window
  /// [s] the sample's window ends this long before the interval's last quasistatic window (which
  /// may already contain the start of the next step); shorter intervals give no sample.
  double end_guard = 0.1;
  std::string validate() const;  ///< empty when usable, else "<field>: <what>"
};

struct Extraction {
  std::vector<Sample> samples;      ///< one per quasistatic interval, origin "bag t=<end> s"
  std::vector<double> sample_time;  ///< end time of each sample's window [s]
  int paired_points = 0;            ///< time points with tip, base and jet data
  int skipped_points = 0;           ///< unpaired or invalid (flagged / non-finite) records
  int windows = 0;                  ///< windows tested
  int quasistatic_windows = 0;
  int merged_intervals = 0;  ///< intervals dropped as repeats of the one before
};

/// Extracts one static sample per quasistatic interval. Records need not be sorted.
/// Throws DataError when the options are invalid or nothing could be paired.
Extraction extract_quasistatic(const std::vector<JetRecord>& jets, const std::vector<PoseRecord>& tip,
                               const std::vector<PoseRecord>& base, const actuation::Nozzle& nozzle,
                               const QuasistaticOptions& options);

}  // namespace calibration
}  // namespace hydrojet
