// Writes the calibrated scene (the calibrator's --out file): the starting scene's YAML with ζ put
// in, so that every other key (tip, gravity, solver, loads, later schema additions, other
// top-level sections) is carried over as it was. load_scene() reads the result. ROS-free.
#pragma once

#include <string>

#include <yaml-cpp/yaml.h>

#include "hydrojet_control/calibration/zeta.h"

namespace hydrojet {
namespace calibration {

/// The scene text `original_yaml` with ζ applied. The paper's form (Zeta::paper_form()):
///   rod: bending_stiffness / torsional_stiffness removed; youngs_modulus = E, shear_modulus = G,
///        outer_diameter / inner_diameter of the cross-section; precurvature = [u_x, u_y, ũ_z]
///   jets: misalignment = [δα, δβ, δγ]
/// The general form: each segment's bending_stiffness, torsional_stiffness and precurvature (moduli
/// and diameters replaced by the stiffness they give), and the tip actuators' position and
/// direction (or the jets' misalignment).
/// Everything else as in the original (comments aside). A previous top-level `calibration`
/// section is replaced by `calibration` when that is defined (load_scene ignores the section).
/// `comment` lines come first, each prefixed "# ". Numbers read back exactly.
/// Throws config::SceneError for text that is not the scene `zeta` was made from.
std::string calibrated_scene_yaml(const std::string& original_yaml, const Zeta& zeta, const ZetaVector& values,
                                  const std::string& comment = "", const YAML::Node& calibration = YAML::Node());

/// A number as YAML text that reads back exactly, shortest of 15–17 significant digits ("null"
/// when not finite).
std::string yaml_number(double v);

}  // namespace calibration
}  // namespace hydrojet
