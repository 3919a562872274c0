#include "hydrojet_control/calibration/synthetic.h"

#include <random>
#include <stdexcept>

#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace calibration {

std::vector<Sample> synthesise(const config::Scene& truth, const SyntheticOptions& o) {
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  rod::RodSolver solver(truth.rod, truth.solver);
  const int n = truth.rod.input_count();
  std::vector<Sample> out;
  for (int k = 0; k < o.samples; ++k) {
    Sample s;
    s.inputs.resize(n);
    for (int i = 0; i < n; ++i) {
      const rod::Actuator& a = truth.rod.actuators[i];
      s.inputs[i] = o.max_force_fraction * (a.min_force + (a.max_force - a.min_force) * u01(rng));
    }
    const rod::RodSolution sol = solver.solve(s.inputs);
    if (!sol.converged)
      throw std::runtime_error("synthesise: rod solve " + std::to_string(k + 1) + " did not converge");
    const Eigen::Vector3d noise(n01(rng), n01(rng), n01(rng));
    s.tip_orientation = Eigen::Quaterniond(sol.tip_rotation * so3::exp(o.noise_rad * noise)).normalized();
    s.origin = "synthetic " + std::to_string(k + 1);
    out.push_back(s);
  }
  return out;
}

}  // namespace calibration
}  // namespace hydrojet
