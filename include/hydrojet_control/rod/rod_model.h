// The robot's description (RodModel: segments, point loads, actuators, tip mass, gravity) and the
// Kirchhoff rod of Campisano et al. 2021, §3, between two of its stations, written for integration
// from the tip (s = L) back to the base (s = 0) as in §7.2. ROS-free (Eigen only).
//
// Paper equations and where they live here:
//   (6)  p' = R e_z                                 -> RodOde::operator(), "p'"
//   (8)  R' = R û                                    -> RodOde::operator(), "R'"
//   (9)  M_b = K (u − ũ)                             -> RodOde (moment from curvature)
//   (12) Q_b' = −û Q_b − f_b   (body frame)          -> closed form in the base frame: n(s) below
//   (13) f = m_b g, P = m_t g                        -> w_dist here; the masses at the stations
//                                                       (src/rod/kernels/sweep_impl.h, apply_station)
//   (14) u' = ũ' − K⁻¹((ûK + K')(u − ũ) + m_b + ê_z Q_b)   -> RodOde::operator(), "u'"
//   (15) p(0) = 0, R(0) = I                          -> the shooting residual (RodSolver)
//   (16)/(25) Q_b(L) = w_f + R(L)ᵀ m_t g, u(L) − ũ = K⁻¹ w_m -> the tip station (apply_station)
//
// Internal force in the base frame: n(s) = R(s) Q_b(s). Because the only distributed force is the
// body weight ρA·g (constant in the base frame on a segment), n' = −ρA g integrates in closed form
// between two stations:  n(σ) = n(s) + ρA g (s − σ),  n(L) = R(L) f_b + m_t g.
// So the state is y = [p, R, u] (15 numbers) and the only shooting unknown is the tip orientation
// R(L) (3 numbers): integrate back to the base and require R(0) = I.
//
// Shearable and extensible (Cosserat) variant, kind = kCosserat: the strains v (shear and
// extension) follow from the same closed-form n(s) through K_se = diag(GA, GA, EA):
//   v = e_z + K_se⁻¹ Rᵀ n,   p' = R v,   u' = −K⁻¹(u × K(u − ũ) + v × Q_b)
// (the moment balance m' = −p' × n in the body frame). As EA, GA → ∞, v → e_z: the Kirchhoff rod.
//
// Model specialisation ("leave out what the model does not need"): RodOde is a template over
// RodTerms, compile-time switches for the Cosserat strains, the distributed load ρA·g and the
// precurvature. The solver picks the smallest variant that holds the model's terms once, at model
// load; the hot loop has no branches on them. RodOde<D> without a second argument is the general
// Kirchhoff variant (every Kirchhoff term). Isotropic bending (EIx = EIy) is not a variant: K is a
// diagonal held as a vector, so isotropy saves nothing (a rewritten u × K(u − ũ) for
// K = diag(k, k, GJ) measured slower).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace rod {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

/// Which constitutive model the rod follows.
enum class RodKind {
  kKirchhoff,  ///< inextensible and unshearable (paper §3): v = e_z
  kCosserat,   ///< shearable and extensible: v = e_z + K_se⁻¹ Rᵀ n, K_se = diag(GA, GA, EA)
};

/// Most actuator inputs a model may have: the storage bound of InputVector (no heap allocation).
constexpr int kMaxInputs = 8;
/// Actuator inputs q [N] (or flows, valve duties: one entry per actuator), in the model's actuator order.
using InputVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxInputs, 1>;

/// One piece of the rod with uniform material and precurvature, base to tip.
struct RodSegment {
  double length = 0.0;               ///< [m], > 0
  Vec3 stiffness = Vec3::Zero();     ///< diag(E·Ix, E·Iy, G·J) [N m^2], each > 0
  Vec3 precurvature = Vec3::Zero();  ///< ũ in the body frame [1/m]
  double linear_density = 0.0;       ///< ρA [kg/m], ≥ 0
  double shear_stiffness = 0.0;      ///< GA [N] (Cosserat only; then > 0)
  double axial_stiffness = 0.0;      ///< EA [N] (Cosserat only; then > 0)

  /// diag(K_se⁻¹) [1/N] of a Cosserat rod; zero for the Kirchhoff rod (the limit EA, GA → ∞).
  Vec3 shear_extension_compliance(RodKind kind) const {
    if (kind != RodKind::kCosserat) return Vec3::Zero();
    return Vec3(1.0 / shear_stiffness, 1.0 / shear_stiffness, 1.0 / axial_stiffness);
  }
};

