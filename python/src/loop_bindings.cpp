// The controller (Algorithm 1), the simulated plant and one experiment run for Python: enough to
// write the closed loop by hand, and the run the experiment tool makes, field for field.
#include <nanobind/stl/optional.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <cmath>
#include <memory>
#include <optional>
#include <tuple>

#include "bindings.h"
#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/control/path.h"
#include "hydrojet_control/sim/closed_loop_run.h"

namespace hydrojet {
namespace python {
namespace {

control::LoopMode parse_mode(const std::string& mode) {
  if (mode == "closed") return control::LoopMode::kClosed;
  if (mode == "open") return control::LoopMode::kOpen;
  throw std::invalid_argument("mode: must be 'closed' or 'open', got '" + mode + "'");
}

/// A spiral duration [s] set into `spiral`: within a path's limit (an hour), as fast as the caller
/// likes (the experiment's --duration; operators' paths have a speed limit, experiments do not).
void set_duration(control::SpiralPath& spiral, double duration, const std::string& what) {
  const double max = control::PathLimits().max_duration;
  if (!(std::isfinite(duration) && duration > 0.0 && duration <= max))
    throw std::invalid_argument(what + ": " + std::to_string(duration) + " s must lie in (0, " + std::to_string(max) +
                                "] s");
  spiral.duration = duration;
}

sim::RunStart parse_start(const std::string& start) {
  sim::RunStart s;
  if (!sim::parse_run_start(start, &s))
    throw std::invalid_argument("start: must be 'rest' or 'on-path', got '" + start + "'");
  return s;
}

/// A controller options file; a key read from a deprecated place gives a FutureWarning (shown by
/// default, as the node logs it), an error when warnings are errors. The GIL is held.
config::ControllerNodeOptions load_options(const std::string& file) {
  config::ControllerNodeOptions o = config::load_controller_options(file);
  for (const std::string& w : o.warnings)
    if (PyErr_WarnEx(PyExc_FutureWarning, (file + ": " + w).c_str(), 1) < 0) throw nb::python_error();
  return o;
}

/// The controller of a scene with the options of a controller YAML file (config/controller.yaml's
/// keys), the experiment's way: its flow regulator in the model, `duration` the spiral's.
class PyController {
 public:
  PyController(const config::Scene& scene, const std::string& options, std::optional<std::string> mode,
               std::optional<double> duration)
      : options_(load_options(options)) {
    if (duration) set_duration(options_.controller.path, *duration, "duration");
    if (mode) options_.controller.mode = parse_mode(*mode);
    model_ = config::make_controller_model(scene, options_.flow_regulator);
    nb::gil_scoped_release release;  // the reachable sets' sweep takes a fraction of a second
    controller_ = std::make_unique<control::Controller>(model_, options_.controller);
  }
  control::Controller& get() { return *controller_; }
  double control_period() const { return 1.0 / options_.rate; }
  std::shared_ptr<control::Path> spiral() const {
    return std::shared_ptr<control::Path>(control::make_spiral(options_.controller.path));
  }
  std::string mode() const { return control::to_string(controller_->options().mode); }
  void set_mode(const std::string& m) { controller_->set_mode(parse_mode(m)); }

 private:
  config::ControllerNodeOptions options_;
  control::RobotModel model_;
  std::unique_ptr<control::Controller> controller_;
};

/// The simulated plant of a scene under a plant YAML file, seeded; sample() keeps the latest
/// sensor readings as the rig's driver does (a tracker dropout leaves the last pose and its stamp).
class PyPlant {
 public:
  PyPlant(const plant::PlantModel& model, unsigned seed) : plant_(model, seed) {
    if (!plant_.error().empty()) throw std::runtime_error("plant: " + plant_.error());
    inputs_.flows = inputs_.forces = rod::InputVector::Zero(plant_.input_count());
  }
  plant::Plant& get() { return plant_; }
  /// The sensors at time t: the tracker's tip frame in the base frame (when valid), flows and forces.
  control::ControllerInputs sample(double t) {
    sim::read_sensors(plant_, t, inputs_);
    return inputs_;
  }

