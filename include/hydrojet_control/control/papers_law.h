// The paper's law, eqs. (17)–(18): x_cntr = K_p dt x_err + K_i dt ∫w x_err dt + K_d Δx_err + k_ff Δx_des
// (DirectionPd). ROS-free.
#pragma once

#include "hydrojet_control/control/direction_law.h"

namespace hydrojet {
namespace control {

class PapersLaw : public DirectionLaw {
 public:
  /// std::invalid_argument naming the field when `pd` is not valid.
  explicit PapersLaw(const PdOptions& pd);
  void reset() override { pd_.reset(); }
  void skip(double dt) override { pd_.skip(dt); }
  Vec3 correction(const LawCycle& c) override { return pd_.correction(c.observed, c.desired, c.dt, options_); }
  double fast_path_weight() const override;
  void set_pd(const PdOptions& pd) override;
  const PdOptions& pd() const override { return options_; }
  ControlLaw kind() const override { return ControlLaw::kPapers; }

 private:
  PdOptions options_;
  DirectionPd pd_;
};

}  // namespace control
}  // namespace hydrojet
