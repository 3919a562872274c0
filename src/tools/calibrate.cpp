// calibrate: offline Ceres calibration of ζ = [ux, uy, E, G, δα, δβ, δγ] (paper §6.2, eq. 27).
// See docs/calibration.md and hydrojet_control/calibration/app.h.
#include <iostream>
#include <string>
#include <vector>

#include "hydrojet_control/calibration/app.h"

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  return hydrojet::calibration::run_calibrate(args, std::cout, std::cerr);
}