/// In which frame a point load's force and moment are fixed.
enum class LoadFrame {
  kBody,  ///< the body frame at its arc length: a follower load
  kBase,  ///< the base frame: a dead load (as a weight)
};

/// A wrench applied at one point of the backbone (besides the tip's), at the centreline.
struct PointLoad {
  double at = 0.0;                     ///< arc length s [m], 0 < s ≤ L
  double mass = 0.0;                   ///< [kg], ≥ 0: its weight m·g (base frame) acts at s
  Vec3 force = Vec3::Zero();           ///< [N], in `frame`
  Vec3 moment = Vec3::Zero();          ///< [N m], in `frame`
  LoadFrame frame = LoadFrame::kBody;  ///< frame of force and moment
};

/// How an actuator's input becomes its force.
enum class ActuatorType {
  kForce,  ///< the input q is the force [N]
  kJet,    ///< a water jet: q from the flow by the thrust equation (26) (needs the scene's nozzle)
};

/// One actuator: input q [N] applies the follower force q·direction at `position` of the body frame
/// at arc length `at`, i.e. the body wrench q·(d, p × d) at the centreline there.
struct Actuator {
  std::string name;
  double at = 0.0;                 ///< arc length s [m], 0 < s ≤ L
  Vec3 position = Vec3::Zero();    ///< point of application, body frame at s [m] (moment arm)
  Vec3 direction = Vec3::UnitX();  ///< unit force direction on the rod, body frame at s
  double min_force = 0.0;          ///< [N] (negative: reversible)
  double max_force = 0.0;          ///< [N], ≥ min_force
  ActuatorType type = ActuatorType::kForce;

  /// Body wrench (f, m) at the centreline at s per unit input: (d, p × d).
  Vec6 unit_wrench() const {
    Vec6 w;
    w << direction, position.cross(direction);
    return w;
  }
};

/// The robot: everything its static model needs besides the inputs. The HydroJet is one uniform
/// segment with three jets at the tip (eq. 24); any follower-actuated robot is segments, point loads
/// and actuators anywhere along the body.
struct RodModel {
  std::vector<RodSegment> segments;  ///< base to tip, at least one
  RodKind kind = RodKind::kKirchhoff;
  std::vector<PointLoad> loads;     ///< besides the tip's, any order
  std::vector<Actuator> actuators;  ///< inputs in this order (0..kMaxInputs of them)
  double tip_mass = 0.0;            ///< m_t [kg] at s = L
  double tip_radius = 0.007;        ///< [m] the tip's contact sphere about s = L (the capsule; keep-out regions)
  Vec3 gravity = Vec3::Zero();      ///< g in the base frame [m/s^2]

