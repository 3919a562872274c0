// The calibration parameter vector ζ of a scene: Campisano et al. 2021, §6.2, eq. (27), and the same
// idea for any follower-actuated robot. ROS-free (Eigen + the scene library).
//
// The paper's form, for a scene of one segment with a `jets` section (the HydroJet):
//   ζ = [u_x, u_y, E, G, δα, δβ, δγ]
// (the paper lists G before E; here, in the CLI and in every report the order is the one above).
// u_x, u_y: precurvature ũ [1/m] (ũ_z is kept from the scene); E, G: Young's and shear moduli [Pa]
// of the body modelled as a hollow cylinder; δα, δβ, δγ: jet misalignments [rad] (eq. 24).
//
// The general form, for any other scene (segments k = 1..S, actuators anywhere along the body):
//   ux<k>, uy<k> [1/m]  precurvature ũ_x, ũ_y of segment k (ũ_z kept)
//   bend<k>             scale of segment k's bending stiffness EI_x, EI_y (1 = the scene's)
//   bend                one scale of every segment's bending stiffness (S ≥ 2): the fallback when
//                       the data cannot tell the segments' scales apart
//   twist               one scale of every segment's torsional stiffness GJ
//   da, db, dg [rad]    the mount of the actuators at the tip, rotated by exp([δα δβ δγ]^) in the tip
//                       frame (positions and directions); for a `jets` section eq. 24's misalignments
// Scales are estimated as their logarithm (they stay positive), like E and G.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "hydrojet_control/config/scene.h"

namespace hydrojet {
namespace calibration {

/// Indices of the paper's form (Zeta::paper_form()).
constexpr int kNumParams = 7;
enum Param { kUx = 0, kUy = 1, kE = 2, kG = 3, kDa = 4, kDb = 5, kDg = 6 };

/// Values of ζ in the order of the scene's Zeta (physical units).
using ZetaVector = Eigen::VectorXd;
/// One flag per parameter of ζ (fitted, identifiable, at a bound, ...).
using ParamMask = std::vector<bool>;

/// Cross-section of the body: a hollow cylinder (paper §6.2: outer 8 mm, inner 6 mm).
///   I = π(D⁴ − d⁴)/64,  EI_x = EI_y = E·I,  GJ = G·J with J = 2I.
struct CrossSection {
  double outer_diameter = 0.008;                                 ///< D [m]
  double inner_diameter = 0.006;                                 ///< d [m], 0 ≤ d < D
  double second_moment() const;                                  ///< I [m^4]
  double polar_moment() const { return 2.0 * second_moment(); }  ///< J [m^4]
  std::string validate() const;                                  ///< empty when usable, else a message naming the field
};

/// The diameters a scene file states (rod.outer_diameter / rod.inner_diameter, present when the
/// scene gives its stiffness as moduli), else `fallback`. Reads the YAML text itself: the Scene
/// struct keeps only the stiffness. Throws config::SceneError on malformed values.
CrossSection cross_section_from_scene_text(const std::string& yaml_text, const CrossSection& fallback);

/// What one component of ζ changes in the scene.
enum class ParamKind {
  kPrecurvatureX,  ///< ũ_x of `segment` [1/m]
  kPrecurvatureY,  ///< ũ_y of `segment` [1/m]
  kYoungsModulus,  ///< E [Pa] (paper's form): EI_x = EI_y = E·I
  kShearModulus,   ///< G [Pa] (paper's form): GJ = G·J
  kBendingScale,   ///< EI_x, EI_y of `segment` (every segment when −1) × the value
  kTorsionScale,   ///< GJ of every segment × the value
  kMount,          ///< rotation of the tip actuators' mount about `axis` [rad]
};

struct Parameter {
  std::string name;  ///< the CLI's --fit name and the JSON key ("ux", "bend2", "da")
  std::string unit;  ///< "1/m", "Pa", "rad", "" for a scale
  ParamKind kind = ParamKind::kPrecurvatureX;
  int segment = -1;          ///< 0-based segment it belongs to; −1: every segment
  int axis = 0;              ///< kMount: 0, 1, 2 for δα, δβ, δγ
  bool logarithmic = false;  ///< positive; estimated as ln(value/start)
  /// A fitted parameter whose standard deviation exceeds this is reported as not identifiable by
  /// the data (relative for logarithmic parameters).
  double resolution = 0.0;
};

/// The parameters ζ of one scene, their values in it, and the scene at other values.
class Zeta {
 public:
  /// Throws config::SceneError("actuators") when the scene has no actuator (nothing to excite the
  /// rod with) and std::invalid_argument for an unusable cross-section (paper's form only).
  Zeta(const config::Scene& scene, const CrossSection& cross_section);

