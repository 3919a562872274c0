#include "hydrojet_control/plant/environment.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace plant {
namespace {

using Eigen::Vector3d;

std::string check_vector(const std::string& field, const Vector3d& v) {
  return v.allFinite() ? "" : field + ": must be finite";
}

}  // namespace

std::string Surface::validate() const {
  if (std::string e = validate_shape(); !e.empty()) return e;
  if (std::string e = util::check_range("stiffness", stiffness, 1e-9, 1e9); !e.empty()) return e;
  if (std::string e = util::check_range("damping", damping, 0.0, 1e6); !e.empty()) return e;
  if (std::string e = util::check_range("friction", friction, 0.0, 10.0); !e.empty()) return e;
  return "";
}

std::string Environment::validate() const {
  if (std::string e = util::check_range("tip_radius", tip_radius, 0.0, 1.0); !e.empty()) return e;
  if (std::string e = util::check_range("friction_speed", friction_speed, 1e-9, 10.0); !e.empty()) return e;
  for (size_t i = 0; i < surfaces.size(); ++i)
    if (std::string e = surfaces[i].validate(); !e.empty()) return "surfaces[" + std::to_string(i) + "]." + e;
  for (size_t i = 0; i < loads.size(); ++i) {
    const ExternalLoad& l = loads[i];
    const std::string at = "loads[" + std::to_string(i) + "].";
    if (!std::isfinite(l.start)) return at + "start: must be finite";
    if (!(l.end >= l.start)) return at + "end: must not be before start (infinite: to the end)";
    if (std::string e = check_vector(at + "force", l.force); !e.empty()) return e;
    if (std::string e = check_vector(at + "moment", l.moment); !e.empty()) return e;
  }
  return "";
}

Contact contact(const Environment& e, const Vector3d& p, const Vector3d& v) {
  Contact c;
  c.clearance = std::numeric_limits<double>::infinity();
  Vector3d normal_sum = Vector3d::Zero();
  double deepest = std::numeric_limits<double>::infinity();
  for (const Surface& s : e.surfaces) {
    const SurfacePoint sp = nearest_point(s, p);
    const double gap = sp.distance - e.tip_radius;
    c.clearance = std::min(c.clearance, gap);
    if (!(gap < 0.0)) continue;
    const double vn = v.dot(sp.normal);
    const double fn = std::max(0.0, -s.stiffness * gap - s.damping * vn);
    const Vector3d vt = v - vn * sp.normal;
    c.force +=
        fn * sp.normal - s.friction * fn * vt / std::sqrt(vt.squaredNorm() + e.friction_speed * e.friction_speed);
    normal_sum += fn * sp.normal;
    c.touching = c.touching || fn > 0.0;
    if (gap < deepest) {
      deepest = gap;
      c.point = sp.point;
      c.normal = sp.normal;
    }
  }
  c.normal_force = normal_sum.norm();
  return c;
}

void loads_at(const Environment& e, double t, const Eigen::Matrix3d& tip_rotation, Vector3d* force, Vector3d* moment) {
  force->setZero();
  moment->setZero();
  for (const ExternalLoad& l : e.loads) {
    if (t < l.start || t >= l.end) continue;
    *force += l.tip_frame ? Vector3d(tip_rotation * l.force) : l.force;
    *moment += l.tip_frame ? Vector3d(tip_rotation * l.moment) : l.moment;
  }
}

double contact_step(const Environment& e, double mass) {
  double step = std::numeric_limits<double>::infinity();
  if (!(mass > 0.0)) return step;
  for (const Surface& s : e.surfaces) {
    step = std::min(step, 0.05 * std::sqrt(mass / s.stiffness));
    if (s.damping > 0.0) step = std::min(step, 0.5 * mass / s.damping);
  }
  return step;
}

}  // namespace plant
}  // namespace hydrojet
