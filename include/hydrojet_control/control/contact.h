// Contact and unknown loads (the paper's §8): the external tip force estimated from what the rig
// measures, a detector with hysteresis, and what the controller does about a contact.
//   Estimate: the tracker's tip pose against the model's (the cycle's solve at q_obs, delayed by the
//   tracker's latency) is the deflection C^b f of an external tip force f; weighted least squares on
//   the deflection's direction and position gives f and its covariance. The model's own mismatch
//   reads as a force too, but it is slow and follows the configuration: a model linear in the inputs
//   q and the tip frame's entries, learned by recursive least squares in free space and frozen in
//   contact, is taken off.
//   A load is not a mismatch: a push that appears at once (the tip gives way to it) is kept as a
//   steady load, apart from the mismatch model, and reported with the rest of the force.
//   Detect: |f| beyond the load above the threshold (or the mismatch model's own 3σ where it has not
//   yet seen the configuration) on two samples in a row; released when the push along the contact's
//   normal stays below its release level. A force along a straight rod's axis is not observed.
// ROS-free (Eigen).
#pragma once

#include <deque>
#include <string>

#include "hydrojet_control/control/robot_model.h"
#include "hydrojet_control/control/task_space.h"

namespace hydrojet {
namespace control {

/// What the controller does when the tip touches something.
enum class ContactReaction {
  kComply,   ///< slide along the surface, pressing with kComplyFraction of max_force
  kHold,     ///< aim where the tip met the surface and stop there; a path ends ("contact: ...")
  kRetreat,  ///< aim off the surface along the normal and stop there; a path ends
};
const char* to_string(ContactReaction r);
/// "comply", "hold", "retreat"; false when `name` is none of them.
bool parse_contact_reaction(const std::string& name, ContactReaction* reaction);

/// The controller file's `contact:` group.
struct ContactOptions {
  /// |estimated external force| above which the tip is in contact [N]; above the free-space estimate's
  /// noise and mismatch (docs/contact.md).
  double force_threshold = 0.012;
  ContactReaction reaction = ContactReaction::kComply;
  /// The tissue is never pressed harder than this [N]; at least 2.5 force_threshold.
  double max_force = 0.04;
  /// comply holds the push at this fraction of max_force (0.5 left 50 mN on the walls of
  /// docs/contact.md, 0.3 a flag after the tip had left).
  static constexpr double kComplyFraction = 0.4;
  /// Empty when valid, else "<field>: <what is wrong>".
  std::string validate() const;
};

/// The estimate and the detector's verdict of one cycle (base frame).
struct ContactState {
  Vec3 force = Vec3::Zero();       ///< external tip force, the model's mismatch taken off [N]
  Vec3 load = Vec3::Zero();        ///< the steady load in `force` (a tether, a fold: not a surface) [N]
  Mat3 covariance = Mat3::Zero();  ///< of `force` [N^2]: the tracker's noise and the mismatch model's
  /// The force beyond the load as the model reads it (base) [N]: what the detector compares with
  /// `threshold`; `force` less `load` is it divided by the reading's gain (ContactEstimator::reading_gain).
  Vec3 reading = Vec3::Zero();
  double threshold = 0.0;          ///< the detector's threshold this cycle [N]
  bool in_contact = false;         ///< the detector's flag
  double since = 0.0;              ///< [s] when the present contact was detected
  Vec3 normal = Vec3::Zero();      ///< unit, the force's direction while in contact (free side)
  Vec3 deflection = Vec3::Zero();  ///< how far the force beyond the load turns the tip direction (base) [rad]
  bool ready = false;              ///< a tracker sample has been compared with the model
};

/// One cycle's view of the model and the tracker.
struct ContactCycle {
  double t = 0.0;                                         ///< now [s]
  bool new_sample = false;                                ///< the tracker's sample is new this cycle
  double stamp = 0.0;                                     ///< when the tracker measured it [s]
  Mat3 measured_rotation = Mat3::Identity();              ///< the tracker's tip frame (base frame)
  Vec3 measured_position = Vec3::Constant(std::nan(""));  ///< the tracker's tip [m] (NaN: not used)
  Mat3 model_rotation = Mat3::Identity();                 ///< the model's tip frame at q_obs now
  Vec3 model_position = Vec3::Zero();                     ///< [m]
  rod::Mat6 compliance = rod::Mat6::Zero();               ///< C^b there
  InputVector inputs;                                     ///< q_obs [N]
  /// The inputs' unit tip wrenches there (body frame; the linearisation's): how the model's pose,
  /// and so the mismatch model's reading, turns as the jets take up a force.
  rod::ActuationJacobian input_wrenches = rod::ActuationJacobian::Zero(6, 0);
  /// The reference was held back from the surface last cycle (the tip still presses on: a weak
  /// estimate then does not release the contact before kHeldRelease).
  bool pressing = false;
  /// The law's supervisor has stepped in (the mode rings, or a jet is held at its bound): the tip's
  /// swing reads as a force, so a contact is flagged above kRingingThreshold times the threshold.
  bool ringing = false;
};

class ContactEstimator {
 public:
  /// input_scale [N]: the inputs' scale (the largest q_max) for the mismatch model's regressors.
  ContactEstimator(const ContactOptions& options, int inputs, double input_scale);
  void set_options(const ContactOptions& options) { options_ = options; }
  /// The present contact is a load, not a surface: released, and the force beyond the load so far
  /// added to the load (settled over kLoadSettle, the mismatch model frozen meanwhile); no new flag
  /// until the force beyond the load has come down below half the threshold (kLoadLearnTime at most).
  void take_as_load(double t);
  /// Whether the present push, with the load held, may be taken for a load: at most kTakeLoad times
  /// contact/max_force. The law holds a load against the tip, and a push held much harder than comply
  /// would press may be tissue (a soft wall that gives way); a held load is given back past kMaxLoad.
  bool load_fits() const { return held_push() <= kTakeLoad * options_.max_force; }
  /// Forgets the present contact and the filters; the learned mismatch is kept (a restart on the same rig).
  void reset();
  /// One control cycle: the model's pose is remembered (for the tracker's latency); a new tracker sample
  /// updates the estimate, the detector and (in free space) the mismatch model.
  const ContactState& update(const ContactCycle& cycle);
  const ContactState& state() const { return state_; }
  /// The tip direction's turn [rad, base frame] that a force f [N, base frame] makes at the last
  /// compared equilibrium (C^b's force-to-rotation block).
  Vec3 deflection(const Vec3& force) const;

