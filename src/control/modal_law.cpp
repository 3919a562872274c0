#include "hydrojet_control/control/modal_law.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <unsupported/Eigen/MatrixFunctions>

#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {
namespace {
constexpr double kSaturationHold = 0.2;     ///< [s] a jet at its bound this long: the law has no authority
constexpr double kAuthorityRecovery = 0.5;  ///< [s] ... and takes it back over this once none is
constexpr double kRingsWindow = 0.25;       ///< [s] under the fall-back: the swing's peak per window, ...
constexpr double kRingsAbove = 1.2;         ///< ... grown and past this many ring_amplitude: the plant rings
}  // namespace

std::string ModalLawOptions::validate() const {
  const struct {
    const char* field;
    double value, lo, hi;
  } ranges[] = {
      {"kp", kp, 0.0, 50.0},
      {"ki", ki, 0.0, 100.0},
      {"gain_speed", gain_speed, 0.0, 10.0},
      {"damping_gain", damping_gain, 0.0, 10.0},
      {"actuator_lag", actuator_lag, 0.0, 1.0},
      {"rounding_force", rounding_force, 0.0, 10.0},
      {"tip_mass_scale", tip_mass_scale, 0.1, 100.0},
      {"damping_time", damping_time, 0.0, 1.0},
      {"tracker_sigma", tracker_sigma, 1e-6, 1.0},
      {"velocity_noise", velocity_noise, 1e-6, 1e3},
      {"disturbance_noise", disturbance_noise, 1e-6, 1e3},
      {"ring_amplitude", ring_amplitude, 1e-3, 1.0},
      {"recover_time", recover_time, 0.0, 60.0},
  };
  for (const auto& r : ranges)
    if (std::string err = util::check_range(r.field, r.value, r.lo, r.hi); !err.empty()) return err;
  return "";
}

void modal_transition(double omega, double zeta, double dt, Eigen::Matrix3d* A, Eigen::Vector3d* B) {
  Eigen::Matrix4d F = Eigen::Matrix4d::Zero();  // (y, v, d, s)
  F(0, 1) = 1.0;
  F(1, 0) = -omega * omega, F(1, 1) = -2.0 * zeta * omega, F(1, 2) = F(1, 3) = omega * omega;
  const Eigen::Matrix4d E = (F * dt).exp();
  *A = E.topLeftCorner<3, 3>();
  *B = E.topRightCorner<3, 1>();
}

void ModalEstimator::start(const Vec3& z, const Vec3& s, double omega, const ModalLawOptions& o) {
  x_.row(0) = z.transpose();
  x_.row(1).setZero();
  x_.row(2) = (z - s).transpose();
  const double sigma = o.tracker_sigma;
  P_ = Eigen::Vector3d(sigma * sigma, std::pow(sigma * omega, 2), 0.03 * 0.03).asDiagonal();
  initialised_ = true;
}

void ModalEstimator::step(const Vec3& s, const Vec3& z, double omega, double zeta, double dt,
                          const ModalLawOptions& o) {
  Eigen::Matrix3d A;
  Eigen::Vector3d B;
  modal_transition(omega, zeta, dt, &A, &B);
  x_ = A * x_ + B * s.transpose();
  P_ = A * P_ * A.transpose();
  P_.diagonal() +=
      Eigen::Vector3d(0.0, o.velocity_noise * o.velocity_noise * dt, o.disturbance_noise * o.disturbance_noise * dt);
  if (!z.allFinite()) return;
  // z = y + noise: H = (1, 0, 0); Joseph form.
  const double R = o.tracker_sigma * o.tracker_sigma;
  const Eigen::Vector3d K = P_.col(0) / (P_(0, 0) + R);
  x_ += K * (z.transpose() - x_.row(0));
  Eigen::Matrix3d IKH = Eigen::Matrix3d::Identity();
  IKH.col(0) -= K;
  P_ = IKH * P_ * IKH.transpose() + R * K * K.transpose();
}

Vec3 modal_shaping(const ReferenceMotion& r, const Vec3& estimated_rate, double omega, double zeta,
                   const ModalLawOptions& o) {
  const double tau = o.actuator_lag;
  return (tau + 2.0 * zeta / omega) * r.rate + (1.0 / (omega * omega) + 2.0 * zeta * tau / omega) * r.accel -
         o.damping_gain * (estimated_rate - r.rate_now) / omega;
}

