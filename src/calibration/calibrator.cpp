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

#include "hydrojet_control/actuation/jet_map.h"
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
  FitContext(const config::Scene& scene, const CrossSection& cs, const ZetaVector& start)
      : model(scene.rod.without_actuators()),
        solver_options(scene.solver),
        jets(scene.jets.value_or(actuation::JetGeometry())),
        E0(start[kE]),
        G0(start[kG]),
        I(cs.second_moment()),
        J(cs.polar_moment()) {
    solver_options.residual_tolerance = std::min(solver_options.residual_tolerance, 1e-12);
  }
  /// A physical value of parameter i → its internal coordinate.
  double internal(int i, double v) const { return i == kE ? std::log(v / E0) : i == kG ? std::log(v / G0) : v; }
  /// Internal coordinates x → ζ in physical units.
  ZetaVector physical(const double* x) const {
    ZetaVector z;
    for (int i = 0; i < kNumParams; ++i) z[i] = x[i];
    z[kE] = E0 * std::exp(x[kE]);
    z[kG] = G0 * std::exp(x[kG]);
    return z;
  }

  rod::RodModel
      model;  ///< the scene's rod without actuators (the jets: eq. 24's tip wrench); stiffness, ũ per evaluation
  rod::ShootingOptions solver_options;
  actuation::JetGeometry jets;  ///< nozzle offset from the scene; misalignment per evaluation
  double E0 = 1.0, G0 = 1.0;    ///< moduli at the start: internal coordinates are ln(E/E0), ln(G/G0)
  double I = 0.0, J = 0.0;      ///< second and polar moments of the cross-section [m^4]
  mutable std::atomic<int> solves{0}, failures{0};
};

/// Internal coordinates x → model and jet geometry.
void build(const FitContext& c, const double* x, rod::RodModel* m, actuation::JetGeometry* g) {
  *m = c.model;
  const double E = c.E0 * std::exp(x[kE]), G = c.G0 * std::exp(x[kG]);
  m->segments[0].stiffness = rod::Vec3(E * c.I, E * c.I, G * c.J);
  m->segments[0].precurvature.x() = x[kUx];
  m->segments[0].precurvature.y() = x[kUy];
  *g = c.jets;
  g->misalignment = Eigen::Vector3d(x[kDa], x[kDb], x[kDg]);
}

/// r_i(x) for one sample, with its own rod solver. Central differences with an
/// absolute step in the (O(1)) internal coordinates; blocks Ceres holds constant are skipped.
class SampleCost : public ceres::SizedCostFunction<3, 1, 1, 1, 1, 1, 1, 1> {
 public:
  static constexpr double kStep = 1e-6;

