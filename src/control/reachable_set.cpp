#include "hydrojet_control/control/reachable_set.h"

#include <chrono>
#include <memory>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "force_polygon.h"
#include "hydrojet_control/actuation/bounded_allocation.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace control {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;

/// The sweep's rays per boundary bin: the polygon's edge maps onto the boundary unevenly (gravity,
/// precurvature), so several edge samples per bin keep every bin filled.
constexpr int kRaysPerBin = 2;

/// The sweep over the inputs: solve + C^b + stability (eq. 23) per point, warm-started along a
/// serpentine of rays (outward on even rays, inward on odd ones) in the steering plane: the tip
/// direction's change per input at rest, S = Eᵀ(−d̂ R J_q,ω) (2×N, E a basis ⊥ d), maps the input box
/// onto a polygon (the jets' force polygon of eq. 24 turned by the rest compliance, for the HydroJet);
/// each point s of a ray is reached by the inputs of eq. (20) for it, q = argmin ‖S q − s‖² + λ‖q‖²
/// within the bounds (the smallest inputs that steer there), and the model is solved at q.
class ForceSweep {
 public:
  ForceSweep(const RobotModel& model, const ReachableSetOptions& options) : model_(model), options_(options) {}

  /// The tip z-axis at rest (inputs at 0, or at the bound nearest to it; unit, base frame), and the
  /// steering plane there; false when the solve fails.
  bool zero_force_direction(Vec3* d) {
    rest_ = InputVector::Zero(model_.input_count()).cwiseMax(model_.lower()).cwiseMin(model_.upper());
    const rod::RodSolution s = model_.solve(rest_);
    const ActuatedModel::Linearisation lin = s.converged ? model_.linearise() : ActuatedModel::Linearisation();
    if (!lin.ok) return false;
    *d = s.tip_rotation.col(2);
    Vec3 e1 = Vec3::UnitX() - d->x() * *d;
    if (e1.norm() < 1e-6) e1 = Vec3::UnitY() - d->y() * *d;
    e1.normalize();
    const Vec3 e2 = d->cross(e1);
    const Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxInputs> M =
        -so3::hat(*d) * s.tip_rotation * lin.actuation.bottomRows<3>();
    steering_.resize(2, model_.input_count());
    steering_.row(0) = e1.transpose() * M;
    steering_.row(1) = e2.transpose() * M;
    lambda_ = 1e-9 * steering_.squaredNorm() / model_.input_count();
    polygon_ = std::make_unique<ForcePolygon>(steering_, model_.lower(), model_.upper(), steering_ * rest_);
    return true;
  }

  /// The accepted directions: converged, σ_c ≥ min_stability_margin and eig_min > 0; their tip
  /// positions in *positions. Stops with std::runtime_error once `deadline` has passed.
  std::vector<Vec3> accepted_directions(std::chrono::steady_clock::time_point deadline, std::vector<Vec3>* positions) {
    std::vector<Vec3> out;
    const int rays = kRaysPerBin * options_.azimuth_bins, rings = options_.force_samples;
    const Eigen::Vector2d o = polygon_->origin();
    Vec3 d, p;
    InputVector q = rest_;
    if (accepted(o, &q, &d, &p)) out.push_back(d), positions->push_back(p);
    for (int j = 0; j < rays; ++j) {
      const Eigen::Vector2d u(std::cos(kTwoPi * j / rays), std::sin(kTwoPi * j / rays));
      const double extent = polygon_->extent(u);
      for (int kk = 1; kk <= rings; ++kk) {
        if (std::chrono::steady_clock::now() > deadline) {
          std::ostringstream os;
          os << "reachable set: the sweep took more than max_time = " << options_.max_time << " s and had solved "
             << j * rings + kk - 1 << " of " << rays * rings << " points (do the solves converge? are the actuator "
             << "bounds sane?)";
          throw std::runtime_error(os.str());
        }
        const int k = j % 2 == 0 ? kk : rings + 1 - kk;
        if (accepted(o + extent * k / rings * u, &q, &d, &p)) out.push_back(d), positions->push_back(p);
      }
    }
    return out;
  }

 private:
  /// The model at the inputs that steer to s (warm-started from *q, which they replace): its tip
  /// direction *d and position *p.
  bool accepted(const Eigen::Vector2d& s, InputVector* q, Vec3* d, Vec3* p) {
    const actuation::BoundedAllocationResult a =
        actuation::allocate_bounded(steering_, s, model_.lower(), model_.upper(), lambda_, 1e-9, q);
    if (!a.ok) return false;
    *q = a.q;
    const rod::RodSolution sol = model_.solve(*q);
    if (!sol.converged) return false;
    *d = sol.tip_rotation.col(2);
    *p = sol.tip_position;
    const ActuatedModel::Linearisation lin = model_.linearise();
    if (!lin.ok) return false;
    const rod::StabilityReport st = model_.stability(lin);
    return st.ok && st.margin >= options_.min_stability_margin && st.eig_min > 0.0;
  }

  ActuatedModel model_;
  const ReachableSetOptions& options_;
  InputVector rest_;
  actuation::InputMatrix steering_;
  double lambda_ = 0.0;
  std::unique_ptr<ForcePolygon> polygon_;
};