ModalLaw::ModalLaw(const PdOptions& pd, const ModalLawOptions& options, double sample_period)
    : DirectionLaw(pd), options_(options), sample_period_(sample_period) {
  if (std::string err = options.validate(); !err.empty()) throw std::invalid_argument("modal/" + err);
  if (!(std::isfinite(sample_period) && sample_period > 0.0))
    throw std::invalid_argument(util::bad("sample_period", sample_period, "must be finite and > 0"));
}

void ModalLaw::reset() {
  DirectionLaw::reset();
  estimator_.reset();
  inputs_.clear();
  drives_ = false;
  shaping_primed_ = false;
  omega_ = 0.0;
  swing_ = band_power_ = 0.0;
  band_x_[0] = band_x_[1] = band_y_[0] = band_y_[1] = Vec3::Zero();
  supervisor_weight_ = authority_ = 1.0;
  calm_for_ = saturated_for_ = 0.0;
  forget_fallback();
}

void ModalLaw::adopt(const PlantIdentity& identity, const actuation::FlowRegulatorOptions& flow) {
  if (std::isfinite(identity.tracker_latency_s) && identity.tracker_latency_s >= 0.0)
    latency_ = identity.tracker_latency_s;
  // The valves' lags lower the PD's gains (modal_gains), never below the paper's; the shaping's τ_a
  // stays modal/actuator_lag (from them it cost plant A at 30° 0.0321 -> 0.0417 rad).
  flow_lag_ = 0.0;
  if (identity.valves_identified) {
    double sum = 0.0;
    int jets = 0;
    for (double tau : identity.valve_time_constants_s)
      if (std::isfinite(tau) && tau > 0.0) sum += tau, ++jets;
    if (jets > 0) flow_lag_ = flow_loop_lag(sum / jets, flow);
  }
  if (identity.mode_identified) {
    options_.tip_mass_scale = identity.tip_mass_scale;
    options_.damping_time = identity.damping_time;
  }
}

// The PD's gains move from pd/* toward modal/* with this weight of the reference's speed
// (modal/gain_speed) while the law drives; 0 otherwise.
double ModalLaw::gain_weight() const {
  return drives_ ? supervisor_weight() * control::fast_path_weight(pd_.speed(), options_.gain_speed) : 0.0;
}

// ζ of the first mode: Kelvin–Voigt damping of time τ gives 2ζω = τω².
double ModalLaw::damping_ratio() const { return 0.5 * omega_ * options_.damping_time; }

double lag_ratio(const ModalLawOptions& o, double sample_period, double latency, double flow_lag) {
  const double own = sample_period + o.actuator_lag;
  return own / (sample_period + std::max(o.actuator_lag, flow_lag) + std::max(latency, 0.0));
}

PdOptions modal_gains(const ModalLawOptions& o, double sample_period, double latency, double flow_lag) {
  const double r = lag_ratio(o, sample_period, latency, flow_lag);
  PdOptions g;
  g.kp = r * o.kp;
  g.ki = r * r * o.ki;
  return g;
}

double flow_loop_lag(double valve_lag, const actuation::FlowRegulatorOptions& flow) {
  const double loop_gain = flow.feedforward > 0.0 ? std::max(flow.kp, 0.0) / flow.feedforward : 0.0;
  return std::max(0.0, valve_lag / (1.0 + loop_gain) - std::max(flow.lead_time, 0.0));
}

PdOptions scheduled_gains(const PdOptions& pd, const PdOptions& top, double weight) {
  PdOptions g = pd;
  g.kp += weight * std::max(top.kp - pd.kp, 0.0);
  g.ki += weight * std::max(top.ki - pd.ki, 0.0);
  return g;
}

Vec3 ModalLaw::correction(const LawCycle& c) {
  estimate(c);
  PdOptions gains = pd_options_;
  if (const double w = gain_weight(); w > 0.0)
    gains = scheduled_gains(pd_options_, modal_gains(options_, sample_period_, latency_, flow_lag_), w);
  const Vec3 shaping = shaping_step(c);  // weighted by the speed over the last step, before this one's
  return pd_.correction(c.observed, c.desired, c.dt, gains) + shaping;
}

// The lost change δd of the tip direction is the rotation d × δd (δd ⊥ d); under kHeldLoss (λ's pull
// through the lower bounds) nothing is held.
void ModalLaw::bounded(const Vec3& lost, const Vec3& d) {
  pd_.hold_integral(lost.norm() > kHeldLoss ? Vec3(d.cross(lost)) : Vec3::Zero());
}

