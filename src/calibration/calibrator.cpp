#include "hydrojet_control/calibration/calibrator.h"

#include <ceres/ceres.h>
#include <ceres/covariance.h>

#include <Eigen/SVD>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace calibration {
namespace {

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof(b), f, v);
  return b;
}

/// Everything the per-sample residuals share.
struct FitContext {
  explicit FitContext(const Zeta& z) : zeta(z), solver_options(z.scene().solver) {
    solver_options.residual_tolerance = std::min(solver_options.residual_tolerance, 1e-12);
  }
  int size() const { return zeta.size(); }
  /// A physical value of parameter i → its internal coordinate.
  double internal(int i, double v) const { return zeta[i].logarithmic ? std::log(v / zeta.start()[i]) : v; }
  /// Internal coordinates x → ζ in physical units.
  ZetaVector physical(const double* x) const {
    ZetaVector z(size());
    for (int i = 0; i < size(); ++i) z[i] = zeta[i].logarithmic ? zeta.start()[i] * std::exp(x[i]) : x[i];
    return z;
  }

  const Zeta& zeta;  ///< its start: internal coordinates of the positive parameters are ln(v/start)
  rod::ShootingOptions solver_options;
  mutable std::atomic<int> solves{0}, failures{0};
};

/// The rods of two models are the same (only the mount, i.e. the tip wrench, differs).
bool same_rod(const rod::RodModel& a, const rod::RodModel& b) {
  for (size_t k = 0; k < a.segments.size(); ++k)
    if (a.segments[k].stiffness != b.segments[k].stiffness || a.segments[k].precurvature != b.segments[k].precurvature)
      return false;
  return true;
}

/// r_i(x) for one sample, with its own rod solver. One parameter block per component of ζ; central
/// differences with an absolute step in the (O(1)) internal coordinates; blocks Ceres holds
/// constant are skipped.
class SampleCost : public ceres::CostFunction {
 public:
  static constexpr double kStep = 1e-6;

  SampleCost(const FitContext* ctx, const Sample& s)
      : ctx_(ctx),
        R_meas_(s.tip_orientation.normalized().toRotationMatrix()),
        solver_(ctx->zeta.rod_without_mount(ctx->zeta.start()), ctx->solver_options) {
    set_num_residuals(3);
    mutable_parameter_block_sizes()->assign(ctx->size(), 1);
    const Zeta& z = ctx->zeta;
    q_body_.resize(static_cast<Eigen::Index>(z.body_inputs().size()));
    for (size_t k = 0; k < z.body_inputs().size(); ++k) q_body_[k] = s.inputs[z.body_inputs()[k]];
    q_mount_.resize(static_cast<Eigen::Index>(z.mount_inputs().size()));
    for (size_t k = 0; k < z.mount_inputs().size(); ++k) q_mount_[k] = s.inputs[z.mount_inputs()[k]];
    // The mount rotation changes only the wrench, not the rod: its differences run first, on the
    // model of the base evaluation, warm-started from it.
    for (int pass = 0; pass < 2; ++pass)
      for (int i = 0; i < z.size(); ++i)
        if ((z[i].kind == ParamKind::kMount) == (pass == 0)) order_.push_back(i);
  }

  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    std::vector<double> x(ctx_->size());
    for (int i = 0; i < ctx_->size(); ++i) x[i] = params[i][0];
    Eigen::Vector3d r;
    if (!residual(x.data(), &r)) return false;
    Eigen::Map<Eigen::Vector3d> res(residuals);
    res = r;
    if (!jacobians) return true;
    for (int i : order_) {
      if (!jacobians[i]) continue;
      Eigen::Vector3d rp, rm;
      const double xi = x[i];
      x[i] = xi + kStep;
      const bool okp = residual(x.data(), &rp);
      x[i] = xi - kStep;
      const bool okm = residual(x.data(), &rm);
      x[i] = xi;
      if (!okp || !okm) return false;
      Eigen::Map<Eigen::Vector3d> col(jacobians[i]);
      col = (rp - rm) / (2.0 * kStep);
    }
    return true;
  }

  bool residual(const double* x, Eigen::Vector3d* r) const {
    const Zeta& zeta = ctx_->zeta;
    const ZetaVector z = ctx_->physical(x);
    rod::TipWrench tw;
    if (q_mount_.size() > 0) {
      const rod::Vec6 w = zeta.mount_wrenches(zeta.mount_rotation(z)) * q_mount_;
      tw.force = w.head<3>();
      tw.moment = w.tail<3>();
    }
    // Same rod as the last solve (only the mount moved): keep the warm start. Otherwise set_model()
    // resets it (RodSolver cannot keep a warm start across a model change), and the solve starts
    // from the unloaded precurved shape with load continuation as fallback: the branch reached by
    // loading the rod from rest, as the rig does.
    const rod::RodModel m = zeta.rod_without_mount(z);
    if (!solver_.has_solution() || !same_rod(solver_.model(), m)) solver_.set_model(m);
    ++ctx_->solves;
    const rod::RodSolution sol = solver_.solve(q_body_, tw);
    if (!sol.converged) {
      ++ctx_->failures;
      return false;
    }
    *r = rotation_error(R_meas_, sol.tip_rotation);
    return r->allFinite();
  }

 private:
  const FitContext* ctx_;
  Eigen::Matrix3d R_meas_;
  rod::InputVector q_body_;  ///< inputs of the actuators that stay in the rod model
  Eigen::VectorXd q_mount_;  ///< inputs of the actuators at the tip mount
  std::vector<int> order_;   ///< parameters in the order their differences run
  mutable rod::RodSolver solver_;
};

