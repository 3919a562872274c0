// Jet map of Campisano et al. 2021, §6.2, eq. (24): tip body wrench from the three jet forces.
// ROS-free (Eigen only).
//
// The three nozzles sit ~120° apart around the capsule and push in the tip xy-plane (Figure 6).
// With zero misalignment the jet force directions in the tip frame are
//   jet 1: 30°,  jet 2: 270° (−90°),  jet 3: 150°   (angles from +x towards +y).
// Manufacturing misalignment rotates each direction about the tip z axis:
//   jet 1 by +δβ, jet 2 by +δα, jet 3 by −δγ   (signs as they fall out of eq. 24's A).
//
// With three jets and only two force DoF (f_x, f_y) the 2×3 matrix A is not square, so the
// "A is invertible" branch of Algorithm 1 never applies: jet forces are allocated with the
// redundancy optimisation of eq. (20) (see allocation.h).
#pragma once

#include <Eigen/Core>

namespace hydrojet {
namespace actuation {

using Vec6 = Eigen::Matrix<double, 6, 1>;

/// Geometry of the three-jet actuator.
struct JetGeometry {
  /// (δα, δβ, δγ) [rad]: misalignment of jets 2, 1 and 3 respectively (eq. 24; Table 1 calibrated
  /// 0.12, 0.06, −0.08).
  Eigen::Vector3d misalignment = Eigen::Vector3d::Zero();
  /// Offset d [m] of the nozzle plane from the tip frame origin along the tip z axis. Each jet force
  /// f then also applies the moment (d e_z) × f = d (−f_y, f_x, 0). 0 = forces act at the origin,
  /// as in the paper.
  double nozzle_offset = 0.0;
};

/// Table 1's calibrated misalignments (δα, δβ, δγ) = (0.12, 0.06, −0.08) [rad].
inline JetGeometry hydrojet_geometry() {
  JetGeometry g;
  g.misalignment = Eigen::Vector3d(0.12, 0.06, -0.08);
  return g;
}

/// Linear map from jet forces q = (q1, q2, q3) [N] to the tip body wrench
/// w = [f_x f_y f_z m_x m_y m_z] ([N], [N m]), eq. (24) extended to six rows.
class JetMap {
 public:
  JetMap() : JetMap(JetGeometry()) {}
  explicit JetMap(const JetGeometry& geometry);

  /// The 2×3 matrix A of eq. (24): rows f_x, f_y [N per N of jet force].
  const Eigen::Matrix<double, 2, 3>& planar() const { return planar_; }

  /// 6×3 body-wrench matrix: column i is the wrench of jet i per unit jet force ([N]/[N] for rows
  /// f_x..f_z, [N m]/[N] for rows m_x..m_z). Rows f_x, f_y are A; f_z = 0; the moment rows are
  /// (nozzle_offset e_z) × force (zero for the default geometry).
  const Eigen::Matrix<double, 6, 3>& wrench_matrix() const { return wrench_; }

  /// Body wrench [N, N m] produced by jet forces q [N].
  Vec6 wrench(const Eigen::Vector3d& q) const { return wrench_ * q; }

  const JetGeometry& geometry() const { return geometry_; }

 private:
  JetGeometry geometry_;
  Eigen::Matrix<double, 2, 3> planar_;
  Eigen::Matrix<double, 6, 3> wrench_;
};

}  // namespace actuation
}  // namespace hydrojet