// The estimator (closed loop): the first mode at this equilibrium (with the capsule's expected
// fill), then one filter step with the model's direction at the last measured inputs and the
// tracker's direction. Open loop: none (it starts afresh when the loop closes again).
void ModalLaw::estimate(const LawCycle& c) {
  drives_ = false;
  if (!c.closed_loop) {
    estimator_.reset();
    inputs_.clear();
    forget_fallback();
    return;
  }
  const ActuatedModel& model = *c.model;
  const ActuatedModel::Linearisation& lin = *c.linearisation;
  // A body whose mass is all at its tip needs only this cycle's C^b; one with mass of its own needs
  // the probe solves.
  const ModalModel modes = !lin.ok || has_body_mass(model.rod())
                               ? lateral_modes(model.solver(), *c.observed_inputs, rod::TipWrench(), options_)
                               : lateral_modes(model.rod(), lin.body_compliance, options_);
  if (modes.ok) omega_ = modes.frequency(0);
  if (!(omega_ > 0.0)) return;  // none yet: the paper's law drives
  // The tracker's sample was measured at its stamp: the filter runs at the stamps (the model's
  // directions held between the cycles that computed them), and is predicted to now for the law.
  const Vec3 s = c.solution->tip_rotation.col(2);
  inputs_.emplace_back(c.t, s);
  if (!estimator_.initialised()) {
    estimator_.start(c.measured, s, omega_, options_);
    time_ = c.measured_stamp;
  } else if (c.measured_stamp > time_) {  // a new sample (a held cycle, a solve that failed, is skipped)
    advance(estimator_, time_, c.measured_stamp, c.measured);
    time_ = c.measured_stamp;
  }
  while (inputs_.size() > 1 && inputs_[1].first <= time_) inputs_.pop_front();
  now_ = estimator_;
  advance(now_, time_, c.t, Vec3::Constant(std::nan("")));
  drives_ = c.reference->on_path();
  supervise(c);
}

// The supervisor: the tracking error's swing at the mode's frequency (a band-pass about ω, Q = 1:
// the path's slow error and most of the tracker's noise fall outside), its amplitude over ~0.1 s.
// Past ring_amplitude (the law rings the rod, or the plant is not what the law takes it for) the
// paper's law takes the cycle at once; after recover_time of calm the modal law takes it back over
// recover_time. Before the 0.5 rad abort (safety/max_oscillation). A jet held at its bound leaves
// the law no authority to shape or damp with (its gains and shaping wind up against the bound): the
// paper's law takes the cycle until no jet is, then hands back within half a second.
void ModalLaw::supervise(const LawCycle& c) {
  const double dt = c.dt;
  if (!(dt > 0.0)) return;
  saturated_for_ = c.saturated ? saturated_for_ + dt : 0.0;
  if (saturated_for_ >= kSaturationHold)
    authority_ = 0.0;
  else if (!c.near_bound)  // near_bound includes saturated
    authority_ = std::min(1.0, authority_ + dt / kAuthorityRecovery);
  const double w0 = std::min(omega_ * dt, 2.5), alpha = 0.5 * std::sin(w0), a0 = 1.0 + alpha;
  const Vec3 x = c.measured - c.desired;
  const Vec3 y = (alpha * x - alpha * band_x_[1] + 2.0 * std::cos(w0) * band_y_[0] - (1.0 - alpha) * band_y_[1]) / a0;
  band_x_[1] = band_x_[0], band_x_[0] = x;
  band_y_[1] = band_y_[0], band_y_[0] = y;
  const double keep = std::exp(-dt / 0.1);
  band_power_ = keep * band_power_ + (1.0 - keep) * y.squaredNorm();
  swing_ = std::sqrt(2.0 * band_power_);
  watch_fallback(dt);
  if (swing_ > options_.ring_amplitude) {
    supervisor_weight_ = 0.0;
    calm_for_ = 0.0;
    return;
  }
  calm_for_ = swing_ < 0.5 * options_.ring_amplitude ? calm_for_ + dt : 0.0;
  if (calm_for_ >= options_.recover_time)
    supervisor_weight_ =
        options_.recover_time > 0.0 ? std::min(1.0, supervisor_weight_ + dt / options_.recover_time) : 1.0;
}

