// The paper's law, eqs. (17)–(18): x_cntr = K_p dt x_err + K_i dt ∫w x_err dt + K_d Δx_err + k_ff Δx_des
// (DirectionPd). ROS-free.
#pragma once

#include "hydrojet_control/control/direction_law.h"

namespace hydrojet {
namespace control {

class PapersLaw : public DirectionLaw {
 public:
  /// std::invalid_argument naming the field when `pd` is not valid.
  explicit PapersLaw(const PdOptions& pd) : DirectionLaw(pd) {}
  Vec3 correction(const LawCycle& c) override { return pd_.correction(c.observed, c.desired, c.dt, pd_options_); }
  ControlLaw kind() const override { return ControlLaw::kPapers; }
};

}  // namespace control
}  // namespace hydrojet