/// The point of the great-circle arc a→b (shorter than π) nearest to the unit vector p.
Vec3 nearest_on_arc(const Vec3& a, const Vec3& b, const Vec3& p) {
  const Vec3 n = a.cross(b);
  if (n.norm() > 1e-15) {
    const Vec3 nh = n.normalized();
    const Vec3 q = p - p.dot(nh) * nh;  // p projected onto the arc's plane
    if (q.norm() > 1e-15) {
      const Vec3 qh = q.normalized();
      if (a.cross(qh).dot(nh) >= 0.0 && qh.cross(b).dot(nh) >= 0.0) return qh;
    }
  }
  return p.dot(a) >= p.dot(b) ? a : b;
}

}  // namespace

std::string ReachableSetOptions::validate() const {
  std::ostringstream os;
  if (!std::isfinite(min_stability_margin) || min_stability_margin < 0.0)
    os << "min_stability_margin: must be finite and >= 0, got " << min_stability_margin;
  else if (force_samples < 4)
    os << "force_samples: must be >= 4, got " << force_samples;
  else if (azimuth_bins < 8)
    os << "azimuth_bins: must be >= 8, got " << azimuth_bins;
  else if (!(max_time > 0.0) || !std::isfinite(max_time))
    os << "max_time: must be finite and > 0, got " << max_time;
  return os.str();
}

ReachableSet ReachableSet::compute(const RobotModel& model, const ReachableSetOptions& options) {
  if (std::string err = options.validate(); !err.empty()) throw std::invalid_argument(err);
  const auto t0 = std::chrono::steady_clock::now();
  ReachableSet set;
  ForceSweep sweep(model, options);
  if (sweep.zero_force_direction(&set.center_)) {
    set.samples_ = sweep.accepted_directions(t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                      std::chrono::duration<double>(options.max_time)),
                                             &set.sample_positions_);
    set.build_boundary(options.azimuth_bins);
  }
  set.compute_time_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return set;
}

double ReachableSet::azimuth_about_center(const Vec3& d) const {
  const double a = std::atan2(d.dot(e2_), d.dot(e1_));
  return a < 0.0 ? a + kTwoPi : a;
}

Vec3 ReachableSet::polar_point(double angle, double azimuth) const {
  return std::cos(angle) * center_ + std::sin(angle) * (std::cos(azimuth) * e1_ + std::sin(azimuth) * e2_);
}

int ReachableSet::bin_of(double azimuth) const {
  const int bins = static_cast<int>(max_angle_.size());
  return std::min(bins - 1, static_cast<int>(azimuth / kTwoPi * bins));
}

void ReachableSet::build_boundary(int bins) {
  if (samples_.empty()) return;
  e1_ = Vec3::UnitX() - center_.x() * center_;
  if (e1_.norm() < 1e-6) e1_ = Vec3::UnitY() - center_.y() * center_;
  e1_.normalize();
  e2_ = center_.cross(e1_);
  max_angle_.assign(bins, -1.0);
  vertex_azimuth_.assign(bins, 0.0);
  boundary_.assign(bins, center_);
  for (const Vec3& s : samples_) {
    const double angle = angle_from_center(s), azimuth = azimuth_about_center(s);
    const int b = bin_of(azimuth);
    if (angle <= max_angle_[b]) continue;
    max_angle_[b] = angle;
    boundary_[b] = s;
    vertex_azimuth_[b] = angle > 1e-12 ? azimuth : kTwoPi * (b + 0.5) / bins;
  }
  const std::vector<double> sampled = max_angle_;
  for (int b = 0; b < bins; ++b) {
    if (sampled[b] >= 0.0) continue;
    double left = -1.0, right = -1.0;
    for (int k = 1; k < bins && (left < 0.0 || right < 0.0); ++k) {
      if (left < 0.0) left = sampled[(b - k + bins) % bins];
      if (right < 0.0) right = sampled[(b + k) % bins];
    }
    max_angle_[b] = std::min(left, right);
    vertex_azimuth_[b] = kTwoPi * (b + 0.5) / bins;
    boundary_[b] = polar_point(max_angle_[b], vertex_azimuth_[b]);
  }
}

bool ReachableSet::contains(const Vec3& direction) const {
  if (empty()) return false;
  const Vec3 d = direction.normalized();
  if (angle_from_center(d) < 1e-12) return true;
  const int bins = static_cast<int>(boundary_.size());
  const double azimuth = azimuth_about_center(d);
  const int b = bin_of(azimuth);
  const int k0 = azimuth >= vertex_azimuth_[b] ? b : (b + bins - 1) % bins;
  const Vec3& a = boundary_[k0];
  const Vec3& c = boundary_[(k0 + 1) % bins];
  // Inside the wedge's spherical triangle (centre, a, c): on the centre's side of the arc a→c.
  return d.dot(a.cross(c)) >= -1e-12;
}

Vec3 ReachableSet::clip(const Vec3& direction, double* moved) const {
  const Vec3 d = direction.normalized();
  Vec3 best = center_;
  if (!empty() && contains(d)) {
    best = d;
  } else if (!empty()) {
    double best_dot = -2.0;
    for (size_t k = 0; k < boundary_.size(); ++k) {
      const Vec3 q = nearest_on_arc(boundary_[k], boundary_[(k + 1) % boundary_.size()], d);
      if (q.dot(d) > best_dot) {
        best_dot = q.dot(d);
        best = q;
      }
    }
  }
  if (moved) *moved = best == d ? 0.0 : geodesic_error(d, best);
  return best;
}

}  // namespace control
}  // namespace hydrojet