ceres::LossFunction* make_loss(Loss l, double scale) {
  switch (l) {
    // ρ acts on s = |r_i|², the squared angle: quadratic up to |r_i| = scale [rad].
    case Loss::kHuber: return new ceres::HuberLoss(scale);
    case Loss::kCauchy: return new ceres::CauchyLoss(scale);
    case Loss::kNone: break;
  }
  return nullptr;
}

/// Residuals (3N) and, if J is given, the dense Jacobian (3N × fitted) at the current parameters.
bool evaluate(ceres::Problem* problem, const std::vector<double*>& fitted, bool apply_loss, Eigen::VectorXd* r,
              Eigen::MatrixXd* J) {
  ceres::Problem::EvaluateOptions eo;
  eo.apply_loss_function = apply_loss;
  eo.parameter_blocks = fitted;
  double cost = 0.0;
  std::vector<double> res;
  ceres::CRSMatrix crs;
  if (!problem->Evaluate(eo, &cost, &res, nullptr, J ? &crs : nullptr)) return false;
  *r = Eigen::Map<Eigen::VectorXd>(res.data(), static_cast<Eigen::Index>(res.size()));
  if (J) {
    J->setZero(crs.num_rows, crs.num_cols);
    for (int i = 0; i < crs.num_rows; ++i)
      for (int k = crs.rows[i]; k < crs.rows[i + 1]; ++k) (*J)(i, crs.cols[k]) = crs.values[k];
  }
  return true;
}

double rms_angle(const Eigen::VectorXd& r, std::vector<double>* angles, std::vector<Eigen::Vector3d>* vecs) {
  const Eigen::Index n = r.size() / 3;
  double s = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d v = r.segment<3>(3 * i);
    s += v.squaredNorm();
    if (angles) angles->push_back(v.norm());
    if (vecs) vecs->push_back(v);
  }
  return n > 0 ? std::sqrt(s / static_cast<double>(n)) : 0.0;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// The mask the fit uses: the options' (checked against ζ) or ζ's default.
ParamMask fit_mask(const Zeta& zeta, const CalibrationOptions& opt) {
  if (opt.fit.empty()) return zeta.default_fit();
  if (static_cast<int>(opt.fit.size()) != zeta.size())
    throw std::invalid_argument("fit mask: " + std::to_string(opt.fit.size()) + " flags for " +
                                std::to_string(zeta.size()) + " parameters (" + zeta.names() + ")");
  return opt.fit;
}

