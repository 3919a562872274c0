#include "hydrojet_control/control/plant_identification.h"

#include <algorithm>
#include <cmath>

#include "hydrojet_control/actuation/flow_regulator.h"
#include "hydrojet_control/identification/free_vibration.h"
#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {

std::string IdentificationOptions::validate() const {
  return util::check_range("probe_amplitude", probe_amplitude, 0.002, 0.2);
}

void LatencyEstimator::add(double now, double stamp) {
  const double delay = now - stamp;
  if (!std::isfinite(delay) || delay < 0.0) return;
  delays_[next_] = delay;
  next_ = (next_ + 1) % kWindow;
  count_ = std::min(count_ + 1, kWindow);
}

double LatencyEstimator::latency() const {
  if (count_ == 0) return 0.0;
  std::array<double, kWindow> d = delays_;
  std::nth_element(d.begin(), d.begin() + count_ / 2, d.begin() + count_);
  return d[count_ / 2];
}

namespace {
constexpr double kForgetting =
    0.99995;  // per step: a memory of ~20000 steps (200 s at 100 Hz): a valve does not change
constexpr double kMovingFraction = 0.005;
constexpr int kMovingSteps = 50;  // moving steps identified() asks for
double lag_at(int l) {
  using E = ValveLagEstimator;
  return E::kMinLag * std::pow(E::kMaxLag / E::kMinLag, static_cast<double>(l) / (E::kLags - 1));
}
}  // namespace

ValveLagEstimator::ValveLagEstimator(double prior_lag, double max_flow) : prior_lag_(prior_lag), scale_(max_flow) {
  reset();
}

void ValveLagEstimator::reset() {
  plays_.assign(kPlays, Play());
  for (int l = 0; l < kLags; ++l) decay_[l] = std::exp(-dt_ / lag_at(l));
  sum_ff_ = weight_ = 0.0;
  growth_ = 1.0;
  next_refresh_ = refreshed_ = calls_ = 0;
  fitted_ = false;
  tau_ = prior_lag_;
  tau_sd_ = 1.0;
  play_ = 0.0;
  moving_steps_ = 0;
}

void ValveLagEstimator::add(double previous_flow, double duty, double flow, double dt) {
  if (!(std::isfinite(previous_flow) && std::isfinite(duty) && std::isfinite(flow) && dt > 0.0)) return;
  if (std::abs(dt - dt_) > 0.01 * dt_) {  // a new sampling period: start again at it
    dt_ = dt;
    reset();
  }
  const double y = flow / scale_, d = std::clamp(duty, 0.0, 1.0);
  // Forgetting as a growing weight of the new sample (the sums are λ^-k times the forgotten ones):
  // no pass over the sums to scale them; brought back to scale before it overflows.
  growth_ /= kForgetting;
  if (growth_ > 1e100) rescale();
  sum_ff_ += growth_ * y * y;
  weight_ += growth_;
  for (int p = 0; p < kPlays; ++p) {
    Play& play = plays_[p];
    play.effective = actuation::play_opening(play.effective, d, kPlayStep * p);
    const int j = static_cast<int>(std::upper_bound(kKnotDuty, kKnotDuty + kKnots - 1, play.effective) - kKnotDuty) - 1;
    const double w = (play.effective - kKnotDuty[j]) / (kKnotDuty[j + 1] - kKnotDuty[j]);
    for (int l = 0; l < kLags; ++l) {
      Fit& f = play.lags[l];
      const double a = decay_[l];
      f.x *= a;
      f.x(j) += (1.0 - a) * (1.0 - w);
      f.x(j + 1) += (1.0 - a) * w;
      f.M.selfadjointView<Eigen::Lower>().rankUpdate(f.x, growth_);
      f.b += growth_ * y * f.x;
    }
  }
  // The counters stop where they matter: no overflow on a controller that runs for months.
  if (std::abs(flow - previous_flow) > kMovingFraction * scale_)
    moving_steps_ = std::min(moving_steps_ + 1, kMovingSteps);
  calls_ = (calls_ + 1) % kRefreshEvery;
  if (calls_ != 0) return;
  refresh(next_refresh_);
  next_refresh_ = (next_refresh_ + 1) % kPlays;
  refreshed_ = std::min(refreshed_ + 1, kPlays);
  if (refreshed_ == kPlays) estimate();
}

void ValveLagEstimator::rescale() {
  const double s = 1.0 / growth_;
  for (Play& play : plays_)
    for (Fit& f : play.lags) f.M *= s, f.b *= s;
  sum_ff_ *= s, weight_ *= s;
  growth_ = 1.0;
}

bool ValveLagEstimator::identified() const { return moving_steps_ >= kMovingSteps && fitted_ && tau_sd_ <= 0.1; }

