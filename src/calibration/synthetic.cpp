#include "hydrojet_control/calibration/synthetic.h"

#include <random>
#include <stdexcept>

#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace calibration {

std::vector<Sample> synthesise(const config::Scene& truth, const SyntheticOptions& o) {
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  // The jets load the tip as a wrench of their geometry (eq. 24).
  rod::RodSolver solver(truth.rod.without_actuators(), truth.solver);
  const actuation::JetMap jets(truth.jets.value_or(actuation::JetGeometry()));
  std::vector<Sample> out;
  for (int k = 0; k < o.samples; ++k) {
    Sample s;
    for (int i = 0; i < 3; ++i) s.jet_force[i] = o.max_force_fraction * truth.rod.actuators[i].max_force * u01(rng);
    const actuation::Vec6 w = jets.wrench(s.jet_force);
    rod::TipWrench tw;
    tw.force = w.head<3>();
    tw.moment = w.tail<3>();
    const rod::RodSolution sol = solver.solve(tw);
    if (!sol.converged)
      throw std::runtime_error("synthesise: rod solve " + std::to_string(k + 1) + " did not converge");
    const Eigen::Vector3d n(n01(rng), n01(rng), n01(rng));
    s.tip_orientation = Eigen::Quaterniond(sol.tip_rotation * so3::exp(o.noise_rad * n)).normalized();
    s.origin = "synthetic " + std::to_string(k + 1);
    out.push_back(s);
  }
  return out;
}

}  // namespace calibration
}  // namespace hydrojet