int count(const ParamMask& m) { return static_cast<int>(std::count(m.begin(), m.end(), true)); }

/// The result before the fit: what is fitted, the start and the bounds (the start must lie inside,
/// the bounds of a positive parameter be positive, the loss scale positive; std::invalid_argument
/// otherwise).
CalibrationResult start_result(const Zeta& zeta, const ParamMask& fit, const CalibrationOptions& opt) {
  const int n = zeta.size();
  CalibrationResult res;
  res.fitted = fit;
  res.start = zeta.start();
  res.zeta = res.start;
  res.bounds = opt.has_bounds ? opt.bounds : default_bounds(zeta);
  if (res.bounds.lower.size() != n || res.bounds.upper.size() != n)
    throw std::invalid_argument("bounds: " + std::to_string(res.bounds.lower.size()) + " values for " +
                                std::to_string(n) + " parameters");
  for (int i = 0; i < n; ++i) {
    const double lo = res.bounds.lower[i], hi = res.bounds.upper[i], s = res.start[i];
    if (!(std::isfinite(lo) && std::isfinite(hi) && lo <= s && s <= hi))
      throw std::invalid_argument("bounds of " + zeta[i].name + ": the start " + fmt("%g", s) + " must lie in [" +
                                  fmt("%g", lo) + ", " + fmt("%g", hi) + "]");
    if (zeta[i].logarithmic && !(lo > 0.0))
      throw std::invalid_argument("bounds of " + zeta[i].name + ": must be positive");
  }
  if (!(opt.loss_scale > 0.0)) throw std::invalid_argument("loss scale must be positive");
  res.stddev = ZetaVector::Constant(n, std::nan(""));
  res.correlation = Eigen::MatrixXd::Constant(n, n, std::nan(""));
  res.identifiable.assign(n, false);
  res.at_bound.assign(n, false);
  return res;
}

/// The least-squares problem in internal coordinates, one parameter block per component of ζ
/// (blocks held constant cost no derivative solves).
struct FitProblem {
  std::vector<double> x;
  std::vector<double*> fitted;    ///< the blocks Ceres estimates, in the order of ζ
  std::vector<int> fitted_index;  ///< their index in ζ
  ceres::Problem problem;
};

void build_problem(const FitContext& ctx, const std::vector<Sample>& samples, const CalibrationOptions& opt,
                   const CalibrationResult& res, FitProblem* fit) {
  const int n = ctx.size();
  fit->x.resize(n);
  for (int i = 0; i < n; ++i) fit->x[i] = ctx.internal(i, res.start[i]);
  std::vector<double*> blocks;
  for (double& v : fit->x) blocks.push_back(&v);
  for (const Sample& s : samples)
    fit->problem.AddResidualBlock(new SampleCost(&ctx, s), make_loss(opt.loss, opt.loss_scale), blocks);
  for (int i = 0; i < n; ++i) {
    if (!res.fitted[i]) {
      fit->problem.SetParameterBlockConstant(&fit->x[i]);
      continue;
    }
    fit->fitted.push_back(&fit->x[i]);
    fit->fitted_index.push_back(i);
    fit->problem.SetParameterLowerBound(&fit->x[i], 0, ctx.internal(i, res.bounds.lower[i]));
    fit->problem.SetParameterUpperBound(&fit->x[i], 0, ctx.internal(i, res.bounds.upper[i]));
  }
}

/// The model failed at the start: names the samples whose rod solve does not converge.
void report_start_failure(const config::Scene& scene, const std::vector<Sample>& samples, CalibrationResult* res) {
  std::string which;
  for (const Sample& smp : samples) {
    bool ok = false;
    predict_tip_rotation(scene, smp.inputs, &ok);
    if (!ok) which += (which.empty() ? "" : ", ") + smp.origin;
  }
  res->message = "the rod model did not converge at the start" + (which.empty() ? std::string() : " for " + which);
  res->warnings.push_back(res->message);
}

