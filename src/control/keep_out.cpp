#include "hydrojet_control/control/keep_out.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {
namespace {

/// Grid nodes per side of the chart: 64 puts a node every 0.025 of the HydroJet's chart (1.4°), so the
/// tip position (curving over the rod's length) is interpolated to ~0.1 mm.
constexpr int kNodes = 64;
/// A node's fit takes the sweep's samples within this many node spacings (Gaussian weight of half it).
constexpr double kFitRadius = 2.5;
constexpr int kFitMinSamples = 6;

}  // namespace

std::string KeepOutRegion::validate() const {
  if (std::string e = surface.validate_shape(); !e.empty()) return e;
  return util::check_range("margin", margin, 0.0, 0.1);
}

KeepOut::KeepOut(std::vector<KeepOutRegion> regions, double tip_radius, std::shared_ptr<const ReachableSet> set)
    : regions_(std::move(regions)), tip_radius_(tip_radius), set_(std::move(set)) {
  for (size_t i = 0; i < regions_.size(); ++i)
    if (std::string e = regions_[i].validate(); !e.empty())
      throw std::invalid_argument("keep_out[" + std::to_string(i) + "]/" + e);
  if (std::string e = util::check_range("tip_radius", tip_radius_, 0.0, 1.0); !e.empty())
    throw std::invalid_argument("keep_out: " + e);
  if (!set_ || set_->empty()) {
    if (!regions_.empty()) throw std::invalid_argument("keep_out: the robot has no reachable set to keep out of");
    return;
  }
  center_ = set_->center();
  e1_ = Vec3::UnitX() - center_.x() * center_;
  if (e1_.norm() < 1e-6) e1_ = Vec3::UnitY() - center_.y() * center_;
  e1_.normalize();
  e2_ = center_.cross(e1_);
  fit_grid();
  bool any = false;
  for (int at = 0; at < n_ * n_; ++at) any = any || (node_valid_[at] && node_in_set_[at] && node_clearance_[at] >= 0.0);
  if (!regions_.empty() && !any)
    throw std::invalid_argument("keep_out: the regions with their margins cover the whole reachable set");
}

KeepOut::Vec2 KeepOut::chart(const Vec3& d) const {
  const Vec2 u(d.dot(e1_), d.dot(e2_));
  // A direction beyond 90° from the centre maps onto the chart's rim (the set never reaches there).
  return d.dot(center_) > 0.0 || u.norm() == 0.0 ? u : Vec2(u.normalized());
}

Vec3 KeepOut::direction(const Vec2& u) const {
  const double s = std::min(1.0, u.squaredNorm());
  return (std::sqrt(1.0 - s) * center_ + u.x() * e1_ + u.y() * e2_).normalized();
}

