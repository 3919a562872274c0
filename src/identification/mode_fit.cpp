#include "hydrojet_control/identification/mode_fit.h"

#include <algorithm>
#include <cmath>

#include <ceres/ceres.h>

namespace hydrojet {
namespace identification {

namespace {

/// The record's residuals for (ln ω, ln ζ), per component (g, b, y₀, ẏ₀).
struct ModeResiduals {
  const ModeRecord* record;
  int substeps;  ///< RK4 steps per sample: stable at the bounds' fastest, most damped mode
  template <typename T>
  bool operator()(const T* mode, const T* first, const T* second, T* residual) const {
    const T omega = exp(mode[0]), zeta = exp(mode[1]);
    const T* params[2] = {first, second};
    const int n = static_cast<int>(record->output.size()), d = record->delay_samples;
    const T h = T(record->dt / substeps);
    for (int c = 0; c < 2; ++c) {
      const T* p = params[c];
      T y = p[2], v = p[3];
      for (int k = 0; k < n - d; ++k) {
        // the state at sample k is observed in output k + d
        residual[2 * k + c] = T(record->output[k + d](c)) - y;
        if (k == n - d - 1) break;
        const double s = record->input.empty() ? 0.0 : record->input[k](c);
        const T target = p[0] * T(s) + p[1];
        auto f = [&](const T& yy, const T& vv, T* dy, T* dv) {
          *dy = vv;
          *dv = omega * omega * (target - yy) - T(2.0) * zeta * omega * vv;
        };
        for (int i = 0; i < substeps; ++i) {
          T k1y, k1v, k2y, k2v, k3y, k3v, k4y, k4v;
          f(y, v, &k1y, &k1v);
          f(y + 0.5 * h * k1y, v + 0.5 * h * k1v, &k2y, &k2v);
          f(y + 0.5 * h * k2y, v + 0.5 * h * k2v, &k3y, &k3v);
          f(y + h * k3y, v + h * k3v, &k4y, &k4v);
          y += h / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y);
          v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
      }
    }
    return true;
  }
};

}  // namespace

double chirp(double t, double guess_hz) {
  if (!(t >= 0.0 && t <= kChirpSeconds)) return 0.0;
  const double f0 = 0.5 * guess_hz, f1 = 2.0 * guess_hz, T = kChirpSeconds, k = std::log(f1 / f0) / T;
  const double phase = 2.0 * M_PI * f0 * (std::exp(k * t) - 1.0) / k;
  const double fade = std::min({1.0, t / 0.1, (T - t) / 0.1});
  return fade * std::sin(phase);
}

bool warm_up() {
  const double omega = 2.0 * M_PI * 3.5, zeta = 0.2, dt = 0.01;
  ModeRecord r;
  r.dt = dt;
  Eigen::Vector2d y = Eigen::Vector2d::Zero(), v = Eigen::Vector2d::Zero();
  for (int k = 0; k * dt < kChirpSeconds + 0.3; ++k) {
    const double c = 0.02 * chirp(k * dt, 3.5);
    const Eigen::Vector2d s(c, 0.5 * c);
    r.input.push_back(s);
    r.output.push_back(y);
    for (int i = 0; i < 20; ++i) {  // semi-implicit Euler, fine enough for a warm-up
      v += dt / 20 * (omega * omega * (s - y) - 2.0 * zeta * omega * v);
      y += dt / 20 * v;
    }
  }
  const ModeFit fit = fit_mode(r, omega);
  return fit.ok && std::abs(fit.omega / omega - 1.0) < 0.01;
}

ModeFit fit_mode(const ModeRecord& record, double omega_guess, double zeta_guess) {
  ModeFit best;
  const int n = static_cast<int>(record.output.size()), d = record.delay_samples;
  if (!(record.dt > 0.0 && std::isfinite(record.dt))) return best.error = "dt: must be finite and > 0", best;
  if (!(omega_guess > 0.0 && std::isfinite(omega_guess))) return best.error = "omega_guess: must be > 0", best;
  if (d < 0 || n - d < 20) return best.error = "record: fewer than 20 samples after the delay", best;
  if (!record.input.empty() && static_cast<int>(record.input.size()) != n)
    return best.error = "record: input and output differ in length", best;
  for (int k = 0; k < n; ++k)
    if (!record.output[k].allFinite() || (!record.input.empty() && !record.input[k].allFinite()))
      return best.error = "record: a sample is not finite", best;
  bool forced = false;
  for (const Eigen::Vector2d& s : record.input) forced = forced || s.cwiseAbs().maxCoeff() > 0.0;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero(), mean_input = Eigen::Vector2d::Zero();
  for (int k = d; k < n; ++k) mean += record.output[k] / (n - d);
  if (forced)
    for (int k = 0; k < n - d; ++k) mean_input += record.input[k] / (n - d);
  double motion = 0.0;
  for (int k = d; k < n; ++k) motion += (record.output[k] - mean).squaredNorm() / (n - d);
  motion = std::sqrt(motion / 2.0);  // per component, as the residual

  // ω within (0.1, 10) times the guess, ζ within (0.001, 1.5); RK4 stays stable (h·2ζω ≤ 1.5).
  const double omega_max = 10.0 * omega_guess, zeta_max = 1.5;
  const int substeps = std::max(4, static_cast<int>(std::ceil(record.dt * 2.0 * zeta_max * omega_max / 1.5)));
  double best_cost = std::numeric_limits<double>::infinity();
  for (const double scale : {0.5, 0.7, 1.0, 1.4, 2.0}) {
    double mode[2] = {std::log(scale * omega_guess), std::log(zeta_guess)};
    double params[2][4];
    for (int c = 0; c < 2; ++c) {
      params[c][0] = forced ? 1.0 : 0.0;
      params[c][1] = mean(c) - params[c][0] * mean_input(c);
      params[c][2] = record.output[d](c);
      params[c][3] = 0.0;
    }
    ceres::Problem problem;
    auto* cost = new ceres::AutoDiffCostFunction<ModeResiduals, ceres::DYNAMIC, 2, 4, 4>(
        new ModeResiduals{&record, substeps}, 2 * (n - d));
    problem.AddResidualBlock(cost, nullptr, mode, params[0], params[1]);
    problem.SetParameterLowerBound(mode, 0, std::log(0.1 * omega_guess));
    problem.SetParameterUpperBound(mode, 0, std::log(omega_max));
    problem.SetParameterLowerBound(mode, 1, std::log(1e-3));
    problem.SetParameterUpperBound(mode, 1, std::log(zeta_max));
    if (!forced)  // a free vibration: g is not in the data
      for (int c = 0; c < 2; ++c) problem.SetManifold(params[c], new ceres::SubsetManifold(4, {0}));
    ceres::Solver::Options options;
    options.max_num_iterations = 100;
    options.linear_solver_type = ceres::DENSE_QR;
    options.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    if (!summary.IsSolutionUsable() || !(summary.final_cost < best_cost)) continue;
    best_cost = summary.final_cost;
    best.omega = std::exp(mode[0]);
    best.zeta = std::exp(mode[1]);
    best.gain = Eigen::Vector2d(params[0][0], params[1][0]);
    if (!forced) best.gain.setOnes();
    best.rms_residual = std::sqrt(2.0 * summary.final_cost / (2 * (n - d)));
    best.ok = summary.termination_type == ceres::CONVERGENCE;
  }
  if (!std::isfinite(best_cost)) return best.ok = false, best.error = "no fit converged", best;
  if (!best.ok)
    best.error = "the fit did not converge";
  else if (!(best.omega > 0.11 * omega_guess && best.omega < 0.99 * omega_max))
    best.ok = false, best.error = "the mode lies at the bounds, (0.1, 10) times the guess";
  else if (!(best.zeta < 0.99 * zeta_max))
    best.ok = false, best.error = "the damping ratio is at its bound 1.5: no mode in the record";
  else if (!(best.rms_residual < 0.866 * motion))  // noise alone leaves 0.91-0.98 (parameters fitted to it)
    best.ok = false, best.error = "the fit explains less than a quarter of the record's motion (variance)";
  return best;
}

}  // namespace identification
}  // namespace hydrojet
