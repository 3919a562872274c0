// The ROS-free calibration core: synthetic recovery of ζ with its covariance, validation
// at the noise level, identifiability warnings, robust loss, data checks, CSV, the scene writer's
// round trip through load_scene, and the quasistatic extraction from time series.
//
// Truth scenes are written as YAML text with moduli and diameters and read by config::parse_scene
// (its own moduli → stiffness conversion, not the calibration's), solved with 16 RK8 steps and a
// 1e-13 rad residual (the fit uses the scene's 4 steps).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>

#include "hydrojet_control/calibration/calibrator.h"
#include "hydrojet_control/calibration/quasistatic.h"
#include "hydrojet_control/calibration/scene_writer.h"
#include "hydrojet_control/calibration/synthetic.h"
#include "hydrojet_control/rod/so3.h"
#include "calibration_fixtures.h"

namespace {

using namespace hydrojet;
using namespace hydrojet::calibration;
using test::jets;
using test::kI;
using test::param_name;
using test::shipped;
using test::truth_zeta;

constexpr double kDeg = M_PI / 180.0;

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof(b), "%.17g", v);
  return b;
}

std::string read_file(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// A complete scene for ζ as YAML text (moduli + diameters), accurate solver settings.
config::Scene truth_scene(const ZetaVector& z, double tilt_deg) {
  const double g = 9.81, t = tilt_deg * kDeg;
  std::ostringstream y;
  y << "rod:\n  length: 0.09\n  youngs_modulus: " << num(z[kE]) << "\n  shear_modulus: " << num(z[kG])
    << "\n  outer_diameter: 0.008\n  inner_diameter: 0.006\n  precurvature: [" << num(z[kUx]) << ", " << num(z[kUy])
    << ", 0.0]\ntip:\n  mass: 0.00258\ngravity: [0.0, " << num(g * std::sin(t)) << ", " << num(g * std::cos(t))
    << "]\nsolver:\n  integrator: rk8\n  steps: 16\n  residual_tolerance: 1.0e-13\njets:\n  misalignment: ["
    << num(z[kDa]) << ", " << num(z[kDb]) << ", " << num(z[kDg])
    << "]\n  max_force: [0.243, 0.224, 0.244]\n  inlet_area: 1.13e-6\n  outlet_area: 3.84e-7\n  water_density: 998.0\n";
  return config::parse_scene(y.str());
}

std::vector<Sample> data(const config::Scene& truth, int n, double noise_deg, unsigned seed) {
  SyntheticOptions o;
  o.samples = n;
  o.noise_rad = noise_deg * kDeg;
  o.seed = seed;
  return synthesise(truth, o);
}

/// RMS angle [rad] between a scene's model and the samples.
double rms_error(const config::Scene& model, const std::vector<Sample>& s) {
  double sum = 0.0;
  for (const Sample& x : s) {
    bool ok = false;
    const Eigen::Matrix3d R = predict_tip_rotation(model, x.inputs, &ok);
    EXPECT_TRUE(ok);
    sum += rotation_error(x.tip_orientation.toRotationMatrix(), R).squaredNorm();
  }
  return std::sqrt(sum / s.size());
}

/// RMS angle [rad] between two scenes' models over the samples' jet forces (noise-free).
double rms_model_difference(const config::Scene& a, const config::Scene& b, const std::vector<Sample>& s) {
  double sum = 0.0;
  for (const Sample& x : s)
    sum += rotation_error(predict_tip_rotation(a, x.inputs), predict_tip_rotation(b, x.inputs)).squaredNorm();
  return std::sqrt(sum / s.size());
}

// ---------------------------------------------------------------------------------------------
// Synthetic recovery
// ---------------------------------------------------------------------------------------------

/// 40 samples, 0.5° noise per axis: ζ within 4σ of the truth (σ from ceres::Covariance, which must
/// itself be small enough to mean something), residual and validation error at the noise level.
void check_recovery(double tilt_deg) {
  SCOPED_TRACE("tilt " + std::to_string(tilt_deg));
  const ZetaVector zt = truth_zeta();
  const config::Scene truth = truth_scene(zt, tilt_deg);
  const config::Scene nominal = shipped(tilt_deg == 0 ? "hydrojet_0deg" : "hydrojet_30deg");
  const CrossSection cs;
  const std::vector<Sample> train = data(truth, 40, 0.5, 3), valid = data(truth, 40, 0.5, 1003);

  const CalibrationResult r = calibrate(Zeta(nominal, cs), train, CalibrationOptions());
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_TRUE(r.covariance_ok);
  EXPECT_TRUE(r.warnings.empty()) << r.warnings.front();
  // Useful precision (the covariance is the tolerance, so it must not be vacuous): u 0.1 1/m,
  // E 2 %, G 15 %, misalignments 0.01 rad (0.6°).
  const ZetaVector useful =
      (ZetaVector(kNumParams) << 0.1, 0.1, 0.02 * zt[kE], 0.15 * zt[kG], 0.01, 0.01, 0.01).finished();
  for (int i = 0; i < kNumParams; ++i) {
    SCOPED_TRACE(param_name(i));
    EXPECT_TRUE(r.identifiable[i]);
    ASSERT_TRUE(std::isfinite(r.stddev[i]) && r.stddev[i] > 0);
    EXPECT_LT(r.stddev[i], useful[i]);
    EXPECT_LE(std::abs(r.zeta[i] - zt[i]), 4.0 * r.stddev[i])
        << "truth " << zt[i] << " estimate " << r.zeta[i] << " std " << r.stddev[i];
  }
  // The start is far from the truth (the fit had work to do).
  EXPECT_GT(r.start_rms_rad, 5.0 * r.rms_rad);
  // Residual: 3 axes of 0.5° noise → RMS angle 0.5°·√3 ≈ 0.87° (less the p fitted dof).
  const double noise_angle = 0.5 * kDeg * std::sqrt(3.0);
  EXPECT_GT(r.rms_rad, 0.8 * noise_angle);
  EXPECT_LT(r.rms_rad, 1.15 * noise_angle);
  EXPECT_NEAR(r.sigma_rad, 0.5 * kDeg, 0.1 * kDeg);

  // Validation on 40 other samples: the fitted model explains them as well as the truth does
  // (within 10 %), and its noise-free prediction error is well below the noise.
  const config::Scene fitted = Zeta(nominal, cs).apply(r.zeta);
  const double val_fit = rms_error(fitted, valid), val_truth = rms_error(truth, valid);
  const double pred = rms_model_difference(fitted, truth, valid);
  std::printf(
      "tilt %g: train RMS %.3f deg, validation RMS %.3f deg (truth model %.3f deg), prediction error "
      "%.3f deg, %.3f s\n",
      tilt_deg, r.rms_rad / kDeg, val_fit / kDeg, val_truth / kDeg, pred / kDeg, r.time_s);
  EXPECT_LT(val_fit, 1.10 * val_truth);
  EXPECT_LT(pred, 0.4 * noise_angle);
  EXPECT_GT(rms_model_difference(nominal, truth, valid), 10 * pred);  // the nominal model is far off
}

TEST(CalibrationSynthetic, RecoversZetaBaseDown) { check_recovery(0.0); }
TEST(CalibrationSynthetic, RecoversZetaBaseTilted30) { check_recovery(30.0); }

TEST(CalibrationSynthetic, NoiseFreeDataGiveTheTruth) {
  const ZetaVector zt = truth_zeta();
  const CalibrationResult r = calibrate(Zeta(shipped("hydrojet_0deg"), CrossSection()),
                                        data(truth_scene(zt, 0), 40, 0.0, 5), CalibrationOptions());
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_LT(r.rms_rad, 1e-7);
  for (int i = 0; i < kNumParams; ++i)
    EXPECT_NEAR(r.zeta[i], zt[i], 1e-5 * std::max(1.0, std::abs(zt[i]))) << param_name(i);
}

/// The reported std is the real spread: 16 noise realisations, the empirical std of each estimate
/// vs the mean reported std, and the normalised errors (est − truth)/std over all 112 estimates.
TEST(CalibrationSynthetic, CovarianceMatchesMonteCarloSpread) {
  const ZetaVector zt = truth_zeta();
  const config::Scene truth = truth_scene(zt, 0), nominal = shipped("hydrojet_0deg");
  const int runs = 16;
  std::vector<ZetaVector> est, sd;
  for (int k = 0; k < runs; ++k) {
    const CalibrationResult r =
        calibrate(Zeta(nominal, CrossSection()), data(truth, 40, 0.5, 100 + k), CalibrationOptions());
    ASSERT_TRUE(r.converged);
    est.push_back(r.zeta);
    sd.push_back(r.stddev);
  }
  double z2 = 0.0;
  for (int i = 0; i < kNumParams; ++i) {
    double mean = 0, msd = 0, var = 0;
    for (int k = 0; k < runs; ++k) mean += est[k][i] / runs, msd += sd[k][i] / runs;
    for (int k = 0; k < runs; ++k) var += (est[k][i] - mean) * (est[k][i] - mean) / (runs - 1);
    for (int k = 0; k < runs; ++k) z2 += std::pow((est[k][i] - zt[i]) / sd[k][i], 2);
    const double ratio = std::sqrt(var) / msd;
    std::printf("%-3s empirical std / reported std = %.2f\n", param_name(i).c_str(), ratio);
    // 16 runs: the sample std scatters by ~18 %; [0.55, 1.6] is beyond 2.5 of those.
    EXPECT_GT(ratio, 0.55) << param_name(i);
    EXPECT_LT(ratio, 1.6) << param_name(i);
  }
  const double z_rms = std::sqrt(z2 / (runs * kNumParams));
  std::printf("RMS of (estimate - truth)/std over %d estimates: %.2f\n", runs * kNumParams, z_rms);
  EXPECT_GT(z_rms, 0.7);
  EXPECT_LT(z_rms, 1.35);
}

TEST(CalibrationSynthetic, FixedParametersStayAtTheStart) {
  const config::Scene nominal = shipped("hydrojet_0deg");
  ZetaVector zt = Zeta(nominal, CrossSection()).start();
  zt[kUx] += 0.5, zt[kE] *= 0.9;  // only these two differ from the nominal scene
  CalibrationOptions o;
  o.fit = Zeta(nominal, CrossSection()).parse("ux,uy,E");
  const CalibrationResult r = calibrate(Zeta(nominal, CrossSection()), data(truth_scene(zt, 0), 20, 0.2, 9), o);
  ASSERT_TRUE(r.converged);
  for (int i : {kG, kDa, kDb, kDg}) {
    EXPECT_EQ(r.zeta[i], r.start[i]) << param_name(i);
    EXPECT_TRUE(std::isnan(r.stddev[i])) << param_name(i);
  }
  for (int i : {kUx, kUy, kE}) EXPECT_LE(std::abs(r.zeta[i] - zt[i]), 4 * r.stddev[i]) << param_name(i);
}

// ---------------------------------------------------------------------------------------------
// Any robot: the general form of ζ
// ---------------------------------------------------------------------------------------------

/// The two-segment robot with its proximal precurvature, both bending stiffnesses, the torsional
/// stiffness and the tip mount changed, built on the Scene itself (not through Zeta::apply), with
/// accurate solver settings. `mount` [rad] is a rotation vector of the tip actuators' mount.
config::Scene perturbed_two_segment(const Eigen::Vector3d& mount) {
  config::Scene t = shipped("two_segment_thrusters");
  t.rod.segments[0].precurvature = Eigen::Vector3d(1.2, -0.8, 0.0);
  t.rod.segments[1].precurvature += Eigen::Vector3d(-1.0, 0.5, 0.0);
  t.rod.segments[0].stiffness.head<2>() *= 0.85;
  t.rod.segments[1].stiffness.head<2>() *= 1.2;
  for (rod::RodSegment& s : t.rod.segments) s.stiffness.z() *= 1.1;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(mount.norm(), mount.normalized()).toRotationMatrix();
  for (rod::Actuator& a : t.rod.actuators)
    if (a.at == t.rod.length()) a.direction = R * a.direction, a.position = R * a.position;
  t.solver.integrator.steps = 16;
  t.solver.residual_tolerance = 1e-13;
  return t;
}

/// 60 samples of a perturbed copy, 0.5° noise per axis, fitted from the shipped scene: every
/// identifiable parameter within 4σ of the truth, and 40 held-back samples predicted within 1.2×
/// the noise (the tracker's noise is the floor: the true model scores ≈ 1.0×).
TEST(CalibrationAnyRobot, TwoSegmentThrustersFromAPerturbedCopy) {
  const Eigen::Vector3d mount(0.02, -0.03, 0.07);
  const config::Scene truth = perturbed_two_segment(mount), nominal = shipped("two_segment_thrusters");
  const Zeta zeta(nominal, CrossSection());
  auto at = [&](const char* n) { return zeta.index(n); };
  ZetaVector zt = zeta.start();
  zt[at("ux1")] = 1.2, zt[at("uy1")] = -0.8, zt[at("ux2")] = -1.0, zt[at("uy2")] = 2.5;
  zt[at("bend1")] = 0.85, zt[at("bend2")] = 1.2, zt[at("twist")] = 1.1;
  zt[at("da")] = mount.x(), zt[at("db")] = mount.y(), zt[at("dg")] = mount.z();

  const std::vector<Sample> train = data(truth, 60, 0.5, 41), held = data(truth, 40, 0.5, 4041);
  const CalibrationResult r = calibrate(zeta, train, CalibrationOptions());
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_FALSE(r.common_bending_scale);
  for (const std::string& w : r.warnings) std::printf("warning: %s\n", w.c_str());
  int identifiable = 0;
  for (int i = 0; i < zeta.size(); ++i) {
    SCOPED_TRACE(zeta[i].name);
    std::printf("%-6s truth %9.4f estimate %9.4f std %.4f%s\n", zeta[i].name.c_str(), zt[i], r.zeta[i], r.stddev[i],
                r.identifiable[i] ? "" : " (not identifiable)");
    if (!r.fitted[i]) {
      EXPECT_EQ(r.zeta[i], zt[i]);  // the common scale stays 1: the per-segment ones carry it
      continue;
    }
    if (!r.identifiable[i]) continue;
    ++identifiable;
    EXPECT_LE(std::abs(r.zeta[i] - zt[i]), 4.0 * r.stddev[i]);
  }
  // What the data must determine: both bending scales, the torsion (tip_ny_arm twists), the
  // mount's turn about the tip axis, and the distal precurvature that curls the whole tip.
  for (const char* n : {"bend1", "bend2", "twist", "dg", "uy2"}) EXPECT_TRUE(r.identifiable[at(n)]) << n;
  EXPECT_GE(identifiable, 7);

  const double noise_angle = 0.5 * kDeg * std::sqrt(3.0);
  const config::Scene fitted = zeta.apply(r.zeta);
  const double held_fit = rms_error(fitted, held), held_truth = rms_error(truth, held);
  const double held_start = rms_error(nominal, held);
  std::printf(
      "held-back RMS: fitted %.3f deg, truth %.3f deg, start %.3f deg (noise %.3f deg); %d iterations, %.2f s\n",
      held_fit / kDeg, held_truth / kDeg, held_start / kDeg, noise_angle / kDeg, r.iterations, r.time_s);
  EXPECT_LT(held_fit, 1.2 * noise_angle);
  EXPECT_LT(held_fit, 1.1 * held_truth);
  EXPECT_GT(held_start, 1.5 * noise_angle);  // the start is off by twice the noise: the fit had work to do
}

/// Two equal segments, no gravity, and a pure bending moment at the tip (a couple of thrusters
/// fired together): the tip turns by M (L1/EI1 + L2/EI2), so the data see one combination of the
/// two bending scales. The fit says so and fits one common scale, which it recovers.
TEST(CalibrationAnyRobot, IndistinguishableSegmentsGetOneCommonScale) {
  const std::string yaml =
      "rod:\n  segments:\n"
      "    - {length: 0.05, bending_stiffness: [5e-4, 5e-4], torsional_stiffness: 4e-4}\n"
      "    - {length: 0.05, bending_stiffness: [5e-4, 5e-4], torsional_stiffness: 4e-4}\n"
      "tip: {mass: 0.0}\ngravity: [0, 0, 0]\n"
      "actuators:\n"
      "  - {name: couple_a, position: [0, 0, 0.01], direction: [0, 1, 0], max_force: 0.2}\n"
      "  - {name: couple_b, position: [0, 0, -0.01], direction: [0, -1, 0], max_force: 0.2}\n";
  const config::Scene nominal = config::parse_scene(yaml);
  config::Scene truth = nominal;
  for (rod::RodSegment& s : truth.rod.segments) s.stiffness.head<2>() *= 1.3;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<Sample> s(30);
  for (Sample& x : s) {
    x.inputs = rod::InputVector::Constant(2, 0.2 * u01(rng));
    const Eigen::Vector3d n(n01(rng), n01(rng), n01(rng));
    x.tip_orientation = Eigen::Quaterniond(predict_tip_rotation(truth, x.inputs) * so3::exp(0.2 * kDeg * n));
  }
  const Zeta zeta(nominal, CrossSection());
  CalibrationOptions o;
  o.fit = zeta.parse("bend1,bend2");
  const CalibrationResult r = calibrate(zeta, s, o);
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_TRUE(r.common_bending_scale);
  const int b = zeta.index("bend");
  EXPECT_TRUE(r.fitted[b] && r.identifiable[b]);
  EXPECT_FALSE(r.fitted[zeta.index("bend1")] || r.fitted[zeta.index("bend2")]);
  EXPECT_LE(std::abs(r.zeta[b] - 1.3), 4.0 * r.stddev[b]);
  EXPECT_LT(r.stddev[b], 0.01);
  ASSERT_FALSE(r.warnings.empty());
  EXPECT_NE(r.warnings.front().find("fitted one common scale 'bend'"), std::string::npos) << r.warnings.front();
  // Asked for per-segment scales whatever the data say: they are reported as not identifiable.
  o.bending_scale = BendingScale::kPerSegment;
  const CalibrationResult p = calibrate(zeta, s, o);
  EXPECT_FALSE(p.common_bending_scale);
  EXPECT_FALSE(p.identifiable[zeta.index("bend1")] && p.identifiable[zeta.index("bend2")]);
}

TEST(CalibrationAnyRobot, SceneWriterWritesEverySegmentAndTheMount) {
  const std::string text = read_file(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/two_segment_thrusters.yaml");
  const config::Scene start = config::parse_scene(text);
  const Zeta zeta(start, CrossSection());
  ZetaVector z = zeta.start();
  z[zeta.index("ux1")] = 0.7, z[zeta.index("uy2")] = 1.5, z[zeta.index("bend1")] = 0.9, z[zeta.index("bend")] = 1.1;
  z[zeta.index("twist")] = 1.2, z[zeta.index("da")] = 0.01, z[zeta.index("dg")] = -0.05;
  const config::Scene expected = zeta.apply(z), back = config::parse_scene(calibrated_scene_yaml(text, zeta, z));
  ASSERT_EQ(back.rod.segments.size(), 2u);
  for (int k = 0; k < 2; ++k) {
    EXPECT_EQ(back.rod.segments[k].stiffness, expected.rod.segments[k].stiffness) << k;
    EXPECT_EQ(back.rod.segments[k].precurvature, expected.rod.segments[k].precurvature) << k;
    EXPECT_EQ(back.rod.segments[k].linear_density, start.rod.segments[k].linear_density) << k;
  }
  for (int i = 0; i < back.rod.input_count(); ++i) {
    EXPECT_LT((back.rod.actuators[i].direction - expected.rod.actuators[i].direction).norm(), 1e-15) << i;
    EXPECT_LT((back.rod.actuators[i].position - expected.rod.actuators[i].position).norm(), 1e-15) << i;
    EXPECT_EQ(back.rod.actuators[i].name, start.rod.actuators[i].name);
    EXPECT_EQ(back.rod.actuators[i].max_force, start.rod.actuators[i].max_force);
  }
  EXPECT_EQ(back.rod.loads.size(), 1u);
  EXPECT_EQ(back.rod.tip_mass, start.rod.tip_mass);
}

// ---------------------------------------------------------------------------------------------
// Identifiability, robust loss, bounds
// ---------------------------------------------------------------------------------------------

TEST(CalibrationIdentifiability, JetNeverFiredIsReportedNotIdentifiable) {
  const ZetaVector zt = truth_zeta();
  const config::Scene truth = truth_scene(zt, 0);
  std::vector<Sample> s = data(truth, 40, 0.0, 21);
  // Re-solve with jet 2 off: δα (jet 2's misalignment) then has no effect on any sample.
  std::mt19937 rng(4);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (Sample& x : s) {
    x.inputs[1] = 0.0;
    const Eigen::Vector3d n(n01(rng), n01(rng), n01(rng));
    x.tip_orientation = Eigen::Quaterniond(predict_tip_rotation(truth, x.inputs) * so3::exp(0.5 * kDeg * n));
  }
  const CalibrationResult r = calibrate(Zeta(shipped("hydrojet_0deg"), CrossSection()), s, CalibrationOptions());
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_FALSE(r.identifiable[kDa]);
  EXPECT_TRUE(std::isnan(r.stddev[kDa]));
  bool warned = false;
  for (const std::string& w : r.warnings) warned |= w.rfind("da is not identifiable", 0) == 0;
  EXPECT_TRUE(warned);
  for (int i : {kUx, kUy, kE, kDb, kDg}) {
    EXPECT_TRUE(r.identifiable[i]) << param_name(i);
    EXPECT_LE(std::abs(r.zeta[i] - zt[i]), 4 * r.stddev[i]) << param_name(i);
  }
}

TEST(CalibrationIdentifiability, SmallForcesLeaveTorsionPoorlyDetermined) {
  // Jet forces below 10 % of their range barely bend the rod: twist (G) is then invisible at
  // 0.5° noise, and the report says so instead of quoting a value.
  const config::Scene truth = truth_scene(truth_zeta(), 0);
  SyntheticOptions o;
  o.samples = 40, o.noise_rad = 0.5 * kDeg, o.seed = 8, o.max_force_fraction = 0.1;
  const CalibrationResult r =
      calibrate(Zeta(shipped("hydrojet_0deg"), CrossSection()), synthesise(truth, o), CalibrationOptions());
  EXPECT_FALSE(r.identifiable[kG]);
  bool warned = false;
  for (const std::string& w : r.warnings) warned |= w.find("G is ") == 0;
  EXPECT_TRUE(warned);
}

TEST(CalibrationRobust, HuberLossShrugsOffOutliers) {
  const ZetaVector zt = truth_zeta();
  const config::Scene truth = truth_scene(zt, 0), nominal = shipped("hydrojet_0deg");
  std::vector<Sample> s = data(truth, 40, 0.5, 31);
  const CalibrationResult clean = calibrate(Zeta(nominal, CrossSection()), s, CalibrationOptions());
  ASSERT_TRUE(clean.converged);
  // Two samples whose tracker reading jumped by 15°.
  for (int k : {4, 17})
    s[k].tip_orientation = s[k].tip_orientation * Eigen::AngleAxisd(15 * kDeg, Eigen::Vector3d(1, 1, 0).normalized());
  CalibrationOptions o;
  o.loss = Loss::kHuber;
  o.loss_scale = 0.02;
  const CalibrationResult robust = calibrate(Zeta(nominal, CrossSection()), s, o);
  const CalibrationResult plain = calibrate(Zeta(nominal, CrossSection()), s, CalibrationOptions());
  ASSERT_TRUE(robust.converged);
  double worst_robust = 0, worst_plain = 0;
  for (int i = 0; i < kNumParams; ++i) {
    worst_robust = std::max(worst_robust, std::abs(robust.zeta[i] - zt[i]) / clean.stddev[i]);
    worst_plain = std::max(worst_plain, std::abs(plain.zeta[i] - zt[i]) / clean.stddev[i]);
  }
  std::printf("worst |error|/std: robust %.2f, plain least squares %.2f\n", worst_robust, worst_plain);
  EXPECT_LT(worst_robust, 4.0);
  EXPECT_GT(worst_plain, worst_robust);
  EXPECT_GT(robust.sample_error_rad[4], 10 * kDeg);  // the outliers stand out in the report
  EXPECT_GT(robust.sample_error_rad[17], 10 * kDeg);
}

TEST(CalibrationBounds, EstimateAtABoundIsFlagged) {
  const ZetaVector zt = truth_zeta();
  const config::Scene nominal = shipped("hydrojet_0deg");
  CalibrationOptions o;
  o.has_bounds = true;
  o.bounds = default_bounds(Zeta(nominal, CrossSection()));
  o.bounds.lower[kE] = 0.95 * Zeta(nominal, CrossSection()).start()[kE];  // the truth (×0.8) lies below
  const CalibrationResult r = calibrate(Zeta(nominal, CrossSection()), data(truth_scene(zt, 0), 40, 0.5, 3), o);
  EXPECT_TRUE(r.at_bound[kE]);
  EXPECT_NEAR(r.zeta[kE], o.bounds.lower[kE], 1e-6 * r.zeta[kE]);
  bool warned = false;
  for (const std::string& w : r.warnings) warned |= w.find("E ended at its bound") == 0;
  EXPECT_TRUE(warned);
  o.bounds.lower[kE] = 2 * zt[kE];  // start outside the bounds: refused
  EXPECT_THROW(calibrate(Zeta(nominal, CrossSection()), data(truth_scene(zt, 0), 10, 0.5, 3), o),
               std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Bad data
// ---------------------------------------------------------------------------------------------

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const DataError& e) {
    return e.what();
  }
  return "";
}

TEST(CalibrationData, BadSamplesAreRejectedByName) {
  const config::Scene nominal = shipped("hydrojet_0deg");
  std::vector<Sample> s = data(nominal, 10, 0.5, 1);
  auto fit = [&](const std::vector<Sample>& x) {
    return [&nominal, x] { calibrate(Zeta(nominal, CrossSection()), x, CalibrationOptions()); };
  };

  EXPECT_NE(error_of(fit(std::vector<Sample>(s.begin(), s.begin() + 6))).find("too few samples: 6 for 7"),
            std::string::npos);
  std::vector<Sample> zero = s;
  for (Sample& x : zero) x.inputs.setZero();
  EXPECT_NE(error_of(fit(zero)).find("every actuator input is zero"), std::string::npos);
  std::vector<Sample> nan = s;
  nan[3].inputs[2] = std::nan("");
  const std::string e = error_of(fit(nan));
  EXPECT_NE(e.find(s[3].origin), std::string::npos) << e;
  EXPECT_NE(e.find("q3 (jet3) is not finite"), std::string::npos) << e;
  std::vector<Sample> nonunit = s;
  nonunit[5].tip_orientation.coeffs() *= 1.1;
  EXPECT_NE(error_of(fit(nonunit)).find("not unit"), std::string::npos);
  std::vector<Sample> negative = s;
  negative[0].inputs[0] = -0.01;
  EXPECT_NE(error_of(fit(negative)).find("q1 (jet1) is negative"), std::string::npos);
}

TEST(CalibrationCsv, ParsesAnyColumnOrderAndIgnoresOthers) {
  const std::string text =
      "# recorded 2021-03-02\n"
      "time, QW,qx,qy,qz, q3,q2,q1, note\n"
      "0.0, 1,0,0,0, 0.0,0.0,0.1, a\n"
      "\n"
      "1.0, 0.7071067811865476,0.7071067811865476,0,0, 0.2,0.05,0, b\n";
  const std::vector<Sample> s = parse_csv(text, jets(), "d.csv");
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(Eigen::Vector3d(s[0].inputs), Eigen::Vector3d(0.1, 0.0, 0.0));
  EXPECT_EQ(Eigen::Vector3d(s[1].inputs), Eigen::Vector3d(0.0, 0.05, 0.2));
  EXPECT_NEAR(s[1].tip_orientation.x(), std::sqrt(0.5), 1e-15);
  EXPECT_EQ(s[1].origin, "d.csv:5");
}

TEST(CalibrationCsv, ErrorsNameTheLineAndColumn) {
  auto err = [](const std::string& t) { return error_of([&] { parse_csv(t, jets(), "d.csv"); }); };
  EXPECT_NE(err("q1,q2,q3,qw,qx,qy\n").find("d.csv:1: header has no column 'qz'"), std::string::npos);
  EXPECT_NE(err("q1,q2,q3,qw,qx,qy,qz\n0.1,0,0,1,0,0,0\n0.1,nan,0,1,0,0,0\n").find("d.csv:3: q2 (jet2) is not finite"),
            std::string::npos);
  EXPECT_NE(err("q1,q2,q3,qw,qx,qy,qz\n0.1,0,0,0.9,0,0,0\n").find("d.csv:2: quaternion (qw,qx,qy,qz) is not unit"),
            std::string::npos);
  EXPECT_NE(err("q1,q2,q3,qw,qx,qy,qz\n0.1,0,0,1,0,0\n").find("d.csv:2: 6 fields, the header has 7"),
            std::string::npos);
  EXPECT_NE(err("q1,q2,q3,qw,qx,qy,qz\n0.1,x,0,1,0,0,0\n").find("d.csv:2: column q2: 'x' is not a number"),
            std::string::npos);
  EXPECT_NE(err("").find("empty"), std::string::npos);
  // to_csv → parse_csv is exact.
  const std::vector<Sample> s = data(shipped("hydrojet_0deg"), 5, 0.5, 2);
  const std::vector<Sample> back = parse_csv(to_csv(s), jets());
  for (size_t i = 0; i < s.size(); ++i) {
    EXPECT_EQ(back[i].inputs, s[i].inputs);
    EXPECT_NEAR(back[i].tip_orientation.angularDistance(s[i].tip_orientation), 0.0, 1e-15);
  }
}

// ---------------------------------------------------------------------------------------------
// Scene writer
// ---------------------------------------------------------------------------------------------

TEST(CalibrationSceneWriter, OutputIsACompleteSceneThatLoadsBack) {
  for (const char* name : {"hydrojet_0deg", "hydrojet_30deg"}) {
    SCOPED_TRACE(name);
    const std::string text = read_file(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/" + name + ".yaml");
    const config::Scene start = config::parse_scene(text);
    const ZetaVector z = truth_zeta();
    YAML::Node cal(YAML::NodeType::Map);
    cal["rms_rad"] = 0.01;
    const std::string yaml = calibrated_scene_yaml(text, Zeta(start, CrossSection()), z, "fitted\nby a test", cal);
    EXPECT_EQ(yaml.rfind("# fitted\n# by a test\n", 0), 0u) << yaml;
    EXPECT_NE(yaml.find("youngs_modulus:"), std::string::npos);
    EXPECT_EQ(yaml.find("bending_stiffness"), std::string::npos);
    EXPECT_NE(yaml.find("length: 0.09\n"), std::string::npos) << yaml;  // short exact numbers
    const config::Scene b = config::parse_scene(yaml);
    // ζ in, through the scene library's own moduli → stiffness conversion.
    EXPECT_NEAR(b.rod.segments[0].stiffness.x(), z[kE] * kI, 1e-14 * b.rod.segments[0].stiffness.x());
    EXPECT_NEAR(b.rod.segments[0].stiffness.y(), z[kE] * kI, 1e-14 * b.rod.segments[0].stiffness.y());
    EXPECT_NEAR(b.rod.segments[0].stiffness.z(), z[kG] * 2 * kI, 1e-14 * b.rod.segments[0].stiffness.z());
    EXPECT_EQ(b.rod.segments[0].precurvature, Eigen::Vector3d(z[kUx], z[kUy], start.rod.segments[0].precurvature.z()));
    EXPECT_EQ(b.jets->misalignment, Eigen::Vector3d(z[kDa], z[kDb], z[kDg]));
    // Everything else carried over.
    EXPECT_EQ(b.rod.segments[0].length, start.rod.segments[0].length);
    EXPECT_EQ(b.rod.segments[0].linear_density, start.rod.segments[0].linear_density);
    EXPECT_EQ(b.rod.tip_mass, start.rod.tip_mass);
    EXPECT_EQ(b.rod.gravity, start.rod.gravity);
    EXPECT_EQ(b.actuated, start.actuated);
    EXPECT_EQ(b.solver.integrator.type, start.solver.integrator.type);
    EXPECT_EQ(b.solver.integrator.steps, start.solver.integrator.steps);
    EXPECT_EQ(b.solver.residual_tolerance, start.solver.residual_tolerance);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(b.rod.actuators[i].max_force, start.rod.actuators[i].max_force);
    EXPECT_EQ(b.nozzle.inlet_area, start.nozzle.inlet_area);
    EXPECT_EQ(b.nozzle.outlet_area, start.nozzle.outlet_area);
    EXPECT_EQ(b.nozzle.water_density, start.nozzle.water_density);
    EXPECT_EQ(b.jets->nozzle_offset, start.jets->nozzle_offset);
    EXPECT_EQ(cross_section_from_scene_text(yaml, CrossSection{0.01, 0.002}).outer_diameter, 0.008);
    EXPECT_EQ(YAML::Load(yaml)["calibration"]["rms_rad"].as<double>(), 0.01);
    // Written again (e.g. a calibrated scene as the next start): one calibration section, still valid.
    const std::string again = calibrated_scene_yaml(yaml, Zeta(start, CrossSection()), z, "", YAML::Node());
    EXPECT_FALSE(YAML::Load(again)["calibration"]);
    EXPECT_EQ(config::parse_scene(again).rod.segments[0].stiffness, b.rod.segments[0].stiffness);
  }
  // Keys the writer does not know survive, in known sections and as sections of their own.
  const std::string custom =
      "rod: {length: 0.1, bending_stiffness: [5e-4, 5e-4], torsional_stiffness: 2e-4}\n"
      "tip: {mass: 0.001, actuated: [fx, fy, mz]}\ngravity: [0, 0, 9.81]\n"
      "solver: {integrator: dopri5, tolerance: 1e-8}\n"
      "jets: {misalignment: [0, 0, 0], max_force: [0.2, 0.2, 0.2], inlet_area: 1e-6, outlet_area: 3e-7,"
      " water_density: 1000, nozzle_offset: 0.003}\nplant: {note: kept}\n";
  const std::string out =
      calibrated_scene_yaml(custom, Zeta(config::parse_scene(custom), CrossSection()), truth_zeta());
  const config::Scene c = config::parse_scene(out);
  EXPECT_EQ(c.solver.integrator.type, rod::IntegratorType::kDopri5);
  EXPECT_EQ(c.solver.integrator.tolerance, 1e-8);
  EXPECT_TRUE(c.actuated[5]);
  EXPECT_EQ(c.jets->nozzle_offset, 0.003);
  EXPECT_EQ(c.rod.segments[0].precurvature.z(), 0.0);
  EXPECT_EQ(YAML::Load(out)["plant"]["note"].as<std::string>(), "kept");
  EXPECT_THROW(
      calibrated_scene_yaml("rod: {length: 1}\n", Zeta(shipped("hydrojet_0deg"), CrossSection()), truth_zeta()),
      config::SceneError);
}

// ---------------------------------------------------------------------------------------------
// Quasistatic extraction
// ---------------------------------------------------------------------------------------------

/// 100 Hz records of holds: jet forces step (first-order lag 50 ms) and the tip rings (5 Hz,
/// decaying as e^{-3t}) towards each hold's orientation; tracker noise 0.3°/axis on both sensors,
/// flow noise 5e-8 m³/s; the base sensor hangs the rod down (Rx(π)) as the plant does.
struct Series {
  std::vector<JetRecord> jets;
  std::vector<PoseRecord> tip, base;
  std::vector<Eigen::Vector3d> force;
  std::vector<Eigen::Matrix3d> R;
};

Series make_series(const std::vector<double>& durations, const actuation::Nozzle& nz) {
  Series s;
  std::mt19937 rng(12);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  // (explicit return type: `auto` would return an Eigen expression referring to a dead temporary)
  auto noise = [&](double sigma) -> Eigen::Vector3d { return Eigen::Vector3d(n01(rng), n01(rng), n01(rng)) * sigma; };
  const Eigen::Matrix3d Rb = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  Eigen::Vector3d F_prev = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_prev = Eigen::Matrix3d::Identity();
  double t0 = 0.0;
  for (double d : durations) {
    const Eigen::Vector3d F(0.2 * u01(rng), 0.2 * u01(rng), 0.2 * u01(rng));
    const Eigen::Matrix3d R = so3::exp(Eigen::Vector3d(u01(rng) - 0.5, u01(rng) - 0.5, 0.2 * (u01(rng) - 0.5)));
    s.force.push_back(F);
    s.R.push_back(R);
    const Eigen::Vector3d step = so3::log(R_prev.transpose() * R);
    for (double tau = 0.0; tau < d - 1e-9; tau += 0.01) {
      const double t = t0 + tau;
      const Eigen::Vector3d Ft = F + (F_prev - F) * std::exp(-tau / 0.05);
      // overshoot and ring about the new orientation
      const Eigen::Vector3d dev = -step * std::exp(-3.0 * tau) * std::cos(2 * M_PI * 5.0 * tau);
      const Eigen::Matrix3d Rt = R * so3::exp(dev);
      JetRecord j;
      j.t = t;
      for (int i = 0; i < 3; ++i) j.flow[i] = actuation::flow_from_force(Ft[i], nz) + 5e-8 * n01(rng);
      s.jets.push_back(j);
      PoseRecord tp, bp;
      tp.t = bp.t = t;
      tp.orientation = Eigen::Quaterniond(Rb * Rt * so3::exp(noise(0.3 * kDeg)));
      bp.orientation = Eigen::Quaterniond(Rb * so3::exp(noise(0.3 * kDeg)));
      s.tip.push_back(tp);
      s.base.push_back(bp);
    }
    F_prev = F, R_prev = R, t0 += d;
  }
  return s;
}

TEST(CalibrationQuasistatic, OneSettledSamplePerHold) {
  const actuation::Nozzle nz;
  // Four 3 s holds, a 0.4 s blip (never settles: no sample), two more 3 s holds.
  const Series s = make_series({3.0, 3.0, 3.0, 3.0, 0.4, 3.0, 3.0}, nz);
  const Extraction ex = extract_quasistatic(s.jets, s.tip, s.base, nz, QuasistaticOptions());
  EXPECT_EQ(ex.paired_points, static_cast<int>(s.tip.size()));
  ASSERT_EQ(ex.samples.size(), 6u);
  const int hold[6] = {0, 1, 2, 3, 5, 6};
  for (int k = 0; k < 6; ++k) {
    SCOPED_TRACE(k);
    const Sample& x = ex.samples[k];
    EXPECT_LT((Eigen::Vector3d(x.inputs) - s.force[hold[k]]).cwiseAbs().maxCoeff(), 0.002);  // mean of 50 noisy forces
    EXPECT_LT(rotation_error(x.tip_orientation.toRotationMatrix(), s.R[hold[k]]).norm(), 0.25 * kDeg);
    EXPECT_EQ(x.origin.rfind("bag t=", 0), 0u);
  }
  // Shuffled input is sorted first.
  Series sh = s;
  std::reverse(sh.jets.begin(), sh.jets.end());
  std::reverse(sh.base.begin(), sh.base.end());
  EXPECT_EQ(extract_quasistatic(sh.jets, sh.tip, sh.base, nz, QuasistaticOptions()).samples.size(), 6u);
}

TEST(CalibrationQuasistatic, RingingIsNotQuasistaticAndPairingIsRequired) {
  const actuation::Nozzle nz;
  const Series s = make_series({3.0, 3.0}, nz);
  const Extraction ex = extract_quasistatic(s.jets, s.tip, s.base, nz, QuasistaticOptions());
  // Each sample's window lies inside its hold (holds end at 3 and 6 s), clear of the next step
  // (without end_guard the first would end at 3.02 s, two points into the next transient), and
  // windows during the ringing after a step are rejected.
  ASSERT_EQ(ex.sample_time.size(), 2u);
  for (int k = 0; k < 2; ++k) {
    EXPECT_GT(ex.sample_time[k], 3.0 * k + 2.0);
    EXPECT_LT(ex.sample_time[k], 3.0 * (k + 1));
  }
  EXPECT_LT(ex.quasistatic_windows, ex.windows);
  int early = 0;  // quasistatic windows in the first 0.8 s after the step at t = 3 s
  for (const JetRecord& j : s.jets) early += j.t > 3.0 && j.t < 3.8;
  EXPECT_LE(ex.quasistatic_windows, ex.windows - early);
  // Jet states from another time span cannot be paired with the poses.
  std::vector<JetRecord> late = s.jets;
  for (JetRecord& j : late) j.t += 100.0;
  EXPECT_THROW(extract_quasistatic(late, s.tip, s.base, nz, QuasistaticOptions()), DataError);
  // Flagged readings are skipped.
  std::vector<JetRecord> flagged = s.jets;
  for (size_t i = 0; i < flagged.size(); i += 2) flagged[i].valid = false;
  const Extraction ef = extract_quasistatic(flagged, s.tip, s.base, nz, QuasistaticOptions());
  EXPECT_EQ(ef.skipped_points, static_cast<int>((flagged.size() + 1) / 2));
}

}  // namespace
