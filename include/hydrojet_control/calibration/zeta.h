// The calibration parameter vector ζ of Campisano et al. 2021, §6.2, eq. (27):
//   ζ = [u_x, u_y, E, G, δα, δβ, δγ]
// (the paper lists G before E; here, in the CLI and in every report the order is the one above).
// u_x, u_y: precurvature ũ [1/m] (ũ_z is kept from the scene); E, G: Young's and shear moduli [Pa]
// of the body modelled as a hollow cylinder; δα, δβ, δγ: jet misalignments [rad] (eq. 24).
// ROS-free (Eigen + the scene library).
#pragma once

#include <array>
#include <string>

#include <Eigen/Core>

#include "hydrojet_control/config/scene.h"

namespace hydrojet {
namespace calibration {

constexpr int kNumParams = 7;
enum Param { kUx = 0, kUy = 1, kE = 2, kG = 3, kDa = 4, kDb = 5, kDg = 6 };

using ZetaVector = Eigen::Matrix<double, kNumParams, 1>;
using ParamMask = std::array<bool, kNumParams>;

/// "ux", "uy", "E", "G", "da", "db", "dg" (the CLI's --fit names and the JSON keys).
const char* param_name(int i);
/// "1/m", "1/m", "Pa", "Pa", "rad", "rad", "rad".
const char* param_unit(int i);
/// Index of a parameter name (as param_name), or -1.
int param_index(const std::string& name);
/// Parses "ux,uy,E" into a mask; throws std::invalid_argument naming an unknown or repeated name.
ParamMask parse_param_list(const std::string& list);
inline ParamMask all_params() { return {true, true, true, true, true, true, true}; }

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

/// ζ of a scene: ũ_x, ũ_y; E = mean(EI_x, EI_y)/I; G = GJ/J; the jet misalignments (zero when the
/// scene has no jets section).
ZetaVector zeta_from_scene(const config::Scene& scene, const CrossSection& cs);

/// The scene with ζ applied: stiffness (E·I, E·I, G·J), precurvature (u_x, u_y, ũ_z of the
/// scene), jet misalignments. Everything else (tip, gravity, solver, nozzles) is unchanged.
config::Scene apply_zeta(const config::Scene& scene, const ZetaVector& zeta, const CrossSection& cs);

}  // namespace calibration
}  // namespace hydrojet
