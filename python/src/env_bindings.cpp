// The stepping core of hydrojet.gym's HydroJet-v0: the plant between two actions, the observation
// and the path's error, in C++ so that an environment step costs the plant's time and little more.
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <memory>
#include <optional>
#include <tuple>
#include <vector>

#include "bindings.h"
#include "hydrojet_control/control/task_space.h"
#include "hydrojet_control/control/path.h"
#include "hydrojet_control/plant/plant.h"
#include "hydrojet_control/sim/closed_loop_run.h"

namespace hydrojet {
namespace python {
namespace {

/// One episode (sim::Episode, the experiment's loop): `settle` seconds at rest with the valves shut,
/// then the path's clock. Actions are per actuator in [-1, 1]: a jet's
/// valve duty (a + 1) / 2, a force actuator's drive a.
class EnvCore {
 public:
  EnvCore(const plant::PlantModel& model, std::shared_ptr<control::Path> path, double control_period,
          std::vector<double> preview, Eigen::VectorXd state_scale, double settle)
      : model_(model),
        path_(std::move(path)),
        dt_(control_period),
        preview_(std::move(preview)),
        scale_(std::move(state_scale)),
        settle_(settle) {
    if (!path_) throw std::invalid_argument("path: must be a Path");
    if (!(dt_ >= 1e-4 && dt_ <= 1.0)) throw std::invalid_argument("control_period: must lie in [1e-4, 1] s");
    if (!(settle_ >= 0.0 && settle_ <= 60.0)) throw std::invalid_argument("settle: must lie in [0, 60] s");
    if (scale_.size() != model_.rod.rod.input_count() || !(scale_.array() > 0.0).all())
      throw std::invalid_argument("state_scale: one positive entry per actuator");
    for (const double p : preview_)
      if (!(p >= 0.0 && p <= 60.0)) throw std::invalid_argument("preview: each must lie in [0, 60] s");
  }

  /// A new episode with the plant's noise seeded; false (see error()) when the plant fails.
  bool reset(unsigned seed) {
    episode_.emplace(model_, seed, dt_);
    if (!episode_->settle(settle_)) return false;
    step0_ = episode_->steps();
    direction_ = measured(rod::Vec3::UnitZ());
    return true;
  }

  /// Applies `action` for one control period: (plant ok, error [rad] against the path).
  std::tuple<bool, double> step(const Eigen::VectorXd& action) {
    if (!episode_) throw std::invalid_argument("step() before reset()");
    const plant::Plant& plant = episode_->plant();
    const rod::InputVector a = to_inputs(action, plant.input_count(), "action");
    rod::InputVector command(a.size());
    for (int i = 0; i < a.size(); ++i) {
      const double ai = std::clamp(a[i], -1.0, 1.0);
      command[i] = plant.is_jet(i) ? 0.5 * (ai + 1.0) : ai;
    }
    bool ok;
    {
      nb::gil_scoped_release release;
      ok = episode_->step(command);
    }
    direction_ = measured(direction_);
    return {ok, control::geodesic_error(path_->direction_at(path_time()), direction_)};
  }

  /// The measured direction, the path's preview, the actuators' measured states over their scale.
  Eigen::VectorXf observation() const {
    if (!episode_) throw std::invalid_argument("observation() before reset()");
    const plant::Plant& plant = episode_->plant();
    const control::ControllerInputs& in = episode_->sensors();
    const int n = plant.input_count();
    Eigen::VectorXf obs(3 * (1 + preview_.size()) + n);
    obs.head<3>() = direction_.cast<float>();
    for (size_t k = 0; k < preview_.size(); ++k)
      obs.segment<3>(3 * (k + 1)) =
          path_->direction_at(std::min(path_time() + preview_[k], path_->duration())).cast<float>();
    for (int i = 0; i < n; ++i)
      obs[3 * (1 + preview_.size()) + i] =
          static_cast<float>((plant.is_jet(i) ? in.flows[i] : in.forces[i]) / scale_[i]);
    return obs.cwiseMax(-2.0f).cwiseMin(2.0f);
  }

  double t() const { return episode_ ? episode_->t() : 0.0; }
  double path_time() const { return episode_ ? (episode_->steps() - step0_) * dt_ : 0.0; }
  const control::ControllerInputs& sensors() const {
    static const control::ControllerInputs none;
    return episode_ ? episode_->sensors() : none;
  }
  std::string error() const { return episode_ ? episode_->error() : std::string(); }

 private:
  rod::Vec3 measured(const rod::Vec3& last) const {
    const control::ControllerInputs& in = episode_->sensors();
    return in.tip_valid ? rod::Vec3(in.tip_rotation.col(2).normalized()) : last;
  }

  plant::PlantModel model_;
  std::shared_ptr<control::Path> path_;
  double dt_;
  std::vector<double> preview_;
  Eigen::VectorXd scale_;
  double settle_;
  std::optional<sim::Episode> episode_;
  long step0_ = 0;  ///< the path's clock started at this control period of the episode
  rod::Vec3 direction_ = rod::Vec3::UnitZ();
};

}  // namespace

void bind_env(nb::module_& m) {
  nb::class_<EnvCore>(m, "_EnvCore")
      .def(nb::init<const plant::PlantModel&, std::shared_ptr<control::Path>, double, std::vector<double>,
                    Eigen::VectorXd, double>(),
           nb::arg("plant"), nb::arg("path").none(), nb::arg("control_period"), nb::arg("preview"),
           nb::arg("state_scale"), nb::arg("settle"))
      .def("reset", &EnvCore::reset, nb::arg("seed"))
      .def("step", &EnvCore::step, nb::arg("action"))
      .def("observation", &EnvCore::observation)
      .def_prop_ro("t", &EnvCore::t)
      .def_prop_ro("path_time", &EnvCore::path_time)
      .def_prop_ro("sensors", &EnvCore::sensors, nb::rv_policy::copy)
      .def_prop_ro("error", &EnvCore::error);
  m.attr("_DEFAULT_SETTLE") = sim::RunPlan().settle;  // [s] at rest before a path, as the experiment's
}

}  // namespace python
}  // namespace hydrojet