/// Levenberg–Marquardt (Ceres' trust region, dense QR).
ceres::Solver::Summary solve(const CalibrationOptions& opt, FitProblem* fit) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = opt.max_iterations;
  so.num_threads = std::max(1, opt.num_threads);
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-14;
  so.parameter_tolerance = 1e-10;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &fit->problem, &summary);
  return summary;
}

/// Convergence, the per-sample errors, their RMS and σ̂ from the residuals r at the estimate
/// (final_ok: every rod solve there converged).
void record_fit_quality(const ceres::Solver::Summary& summary, bool final_ok, const Eigen::VectorXd& r, int p,
                        CalibrationResult* res) {
  res->converged = summary.termination_type == ceres::CONVERGENCE && final_ok;
  if (!final_ok) {
    res->warnings.push_back("the rod model did not converge for every sample at the estimate");
  } else {
    res->rms_rad = rms_angle(r, &res->sample_error_rad, &res->residuals);
    const double dof = static_cast<double>(r.size()) - p;
    res->sigma_rad = dof > 0 ? std::sqrt(r.squaredNorm() / dof) : std::nan("");
  }
  if (summary.termination_type != ceres::CONVERGENCE)
    res->warnings.push_back("Ceres did not converge: " + summary.message);
}

/// Fitted parameters that ended at a bound (their estimate and std say nothing).
void flag_bounds(const FitContext& ctx, const FitProblem& fit, CalibrationResult* res) {
  const Zeta& zeta = ctx.zeta;
  for (int i = 0; i < zeta.size(); ++i) {
    if (!res->fitted[i]) continue;
    const double lo = ctx.internal(i, res->bounds.lower[i]), hi = ctx.internal(i, res->bounds.upper[i]);
    const double tol = 1e-6 * std::max(1.0, hi - lo);
    if (fit.x[i] <= lo + tol || fit.x[i] >= hi - tol) {
      res->at_bound[i] = true;
      res->warnings.push_back(zeta[i].name + " ended at its bound (" + fmt("%.6g", res->zeta[i]) + " " + zeta[i].unit +
                              "): the data push it outside [" + fmt("%.6g", res->bounds.lower[i]) + ", " +
                              fmt("%.6g", res->bounds.upper[i]) + "]; its estimate and std are not meaningful");
    }
  }
}

/// Directions the data do not see at all: null space of the Jacobian J (3N × fitted; relative
/// singular value below 1e-7, the threshold at which ceres::Covariance drops them below).
ParamMask null_space(const Eigen::MatrixXd& J, const FitProblem& fit, int n) {
  ParamMask in_null(n, false);
  const int p = static_cast<int>(fit.fitted.size());
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(J, Eigen::ComputeFullV);
  const Eigen::VectorXd sv = svd.singularValues();
  const double smax = sv.size() ? sv[0] : 0.0;
  for (int k = 0; k < p; ++k) {
    const double s = k < sv.size() ? sv[k] : 0.0;
    if (smax > 0.0 && s > 1e-7 * smax) continue;
    for (int j = 0; j < p; ++j)
      if (std::abs(svd.matrixV()(j, k)) > 0.1) in_null[fit.fitted_index[j]] = true;
  }
  return in_null;
}

