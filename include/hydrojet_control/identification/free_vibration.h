// The first lateral mode about a dynamic rod's loaded equilibrium, from the rod's own free vibration:
// at rest under its inputs and a tip wrench, pushed for 20 ms by 2 mN along its tip's x axis, then
// free for 1.2 s, the tip's direction in the tip frame of the equilibrium every 4 ms, fitted as the
// probe is (fit_mode). The follower load is in it: the mode's damping falls as the jets' force grows,
// below zero where the equilibrium flutters (the fit then reads the floor of ζ, 0.001). The simulated
// plant's truth takes it on the plant's rod, the controller on its own model's. ROS-free.
#pragma once

#include "hydrojet_control/identification/mode_fit.h"
#include "hydrojet_control/rod/dynamic_rod.h"

namespace hydrojet {
namespace identification {

/// The mode about the equilibrium of `model` under `inputs` (one per actuator) and the wrench `w`
/// (tip frame). Not ok, with the reason, when the rod has no equilibrium there or its vibration
/// cannot be fitted.
ModeFit free_vibration_mode(const rod::DynamicRodModel& model, const rod::InputVector& inputs,
                            const rod::TipWrench& w = rod::TipWrench());

}  // namespace identification
}  // namespace hydrojet
