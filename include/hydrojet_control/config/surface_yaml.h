// One surface of a list in a YAML file (geometry/surface.h): a plant's environment.surfaces and the
// controller's keep_out share its keys (type plane|sphere|ellipsoid, point, normal, centre, radius,
// radii, inside); each list adds its own (`extra`). Errors name the item's key.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "hydrojet_control/config/yaml_tree.h"
#include "hydrojet_control/geometry/surface.h"

namespace hydrojet {
namespace config {

template <class Tree>
geometry::Surface read_surface_shape(Tree& t, const std::vector<std::string>& extra) {
  geometry::Surface s;
  const std::string type = t.text("type", "");
  auto allow = [&](std::vector<std::string> own) {
    own.insert(own.end(), extra.begin(), extra.end());
    t.keys("", own);
  };
  if (type == "plane") {
    allow({"type", "point", "normal"});
    s.type = geometry::SurfaceType::kPlane;
    s.point = t.template vec3<Eigen::Vector3d>("point");
    s.normal = t.template vec3<Eigen::Vector3d>("normal");
  } else if (type == "sphere") {
    allow({"type", "centre", "radius", "inside"});
    s.type = geometry::SurfaceType::kSphere;
    s.point = t.template vec3<Eigen::Vector3d>("centre");
    s.radii = Eigen::Vector3d::Constant(t.number("radius"));
    s.inside = t.boolean("inside", false);
  } else if (type == "ellipsoid") {
    allow({"type", "centre", "radii", "inside"});
    s.type = geometry::SurfaceType::kEllipsoid;
    s.point = t.template vec3<Eigen::Vector3d>("centre");
    s.radii = t.template vec3<Eigen::Vector3d>("radii");
    s.inside = t.boolean("inside", false);
  } else {
    t.fail("type", "must be plane, sphere or ellipsoid (got '" + type + "')");
  }
  const std::string e = s.validate_shape();
  if (!e.empty()) t.fail(e.substr(0, e.find(':')), e.substr(e.find(':') + 2));
  return s;
}

}  // namespace config
}  // namespace hydrojet
