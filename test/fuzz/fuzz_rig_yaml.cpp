// Rig options (config/rig.yaml, rig_node's private parameters): tracker, flow sensors (units,
// regexes, fields), valve board. Contract (devices/rig_config.h): parse_rig_options() fails only
// with RigOptionsError naming the key; accepted tracker options validate.
#include "fuzz_common.h"
#include "hydrojet_control/devices/rig_config.h"

using namespace hydrojet;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  YAML::Node root;
  if (!fuzz::as_yaml(data, size, &root)) return 0;
  devices::RigOptions o;
  try {
    o = devices::parse_rig_options(root);
  } catch (const devices::RigOptionsError& e) {
    FUZZ_CHECK(std::string(e.what()).size() > 0, "an error says what");
    return 0;
  }
  FUZZ_CHECK(o.tracker.validate().empty(), "accepted tracker options validate");
  return 0;
}