// One play's least squares at every lag: the residual's mean square (f² − bᵀc at c = M⁻¹b, over the
// sums' weight: plays refreshed at different samples compare) with a light ridge for the knots the
// duty has not visited.
void ValveLagEstimator::refresh(int p) {
  Play& play = plays_[p];
  for (int l = 0; l < kLags; ++l) {
    const Fit& f = play.lags[l];
    Mat M = f.M.selfadjointView<Eigen::Lower>();
    M.diagonal().array() += 1e-9 * (M.trace() / kKnots) + 1e-12;
    const Vec c = M.ldlt().solve(f.b);
    play.residual[l] = std::max(0.0, sum_ff_ - f.b.dot(c)) / weight_;
  }
}

namespace {
// The parabola through three values a grid step apart (at −1, 0, 1): its least's abscissa, clamped
// to half a step (the middle value is the grid's least), and its value there; false where it does
// not bend upward.
struct Vertex {
  double at = 0.0;
  double value = 0.0;
  double bend = 0.0;  ///< the second difference
  bool ok = false;
};
Vertex parabola_vertex(double lo, double mid, double hi) {
  Vertex v{0.0, mid, lo - 2.0 * mid + hi, false};
  if (!(v.bend > 0.0)) return v;
  v.at = std::clamp(0.5 * (lo - hi) / v.bend, -0.5, 0.5);
  v.value = mid + 0.5 * (hi - lo) * v.at + 0.5 * v.bend * v.at * v.at;
  v.ok = true;
  return v;
}
}  // namespace

// The play and lag of least residual; τ from a parabola through it and its neighbours in log τ, its
// spread from the parabola's curvature against the residual's variance (one standard deviation
// raises the residual sum, the samples' count times its mean square, by about that variance).
void ValveLagEstimator::estimate() {
  int bp = 0, bl = 0;
  for (int p = 0; p < kPlays; ++p)
    for (int l = 0; l < kLags; ++l)
      if (plays_[p].residual[l] < plays_[bp].residual[bl]) bp = p, bl = l;
  play_ = kPlayStep * bp;
  if (bp > 0 && bp < kPlays - 1) {      // between the grid's plays: a parabola through each one's least residual
    const auto least = [this](int p) {  // over the lags, refined by a parabola in log τ (τ and the play trade off)
      const auto& r = plays_[p].residual;
      const int l = static_cast<int>(std::min_element(r.begin(), r.end()) - r.begin());
      return l == 0 || l == kLags - 1 ? r[l] : parabola_vertex(r[l - 1], r[l], r[l + 1]).value;
    };
    const Vertex v = parabola_vertex(least(bp - 1), least(bp), least(bp + 1));
    play_ += kPlayStep * v.at;
  }
  fitted_ = bl > 0 && bl < kLags - 1 && weight_ > 0.0;
  if (!fitted_) return;
  const auto& r = plays_[bp].residual;
  const Vertex v = parabola_vertex(r[bl - 1], r[bl], r[bl + 1]);
  if (!v.ok) {
    fitted_ = false;
    return;
  }
  const double h = std::log(kMaxLag / kMinLag) / (kLags - 1);  // the grid's step in log τ
  tau_ = lag_at(bl) * std::exp(h * v.at);
  const double samples = weight_ / growth_;  // the forgotten count
  tau_sd_ = std::sqrt(2.0 * r[bl] * h * h / (samples * v.bend));
}

rod::DynamicRodModel robot_dynamics(const rod::RodModel& robot, double tip_mass_scale, double damping_time) {
  rod::DynamicRodModel d;
  d.rod = robot;
  d.rod.tip_mass *= tip_mass_scale;
  d.kelvin_voigt_time = damping_time;
  return d;
}

ProbeJob::Result ProbeJob::run() const {
  Result r;
  r.index = index;
  r.mode = identification::fit_mode(record, omega_guess);
  if (r.mode.ok && !(r.mode.rms_residual <= kMaxResidual)) {
    r.mode.ok = false;
    r.mode.error = "the fit leaves " + util::num(r.mode.rms_residual) + " rad of the record unexplained (at most " +
                   util::num(kMaxResidual) + "): the tip was disturbed during the probe";
  }
  if (!r.mode.ok) return r;
  const double scale = r.mode.omega / omega_guess;
  r.tip_mass_scale = tip_mass_scale / (scale * scale);
  r.damping_time = 2.0 * r.mode.zeta / r.mode.omega;
  double fill = r.tip_mass_scale, tau = r.damping_time;
  for (int round = 0; round < 6; ++round) {
    const identification::ModeFit m = identification::free_vibration_mode(robot_dynamics(robot, fill, tau), inputs);
    if (!m.ok) return r.rod_error = "the robot's dynamic rod: " + m.error, r;
    const double wr = m.omega / r.mode.omega, zr = m.zeta / r.mode.zeta;
    if (std::abs(wr - 1.0) < 0.005 && std::abs(zr - 1.0) < 0.02) {
      r.rod_ok = true;
      r.rod_tip_mass_scale = fill;
      r.rod_damping_time = tau;
      return r;
    }
    fill = std::clamp(fill * wr * wr, 0.1, 100.0);
    tau = std::clamp(tau / zr, 1e-4, 1.0);
  }
  r.rod_error = "the robot's dynamic rod does not reach the probe's mode in six rounds";
  return r;
}

}  // namespace control
}  // namespace hydrojet