 private:
  plant::Plant plant_;
  control::ControllerInputs inputs_;
};

/// What one experiment run loads from its files, each checked (ValueError naming the key).
struct RunSetup {
  config::ControllerNodeOptions copt;
  sim::RunPlan plan;
  config::Scene scene;
  control::RobotModel model;
  plant::PlantModel plant;
};

RunSetup load_run(const std::string& scene_file, const std::string& plant_file, const std::string& controller_file,
                  const std::string& mode, double duration, std::optional<std::string> path_file,
                  const std::string& start) {
  RunSetup r;
  r.copt = load_options(controller_file);
  if (duration < 0.0 || !std::isfinite(duration))
    throw std::invalid_argument("duration: must be a finite number of seconds >= 0 (0: the controller file's)");
  if (duration > 0.0) set_duration(r.copt.controller.path, duration, "duration");
  r.copt.controller.mode = parse_mode(mode);
  r.plan.start = parse_start(start);
  r.plan.control_period = 1.0 / r.copt.rate;
  if (path_file) r.plan.path = control::load_path_file(*path_file);
  r.scene = config::load_scene(scene_file);
  r.model = config::make_controller_model(r.scene, r.copt.flow_regulator);
  r.plant = config::load_plant(r.scene, plant_file);
  return r;
}

/// One run of the experiment tool (its JSON fields): scene, plant and controller files, seed,
/// loop mode, the spiral's duration (or a path file) and how the run starts.
nb::dict identity_dict(const control::PlantIdentity& id, bool identified);
nb::dict run_experiment(const std::string& scene_file, const std::string& plant_file,
                        const std::string& controller_file, unsigned seed, const std::string& mode, double duration,
                        std::optional<std::string> path_file, const std::string& start) {
  const RunSetup setup = load_run(scene_file, plant_file, controller_file, mode, duration, path_file, start);
  sim::RunResult r;
  {
    nb::gil_scoped_release release;
    r = sim::run_path(setup.model, setup.copt.controller, setup.plant, seed, setup.plan);
  }
  const config::Scene& sc = setup.scene;
  nb::dict d;
  d["mode"] = mode;
  d["tilt_deg"] = sim::base_tilt_deg(sc.rod.gravity);
  d["seed"] = seed;
  d["rms_rad"] = r.rms;
  d["rms_true_rad"] = r.rms_true;
  d["water_ml_per_min"] = sim::ml_per_min(r.water_flow);
  d["start"] = std::string(sim::to_string(r.start));
  d["approach_time_s"] = r.approach_time;
  d["completed"] = r.completed;
  d["aborted_at_s"] = r.aborted_at >= 0 ? nb::cast(r.aborted_at) : nb::none();
  d["reason"] = r.reason;
  d["median_rad"] = r.median;
  d["max_rad"] = r.max;
  d["rms_pitch_yaw_rad"] = r.rms_pitch_yaw;
  d["simulated_s"] = r.simulated_seconds;
  d["wall_s"] = r.wall_seconds;
  d["time_scale"] = r.time_scale;
  d["reach_limited_s"] = r.reach_limited_s;
  d["keep_out_s"] = r.keep_out_s;
  d["supervisor_fallbacks"] = r.supervisor_fallbacks;
  d["supervised_s"] = r.supervised_s;
  d["identified"] = identity_dict(r.identified, true);
  d["plant_truth"] = identity_dict(r.truth, false);
  auto or_none = [](double v) { return std::isfinite(v) ? nb::cast(v) : nb::none(); };
  const sim::ContactSummary& c = r.contact;  // as the experiment's JSON
  d["contact_onsets"] = c.onsets;
  d["detection_delay_s"] = or_none(c.detection_delay_s);
  d["missed_contact_s"] = c.missed_contact_s;
  d["false_contact_s"] = c.false_contact_s;
  d["max_contact_force_n"] = c.max_contact_force_n;
  d["max_contact_force_after_detection_n"] = or_none(c.max_contact_force_after_detection_n);
  d["external_force_rms_error_n"] = c.external_force_rms_error_n;
  d["min_clearance_m"] = or_none(c.min_clearance_m);
  return d;
}

/// The experiment's `identified` and `plant_truth` (as its JSON: the mode None when not known).
nb::dict identity_dict(const control::PlantIdentity& id, bool identified) {
  nb::dict d;
  d["mode_hz"] = id.mode_hz > 0.0 ? nb::cast(id.mode_hz) : nb::none();
  d["damping_ratio"] = id.mode_hz > 0.0 ? nb::cast(id.damping_ratio) : nb::none();
  d["valve_time_constants_s"] = id.valve_time_constants_s;
  d["tracker_latency_s"] = id.tracker_latency_s;
  if (!id.valve_plays.empty()) d["valve_plays"] = id.valve_plays;
  if (identified) {
    d["mode_identified"] = id.mode_identified;
    d["valves_identified"] = id.valves_identified;
    if (!id.mode_error.empty()) d["mode_error"] = id.mode_error;
  }
  return d;
}

void bind_io(nb::module_& m) {
  using control::ControllerInputs;
  nb::class_<ControllerInputs>(m, "Sensors", "What the controller reads in one cycle (time, tracker, flows)")
      .def(nb::init<>())
      .def_rw("t", &ControllerInputs::t, "now [s]")
      .def_rw("tip_valid", &ControllerInputs::tip_valid)
      .def_rw("tip_stamp", &ControllerInputs::tip_stamp, "[s]")
      .def_prop_rw(
          "tip_rotation", [](const ControllerInputs& in) { return Eigen::Matrix3d(in.tip_rotation); },
          [](ControllerInputs& in, const Eigen::Matrix3d& r) { in.tip_rotation = r; },
          "measured tip frame in the base frame")
      .def_rw("flow_valid", &ControllerInputs::flow_valid)
      .def_rw("flow_stamp", &ControllerInputs::flow_stamp, "[s]")
      .def_prop_rw(
          "flows", [](const ControllerInputs& in) { return to_dynamic(in.flows); },
          [](ControllerInputs& in, const Eigen::VectorXd& v) { in.flows = to_bounded(v, "flows"); },
          "[m^3/s] per actuator")
      .def_prop_rw(
          "forces", [](const ControllerInputs& in) { return to_dynamic(in.forces); },
          [](ControllerInputs& in, const Eigen::VectorXd& v) { in.forces = to_bounded(v, "forces"); },
          "[N] per actuator (read for force actuators)");

  using control::ControllerOutput;
  nb::class_<ControllerOutput>(m, "ControllerOutput", "One control cycle's result")
      .def_prop_ro("state", [](const ControllerOutput& o) { return std::string(control::to_string(o.state)); })
      .def_ro("reason", &ControllerOutput::reason)
      .def_prop_ro(
          "valve_command", [](const ControllerOutput& o) { return to_dynamic(o.valve_command); },
          "per actuator: valve duty [0, 1] (jets), drive [-1, 1] (force actuators)")
      .def_prop_ro("jet_force_command", [](const ControllerOutput& o) { return to_dynamic(o.jet_force_command); })
      .def_prop_ro("flow_command", [](const ControllerOutput& o) { return to_dynamic(o.flow_command); })
      .def_prop_ro("jet_force_observed", [](const ControllerOutput& o) { return to_dynamic(o.jet_force_observed); })
      .def_prop_ro("desired_direction", [](const ControllerOutput& o) { return Eigen::Vector3d(o.desired_direction); })
      .def_prop_ro("measured_direction",
                   [](const ControllerOutput& o) { return Eigen::Vector3d(o.measured_direction); })
      .def_ro("error_geodesic", &ControllerOutput::error_geodesic, "[rad]")
      .def_ro("error_pitch_yaw", &ControllerOutput::error_pitch_yaw, "[rad]")
      .def_ro("path_time", &ControllerOutput::path_time, "[s]")
      .def_ro("approaching", &ControllerOutput::approaching)
      .def_ro("approach_time", &ControllerOutput::approach_time, "[s]")
      .def_ro("path_failure", &ControllerOutput::path_failure)
      .def_ro("solver_converged", &ControllerOutput::solver_converged)
      .def_ro("stability_margin", &ControllerOutput::stability_margin, "[N/m]");
}

}  // namespace

void bind_loop(nb::module_& m) {
  bind_io(m);
  nb::class_<PyController>(m, "_Controller")
      .def(nb::init<const config::Scene&, const std::string&, std::optional<std::string>, std::optional<double>>(),
           nb::arg("scene"), nb::arg("options"), nb::arg("mode") = nb::none(), nb::arg("duration") = nb::none())
      .def_prop_ro("control_period", &PyController::control_period, "[s] (1 / rate)")
      .def_prop_ro("actuator_count", [](PyController& c) { return c.get().input_count(); })
      .def_prop_ro("state", [](PyController& c) { return std::string(control::to_string(c.get().state())); })
      .def_prop_rw("mode", &PyController::mode, &PyController::set_mode)
      .def("spiral", &PyController::spiral, "The configured spiral (eq. 28) as a Path")
      .def(
          "start", [](PyController& c, double t) { c.get().start(finite_time(t, "t")); }, nb::arg("t"))
      .def("stop", [](PyController& c) { c.get().stop(); })
      .def(
          "follow",
          [](PyController& c, std::shared_ptr<control::Path> path, double t, const std::string& start) {
            if (!path) throw std::invalid_argument("path: must be a Path (hydrojet.load_path, Controller.spiral)");
            c.get().follow(path, finite_time(t, "t"),
                           parse_start(start) == sim::RunStart::kOnPath ? control::Reference::PathStart::kApproach
                                                                        : control::Reference::PathStart::kJump,
                           control::Reference::PathClip::kDesigned);
          },
          nb::arg("path").none(), nb::arg("t"), nb::arg("start") = "rest")
      .def(
          "update", [](PyController& c, const control::ControllerInputs& in) { return c.get().update(in); },
          nb::arg("sensors"), "One cycle of Algorithm 1");

  nb::class_<plant::PlantModel>(m, "PlantModel", "A scene's robot as the plant file says it truly is");
  m.def("load_plant", &config::load_plant, nb::arg("scene"), nb::arg("path"),
        "The plant model of a scene under a plant YAML file (ValueError naming the key)");
  nb::class_<PyPlant>(m, "_Plant")
      .def(nb::init<const plant::PlantModel&, unsigned>(), nb::arg("model"), nb::arg("seed"))
      .def_prop_ro("actuator_count", [](PyPlant& p) { return p.get().input_count(); })
      .def_prop_ro("time", [](PyPlant& p) { return p.get().time(); })
      .def_prop_ro("error", [](PyPlant& p) { return p.get().error(); })
      .def(
          "advance_to",
          [](PyPlant& p, double t) {
            nb::gil_scoped_release release;
            return p.get().advance_to(t);
          },
          nb::arg("t"),
          "Integrates to time t [s]; False (see error) when the rod solver failed or t is not finite or lies\n"
          "more than an hour ahead")
      .def(
          "command",
          [](PyPlant& p, const Eigen::VectorXd& v, double t) {
            p.get().command(to_inputs(v, p.get().input_count(), "command"), finite_time(t, "t"));
          },
          nb::arg("command"), nb::arg("t"), "Valve duty [0, 1] (jets) or drive [-1, 1] per actuator at time t")
      .def(
          "sample", [](PyPlant& p, double t) { return p.sample(finite_time(t, "t")); }, nb::arg("t"),
          "The sensors at time t, as the rig's driver delivers them")
      .def_prop_ro(
          "tip_rotation", [](PyPlant& p) { return Eigen::Matrix3d(p.get().tip_rotation()); },
          "true tip frame, base frame")
      .def_prop_ro(
          "tip_position", [](PyPlant& p) { return Eigen::Vector3d(p.get().tip_position()); },
          "true tip position [m], base frame")
      .def_prop_ro(
          "jet_forces", [](PyPlant& p) { return to_dynamic(p.get().jet_forces()); }, "true forces [N]")
      .def_prop_ro(
          "flows", [](PyPlant& p) { return to_dynamic(p.get().flows()); }, "true flows [m^3/s]");

  m.def(
      "_spiral_and_abort_angle",
      [](const std::string& options, double duration) {
        config::ControllerNodeOptions o = load_options(options);
        set_duration(o.controller.path, duration, "duration");
        return std::make_tuple(std::shared_ptr<control::Path>(control::make_spiral(o.controller.path)),
                               o.controller.safety.max_oscillation);
      },
      nb::arg("options"), nb::arg("duration"),
      "A controller options file's spiral (eq. 28) over `duration` [s] and its safety/max_oscillation [rad]");
  m.def(
      "_check_run",
      [](const std::string& scene, const std::string& plant, const std::string& controller,
         std::optional<std::string> path) { load_run(scene, plant, controller, "closed", 0.0, path, "rest"); },
      nb::arg("scene"), nb::arg("plant"), nb::arg("controller"), nb::arg("path") = nb::none(),
      "Loads a run's files as run_experiment does; ValueError naming the key when one is bad");
  m.def("_run_experiment", &run_experiment, nb::arg("scene"), nb::arg("plant"), nb::arg("controller"), nb::arg("seed"),
        nb::arg("mode"), nb::arg("duration"), nb::arg("path") = nb::none(), nb::arg("start") = "rest");
}

}  // namespace python
}  // namespace hydrojet
