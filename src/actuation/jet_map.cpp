#include "hydrojet_control/actuation/jet_map.h"

#include <cmath>

namespace hydrojet {
namespace actuation {

JetMap::JetMap(const JetGeometry& geometry) : geometry_(geometry) {
  const double da = geometry.misalignment(0), db = geometry.misalignment(1), dg = geometry.misalignment(2);
  const double p3 = M_PI / 3.0;
  // eq. (24)
  planar_ << std::sin(p3 - db), std::sin(da), -std::sin(p3 - dg), std::cos(p3 - db), -std::cos(da), std::cos(p3 - dg);

  const double d = geometry.nozzle_offset;
  wrench_.setZero();
  wrench_.topRows<2>() = planar_;        // f_x, f_y; f_z = 0
  wrench_.row(3) = -d * planar_.row(1);  // m = (d e_z) × f = d (−f_y, f_x, 0)
  wrench_.row(4) = d * planar_.row(0);
}

}  // namespace actuation
}  // namespace hydrojet