/// Standard deviations and correlations of the parameters outside the null space: ceres::Covariance
/// (pseudo-inverse, so that a rank-deficient problem still reports the identifiable part) scaled by
/// σ̂², mapped to the positive parameters by the delta method.
void estimate_covariance(const Zeta& zeta, const CalibrationOptions& opt, const ParamMask& in_null, FitProblem* fit,
                         CalibrationResult* res) {
  const int p = static_cast<int>(fit->fitted.size());
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;
  co.min_reciprocal_condition_number = 1e-14;
  co.apply_loss_function = true;
  co.num_threads = std::max(1, opt.num_threads);
  ceres::Covariance cov(co);
  std::vector<const double*> blocks(fit->fitted.begin(), fit->fitted.end());
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> C(p, p);
  if (cov.Compute(blocks, &fit->problem) && cov.GetCovarianceMatrix(blocks, C.data())) {
    res->covariance_ok = true;
    const std::vector<int>& idx = fit->fitted_index;
    const double s2 = res->sigma_rad * res->sigma_rad;
    for (int a = 0; a < p; ++a) {
      const int i = idx[a];
      if (in_null[i]) continue;
      const double sd = std::sqrt(s2 * C(a, a));
      res->stddev[i] = zeta[i].logarithmic ? res->zeta[i] * sd : sd;  // delta method for ln(v/start)
      for (int b = 0; b < p; ++b) {
        const int j = idx[b];
        if (in_null[j]) continue;
        res->correlation(i, j) = C(a, b) / std::sqrt(C(a, a) * C(b, b));
      }
    }
  }
  if (!res->covariance_ok) res->warnings.push_back("the covariance could not be computed");
}

/// Which fitted parameters the data determine: not in the null space and std ≤ resolution; a
/// warning for each that is not and for each strongly correlated pair.
void assess_identifiability(const Zeta& zeta, const CalibrationOptions& opt, const ParamMask& in_null,
                            CalibrationResult* res) {
  for (int i = 0; i < zeta.size(); ++i) {
    const Parameter& p = zeta[i];
    if (!res->fitted[i]) continue;
    if (in_null[i]) {
      res->warnings.push_back(p.name +
                              " is not identifiable: the tip orientations do not depend on it (or only in a "
                              "combination with others) for these inputs; fix it (leave it out of --fit) or "
                              "add samples that excite it");
      continue;
    }
    if (!res->covariance_ok) continue;
    const double rel = p.logarithmic ? res->stddev[i] / res->zeta[i] : res->stddev[i];
    if (rel <= p.resolution) {
      res->identifiable[i] = true;
      continue;
    }
    const std::string sd = p.logarithmic ? fmt("%.3g", 100.0 * rel) + " %" : fmt("%.3g", rel) + " " + p.unit;
    const std::string lim =
        p.logarithmic ? fmt("%.3g", 100.0 * p.resolution) + " %" : fmt("%.3g", p.resolution) + " " + p.unit;
    res->warnings.push_back(p.name + " is poorly identifiable from these data: std " + sd + " > " + lim +
                            "; fix it (leave it out of --fit) or add samples that excite it");
  }
  for (int i = 0; i < zeta.size(); ++i)
    for (int j = i + 1; j < zeta.size(); ++j)
      if (std::abs(res->correlation(i, j)) > opt.max_correlation)
        res->warnings.push_back(zeta[i].name + " and " + zeta[j].name + " are strongly correlated (" +
                                fmt("%.4f", res->correlation(i, j)) +
                                "): the data determine mainly a combination of the two");
}

/// One fit of the parameters in `fit`.
CalibrationResult fit_once(const Zeta& zeta, const std::vector<Sample>& samples, const ParamMask& mask,
                           const CalibrationOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  validate_samples(samples, zeta.scene().rod.actuators, count(mask));
  CalibrationResult res = start_result(zeta, mask, opt);
  const FitContext ctx(zeta);
  FitProblem fit;
  build_problem(ctx, samples, opt, res, &fit);

  Eigen::VectorXd r;
  if (!evaluate(&fit.problem, fit.fitted, false, &r, nullptr)) {
    report_start_failure(zeta.scene(), samples, &res);
    res.time_s = seconds_since(t0);
    return res;
  }
  res.start_rms_rad = rms_angle(r, nullptr, nullptr);

  const ceres::Solver::Summary summary = solve(opt, &fit);
  res.iterations = static_cast<int>(summary.iterations.size()) - 1;
  res.message = summary.message;
  res.zeta = ctx.physical(fit.x.data());

  // Residuals and Jacobian at the estimate (no loss: the geometric errors).
  Eigen::MatrixXd J;
  const bool final_ok = evaluate(&fit.problem, fit.fitted, false, &r, &J);
  const int p = count(mask);
  record_fit_quality(summary, final_ok, r, p, &res);
  flag_bounds(ctx, fit, &res);
  ParamMask in_null(zeta.size(), false);
  if (final_ok && p > 0) in_null = null_space(J, fit, zeta.size());
  if (final_ok && p > 0 && std::isfinite(res.sigma_rad)) estimate_covariance(zeta, opt, in_null, &fit, &res);
  assess_identifiability(zeta, opt, in_null, &res);

  res.rod_solves = ctx.solves.load();
  res.failed_solves = ctx.failures.load();
  res.time_s = seconds_since(t0);
  return res;
}