  /// L [m]: the sum of the segment lengths.
  double length() const {
    double L = 0.0;
    for (const auto& s : segments) L += s.length;
    return L;
  }
  int input_count() const { return static_cast<int>(actuators.size()); }
  /// The same rod without its actuators: loaded by a tip wrench alone.
  RodModel without_actuators() const {
    RodModel m = *this;
    m.actuators.clear();
    return m;
  }
  /// One uniform segment, no point loads and every actuator at the tip: the tip wrench says it all
  /// (the solver then integrates one piece, and J_q = C^b W).
  bool tip_actuated_uniform() const;
  /// Empty when valid, else a message naming the offending field ("segments[1].length: ...").
  std::string validate() const;
  /// Empty when q has one input per actuator, each within its [min_force, max_force]; else a message
  /// naming the first that is not ("input 2 (jet2) = 0.3 N lies outside ...", counted from 1).
  std::string check_inputs(const Eigen::Ref<const Eigen::VectorXd>& q) const;
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

/// Compile-time switches of the right-hand side: which terms of the model are computed.
template <bool Cosserat, bool DistributedLoad, bool Precurved>
struct RodTerms {
  static constexpr bool kCosserat = Cosserat;                ///< shear/extension strains v
  static constexpr bool kDistributedLoad = DistributedLoad;  ///< n(s) varies (ρA·g ≠ 0)
  static constexpr bool kPrecurved = Precurved;              ///< ũ ≠ 0
};
using KirchhoffGeneral = RodTerms<false, true, true>;  ///< every Kirchhoff term
using CosseratGeneral = RodTerms<true, true, true>;    ///< every term (Kirchhoff: K_se⁻¹ = 0)

/// The same switches at run time: what a given model needs (see needed_terms()).
struct RodTermSet {
  bool cosserat = false;
  bool distributed_load = true;
  bool precurved = true;
  bool operator==(const RodTermSet& o) const {
    return cosserat == o.cosserat && distributed_load == o.distributed_load && precurved == o.precurved;
  }
};

/// The terms a model needs: Cosserat only for kCosserat, the distributed load only when some ρA·g ≠ 0,
/// the precurvature only when some ũ ≠ 0.
inline RodTermSet needed_terms(const RodModel& m) {
  RodTermSet t;
  t.cosserat = m.kind == RodKind::kCosserat;
  t.distributed_load = false;
  t.precurved = false;
  for (const RodSegment& s : m.segments) {
    t.distributed_load = t.distributed_load || (s.linear_density != 0.0 && m.gravity.squaredNorm() != 0.0);
    t.precurved = t.precurved || s.precurvature.squaredNorm() != 0.0;
  }
  return t;
}

/// Right-hand side of the rod ODE plus D forward-mode sensitivity directions.
///
/// State layout: [p(3), R(9, column-major), u(3)] then, per direction d, [η(3), δu(3), δp(3)] where
/// the perturbed orientation is R·exp(η̂), the perturbed curvature u + δu, the perturbed position
/// p + δp. The linearised equations (derived from p' = R v, R' = R û and eq. 14):
///   η'  = δu − u × η
///   δp' = R (η × v + δv)                          (Kirchhoff: v = e_z, δv = 0)
///   δu' = −K⁻¹( δu × K(u − ũ) + u × K δu + δv × Q_b + v × δQ_b ),  δQ_b = −η × Q_b + Rᵀ δn_d
///   δv  = K_se⁻¹ δQ_b                              (Cosserat only)
/// where δn_d is the (constant, base-frame) change of n(L) caused by direction d.
/// T (RodTerms) selects the compiled terms; the fields a variant does not use are ignored.
template <int D, class T = KirchhoffGeneral>
struct RodOde {
  static constexpr int kBase = 15;
  static constexpr int kPerDir = 9;
  static constexpr int kDirections = D;
  static constexpr int kSize = kBase + kPerDir * D;
  using State = Eigen::Matrix<double, kSize, 1>;
  using BaseState = Eigen::Matrix<double, kBase, 1>;
  using Terms = T;

  // Fixed for one integration.
  Vec3 k_diag;                                   ///< diag(K)
  Vec3 k_inv;                                    ///< diag(K⁻¹)
  Vec3 u_tilde;                                  ///< ũ
  Vec3 n_tip;                                    ///< n(L), base frame [N]
  Vec3 w_dist;                                   ///< ρA g, base frame [N/m]
  double length = 0;                             ///< L [m]
  Vec3 kse_inv = Vec3::Zero();                   ///< diag(K_se⁻¹) [1/N] (Cosserat terms; 0 = Kirchhoff limit)
  Eigen::Matrix<double, 3, (D > 0 ? D : 1)> dn;  ///< δn_d per direction (base frame)