  /// One segment with a `jets` section: ζ = [u_x, u_y, E, G, δα, δβ, δγ], indices kUx..kDg.
  bool paper_form() const { return paper_form_; }
  int size() const { return static_cast<int>(params_.size()); }
  const Parameter& operator[](int i) const { return params_[i]; }
  /// Index of a parameter name, or −1.
  int index(const std::string& name) const;
  /// The names, comma separated ("ux, uy, E, G, da, db, dg"), for messages.
  std::string names() const;
  /// Parses "ux,uy,E" into a mask; throws std::invalid_argument naming an unknown or repeated name,
  /// or both `bend` and a `bend<k>`.
  ParamMask parse(const std::string& list) const;
  /// What is fitted when nothing is said: every parameter, except the common `bend` (the per-segment
  /// scales come first) and `twist` when no actuator twists the rod (no data could tell it).
  ParamMask default_fit() const;
  /// The per-segment bending scales of the mask swapped for the common one.
  ParamMask with_common_bending_scale(const ParamMask& mask) const;
  /// Indices of the per-segment bending scales (general form, S ≥ 2), and of the common one (−1 if none).
  std::vector<int> segment_bending_scales() const;
  int common_bending_scale() const { return common_bend_; }

  /// ζ of the scene: ũ_x, ũ_y; E = mean(EI_x, EI_y)/I, G = GJ/J; scales 1; the jets' misalignments
  /// (zero for actuators listed one by one: their mount is the reference).
  const ZetaVector& start() const { return start_; }
  /// The scene with ζ applied (everything ζ does not name is unchanged).
  config::Scene apply(const ZetaVector& zeta) const;

  /// Model pieces for the fit: the rod at ζ without its tip actuators (those the mount rotation
  /// moves), which load the tip as the wrench mount_wrenches(δ) q_mount instead.
  rod::RodModel rod_without_mount(const ZetaVector& zeta) const;
  /// 6 × (tip actuators) unit body wrenches at mount rotation δ = (δα, δβ, δγ).
  Eigen::Matrix<double, 6, Eigen::Dynamic> mount_wrenches(const Eigen::Vector3d& delta) const;
  /// (δα, δβ, δγ) of ζ [rad] (zero when no actuator sits at the tip).
  Eigen::Vector3d mount_rotation(const ZetaVector& zeta) const;
  /// Inputs (indices into the scene's actuators) at the tip mount and elsewhere, in scene order.
  const std::vector<int>& mount_inputs() const { return mount_inputs_; }
  const std::vector<int>& body_inputs() const { return body_inputs_; }

  const config::Scene& scene() const { return scene_; }
  const CrossSection& cross_section() const { return cs_; }

 private:
  void add(const std::string& name, const std::string& unit, ParamKind kind, int segment, int axis, bool logarithmic,
           double resolution, double start);

  config::Scene scene_;
  rod::RodModel body_rod_;  ///< the scene's rod with only the actuators off the tip mount (rod_without_mount's base)
  CrossSection cs_;
  bool paper_form_ = false;
  std::vector<Parameter> params_;
  ZetaVector start_;
  int common_bend_ = -1;
  int first_mount_ = -1;  ///< index of δα (δβ, δγ follow), −1 when no actuator sits at the tip
  std::vector<int> mount_inputs_, body_inputs_;
};

}  // namespace calibration
}  // namespace hydrojet
