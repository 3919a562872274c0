// The `calibrate` command line (docs/calibration.md) as a function, so that the tool's main() and
// the calibration recorder node run the same code. Part of hydrojet_calibration_ros (it reads bags).
#pragma once

#include <ostream>
#include <string>
#include <vector>

namespace hydrojet {
namespace calibration {

/// Runs `calibrate` with `args` (argv without the program name): report on `out` (last line one
/// JSON object), errors and warnings on `err`. Returns the exit status: 0 converged (or data
/// synthesised), 1 the fit did not converge, 2 bad input (one line on `err` naming the problem,
/// nothing on `out`).
int run_calibrate(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

/// The usage text.
std::string calibrate_usage();

}  // namespace calibration
}  // namespace hydrojet
