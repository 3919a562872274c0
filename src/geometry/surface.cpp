#include "hydrojet_control/geometry/surface.h"

#include <algorithm>
#include <cmath>

namespace hydrojet {
namespace geometry {
namespace {

using Eigen::Vector3d;

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

std::string Surface::validate_shape() const {
  const char* where = type == SurfaceType::kPlane ? "point" : "centre";
  if (!point.allFinite()) return std::string(where) + ": must be finite";
  if (type == SurfaceType::kPlane && (!normal.allFinite() || !(normal.norm() > 1e-9)))
    return "normal: must be finite and not zero";
  if (type != SurfaceType::kPlane && (!radii.allFinite() || !(radii.minCoeff() > 0.0)))
    return std::string(type == SurfaceType::kSphere ? "radius" : "radii") + ": must be finite and > 0";
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

}  // namespace geometry
}  // namespace hydrojet
