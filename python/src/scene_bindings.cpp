// Scenes, the rod solver and paths for Python: the numbers rod_fk prints, as numpy arrays.
#include <nanobind/stl/optional.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <memory>
#include <optional>

#include "bindings.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/control/path.h"
#include "hydrojet_control/rod/so3.h"
#include "hydrojet_control/rod/stability.h"

namespace hydrojet {
namespace python {
namespace {

/// Inputs within each actuator's [min_force, max_force], as rod_fk --actuators checks them.
rod::InputVector checked_inputs(const config::Scene& scene, const Eigen::VectorXd& v) {
  const rod::InputVector q = to_inputs(v, scene.rod.input_count(), "inputs");
  if (const std::string e = scene.rod.check_inputs(q); !e.empty()) throw std::invalid_argument("inputs: " + e);
  return q;
}

/// One solve as rod_fk --actuators ... --compliance --shape K reports it (null fields: None).
nb::dict solve(rod::RodSolver& solver, const config::Scene& scene, const Eigen::VectorXd& inputs,
               const rod::Vec3& force, const rod::Vec3& moment, int shape_segments) {
  if (shape_segments < 1 || shape_segments > 100000)
    throw std::invalid_argument("shape_segments: must be an integer in [1, 100000]");
  rod::TipWrench w;
  w.force = finite3(force, "force");
  w.moment = finite3(moment, "moment");
  const rod::InputVector q = checked_inputs(scene, inputs);
  rod::RodSolution sol;
  {
    nb::gil_scoped_release release;
    sol = solver.solve(q, w);
  }
  nb::dict d;
  d["converged"] = sol.converged;
  d["message"] = sol.message;
  d["warning"] = sol.warning;
  d["iterations"] = sol.iterations;
  d["residual"] = sol.residual;
  d["fold_crossings"] = sol.fold_crossings;
  d["tip_position"] = Eigen::Vector3d(sol.tip_position);
  d["tip_rotation"] = Eigen::Matrix3d(sol.tip_rotation);
  d["tip_quaternion_wxyz"] = Eigen::Vector4d(so3::quaternion_wxyz(sol.tip_rotation));
  for (const char* k : {"compliance", "actuation_jacobian", "stability_margin", "stability_eig_min", "shape"})
    d[k] = nb::none();
  if (!sol.converged) return d;
  const rod::Compliance c = solver.compliance();
  if (c.ok) {
    // eq. (23) on the scene's tip.actuated (actuators at the tip), else on the actuators' equivalent
    // tip wrenches: rod_fk's choice.
    const bool actuated = solver.input_count() > 0;
    const rod::StabilityReport st =
        actuated && !scene.rod.tip_actuated_uniform()
            ? rod::stability(c.body, rod::equivalent_tip_wrenches(c.body, c.actuation), scene.rod.length())
            : rod::stability(c.body, scene.actuated);
    d["compliance"] = Eigen::Matrix<double, 6, 6>(c.body);
    d["actuation_jacobian"] = Eigen::MatrixXd(c.actuation);
    d["stability_margin"] = st.margin;
    d["stability_eig_min"] = st.eig_min;
  }
  const std::vector<rod::Vec3> pts = solver.shape(shape_segments);
  Eigen::MatrixXd shape(pts.size(), 3);
  for (size_t i = 0; i < pts.size(); ++i) shape.row(i) = pts[i].transpose();
  d["shape"] = shape;
  return d;
}

/// A solver that keeps its warm start between solves (rod_fk --batch).
struct WarmSolver {
  explicit WarmSolver(const config::Scene& s) : scene(s), solver(s.rod, s.solver) {}
  config::Scene scene;
  rod::RodSolver solver;
};

std::vector<std::string> actuator_names(const config::Scene& s) {
  std::vector<std::string> names;
  for (const rod::Actuator& a : s.rod.actuators) names.push_back(a.name);
  return names;
}

Eigen::VectorXd bound(const config::Scene& s, bool upper) {
  Eigen::VectorXd b(s.rod.input_count());
  for (int i = 0; i < b.size(); ++i) b[i] = upper ? s.rod.actuators[i].max_force : s.rod.actuators[i].min_force;
  return b;
}

}  // namespace

void bind_scene(nb::module_& m) {
  nb::class_<config::Scene>(m, "Scene", "A scene file: the robot, its actuators and the solver's options")
      .def_prop_ro("actuator_names", &actuator_names)
      .def_prop_ro("actuator_count", [](const config::Scene& s) { return s.rod.input_count(); })
      .def_prop_ro(
          "input_lower", [](const config::Scene& s) { return bound(s, false); }, "min_force [N] per actuator")
      .def_prop_ro(
          "input_upper", [](const config::Scene& s) { return bound(s, true); }, "max_force [N] per actuator")
      .def_prop_ro(
          "length", [](const config::Scene& s) { return s.rod.length(); }, "[m]")
      .def_prop_ro(
          "tip_mass", [](const config::Scene& s) { return s.rod.tip_mass; }, "[kg]")
      .def_prop_ro(
          "gravity", [](const config::Scene& s) { return Eigen::Vector3d(s.rod.gravity); }, "[m/s^2], base frame")
      .def_prop_ro("has_jets", [](const config::Scene& s) { return s.jets.has_value(); })
      .def_prop_ro(
          "actuator_is_jet",
          [](const config::Scene& s) {
            std::vector<bool> jet;
            for (const rod::Actuator& a : s.rod.actuators) jet.push_back(a.type == rod::ActuatorType::kJet);
            return jet;
          },
          "per actuator: a water jet (valve duty command) or a force actuator (drive command)")
      .def_prop_ro(
          "max_flow",
          [](const config::Scene& s) {
            Eigen::VectorXd q(s.rod.input_count());
            for (int i = 0; i < q.size(); ++i) {
              const rod::Actuator& a = s.rod.actuators[i];
              q[i] = a.type == rod::ActuatorType::kJet ? actuation::flow_from_force(a.max_force, s.nozzle) : 0.0;
            }
            return q;
          },
          "per actuator: the flow at max_force by eq. (26) [m^3/s] (0 for force actuators)");
  m.def("load_scene", &config::load_scene, nb::arg("path"), "Reads a scene YAML file (ValueError naming the key)");
  m.def("parse_scene", &config::parse_scene, nb::arg("text"), "Parses scene YAML text (ValueError naming the key)");

  m.def(
      "_solve",
      [](const config::Scene& scene, const Eigen::VectorXd& inputs, const rod::Vec3& force, const rod::Vec3& moment,
         int shape_segments) {
        rod::RodSolver solver(scene.rod, scene.solver);  // cold, as one rod_fk call
        return solve(solver, scene, inputs, force, moment, shape_segments);
      },
      nb::arg("scene"), nb::arg("inputs"), nb::arg("force"), nb::arg("moment"), nb::arg("shape_segments"));
  nb::class_<WarmSolver>(m, "_WarmSolver")
      .def(nb::init<const config::Scene&>())
      .def("solve", [](WarmSolver& s, const Eigen::VectorXd& inputs, const rod::Vec3& force, const rod::Vec3& moment,
                       int shape_segments) { return solve(s.solver, s.scene, inputs, force, moment, shape_segments); });

  nb::class_<control::Path>(m, "Path", "A path of tip directions over time (the spiral or a path file)")
      .def_prop_ro("duration", &control::Path::duration, "[s]")
      .def_prop_ro("type", [](const control::Path& p) { return std::string(p.type()); })
      .def(
          "direction_at", [](const control::Path& p, double t) { return Eigen::Vector3d(p.direction_at(t)); },
          nb::arg("t"), "The desired tip z-axis (unit, base frame) at t [s] since the path's clock started");
  m.def(
      "load_path",
      [](const std::string& file) { return std::shared_ptr<control::Path>(control::load_path_file(file)); },
      nb::arg("file"), "A path file (t, theta, phi rows; CSV or YAML), as follow_path and experiment --path read it");
}

}  // namespace python
}  // namespace hydrojet