// Each node: a weighted linear fit of the sweep's tip positions in the chart about it (its constant
// term), from the samples within kFitRadius spacings; no fit where the sweep has too few.
void KeepOut::fit_grid() {
  const std::vector<Vec3>& dirs = set_->samples();
  const std::vector<Vec3>& pos = set_->sample_positions();
  double reach = 0.0;
  for (const Vec3& d : dirs) reach = std::max(reach, chart(d).norm());
  n_ = kNodes;
  const double step0 = 2.0 * reach / (n_ - 3);
  extent_ = reach + step0;
  const double step = 2.0 * extent_ / (n_ - 1), radius = kFitRadius * step;
  std::vector<std::vector<int>> bucket(n_ * n_);
  std::vector<Vec2> us(dirs.size());
  auto cell = [&](double x) { return std::clamp(static_cast<int>(std::lround((x + extent_) / step)), 0, n_ - 1); };
  for (size_t k = 0; k < dirs.size(); ++k) {
    us[k] = chart(dirs[k]);
    bucket[cell(us[k].y()) * n_ + cell(us[k].x())].push_back(static_cast<int>(k));
  }
  node_position_.assign(n_ * n_, Vec3::Zero());
  node_gradient_.assign(n_ * n_, Eigen::Matrix<double, 3, 2>::Zero());
  node_valid_.assign(n_ * n_, 0);
  node_in_set_.assign(n_ * n_, 0);
  node_clearance_.assign(n_ * n_, -std::numeric_limits<double>::infinity());
  const int reach_cells = static_cast<int>(std::ceil(kFitRadius));
  for (int j = 0; j < n_; ++j) {
    for (int i = 0; i < n_; ++i) {
      const Vec2 node(-extent_ + i * step, -extent_ + j * step);
      Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
      Eigen::Matrix3d B = Eigen::Matrix3d::Zero();  // rows: the basis (1, du) against the position's x, y, z
      int used = 0;
      for (int jj = std::max(0, j - reach_cells); jj <= std::min(n_ - 1, j + reach_cells); ++jj)
        for (int ii = std::max(0, i - reach_cells); ii <= std::min(n_ - 1, i + reach_cells); ++ii)
          for (int k : bucket[jj * n_ + ii]) {
            const Vec2 du = us[k] - node;
            if (du.norm() > radius) continue;
            const double w = std::exp(-2.0 * du.squaredNorm() / (radius * radius));
            const Eigen::Vector3d b(1.0, du.x() / step, du.y() / step);
            A += w * b * b.transpose();
            B += w * b * pos[k].transpose();
            ++used;
          }
      if (used < kFitMinSamples) continue;
      const Eigen::LDLT<Eigen::Matrix3d> ldlt(A);
      if (ldlt.info() != Eigen::Success || !(A.determinant() > 1e-9 * std::pow(A.trace(), 3))) continue;
      const Eigen::Matrix3d X = ldlt.solve(B);
      if (!X.allFinite()) continue;
      const int at = j * n_ + i;
      node_position_[at] = X.row(0).transpose();
      node_gradient_[at] << X.row(1).transpose() / step, X.row(2).transpose() / step;
      node_valid_[at] = 1;
      node_in_set_[at] = set_->contains(direction(node));
      node_clearance_[at] = clearance_of(node_position_[at]);
    }
  }
}

Vec3 KeepOut::position_at(const Vec2& u) const {
  if (!u.allFinite()) return Vec3::Constant(std::nan(""));
  const double step = 2.0 * extent_ / (n_ - 1);
  const double x = std::clamp((u.x() + extent_) / step, 0.0, n_ - 1.000001);
  const double y = std::clamp((u.y() + extent_) / step, 0.0, n_ - 1.000001);
  const int i = static_cast<int>(x), j = static_cast<int>(y);
  const double fx = x - i, fy = y - j;
  Vec3 sum = Vec3::Zero();
  double weight = 0.0;
  const int at[4] = {j * n_ + i, j * n_ + i + 1, (j + 1) * n_ + i, (j + 1) * n_ + i + 1};
  const double w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
  for (int k = 0; k < 4; ++k) {
    if (!node_valid_[at[k]]) continue;
    const Vec2 node(-extent_ + (at[k] % n_) * step, -extent_ + (at[k] / n_) * step);
    sum += w[k] * (node_position_[at[k]] + node_gradient_[at[k]] * (u - node));
    weight += w[k];
  }
  if (weight > 1e-6) return sum / weight;
  // Off the sweep (a direction the set does not reach): the nearest sample's position.
  const std::vector<Vec3>& dirs = set_->samples();
  const Vec3 d = direction(u);
  size_t best = 0;
  for (size_t k = 1; k < dirs.size(); ++k)
    if (dirs[k].dot(d) > dirs[best].dot(d)) best = k;
  return set_->sample_positions()[best];
}

double KeepOut::clearance_of(const Vec3& p) const {
  double least = std::numeric_limits<double>::infinity();
  for (const KeepOutRegion& r : regions_) {
    const double c = geometry::nearest_point(r.surface, p).distance - tip_radius_ - r.margin - kTrackingAllowance;
    if (!std::isfinite(c)) return -std::numeric_limits<double>::infinity();  // unknown: not allowed
    least = std::min(least, c);
  }
  return least;
}

double KeepOut::clearance_at(const Vec2& u, const Vec3& offset) const { return clearance_of(position_at(u) + offset); }

