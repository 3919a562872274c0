// Scene files (YAML text: rod or rod.segments, tip, gravity, solver, jets, loads, actuators,
// nozzle). Contract (config/scene.h, config/yaml_tree.h): parse_scene() fails only with
// SceneError naming a key; an accepted scene is a valid general rod (RodModel::validate()
// empty) with a positive, finite length.
#include <cmath>

#include "fuzz_common.h"
#include "hydrojet_control/config/scene.h"

using namespace hydrojet;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size > 8192) return 0;  // scene files are a few hundred bytes
  config::Scene scene;
  try {
    scene = config::parse_scene(fuzz::as_text(data, size));
  } catch (const config::SceneError& e) {
    FUZZ_CHECK(std::string(e.what()).size() > 0, "an error says what");
    return 0;
  }
  FUZZ_CHECK(scene.rod.validate().empty(), "an accepted scene is a valid rod");
  const double L = scene.rod.length();
  FUZZ_CHECK(std::isfinite(L) && L > 0.0, "an accepted scene has a positive length");
  FUZZ_CHECK(!scene.rod.segments.empty(), "an accepted scene has a segment");
  return 0;
}