  SampleCost(const FitContext* ctx, const Sample& s)
      : ctx_(ctx),
        q_(s.jet_force),
        R_meas_(s.tip_orientation.normalized().toRotationMatrix()),
        solver_(ctx->model, ctx->solver_options) {}

  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    double x[kNumParams];
    for (int i = 0; i < kNumParams; ++i) x[i] = params[i][0];
    Eigen::Vector3d r;
    if (!residual(x, &r)) return false;
    Eigen::Map<Eigen::Vector3d> res(residuals);
    res = r;
    if (!jacobians) return true;
    // The misalignments change only the wrench, not the rod: their differences run first, on the
    // model of the base evaluation, warm-started from it.
    static constexpr int kOrder[kNumParams] = {kDa, kDb, kDg, kUx, kUy, kE, kG};
    for (int i : kOrder) {
      if (!jacobians[i]) continue;
      Eigen::Vector3d rp, rm;
      const double xi = x[i];
      x[i] = xi + kStep;
      const bool okp = residual(x, &rp);
      x[i] = xi - kStep;
      const bool okm = residual(x, &rm);
      x[i] = xi;
      if (!okp || !okm) return false;
      Eigen::Map<Eigen::Vector3d> col(jacobians[i]);
      col = (rp - rm) / (2.0 * kStep);
    }
    return true;
  }

  bool residual(const double* x, Eigen::Vector3d* r) const {
    rod::RodModel m;
    actuation::JetGeometry g;
    build(*ctx_, x, &m, &g);
    const actuation::Vec6 w = actuation::JetMap(g).wrench(q_);
    rod::TipWrench tw;
    tw.force = w.head<3>();
    tw.moment = w.tail<3>();
    // Same rod as the last solve (only the misalignments moved): keep the warm start. Otherwise
    // set_model() resets it (RodSolver cannot keep a warm start across a model change), and
    // the solve starts from the unloaded precurved shape with load continuation as fallback: the
    // branch reached by loading the rod from rest, as the rig does.
    const rod::RodModel& cur = solver_.model();
    if (!solver_.has_solution() || cur.segments[0].stiffness != m.segments[0].stiffness ||
        cur.segments[0].precurvature != m.segments[0].precurvature)
      solver_.set_model(m);
    ++ctx_->solves;
    const rod::RodSolution sol = solver_.solve(tw);
    if (!sol.converged) {
      ++ctx_->failures;
      return false;
    }
    *r = rotation_error(R_meas_, sol.tip_rotation);
    return r->allFinite();
  }

 private:
  const FitContext* ctx_;
  Eigen::Vector3d q_;
  Eigen::Matrix3d R_meas_;
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

/// Throws for unusable input (see calibrate()); returns the number of fitted parameters.
int check_inputs(const config::Scene& scene, const CrossSection& cs, const std::vector<Sample>& samples,
                 const CalibrationOptions& opt) {
  if (!scene.jets) throw config::SceneError("jets", "missing (the calibration needs the jet geometry, eq. 24)");
  const std::string cse = cs.validate();
  if (!cse.empty()) throw std::invalid_argument("cross-section " + cse);
  int p = 0;
  for (bool f : opt.fit) p += f ? 1 : 0;
  validate_samples(samples, p);
  return p;
}

/// The result before the fit: what is fitted, the start and the bounds (the start must lie inside,
/// the moduli's bounds be positive, the loss scale positive; std::invalid_argument otherwise).
CalibrationResult start_result(const config::Scene& scene, const CrossSection& cs, const CalibrationOptions& opt) {
  CalibrationResult res;
  res.fitted = opt.fit;
  res.start = zeta_from_scene(scene, cs);
  res.bounds = opt.has_bounds ? opt.bounds : default_bounds(res.start);
  for (int i = 0; i < kNumParams; ++i) {
    const double lo = res.bounds.lower[i], hi = res.bounds.upper[i], s = res.start[i];
    if (!(std::isfinite(lo) && std::isfinite(hi) && lo <= s && s <= hi))
      throw std::invalid_argument(std::string("bounds of ") + param_name(i) + ": the start " + fmt("%g", s) +
                                  " must lie in [" + fmt("%g", lo) + ", " + fmt("%g", hi) + "]");
    if ((i == kE || i == kG) && !(lo > 0.0))
      throw std::invalid_argument(std::string("bounds of ") + param_name(i) + ": must be positive");
  }
  if (!(opt.loss_scale > 0.0)) throw std::invalid_argument("loss scale must be positive");
  return res;
}

/// The least-squares problem in internal coordinates, one parameter block per component of ζ
/// (blocks held constant cost no derivative solves).
struct FitProblem {
  double x[kNumParams];
  std::vector<double*> fitted;    ///< the blocks Ceres estimates, in the order of ζ
  std::vector<int> fitted_index;  ///< their index in ζ
  ceres::Problem problem;
};