Vec3 KeepOut::tip_position(const Vec3& d) const {
  return set_ && !set_->empty() ? position_at(chart(d.normalized())) : Vec3(Vec3::Constant(std::nan("")));
}

double KeepOut::clearance(const Vec3& d, const Vec3& offset) const {
  if (regions_.empty()) return std::numeric_limits<double>::infinity();
  return clearance_at(chart(d.normalized()), offset);
}

KeepOut::Vec2 KeepOut::edge_toward(const Vec2& allowed, const Vec2& u, const Vec3& offset, bool slide) const {
  Vec2 in = allowed, out = u;
  for (int k = 0; k < 40 && (out - in).norm() > 1e-9; ++k) {
    const Vec2 mid = 0.5 * (in + out);
    (clearance_at(mid, offset) >= 0.0 ? in : out) = mid;
  }
  // Slide along the edge to the point nearest u on the sphere: Newton steps on the geodesic distance
  // along the edge's tangent (finite differences), each put back onto the edge along the clearance's
  // gradient, kept only while allowed and nearer.
  const Vec3 target = direction(u);
  auto distance = [&](const Vec2& v) { return geodesic_error(target, direction(v)); };
  const double h = 1e-5;
  for (int it = 0; slide && it < 10; ++it) {
    const Vec2 g((clearance_at(in + Vec2(h, 0), offset) - clearance_at(in - Vec2(h, 0), offset)) / (2 * h),
                 (clearance_at(in + Vec2(0, h), offset) - clearance_at(in - Vec2(0, h), offset)) / (2 * h));
    if (!(g.norm() > 1e-12)) break;
    const Vec2 t = Vec2(-g.y(), g.x()).normalized();
    const double f0 = distance(in), fp = distance(in + h * t), fm = distance(in - h * t);
    const double slope = (fp - fm) / (2 * h), curve = (fp - 2 * f0 + fm) / (h * h);
    double s = curve > 1e-9 ? -slope / curve : -slope;
    s = std::clamp(s, -0.05, 0.05);
    Vec2 next = in + s * t;
    for (int k = 0; k < 3; ++k) next -= clearance_at(next, offset) / g.squaredNorm() * g;
    for (int k = 0; k < 20 && clearance_at(next, offset) < 0.0; ++k) next += 1e-6 * g.normalized();
    if (!(clearance_at(next, offset) >= 0.0) || !(distance(next) < f0 - 1e-12)) break;
    in = next;
  }
  return in;
}

Vec3 KeepOut::clip(const Vec3& d, double* moved, const Vec3& offset) const {
  const Vec3 unit = d.normalized();
  if (moved) *moved = 0.0;
  if (!unit.allFinite() || allows(unit, offset)) return unit;
  const Vec2 u = chart(unit);
  const double step = 2.0 * extent_ / (n_ - 1);
  auto node_at = [&](int at) { return Vec2(-extent_ + (at % n_) * step, -extent_ + (at / n_) * step); };
  // The start: the nearest node allowed for any offset as long as this one (a surface's distance
  // changes by at most the offset's length); failing that, the nearest allowed with this offset.
  int best = -1;
  for (const bool exact : {false, true}) {
    double best_dot = -2.0;
    for (int at = 0; at < n_ * n_; ++at) {
      if (!node_valid_[at] || !node_in_set_[at]) continue;
      if (exact ? !(clearance_at(node_at(at), offset) >= 0.0) : !(node_clearance_[at] >= offset.norm())) continue;
      const double dot = direction(node_at(at)).dot(unit);
      if (dot > best_dot) best_dot = dot, best = at;
    }
    if (best >= 0) break;
  }
  if (best < 0) return unit;  // nothing allowed with this offset: the caller holds (Reference)
  const Vec2 node = node_at(best);
  Vec3 out = direction(edge_toward(node, u, offset, true));
  if (!set_->contains(out))
    out = direction(edge_toward(node, u, offset, false));  // slid off the set: the edge's first point
  if (moved) *moved = geodesic_error(unit, out);
  return out;
}

}  // namespace control
}  // namespace hydrojet
