// Elastic stability of an equilibrium (paper §4.1, eqs. 21–23) and the hybrid compliance of eq. (19).
// ROS-free (Eigen only).
#pragma once

#include <array>

#include "hydrojet_control/rod/rod_model.h"

namespace hydrojet {
namespace rod {

/// Which body-wrench components (f_x, f_y, f_z, l_x, l_y, l_z) the actuators produce. The stability
/// block of C^b takes these columns and their work-conjugate rows (v_x, v_y, v_z, ω_x, ω_y, ω_z), so
/// that S = (C^b_block)^† is a stiffness. The HydroJet's jets lie in the tip xy-plane: {f_x, f_y}.
using ActuatedSet = std::array<bool, 6>;
inline ActuatedSet lateral_force_actuation() { return {true, true, false, false, false, false}; }

struct StabilityReport {
  /// σ_c of eq. (23): the smallest singular value of S = (C^b_block)^†, i.e. 1/σ_max(C^b_block)
  /// [N/m for force blocks]. Never negative, so it cannot flag an instability by itself.
  double margin = 0.0;
  /// The smallest real part of the eigenvalues of S on the same block: ≤ 0 marks an unstable
  /// equilibrium (a restoring stiffness that has vanished or reversed).
  double eig_min = 0.0;
  bool ok = false;
};

StabilityReport stability(const Mat6& compliance_body, const ActuatedSet& actuated);

/// The same for a general actuator set: the block of C^b on the span of the actuators'
/// tip body wrenches (columns of `wrenches`), Uᵀ C^b U with U an orthonormal basis of that span. For
/// actuators at the tip pass their unit wrenches (d, p × d); the HydroJet's three jets span {f_x, f_y},
/// so this equals stability(C, lateral_force_actuation()) up to rounding (U rotates within the block).
/// `arm` [m] makes the units one when the span has moments: moments count as forces at that arm
/// (wrench (f, m/arm), twist (v, ω·arm)), so σ_c is in N/m for every direction (torsion and bending
/// about the tip as the stiffness against a lateral force at the arm). The controller passes L;
/// it does not matter for force-only spans (the HydroJet's).
StabilityReport stability(const Mat6& compliance_body,
                          const Eigen::Ref<const Eigen::Matrix<double, 6, Eigen::Dynamic>>& wrenches, double arm = 1.0);

/// The unit body wrench along the softest direction of the `actuated` components at C^b: the
/// eigenvector of the symmetric part of the stiffness S = (C^b block)^† with the smallest (most
/// negative) eigenvalue, i.e. the mode an unstable equilibrium leaves along first (a column buckles
/// about its weaker axis). NaN when the eigen-solve fails or nothing is actuated.
Vec6 softest_wrench_direction(const Mat6& compliance_body, const ActuatedSet& actuated);

/// The tip body wrenches that move the tip as the actuators do: (C^b)^† J_q (for actuators at the tip
/// their unit wrenches, up to the null space of C^b). Their span is where a general actuator set
/// loads the tip; stability(C, equivalent_tip_wrenches(C, J_q)) is its indicator.
Eigen::Matrix<double, 6, Eigen::Dynamic> equivalent_tip_wrenches(
    const Mat6& compliance_body, const Eigen::Ref<const Eigen::Matrix<double, 6, Eigen::Dynamic>>& actuation_jacobian);

/// Hybrid compliance R^h(L) C^b of eq. (19): tip twist in base-frame axes per body wrench.
Mat6 hybrid_compliance(const Mat3& tip_rotation, const Mat6& compliance_body);

}  // namespace rod
}  // namespace hydrojet
