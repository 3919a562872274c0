// The resolved-rates law of the paper, §4, eqs. (17)–(19) (Algorithm 1, lines 5 and 7): a PD
// correction plus feedforward on the tip-direction error, resolved into a tip-force change through
// the damped pseudo-inverse of R^h C^b. ROS-free (Eigen, the rod library).
#pragma once

#include <Eigen/Core>

#include "hydrojet_control/control/controller_options.h"
#include "hydrojet_control/rod/shooting_solver.h"

namespace hydrojet {
namespace control {

/// eqs. (17)–(18), Algorithm 1 line 5: x_cntr = PD(x_err) + feedforward. Remembers the previous
/// error and desired direction for the derivative and feedforward terms.
class DirectionPd {
 public:
  /// Starts afresh: the next step has no derivative and no feedforward term.
  void reset() { primed_ = false; }

  /// x_err is the rotation vector taking the observed tip direction onto the desired one (both
  /// unit, base frame); returns
  ///   x_cntr = K_p dt x_err + K_d (x_err − x_err,prev) + k_ff ∠(x_des,prev → x_des)   [rad],
  /// the rotation (base frame) the tip direction should make this step. dt [s].
  Vec3 correction(const Vec3& observed, const Vec3& desired, double dt, const ControllerOptions& gains);

 private:
  bool primed_ = false;
  Vec3 prev_error_ = Vec3::Zero();
  Vec3 prev_desired_ = Vec3::UnitZ();
};

/// eq. (19), Algorithm 1 line 7: ẇ^b = (R^h C^b)^† x_cntr on the actuated force columns (f_x, f_y)
/// of the body compliance C^b. Only the change of the tip direction d matters,
/// δd = ω × d = −d^ R(L) C^b_ω δf, so the map is projected onto the plane ⊥ d and inverted with a
/// damped pseudo-inverse (Levenberg–Marquardt damping μ [rad/N] near singularities).
/// tip_rotation: R^h(L) of the model; returns the tip-force change (δf_x, δf_y) [N].
Eigen::Vector2d force_change(const Mat3& tip_rotation, const rod::Mat6& body_compliance, const Vec3& x_cntr,
                             double damping);

}  // namespace control
}  // namespace hydrojet
