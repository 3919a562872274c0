// Online estimate of the model's error as a tip force (after the HydroJet group's
// follow-up, which estimated a disturbance wrench from orientation feedback). The quasi-static model
// at the measured inputs, loaded in addition with the estimate f_d (a force at the tip, tip frame),
// is driven to point where the tracker says:
//   e = ∠(d_model → d_measured),  M = −d̂ R C^b_ω,f  (tip-direction change per tip force, 3×3, rank 2),
//   f_d ← f_d + (dt / τ) (MᵀM + μ²)⁻¹ Mᵀ e,
// a first-order observer with time constant τ on the direction error (the force part of C^b maps a
// force to the direction; the component along the axis, which does not turn it, stays 0). What it
// absorbs: precurvature, stiffness, misalignment, tip-mass and tilt errors, and a real external
// force. The controller then linearises at the corrected equilibrium and (ControllerOptions::
// observer_prediction) closes its loop on the corrected model's direction at the commanded inputs.
// ROS-free (Eigen, the rod library).
#pragma once

#include <Eigen/Core>
#include <string>

#include "hydrojet_control/control/task_space.h"
#include "hydrojet_control/rod/rod_model.h"

namespace hydrojet {
namespace control {

struct DisturbanceObserverOptions {
  double time_constant = 0.25;  ///< τ [s], > 0: how fast the estimate follows the direction error
  double max_force = 0.3;       ///< |f_d| is clamped to this [N]
  double damping = 0.02;        ///< μ [rad/N] of the damped pseudo-inverse
  std::string validate() const;
};

class DisturbanceObserver {
 public:
  explicit DisturbanceObserver(const DisturbanceObserverOptions& o = DisturbanceObserverOptions()) : o_(o) {}
  void set_options(const DisturbanceObserverOptions& o) { o_ = o; }
  /// f_d = 0.
  void reset() { force_.setZero(); }
  /// One update after dt [s]: the model's tip direction with the current estimate (unit, base frame),
  /// the measured one, the model's tip rotation R(L) and body compliance C^b there. Non-finite
  /// input leaves the estimate unchanged.
  void update(const Vec3& model_direction, const Vec3& measured_direction, const Mat3& tip_rotation,
              const rod::Mat6& body_compliance, double dt);
  /// f_d [N], tip frame.
  const Vec3& force() const { return force_; }
  /// f_d as a tip wrench (no moment).
  rod::TipWrench wrench() const {
    rod::TipWrench w;
    w.force = force_;
    return w;
  }

 private:
  DisturbanceObserverOptions o_;
  Vec3 force_ = Vec3::Zero();
};

}  // namespace control
}  // namespace hydrojet
