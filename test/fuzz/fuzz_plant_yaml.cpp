// Plant files (config/plant.yaml, config/plants/*.yaml): the simulated plant's mismatch, valves,
// sensors, noise and latency, on the HydroJet's nominal scene. Contract (config/plant_config.h):
// make_plant() fails only with a KeyError naming the key; an accepted plant validates
// (PlantModel::validate() empty), so the simulator never starts on a description it refuses.
#include <fstream>
#include <sstream>

#include "fuzz_common.h"
#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/config/scene.h"

using namespace hydrojet;

namespace {

const config::Scene& nominal() {
  static const config::Scene scene = config::load_scene(HYDROJET_SOURCE_DIR "/config/scenes/hydrojet_0deg.yaml");
  return scene;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size > 8192) return 0;
  plant::PlantModel model;
  try {
    model = config::make_plant(nominal(), fuzz::as_text(data, size));
  } catch (const config::KeyError& e) {
    FUZZ_CHECK(std::string(e.what()).size() > 0, "an error says what");
    return 0;
  }
  FUZZ_CHECK(model.validate().empty(), "an accepted plant validates");
  return 0;
}
