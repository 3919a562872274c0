#include "hydrojet_control/identification/free_vibration.h"

#include <algorithm>
#include <cmath>

namespace hydrojet {
namespace identification {

ModeFit free_vibration_mode(const rod::DynamicRodModel& model, const rod::InputVector& inputs,
                            const rod::TipWrench& w) {
  ModeFit fit;
  if (const std::string e = model.validate(); !e.empty()) return fit.error = "model: " + e, fit;
  rod::DynamicRod rod(model);
  if (!rod.set_inputs(inputs)) return fit.error = "inputs: not one finite value per actuator", fit;
  if (!rod.reset_to_static(w)) return fit.error = "no equilibrium under these inputs", fit;
  const Eigen::Matrix3d frame = rod.tip_rotation();
  rod::TipWrench push = w;
  push.force.x() += 0.002;
  for (int k = 0; k < 10; ++k)
    if (!rod.step(push, 0.002)) return fit.error = "the rod's step failed", fit;
  ModeRecord record;
  record.dt = 0.004;
  for (int k = 0; k < 300; ++k) {
    record.output.push_back((frame.transpose() * rod.tip_rotation().col(2)).head<2>());
    if (!rod.step(w, 0.002) || !rod.step(w, 0.002)) return fit.error = "the rod's step failed", fit;
  }
  // The guess from the crossings of its mean by the component that swings more (the mean, not the
  // last sample: a fluttering equilibrium's swing grows to the end).
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& y : record.output) mean += y / static_cast<double>(record.output.size());
  Eigen::Vector2d swing = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& y : record.output) swing = swing.cwiseMax((y - mean).cwiseAbs());
  const int c = swing(0) >= swing(1) ? 0 : 1;
  int crossings = 0;
  for (size_t k = 1; k < record.output.size(); ++k)
    crossings += (record.output[k](c) - mean(c)) * (record.output[k - 1](c) - mean(c)) < 0;
  const double guess = M_PI * std::max(crossings, 2) / (record.dt * record.output.size());
  return fit_mode(record, guess);
}

}  // namespace identification
}  // namespace hydrojet