void build_problem(const FitContext& ctx, const std::vector<Sample>& samples, const CalibrationOptions& opt,
                   const CalibrationResult& res, FitProblem* fit) {
  double* x = fit->x;
  for (int i = 0; i < kNumParams; ++i) x[i] = res.start[i];
  x[kE] = 0.0, x[kG] = 0.0;
  for (const Sample& s : samples)
    fit->problem.AddResidualBlock(new SampleCost(&ctx, s), make_loss(opt.loss, opt.loss_scale), &x[0], &x[1], &x[2],
                                  &x[3], &x[4], &x[5], &x[6]);
  for (int i = 0; i < kNumParams; ++i) {
    if (!opt.fit[i]) {
      fit->problem.SetParameterBlockConstant(&x[i]);
      continue;
    }
    fit->fitted.push_back(&x[i]);
    fit->fitted_index.push_back(i);
    fit->problem.SetParameterLowerBound(&x[i], 0, ctx.internal(i, res.bounds.lower[i]));
    fit->problem.SetParameterUpperBound(&x[i], 0, ctx.internal(i, res.bounds.upper[i]));
  }
}

/// The model failed at the start: names the samples whose rod solve does not converge.
void report_start_failure(const config::Scene& scene, const std::vector<Sample>& samples, CalibrationResult* res) {
  std::string which;
  for (const Sample& smp : samples) {
    bool ok = false;
    predict_tip_rotation(scene, smp.jet_force, &ok);
    if (!ok) which += (which.empty() ? "" : ", ") + smp.origin;
  }
  res->message = "the rod model did not converge at the start" + (which.empty() ? std::string() : " for " + which);
  res->warnings.push_back(res->message);
  res->zeta = res->start;
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
void flag_bounds(const FitContext& ctx, const FitProblem& fit, const CalibrationOptions& opt, CalibrationResult* res) {
  for (int i = 0; i < kNumParams; ++i) {
    if (!opt.fit[i]) continue;
    const double lo = ctx.internal(i, res->bounds.lower[i]), hi = ctx.internal(i, res->bounds.upper[i]);
    const double tol = 1e-6 * std::max(1.0, hi - lo);
    if (fit.x[i] <= lo + tol || fit.x[i] >= hi - tol) {
      res->at_bound[i] = true;
      res->warnings.push_back(std::string(param_name(i)) + " ended at its bound (" + fmt("%.6g", res->zeta[i]) + " " +
                              param_unit(i) + "): the data push it outside [" + fmt("%.6g", res->bounds.lower[i]) +
                              ", " + fmt("%.6g", res->bounds.upper[i]) + "]; its estimate and std are not meaningful");
    }
  }
}

/// Directions the data do not see at all: null space of the Jacobian J (3N × fitted; relative
/// singular value below 1e-7, the threshold at which ceres::Covariance drops them below).
ParamMask null_space(const Eigen::MatrixXd& J, const FitProblem& fit) {
  ParamMask in_null{};
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
/// σ̂², mapped to E and G by the delta method.
void estimate_covariance(const CalibrationOptions& opt, const ParamMask& in_null, FitProblem* fit,
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
      res->stddev[i] = (i == kE || i == kG) ? res->zeta[i] * sd : sd;  // delta method for the moduli
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
void assess_identifiability(const CalibrationOptions& opt, const ParamMask& in_null, CalibrationResult* res) {
  for (int i = 0; i < kNumParams; ++i) {
    if (!opt.fit[i]) continue;
    if (in_null[i]) {
      res->warnings.push_back(std::string(param_name(i)) +
                              " is not identifiable: the tip orientations do not depend on it (or only in a "
                              "combination with others) for these jet forces; fix it (leave it out of --fit) or "
                              "add samples that excite it");
      continue;
    }
    if (!res->covariance_ok) continue;
    const bool modulus = i == kE || i == kG;
    const double rel = modulus ? res->stddev[i] / res->zeta[i] : res->stddev[i];
    if (rel <= opt.resolution[i]) {
      res->identifiable[i] = true;
      continue;
    }
    const std::string sd = modulus ? fmt("%.3g", 100.0 * rel) + " %" : fmt("%.3g", rel) + " " + param_unit(i);
    const std::string lim =
        modulus ? fmt("%.3g", 100.0 * opt.resolution[i]) + " %" : fmt("%.3g", opt.resolution[i]) + " " + param_unit(i);
    res->warnings.push_back(std::string(param_name(i)) + " is poorly identifiable from these data: std " + sd + " > " +
                            lim + "; fix it (leave it out of --fit) or add samples that excite it");
  }
  for (int i = 0; i < kNumParams; ++i)
    for (int j = i + 1; j < kNumParams; ++j)
      if (std::abs(res->correlation(i, j)) > opt.max_correlation)
        res->warnings.push_back(std::string(param_name(i)) + " and " + param_name(j) + " are strongly correlated (" +
                                fmt("%.4f", res->correlation(i, j)) +
                                "): the data determine mainly a combination of the two");
}

}  // namespace

Bounds default_bounds(const ZetaVector& s) {
  Bounds b;
  b.lower = s, b.upper = s;
  for (int i : {kUx, kUy}) b.lower[i] -= 20.0, b.upper[i] += 20.0;
  for (int i : {kE, kG}) b.lower[i] = s[i] / 20.0, b.upper[i] = s[i] * 20.0;
  for (int i : {kDa, kDb, kDg}) b.lower[i] -= 0.5, b.upper[i] += 0.5;
  return b;
}

Eigen::Vector3d rotation_error(const Eigen::Matrix3d& R_meas, const Eigen::Matrix3d& R_model) {
  return so3::log(R_meas.transpose() * R_model);
}

Eigen::Matrix3d predict_tip_rotation(const config::Scene& scene, const Eigen::Vector3d& q, bool* ok) {
  rod::RodSolver solver(scene.rod.without_actuators(), scene.solver);
  const actuation::Vec6 w = actuation::JetMap(scene.jets.value_or(actuation::JetGeometry())).wrench(q);
  rod::TipWrench tw;
  tw.force = w.head<3>();
  tw.moment = w.tail<3>();
  const rod::RodSolution sol = solver.solve(tw);
  if (ok) *ok = sol.converged;
  return sol.tip_rotation;
}

CalibrationResult calibrate(const config::Scene& scene, const CrossSection& cs, const std::vector<Sample>& samples,
                            const CalibrationOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  const int p = check_inputs(scene, cs, samples, opt);
  CalibrationResult res = start_result(scene, cs, opt);
  const FitContext ctx(scene, cs, res.start);
  FitProblem fit;
  build_problem(ctx, samples, opt, res, &fit);

  Eigen::VectorXd r;
  if (!evaluate(&fit.problem, fit.fitted, false, &r, nullptr)) {
    report_start_failure(scene, samples, &res);
    res.time_s = seconds_since(t0);
    return res;
  }
  res.start_rms_rad = rms_angle(r, nullptr, nullptr);

  const ceres::Solver::Summary summary = solve(opt, &fit);
  res.iterations = static_cast<int>(summary.iterations.size()) - 1;
  res.message = summary.message;
  res.zeta = ctx.physical(fit.x);

  // Residuals and Jacobian at the estimate (no loss: the geometric errors).
  Eigen::MatrixXd J;
  const bool final_ok = evaluate(&fit.problem, fit.fitted, false, &r, &J);
  record_fit_quality(summary, final_ok, r, p, &res);
  flag_bounds(ctx, fit, opt, &res);
  ParamMask in_null{};
  if (final_ok && p > 0) in_null = null_space(J, fit);
  if (final_ok && p > 0 && std::isfinite(res.sigma_rad)) estimate_covariance(opt, in_null, &fit, &res);
  assess_identifiability(opt, in_null, &res);

  res.rod_solves = ctx.solves.load();
  res.failed_solves = ctx.failures.load();
  res.time_s = seconds_since(t0);
  return res;
}

}  // namespace calibration
}  // namespace hydrojet
