// identify: the rig's first day, on the simulated plant. The controller holds the tip at rest, probes
// the first mode there (mode_probe.h: a chirp of the jets, fitted with Ceres), then takes the tip
// round four directions 0.3 rad out (the valves' lags learn from the flows meanwhile), and writes
// what it measured to a file that the controller file loads (identification/file):
//   identification: {tip_mass_scale, damping_time, valve_time_constants_s, valve_plays,
//                    tracker_latency_s, mode_hz, damping_ratio}
// The last line of stdout is one JSON object: {"identified": {...}, "plant_truth": {...}, "out": FILE}
// (plant_truth: the simulated plant's own, sim::plant_truth, at the same equilibrium).
//   identify --scene FILE --plant FILE --controller FILE [--seed N] [--out FILE.yaml]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/control/path.h"
#include "hydrojet_control/sim/closed_loop_run.h"
#include "hydrojet_control/util/json_writer.h"

using namespace hydrojet;

namespace {

void usage() {
  std::cerr << "usage: identify --scene FILE --plant FILE --controller FILE [--seed N] [--out FILE.yaml]\n"
               "  the controller's probe and flow sensors on the simulated plant; writes the identification\n"
               "  file the controller file loads (identification/file), default .build/identification.yaml\n";
}

std::string list(const std::vector<double>& v) {
  std::string s = "[";
  char buf[32];
  for (size_t i = 0; i < v.size(); ++i) {
    std::snprintf(buf, sizeof(buf), "%s%.6g", i ? ", " : "", v[i]);
    s += buf;
  }
  return s + "]";
}

/// The command line into the arguments; false (after saying why) on a usage error.
bool parse_args(int argc, char** argv, std::string* scene, std::string* plant, std::string* controller,
                std::string* out, unsigned* seed) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (i + 1 >= argc) {
      std::cerr << "identify: " << arg << ": expects a value\n";
      usage();
      return false;
    }
    const std::string value = argv[++i];
    if (arg == "--scene") {
      *scene = value;
    } else if (arg == "--plant") {
      *plant = value;
    } else if (arg == "--controller") {
      *controller = value;
    } else if (arg == "--out") {
      *out = value;
    } else if (arg == "--seed") {
      char* end = nullptr;
      const long s = std::strtol(value.c_str(), &end, 10);
      if (*end != '\0' || s < 0 || s > 4294967295L) {
        std::cerr << "identify: --seed: must be an integer in [0, 2^32), got '" << value << "'\n";
        return false;
      }
      *seed = static_cast<unsigned>(s);
    } else {
      std::cerr << "identify: " << arg << ": unknown argument\n";
      usage();
      return false;
    }
  }
  if (scene->empty() || plant->empty() || controller->empty()) {
    usage();
    return false;
  }
  return true;
}

/// The probe and a round of four directions 0.3 rad out on the simulated plant (throws on a
/// configuration error).
sim::RunResult run(const std::string& scene_file, const std::string& plant_file, const std::string& controller_file,
                   unsigned seed) {
  config::ControllerNodeOptions o = config::load_controller_options(controller_file);
  o.controller.identification.probe = true;
  o.controller.mode = control::LoopMode::kClosed;
  const config::Scene sc = config::load_scene(scene_file);
  const control::RobotModel model = config::make_controller_model(sc, o.flow_regulator);
  const plant::PlantModel plant = config::load_plant(sc, plant_file);
  std::vector<control::Waypoint> w;
  const control::Vec3 rest = control::direction(0.0, 0.0);
  w.push_back({0.0, rest});
  for (int k = 0; k < 4; ++k) w.push_back({4.0 * (k + 1), control::direction(0.3, k * M_PI / 2)});
  w.push_back({20.0, rest});
  sim::RunPlan plan;
  plan.path = control::make_waypoints(w);
  plan.start = sim::RunStart::kOnPath;
  plan.control_period = 1.0 / o.rate;
  return sim::run_path(model, o.controller, plant, seed, plan);
}

/// The identification file (config::load_identification reads it back); false when it cannot be written.
bool write_file(const std::string& out, const std::string& plant_file, unsigned seed,
                const control::PlantIdentity& id) {
  std::ofstream f(out);
  char buf[2048];
  std::snprintf(buf, sizeof(buf),
                "# The plant present, measured by identify (%s, seed %u): the controller's probe and flow sensors.\n"
                "# Load it with the controller file's identification/file.\n"
                "identification:\n"
                "  tip_mass_scale: %.6g    # the capsule's effective fill: the model's first mode is the one measured\n"
                "  damping_time: %.6g      # [s] Kelvin-Voigt time of that mode's damping\n"
                "  valve_time_constants_s: %s  # [s] per actuator (0: not a jet)\n"
                "  valve_plays: %s  # [duty] per actuator: each valve's play (backlash)\n"
                "  tracker_latency_s: %.6g # [s]\n"
                "  mode_hz: %.6g           # [Hz] at the run's end (rest)\n"
                "  damping_ratio: %.6g     # there\n"
                "  valves_identified: %s\n",
                plant_file.c_str(), seed, id.tip_mass_scale, id.damping_time, list(id.valve_time_constants_s).c_str(),
                list(id.valve_plays).c_str(), id.tracker_latency_s, id.mode_hz, id.damping_ratio,
                id.valves_identified ? "true" : "false");
  f << buf;
  f.close();
  return static_cast<bool>(f);
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene_file, plant_file, controller_file, out = ".build/identification.yaml";
  unsigned seed = 1;
  if (!parse_args(argc, argv, &scene_file, &plant_file, &controller_file, &out, &seed)) return 2;
  sim::RunResult r;
  try {
    r = run(scene_file, plant_file, controller_file, seed);
  } catch (const std::exception& e) {
    std::cerr << "identify: " << e.what() << "\n";
    return 2;
  }
  if (!r.completed) {
    std::cerr << "identify: the run did not complete: " << r.reason << "\n";
    return 1;
  }
  const control::PlantIdentity& id = r.identified;
  if (!id.mode_identified) {
    std::cerr << "identify: the probe's fit did not hold: " << id.mode_error << "\n";
    return 1;
  }
  if (!write_file(out, plant_file, seed, id)) {
    std::cerr << "identify: cannot write '" << out << "'\n";
    return 2;
  }
  std::printf("identified: mode %.3f Hz, damping ratio %.3f, tracker %.3f s late, valves %s s -> %s\n", id.mode_hz,
              id.damping_ratio, id.tracker_latency_s, list(id.valve_time_constants_s).c_str(), out.c_str());
  util::JsonObject o;
  o.raw("identified", sim::identity_json(id, true))
      .raw("plant_truth", sim::identity_json(r.truth, false))
      .add("out", out);
  std::printf("%s\n", o.str().c_str());
  return 0;
}
