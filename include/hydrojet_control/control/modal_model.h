// The rod's lowest lateral modes about a quasi-static equilibrium, for a controller that knows the
// rod moves: a Rayleigh–Ritz model whose two shapes are the rod's static deflections under a lateral
// tip force (tip-frame x and y). Those shapes carry the masses the scene knows (the tip mass, ρA
// along the body, point masses, an optional capsule inertia); the potential energy is the static
// compliance's. With the mass at the tip, as in the HydroJet, the static shape is the first mode's
// to within a fraction of a percent; with a distributed mass it is Rayleigh's classical estimate
// (m_t + 33/140 ρA L for a uniform cantilever). ROS-free (Eigen, the rod solver).
//
// Coordinates: x ∈ ℝ², the tip's lateral displacement in the tip frame's x and y axes [m]. Equation
// of motion for a lateral tip follower force u [N] (tip frame):  M ẍ + K x = u,  K = C⁻¹ with C the
// (symmetrised) lateral block of the tip's translation compliance. The tip's body rotation is
// `rotation` · x (3 × 2), so its z axis turns by (θ_y, −θ_x) in the tip frame.
#pragma once

#include <string>

#include <Eigen/Core>

#include "hydrojet_control/rod/rod_solver.h"

namespace hydrojet {
namespace control {

struct ModalModel {
  bool ok = false;
  std::string error;                                    ///< why not (a solve that did not converge)
  Eigen::Matrix2d stiffness = Eigen::Matrix2d::Zero();  ///< K [N/m]
  Eigen::Matrix2d mass = Eigen::Matrix2d::Zero();       ///< M [kg]
  Eigen::Vector2d frequency = Eigen::Vector2d::Zero();  ///< ω₁ ≤ ω₂ [rad/s]
  Eigen::Matrix2d modes = Eigen::Matrix2d::Zero();      ///< columns: M-normalised mode shapes in x
  Eigen::Matrix<double, 3, 2> rotation = Eigen::Matrix<double, 3, 2>::Zero();  ///< tip body rotation per x [rad/m]
};

struct ModalOptions {
  rod::Vec3 tip_inertia = rod::Vec3::Zero();  ///< capsule inertia about its centre, tip frame [kg m²]
  /// The tip's mass and inertia in the modes over the scene's tip mass (a capsule that fills with
  /// water is heavier than its weight in the statics says) [-].
  double tip_mass_scale = 1.0;
  int samples = 64;  ///< backbone intervals for the distributed mass
  /// Probe force of the central differences, relative to the rod's force scale max EI / L².
  double probe = 1e-3;
};

/// The modes about the equilibrium at inputs q and extra tip wrench w, from a copy of `solver` (its
/// warm start is used, the caller's solver is not touched): one solve and C^b (the tip's translation
/// and rotation per lateral tip force); a body with mass of its own (ρA, point masses) adds four
/// probe solves for the backbone's shape.
ModalModel lateral_modes(const rod::RodSolver& solver, const rod::InputVector& q, const rod::TipWrench& w,
                         const ModalOptions& options = {});

/// The modes from C^b already computed at the equilibrium (the controller's cycle has it), with no
/// solve; for a body whose mass is all at its tip. A body with mass of its own (has_body_mass) needs
/// the overload above: this one fails with a message saying so.
ModalModel lateral_modes(const rod::RodModel& model, const rod::Mat6& body_compliance,
                         const ModalOptions& options = {});

/// Whether the body carries mass of its own (ρA along a segment, point masses), beyond the tip's.
bool has_body_mass(const rod::RodModel& model);

}  // namespace control
}  // namespace hydrojet