  // The tracker's specified per-axis noise (NDI Aurora): the weights of direction against position.
  static constexpr double kDirectionSigma = 0.3 * M_PI / 180.0;  ///< [rad]
  static constexpr double kPositionSigma = 0.5e-3;               ///< [m]
  static constexpr double kMemory = 5.0;                         ///< [s] the mismatch model's forgetting time
  static constexpr double kFilterTime = 0.03;                    ///< [s] the force's low-pass
  static constexpr double kReleaseTime = 0.15;                   ///< [s] below the release level before a release
  static constexpr double kHeldRelease = 0.3;                    ///< [s] the same while the reference is held back
  static constexpr double kRingingThreshold = 1.5;               ///< the threshold's factor while ringing
  static constexpr double kArmTime = 0.5;                        ///< [s] of samples before the detector may flag
  static constexpr double kLoadLearnTime = 2.0;  ///< [s] take_as_load keeps the detector down at most this long
  static constexpr double kRelearnDelay = 1.0;   ///< [s] after a release before the mismatch learns again
  static constexpr double kLoadSettle = 1.0;     ///< [s] after take_as_load the load follows the force, then is kept
  static constexpr double kLoadTime = 0.2;       ///< [s] the load's averaging time while it settles
  static constexpr double kMaxLoad = 2.5;        ///< a held load is given back past this times max_force
  static constexpr double kTakeLoad = 2.0;  ///< ... and taken up to this (the gap: no taking and giving back in turn)
  /// A flag where the tip has given way along the force's turn by at least this fraction of the turn's
  /// growth since the force rose, the model having gone against it by at most kPressFraction (a
  /// surface stops the tip or throws it back while the model goes on into it; a load moves the tip
  /// while the model stays) is a load.
  static constexpr double kGiveFraction = 0.5;
  static constexpr double kPressFraction = 0.5;
  static constexpr double kMinGiveTurn = 0.01;  ///< [rad] ... when the turn grew by at least this much
  /// [s] the give is counted from this long before the force rose past half the threshold (a small
  /// load has moved the tip most of its way by then)
  static constexpr double kGiveLookBack = 0.1;
  /// [s] a rise older than this (the force above half the threshold, neither flagged nor given way
  /// to) is counted afresh: the give and the rollback are of the last moments, not of seconds ago
  static constexpr double kMaxRiseAge = 0.5;
  /// [s] a push that the mismatch model of up to this long ago reads as free space is a graze
  /// learned as mismatch since (a surface met under the threshold), then left: not a contact.
  static constexpr double kUnlearnLookBack = 3.0;
  static constexpr double kSnapshotPeriod = 0.25;  ///< [s] between the mismatch model's snapshots
  /// A snapshot is trusted where its model's variance is at most this many residual variances.
  static constexpr double kSnapshotSpread = 1.0;
  /// The reading's gain (the plant's compliance over the model's along the jets' forces) is held to
  /// these bounds: a mismatch model that has learned little reads 1.
  static constexpr double kMinReadingGain = 0.5;
  static constexpr double kMaxReadingGain = 2.0;

