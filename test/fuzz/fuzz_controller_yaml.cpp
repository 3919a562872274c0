// Controller options (config/controller.yaml, controller_node's private parameters): gains, limits,
// safety, path, flow regulator, modal law, teleop. Contract (config/controller_config.h): a YAML
// syntax error is the loader's (YAML::Exception, turned into ParamError by
// load_controller_options); parse_controller_options() fails only with ParamError naming the key;
// accepted options validate.
#include "fuzz_common.h"
#include "hydrojet_control/config/controller_config.h"

using namespace hydrojet;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  YAML::Node root;
  if (!fuzz::as_yaml(data, size, &root)) return 0;
  config::ControllerNodeOptions o;
  try {
    o = config::parse_controller_options(root);
  } catch (const config::ParamError& e) {
    FUZZ_CHECK(std::string(e.what()).size() > 0, "an error says what");
    return 0;
  }
  FUZZ_CHECK(o.controller.validate().empty(), "accepted controller options validate");
  FUZZ_CHECK(o.rate > 0.0 && o.rate <= 10000.0, "a usable control rate");
  return 0;
}
