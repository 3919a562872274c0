// geometry::Surface as the message hydrojet_control/Surface (the plant's environment, keep-out
// regions). Header-only: the nodes that publish surfaces include it.
#pragma once

#include "hydrojet_control/Surface.h"
#include "hydrojet_control/geometry/surface.h"

namespace hydrojet {
namespace ros_bridge {

inline hydrojet_control::Surface to_msg(const geometry::Surface& s) {
  hydrojet_control::Surface m;
  m.type = s.type == geometry::SurfaceType::kPlane    ? "plane"
           : s.type == geometry::SurfaceType::kSphere ? "sphere"
                                                      : "ellipsoid";
  m.point.x = s.point.x(), m.point.y = s.point.y(), m.point.z = s.point.z();
  m.normal.x = s.normal.x(), m.normal.y = s.normal.y(), m.normal.z = s.normal.z();
  m.radii.x = s.radii.x(), m.radii.y = s.radii.y(), m.radii.z = s.radii.z();
  m.inside = s.inside;
  return m;
}

}  // namespace ros_bridge
}  // namespace hydrojet
