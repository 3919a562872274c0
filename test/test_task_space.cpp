// The task space (task_space.h): bend angle and azimuth of a direction, the rotation between two
// directions, the geodesic and pitch-yaw errors, and the spiral of eq. (28).
#include <gtest/gtest.h>

#include <cmath>

#include "hydrojet_control/control/task_space.h"
#include "hydrojet_control/rod/so3.h"

using namespace hydrojet;
using control::Vec3;

TEST(TaskSpace, AnglesDirectionsAndMetrics) {
  for (double th : {0.0, 0.3, 1.04, 1.5})
    for (double ph : {-3.0, -0.5, 0.0, 2.0}) {
      const Vec3 d = control::direction(th, ph);
      EXPECT_NEAR(d.norm(), 1.0, 1e-15);
      EXPECT_NEAR(control::bend_angle(d), th, 1e-12);
      if (th > 0) {
        EXPECT_NEAR(std::remainder(control::azimuth(d) - ph, 2 * M_PI), 0.0, 1e-12);
      }
    }
  const Vec3 a = control::direction(0.4, 0.2), b = control::direction(0.9, 1.7);
  const Vec3 r = control::rotation_between(a, b);
  EXPECT_LT((so3::exp(r) * a - b).norm(), 1e-12);
  EXPECT_NEAR(r.norm(), control::geodesic_error(a, b), 1e-12);
  // Pure pitch: the paper's metric equals the geodesic angle.
  EXPECT_NEAR(control::pitch_yaw_error(control::direction(0.2, 0.0), control::direction(0.5, 0.0)), 0.3, 1e-12);
  // Spiral end point (eq. 28 defaults).
  control::SpiralPath s;
  EXPECT_NEAR(s.angles(600.0)[0], 1.04, 1e-12);
  EXPECT_NEAR(s.angles(600.0)[1], 14.0, 1e-12);
  EXPECT_NEAR(s.angles(300.0)[0], 0.52, 1e-12);
}