  /// n(s) in the base frame.
  Vec3 internal_force(double s) const {
    if constexpr (T::kDistributedLoad) {
      return n_tip + w_dist * (length - s);
    } else {
      return n_tip;
    }
  }
  void operator()(double s, const State& y, State& dy) const {
    const Eigen::Map<const Mat3> R(y.data() + 3);
    const Vec3 u = y.template segment<3>(12);
    Vec3 Qb;  // internal force, body frame
    if constexpr (T::kDistributedLoad) {
      Qb.noalias() = R.transpose() * (n_tip + w_dist * (length - s));
    } else {
      Qb.noalias() = R.transpose() * n_tip;
    }
    Vec3 Ku;  // internal moment M_b, eq. (9)
    if constexpr (T::kPrecurved) {
      Ku = k_diag.cwiseProduct(u - u_tilde);
    } else {
      Ku = k_diag.cwiseProduct(u);
    }
    Eigen::Map<Mat3> dR(dy.data() + 3);
    dR.col(0) = R.col(1) * u.z() - R.col(2) * u.y();
    dR.col(1) = R.col(2) * u.x() - R.col(0) * u.z();
    dR.col(2) = R.col(0) * u.y() - R.col(1) * u.x();
    if constexpr (T::kCosserat) {
      const Vec3 v = Vec3::UnitZ() + kse_inv.cwiseProduct(Qb);
      dy.template segment<3>(0) = R * v;  // p' = R v
      dy.template segment<3>(12) = -k_inv.cwiseProduct(u.cross(Ku) + v.cross(Qb));
      for (int d = 0; d < D; ++d) {
        const int o = kBase + kPerDir * d;
        const Vec3 eta = y.template segment<3>(o);
        const Vec3 du = y.template segment<3>(o + 3);
        const Vec3 dQb = -eta.cross(Qb) + R.transpose() * dn.col(d);
        const Vec3 dv = kse_inv.cwiseProduct(dQb);
        dy.template segment<3>(o) = du - u.cross(eta);
        dy.template segment<3>(o + 3) =
            -k_inv.cwiseProduct(du.cross(Ku) + u.cross(k_diag.cwiseProduct(du)) + dv.cross(Qb) + v.cross(dQb));
        dy.template segment<3>(o + 6) = R * (eta.cross(v) + dv);  // R (η × v + δv)
      }
    } else {
      dy.template segment<3>(0) = R.col(2);  // eq. (6): p' = R e_z
      const Vec3 ez_x_Qb(-Qb.y(), Qb.x(), 0.0);
      dy.template segment<3>(12) = -k_inv.cwiseProduct(u.cross(Ku) + ez_x_Qb);
      for (int d = 0; d < D; ++d) {
        const int o = kBase + kPerDir * d;
        const Vec3 eta = y.template segment<3>(o);
        const Vec3 du = y.template segment<3>(o + 3);
        const Vec3 dQb = -eta.cross(Qb) + R.transpose() * dn.col(d);
        const Vec3 ez_x_dQb(-dQb.y(), dQb.x(), 0.0);
        dy.template segment<3>(o) = du - u.cross(eta);
        dy.template segment<3>(o + 3) = -k_inv.cwiseProduct(du.cross(Ku) + u.cross(k_diag.cwiseProduct(du)) + ez_x_dQb);
        dy.template segment<3>(o + 6) = R * Vec3(eta.y(), -eta.x(), 0.0);  // R (η × e_z)
      }
    }
  }

  /// Directional derivative of the base right-hand side (the first 15 components) in the plain
  /// state coordinates: given y and a change (δp, δR (9), δu) of it and a change δn of n(L),
  /// returns δ(dy/ds). Exact (it is the Jacobian–vector product), used for CVODE's Jacobian and
  /// CVODES' forward sensitivities.
  template <class Y, class DY, class Out>
  void jvp(double s, const Y& y, const DY& dyin, const Vec3& dn_in, Out&& out) const {
    const Eigen::Map<const Mat3> R(y.data() + 3);
    const Eigen::Map<const Mat3> dR(dyin.data() + 3);
    const Vec3 u = y.template segment<3>(12);
    const Vec3 du = dyin.template segment<3>(12);
    const Vec3 n = internal_force(s);
    const Vec3 Qb = R.transpose() * n;
    const Vec3 dQb = dR.transpose() * n + R.transpose() * dn_in;
    const Vec3 Ku = T::kPrecurved ? Vec3(k_diag.cwiseProduct(u - u_tilde)) : Vec3(k_diag.cwiseProduct(u));
    const Vec3 Kdu = k_diag.cwiseProduct(du);
    Vec3 v = Vec3::UnitZ(), dv = Vec3::Zero();
    if constexpr (T::kCosserat) {
      v += kse_inv.cwiseProduct(Qb);
      dv = kse_inv.cwiseProduct(dQb);
    }
    out.template segment<3>(0) = dR * v + R * dv;
    Mat3 dRp;
    dRp.col(0) = dR.col(1) * u.z() - dR.col(2) * u.y() + R.col(1) * du.z() - R.col(2) * du.y();
    dRp.col(1) = dR.col(2) * u.x() - dR.col(0) * u.z() + R.col(2) * du.x() - R.col(0) * du.z();
    dRp.col(2) = dR.col(0) * u.y() - dR.col(1) * u.x() + R.col(0) * du.y() - R.col(1) * du.x();
    for (int c = 0; c < 3; ++c) out.template segment<3>(3 + 3 * c) = dRp.col(c);
    out.template segment<3>(12) = -k_inv.cwiseProduct(du.cross(Ku) + u.cross(Kdu) + dv.cross(Qb) + v.cross(dQb));
  }
};

}  // namespace rod
}  // namespace hydrojet