/// Why the fitted per-segment bending scales cannot be told apart ("" when they can).
std::string per_segment_scales_problem(const Zeta& zeta, const CalibrationResult& res, double max_correlation) {
  std::vector<int> fitted;
  for (int k : zeta.segment_bending_scales())
    if (res.fitted[k]) fitted.push_back(k);
  if (fitted.size() < 2 || !res.converged) return "";
  for (int k : fitted)
    if (!res.identifiable[k]) return zeta[k].name + " is not identifiable";
  for (size_t a = 0; a < fitted.size(); ++a)
    for (size_t b = a + 1; b < fitted.size(); ++b)
      if (std::abs(res.correlation(fitted[a], fitted[b])) > max_correlation)
        return zeta[fitted[a]].name + " and " + zeta[fitted[b]].name + " are correlated (" +
               fmt("%.4f", res.correlation(fitted[a], fitted[b])) + ")";
  return "";
}

}  // namespace

Bounds default_bounds(const Zeta& zeta) {
  const ZetaVector& s = zeta.start();
  Bounds b;
  b.lower = s, b.upper = s;
  for (int i = 0; i < zeta.size(); ++i) {
    switch (zeta[i].kind) {
      case ParamKind::kPrecurvatureX:
      case ParamKind::kPrecurvatureY: b.lower[i] -= 20.0, b.upper[i] += 20.0; break;
      case ParamKind::kMount: b.lower[i] -= 0.5, b.upper[i] += 0.5; break;
      default: b.lower[i] = s[i] / 20.0, b.upper[i] = s[i] * 20.0; break;
    }
  }
  return b;
}

Eigen::Vector3d rotation_error(const Eigen::Matrix3d& R_meas, const Eigen::Matrix3d& R_model) {
  return so3::log(R_meas.transpose() * R_model);
}

Eigen::Matrix3d predict_tip_rotation(const config::Scene& scene, const rod::InputVector& q, bool* ok) {
  rod::RodSolver solver(scene.rod, scene.solver);
  const rod::RodSolution sol = solver.solve(q);
  if (ok) *ok = sol.converged;
  return sol.tip_rotation;
}

CalibrationResult calibrate(const Zeta& zeta, const std::vector<Sample>& samples, const CalibrationOptions& opt) {
  const ParamMask mask = fit_mask(zeta, opt);
  CalibrationResult res = fit_once(zeta, samples, mask, opt);
  if (opt.bending_scale != BendingScale::kAuto) return res;
  const std::string problem = per_segment_scales_problem(zeta, res, opt.max_correlation);
  if (problem.empty()) return res;
  CalibrationResult common = fit_once(zeta, samples, zeta.with_common_bending_scale(mask), opt);
  common.common_bending_scale = true;
  common.warnings.insert(common.warnings.begin(), "the data cannot tell the segments' bending stiffness apart (" +
                                                      problem +
                                                      "): fitted one common scale 'bend' instead of one per segment");
  common.rod_solves += res.rod_solves;
  common.failed_solves += res.failed_solves;
  common.time_s += res.time_s;
  return common;
}

}  // namespace calibration
}  // namespace hydrojet
