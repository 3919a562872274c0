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

/// The nearest point of the axis-aligned ellipsoid with semi-axes a (centred at 0) to z ≥ 0 (each
/// component): x_i = a_i² z_i / (t + a_i²), with t the root of Σ (a_i z_i / (t + a_i²))² = 1, found
/// by bisection (the sum falls monotonically in t > −min a_i²; Eberly's method). A zero component is
/// nudged off its axis, which gives the limit the nearest point takes there.
Vector3d ellipsoid_nearest(const Vector3d& a, Vector3d z) {
  const double tiny = 1e-12 * a.maxCoeff();
  z = z.cwiseMax(tiny);
  auto f = [&](double t) { return (a.cwiseProduct(z).array() / (t + a.array().square())).square().sum() - 1.0; };
  double lo = -a.array().square().minCoeff(), hi = a.maxCoeff() * z.norm();
  for (int k = 0; k < 200 && hi - lo > 1e-15 * (std::abs(lo) + std::abs(hi)); ++k) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) > 0.0 ? lo : hi) = mid;
  }
  const double t = 0.5 * (lo + hi);
  Vector3d x = (a.array().square() * z.array() / (t + a.array().square())).matrix();
  // Components whose t + a_j² is lost to rounding (t next to −a_j²: a point near the centre or an
  // axis) take the rest of the way to the surface, in the proportions computed.
  auto lost = [&](int j) { return t + a[j] * a[j] < 1e-6 * a[j] * a[j]; };
  double rest = 1.0, ill = 0.0;
  for (int j = 0; j < 3; ++j) {
    const double share = (x[j] / a[j]) * (x[j] / a[j]);
    if (lost(j))
      ill += share;
    else
      rest -= share;
  }
  if (ill > 0.0)
    for (int j = 0; j < 3; ++j)
      if (lost(j)) x[j] *= std::sqrt(std::max(0.0, rest) / ill);
  return x;
}

}  // namespace

std::string Surface::validate() const {
  if (std::string e = check_vector(type == SurfaceType::kPlane ? "point" : "centre", point); !e.empty()) return e;
  if (type == SurfaceType::kPlane && (!normal.allFinite() || !(normal.norm() > 1e-9)))
    return "normal: must be finite and not zero";
  if (type != SurfaceType::kPlane && (!radii.allFinite() || !(radii.minCoeff() > 0.0)))
    return std::string(type == SurfaceType::kSphere ? "radius" : "radii") + ": must be finite and > 0";
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

SurfacePoint nearest_point(const Surface& s, const Vector3d& p) {
  SurfacePoint out;
  if (s.type == SurfaceType::kPlane) {
    out.normal = s.normal.normalized();
    out.distance = (p - s.point).dot(out.normal);
    out.point = p - out.distance * out.normal;
    return out;
  }
  const Vector3d y = p - s.point;
  Vector3d outward;
  double gap;  // distance from the surface, positive outside the body
  if (s.type == SurfaceType::kSphere) {
    const double r = s.radii.x(), n = y.norm();
    outward = n > 0.0 ? Vector3d(y / n) : Vector3d::UnitX();
    gap = n - r;
    out.point = s.point + r * outward;
  } else {
    Vector3d sign;
    for (int i = 0; i < 3; ++i) sign[i] = y[i] < 0.0 ? -1.0 : 1.0;
    const Vector3d x = ellipsoid_nearest(s.radii, y.cwiseAbs()).cwiseProduct(sign);
    outward = x.cwiseQuotient(s.radii.cwiseProduct(s.radii)).normalized();
    const bool outside = y.cwiseQuotient(s.radii).squaredNorm() > 1.0;
    gap = (outside ? 1.0 : -1.0) * (y - x).norm();
    out.point = s.point + x;
  }
  out.distance = s.inside ? -gap : gap;
  out.normal = s.inside ? Vector3d(-outward) : outward;
  return out;
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