// Under the fall-back the paper's law has the cycle: a swing that a step or a kick left decays under
// it; one whose peak grows from window to window past kRingsAbove × ring_amplitude rings at these
// jets' forces under the paper's law too, and is reported through the next window (or until the
// swing is below ring_amplitude, or the modal law takes the cycle back).
void ModalLaw::watch_fallback(double dt) {
  if (supervisor_weight_ > 0.0) {
    forget_fallback();
    return;
  }
  fallen_for_ += dt;
  window_peak_ = std::max(window_peak_, swing_);
  if (fallen_for_ >= kRingsWindow) {
    plant_rings_ = last_window_peak_ > 0.0 && window_peak_ > last_window_peak_ &&
                   window_peak_ > kRingsAbove * options_.ring_amplitude;
    last_window_peak_ = window_peak_;
    window_peak_ = 0.0;
    fallen_for_ -= kRingsWindow;
  }
  if (swing_ < options_.ring_amplitude) plant_rings_ = false;
}

void ModalLaw::forget_fallback() {
  fallen_for_ = window_peak_ = last_window_peak_ = 0.0;
  plant_rings_ = false;
}

// Steps `e` from time `from` to `to` [s] through the model's directions held since the cycles that
// computed them, then takes the tracker's z (not finite: none).
void ModalLaw::advance(ModalEstimator& e, double from, double to, const Vec3& z) const {
  const Vec3 none = Vec3::Constant(std::nan(""));
  for (size_t k = 0; k < inputs_.size() && from < to; ++k) {
    if (k + 1 < inputs_.size() && inputs_[k + 1].first <= from) continue;
    const double end = k + 1 < inputs_.size() ? std::min(to, inputs_[k + 1].first) : to;
    if (end < to && end - from < 1e-9) continue;
    e.step(inputs_[k].second, end < to ? none : z, omega_, damping_ratio(), end - from, options_);
    from = end;
  }
}

// The shaping (modal_shaping) as the change since the last step: x_cntr moves the forces by
// increments, so an added direction m(t) enters as the rotation d × (m(t) − m(t − dt)); weighted
// by the path's speed (fast_path_rate: a slow path gets nearly the paper's law).
Vec3 ModalLaw::shaping_step(const LawCycle& c) {
  if (!drives_) {
    shaping_primed_ = false;
    return Vec3::Zero();
  }
  const double h = sample_period_;
  const Reference& ref = *c.reference;
  const Vec3 a = ref.preview(c.t, h), b = ref.preview(c.t, 2 * h), d = ref.preview(c.t, 3 * h);
  ReferenceMotion r;
  r.rate = (d - a) / (2 * h);
  r.accel = (d - 2 * b + a) / (h * h);
  r.rate_now = (a - c.desired) / h;
  // Its feedforward (the path's own motion) apart from its damping (v̂ − ṙ: zero in the first).
  const double w = fast_path_weight();
  // The damping acts on the rate estimated through the latency and the flow loop's lag: scaled by
  // the square of the PD gains' ratio (at 20-30 ms of latency its full gain made the law worse than
  // the paper's), but in full while a jet is held at its bound (the law has no authority to shape
  // with, and the rod rang at the reach's edge without it).
  const double lagged = std::pow(lag_ratio(options_, sample_period_, latency_, flow_lag_), 2);
  const double scale = authority_ * lagged + (1.0 - authority_);
  const Vec3 feedforward = w * modal_shaping(r, r.rate_now, omega_, damping_ratio(), options_);
  const Vec3 damping = w * modal_shaping(r, now_.rate(), omega_, damping_ratio(), options_) - feedforward;
  // The supervisor weighs the increments, not m: its fall-back must not kick the forces by −m. A jet
  // held at its bound stops the feedforward (it winds up there), not the damping; the damping's
  // scale, linear in it, weighs its increments too, so a change of scale does not step the forces
  // (what a lower scale held back stays, for the PD's integral to take up).
  const Vec3 change = authority_ * (feedforward - previous_feedforward_) + scale * (damping - previous_damping_);
  const Vec3 step =
      shaping_primed_ ? Vec3(supervisor_weight_ * Vec3(c.solution->tip_rotation.col(2)).cross(change)) : Vec3::Zero();
  previous_feedforward_ = feedforward;
  previous_damping_ = damping;
  shaping_primed_ = true;
  return step;
}

}  // namespace control
}  // namespace hydrojet
