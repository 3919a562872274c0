// The valve model of the simulated plant (plant/hydraulics.h): dead zone, first-order lag, saturation,
// hysteresis, a stuck valve, and the validation of its parameters.
#include <gtest/gtest.h>

#include <cmath>

#include "hydrojet_control/plant/hydraulics.h"

using namespace hydrojet;

TEST(Valve, DeadZoneLagHysteresisAndSaturation) {
  plant::ValveModel p;
  p.max_flow = 1.6e-5, p.dead_zone = 0.1, p.exponent = 0.8, p.hysteresis = 0.0, p.time_constant = 0.05;
  p.saturation = 1.0;
  plant::Valve v(p);
  EXPECT_EQ(v.steady_flow(0.05), 0.0);  // inside the dead zone
  const double u = (0.6 - 0.1) / 0.9;
  EXPECT_NEAR(v.steady_flow(0.6), 1.6e-5 * std::pow(u, 0.8), 1e-18);
  // First-order lag: after one time constant 1 − e⁻¹ of the step.
  double q = 0.0;
  for (int i = 0; i < 50; ++i) q = v.step(0.6, 0.001);
  EXPECT_NEAR(q / v.steady_flow(0.6), 1.0 - std::exp(-1.0), 1e-12);
  // Saturation.
  p.saturation = 1e-5;
  plant::Valve s(p);
  for (int i = 0; i < 2000; ++i) s.step(1.0, 0.001);
  EXPECT_NEAR(s.flow(), 1e-5, 1e-12);
  // Hysteresis (play of width h): coming down, the effective duty lags by h.
  p.saturation = 1.0, p.hysteresis = 0.1, p.time_constant = 1e-4;
  plant::Valve h(p);
  for (int i = 0; i < 100; ++i) h.step(0.8, 0.001);
  for (int i = 0; i < 100; ++i) h.step(0.7, 0.001);
  EXPECT_NEAR(h.flow(), 1.6e-5 * std::pow((0.75 - 0.1) / 0.9, 0.8), 1e-12);  // 0.7 + h/2
  // Stuck: ignores the command.
  h.set_stuck(1.0);
  for (int i = 0; i < 100; ++i) h.step(0.0, 0.001);
  EXPECT_GT(h.flow(), 1.5e-5);
  EXPECT_EQ(p.validate(), "");
  p.dead_zone = 1.0;
  EXPECT_EQ(p.validate().rfind("dead_zone", 0), 0u);
}