 private:
  /// [N] the push with the load held: the load plus the force beyond it.
  double held_push() const { return (load_ + to_force_ * filtered_).norm(); }
  struct ModelPose {
    double t;
    Mat3 rotation;
    Vec3 position;
    rod::Mat6 compliance;
    InputVector inputs;
    rod::ActuationJacobian wrenches;
  };
  const ModelPose* pose_at(double stamp) const;
  Eigen::VectorXd regressor(const Mat3& rotation, const InputVector& q) const;
  bool deflection_force(const ContactCycle& c, const ModelPose& pose, Vec3* force, Mat3* cov) const;
  Mat3 reading_gain(const ModelPose& pose) const;
  Vec3 mismatch_change(const Mat3& dR, int input) const;
  void learn(const Eigen::VectorXd& phi, const Vec3& error, double dt);
  void detect(double t, double alpha, const ContactCycle& c, const Vec3& measured_direction,
              const Vec3& model_direction);
  bool unlearn();

  ContactOptions options_;
  double input_scale_;
  std::deque<ModelPose> history_;  ///< the model's poses of the last 0.5 s
  // The mismatch model: f_tip ≈ Θᵀ φ, φ = regressor(); recursive least squares.
  Eigen::MatrixXd theta_;                     ///< (10 + inputs) × 3
  Eigen::MatrixXd info_;                      ///< (10 + inputs)², the regressors' information
  Eigen::MatrixXd info0_;                     ///< its prior's (what calibration leaves), to which it forgets
  Eigen::MatrixXd p_;                         ///< info_'s inverse
  Vec3 residual_var_ = Vec3::Constant(1e-4);  ///< the fit's residual variance per axis [N^2]
  double last_sample_t_ = -1.0;
  double first_sample_t_ = -1.0;  ///< [s] the first sample compared since reset
  double free_since_ = -1e300;    ///< [s] the last release (learning waits kRelearnDelay)
  double below_since_ = -1.0;     ///< [s] the force fell below the release level
  int above_ = 0;                 ///< samples in a row above the threshold
  double load_since_ = -1.0;      ///< [s] take_as_load's time
  bool learning_load_ = false;    ///< take_as_load: no flag until the estimate has come down
  Vec3 load_ = Vec3::Zero();      ///< the steady load [N, base]
  bool load_held_ = false;        ///< a load was taken and has not gone away
  bool rising_ = false;           ///< the force beyond the load is above half the threshold
  struct Look {
    double t;
    Vec3 measured;    ///< the measured tip direction
    Vec3 deflection;  ///< the force's turn [rad, base]
    Vec3 model;       ///< the model's tip direction
  };
  Look rise_{0.0, Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};  ///< where the give is counted from
  std::deque<Look> looks_;                  ///< the last kGiveLookBack of samples: where the give is counted from
  Eigen::MatrixXd rise_theta_, rise_info_;  ///< the mismatch model then (what it learned since was the load)
  struct Snapshot {
    double t;
    Eigen::MatrixXd theta, info;
  };
  std::deque<Snapshot> snapshots_;           ///< the mismatch model, every kSnapshotPeriod, back to kUnlearnLookBack
  Eigen::VectorXd phi_;                      ///< the last sample's regressor
  Vec3 filtered_ = Vec3::Zero();             ///< the reading beyond the mismatch and the load [N, base]
  Vec3 measured_direction_ = Vec3::UnitZ();  ///< the tracker's tip direction, low-passed as filtered_
  bool direction_known_ = false;
  Mat3 last_rotation_ = Mat3::Identity();
  Mat3 to_force_ = Mat3::Identity();  ///< the reading (base frame) to the force: R gain⁻¹ Rᵀ (reading_gain)
  rod::Mat6 last_compliance_ = rod::Mat6::Zero();
  ContactState state_;
};

}  // namespace control
}  // namespace hydrojet
