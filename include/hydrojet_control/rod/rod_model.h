// The Kirchhoff rod of Campisano et al. 2021, §3, under a tip follower wrench, gravity and
// precurvature, written for integration from the tip (s = L) back to the base (s = 0) as in §7.2.
// ROS-free (Eigen only).
//
// Paper equations and where they live here:
//   (6)  p' = R e_z                                 -> RodOde::operator(), "p'"
//   (8)  R' = R û                                    -> RodOde::operator(), "R'"
//   (9)  M_b = K (u − ũ)                             -> RodOde (moment from curvature)
//   (12) Q_b' = −û Q_b − f_b   (body frame)          -> closed form in the base frame: n(s) below
//   (13) f = m_b g, P = m_t g                        -> RodModel::tip_force_base / distributed_weight
//   (14) u' = ũ' − K⁻¹((ûK + K')(u − ũ) + m_b + ê_z Q_b)   -> RodOde::operator(), "u'"
//   (15) p(0) = 0, R(0) = I                          -> the shooting residual (ShootingSolver)
//   (16)/(25) Q_b(L) = w_f + R(L)ᵀ m_t g, u(L) − ũ = K⁻¹ w_m -> RodOde tip values
//
// Internal force in the base frame: n(s) = R(s) Q_b(s). Because the only distributed force is the
// body weight ρA·g (constant in the base frame), n' = −ρA g integrates in closed form:
//   n(s) = n(L) + ρA g (L − s),   n(L) = R(L) f_b + m_t g.
// So the state is y = [p, R, u] (15 numbers) and the only shooting unknown is the tip orientation
// R(L) (3 numbers): integrate back to the base and require R(0) = I.
#pragma once

#include <Eigen/Core>

#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace rod {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

/// Material and geometry of the rod. Uniform along s; stiffness_at()/precurvature_at() are the
/// seam for K(s) and ũ(s) (their s-derivatives enter eq. 14 as K' and ũ').
struct RodParameters {
  double length = 0.09;                      ///< L [m]
  Vec3 stiffness = Vec3(6.01e-4, 6.01e-4, 2.23e-4);  ///< diag(E·Ix, E·Iy, G·J) [N m^2]
  Vec3 precurvature = Vec3::Zero();          ///< ũ in the body frame [1/m]
  double linear_density = 0.0;               ///< ρA [kg/m]; 0 = massless body

  Vec3 stiffness_at(double /*s*/) const { return stiffness; }
  Vec3 precurvature_at(double /*s*/) const { return precurvature; }
};

/// Everything the static model needs besides the actuation wrench.
struct RodModel {
  RodParameters rod;
  double tip_mass = 0.0;              ///< m_t [kg]
  Vec3 gravity = Vec3::Zero();        ///< g in the base frame [m/s^2]
};

/// Follower wrench at the tip, expressed in the tip frame (w_a of eq. 16).
struct TipWrench {
  Vec3 force = Vec3::Zero();   ///< f_b [N]
  Vec3 moment = Vec3::Zero();  ///< l_b [N m]
  Vec6 stacked() const {
    Vec6 w;
    w << force, moment;
    return w;
  }
};

/// Right-hand side of the rod ODE plus D forward-mode sensitivity directions.
///
/// State layout: [p(3), R(9, column-major), u(3)] then, per direction d, [η(3), δu(3), δp(3)] where
/// the perturbed orientation is R·exp(η̂), the perturbed curvature u + δu, the perturbed position
/// p + δp. The linearised equations (derived from p' = R e_z, R' = R û and eq. 14):
///   η'  = δu − u × η
///   δp' = R (η × e_z)
///   δu' = −K⁻¹( δu × K(u − ũ) + u × K δu + e_z × δQ_b ),  δQ_b = −η × Q_b + Rᵀ δn_d
/// where δn_d is the (constant, base-frame) change of n(L) caused by direction d.
template <int D>
struct RodOde {
  static constexpr int kBase = 15;
  static constexpr int kPerDir = 9;
  static constexpr int kSize = kBase + kPerDir * D;
  using State = Eigen::Matrix<double, kSize, 1>;

  // Fixed for one integration.
  Vec3 k_diag;       ///< diag(K)
  Vec3 k_inv;        ///< diag(K⁻¹)
  Vec3 u_tilde;      ///< ũ
  Vec3 n_tip;        ///< n(L), base frame [N]
  Vec3 w_dist;       ///< ρA g, base frame [N/m]
  double length = 0; ///< L [m]
  Eigen::Matrix<double, 3, (D > 0 ? D : 1)> dn;  ///< δn_d per direction (base frame)

  void operator()(double s, const State& y, State& dy) const {
    const Eigen::Map<const Mat3> R(y.data() + 3);
    const Vec3 u = y.template segment<3>(12);
    const Vec3 n = n_tip + w_dist * (length - s);
    const Vec3 Qb = R.transpose() * n;             // internal force, body frame
    const Vec3 Ku = k_diag.cwiseProduct(u - u_tilde);  // internal moment M_b, eq. (9)
    // eq. (6): p' = R e_z
    dy.template segment<3>(0) = R.col(2);
    // eq. (8): R' = R û  (column-major: d/ds of the columns of R)
    Eigen::Map<Mat3> dR(dy.data() + 3);
    dR.col(0) = R.col(1) * u.z() - R.col(2) * u.y();
    dR.col(1) = R.col(2) * u.x() - R.col(0) * u.z();
    dR.col(2) = R.col(0) * u.y() - R.col(1) * u.x();
    // eq. (14) with K' = 0, ũ' = 0, m_b = 0: u' = −K⁻¹(u × K(u−ũ) + e_z × Q_b)
    const Vec3 ez_x_Qb(-Qb.y(), Qb.x(), 0.0);
    dy.template segment<3>(12) = -k_inv.cwiseProduct(u.cross(Ku) + ez_x_Qb);

    for (int d = 0; d < D; ++d) {
      const int o = kBase + kPerDir * d;
      const Vec3 eta = y.template segment<3>(o);
      const Vec3 du = y.template segment<3>(o + 3);
      const Vec3 dQb = -eta.cross(Qb) + R.transpose() * dn.col(d);
      const Vec3 ez_x_dQb(-dQb.y(), dQb.x(), 0.0);
      dy.template segment<3>(o) = du - u.cross(eta);
      dy.template segment<3>(o + 3) =
          -k_inv.cwiseProduct(du.cross(Ku) + u.cross(k_diag.cwiseProduct(du)) + ez_x_dQb);
      dy.template segment<3>(o + 6) = R * Vec3(eta.y(), -eta.x(), 0.0);  // R (η × e_z)
    }
  }
};

}  // namespace rod
}  // namespace hydrojet
