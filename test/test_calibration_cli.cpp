// `calibrate` as a user runs it: CSV and rosbag input, the report and its last JSON line, the
// fitted scene read back by load_scene(), and exit status 2 with a message naming the problem for
// bad input. The data are synthesized by the tool itself (--synthesize, from a truth scene file)
// or, for the bag, written here with the rosbag API from the static model.
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>
#include <rosbag/bag.h>
#include <topic_tools/shape_shifter.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <set>
#include <string>

#include "hydrojet_control/JetState.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/calibration/bag_reader.h"
#include "hydrojet_control/calibration/calibrator.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/so3.h"
#include "cli_helpers.h"

namespace {

using namespace hydrojet;

using test::CliRun;
using test::number_field;
using test::object_field;

CliRun run(const std::string& args) { return test::run_cli(HYDROJET_CALIBRATE, args); }

/// Per-process temp names (several builds may run this test at the same time), removed at exit.
std::set<std::string>& temp_files() {
  static std::set<std::string> files;
  return files;
}
std::string tmp(const std::string& name) {
  const std::string p = ::testing::TempDir() + "calibrate_" + std::to_string(getpid()) + "_" + name;
  temp_files().insert(p);
  return p;
}
struct TempCleanup : ::testing::Environment {
  void TearDown() override {
    for (const std::string& f : temp_files()) std::remove(f.c_str());
    std::remove((::testing::TempDir() + "calibrate_" + std::to_string(getpid()) + "_err.txt").c_str());
  }
};
const auto* const kCleanup = ::testing::AddGlobalTestEnvironment(new TempCleanup);

std::string write(const std::string& name, const std::string& text) {
  const std::string p = tmp(name);
  std::ofstream(p) << text;
  return p;
}

std::string scene(const std::string& name) {
  return std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/" + name + ".yaml";
}

/// The truth of these tests: Table 1 with the mismatch of config/plant.yaml (ũ + (0.6, −0.4),
/// EI × 0.8, GJ × 1.25, misalignments + (0.06, −0.06, 0.05)), stiffness given directly.
const char* kTruthScene =
    "rod:\n  length: 0.09\n  bending_stiffness: [4.808e-4, 4.808e-4]\n  torsional_stiffness: 2.7875e-4\n"
    "  precurvature: [0.634, 0.48, 0.0]\ntip:\n  mass: 0.00258\ngravity: [0.0, 0.0, 9.81]\n"
    "solver:\n  steps: 16\n  residual_tolerance: 1.0e-13\n"
    "jets:\n  misalignment: [0.18, 0.0, -0.03]\n  max_force: [0.243, 0.224, 0.244]\n"
    "  inlet_area: 1.13e-6\n  outlet_area: 3.84e-7\n  water_density: 998.0\n";
const double kI = M_PI * (std::pow(0.008, 4) - std::pow(0.006, 4)) / 64.0;
const double kTruth[7] = {0.634, 0.48, 4.808e-4 / kI, 2.7875e-4 / (2 * kI), 0.18, 0.0, -0.03};
const char* kNames[7] = {"ux", "uy", "E", "G", "da", "db", "dg"};

std::string synthesised_csv(int n, unsigned seed) {
  const std::string truth = write("truth.yaml", kTruthScene), csv = tmp("data_" + std::to_string(seed) + ".csv");
  const CliRun r = run("--scene " + truth + " --synthesize " + std::to_string(n) + " --seed " + std::to_string(seed) +
                       " --noise-deg 0.5 --out " + csv);
  EXPECT_EQ(r.status, 0) << r.err;
  return csv;
}

TEST(CalibrateCli, FitsCsvWritesSceneAndEndsWithJson) {
  const std::string csv = synthesised_csv(40, 4), out = tmp("fit.yaml");
  std::remove(out.c_str());
  const CliRun r = run("--scene " + scene("hydrojet_0deg") + " --data " + csv + " --out " + out);
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  const std::string json = r.last_line();
  ASSERT_EQ(json.front(), '{');
  ASSERT_EQ(json.back(), '}');
  EXPECT_NE(json.find("\"converged\": true"), std::string::npos);
  const double rms = number_field(json, "rms_rad");
  EXPECT_GT(rms, 0.6 * M_PI / 180);  // 0.5°/axis noise → ≈0.87° RMS angle
  EXPECT_LT(rms, 1.1 * M_PI / 180);
  EXPECT_GE(number_field(json, "time_s"), 0.0);
  const std::string p = object_field(json, "parameters"), s = object_field(json, "std");
  for (int i = 0; i < 7; ++i) {
    SCOPED_TRACE(kNames[i]);
    const double v = number_field(p, kNames[i]), sd = number_field(s, kNames[i]);
    ASSERT_TRUE(std::isfinite(v) && std::isfinite(sd) && sd > 0);
    EXPECT_LE(std::abs(v - kTruth[i]), 4 * sd) << v << " vs " << kTruth[i];
  }
  // The report: parameter table, correlations, per-sample errors; no warnings for these data.
  EXPECT_NE(r.out.find("correlations:"), std::string::npos);
  EXPECT_NE(r.out.find("per-sample orientation error"), std::string::npos);
  EXPECT_NE(r.out.find(csv + ":41"), std::string::npos);  // the last data line is named
  EXPECT_NE(json.find("\"warnings\": []"), std::string::npos);

  // The fitted scene loads and carries the fitted values (moduli and diameters of §6.2).
  config::Scene fitted;
  ASSERT_NO_THROW(fitted = config::load_scene(out));
  EXPECT_NEAR(fitted.rod.segments[0].stiffness.x(), number_field(p, "E") * kI,
              1e-12 * fitted.rod.segments[0].stiffness.x());
  EXPECT_NEAR(fitted.rod.segments[0].stiffness.z(), number_field(p, "G") * 2 * kI,
              1e-12 * fitted.rod.segments[0].stiffness.z());
  EXPECT_EQ(fitted.rod.segments[0].precurvature.x(), number_field(p, "ux"));
  EXPECT_EQ(fitted.jets->misalignment[2], number_field(p, "dg"));
  EXPECT_EQ(fitted.rod.tip_mass, 0.00258);
  // ... and calibrating again from it changes nothing (it is the optimum for these data).
  const CliRun again = run("--scene " + out + " --data " + csv + " --out " + tmp("fit2.yaml"));
  ASSERT_EQ(again.status, 0) << again.err;
  const std::string p2 = object_field(again.last_line(), "parameters");
  for (int i = 0; i < 7; ++i)
    EXPECT_NEAR(number_field(p2, kNames[i]), number_field(p, kNames[i]), 0.01 * number_field(s, kNames[i]))
        << kNames[i];
}

TEST(CalibrateCli, FitSubsetKeepsTheOthersAndReportsNullStd) {
  const std::string csv = synthesised_csv(20, 6);
  const CliRun r = run("--scene " + scene("hydrojet_0deg") + " --data " + csv + " --fit E,ux --out " + tmp("sub.yaml"));
  ASSERT_NE(r.status, 2) << r.err;
  const std::string json = r.last_line();
  const std::string p = object_field(json, "parameters"), s = object_field(json, "std");
  EXPECT_EQ(number_field(p, "uy"), 0.88);  // the scene's values
  EXPECT_EQ(number_field(p, "da"), 0.12);
  EXPECT_TRUE(std::isnan(number_field(s, "uy")));
  EXPECT_NE(s.find("\"uy\": null"), std::string::npos);
  EXPECT_GT(number_field(s, "E"), 0.0);
}

TEST(CalibrateCli, CrossSectionOptionsRescaleTheModuli) {
  const std::string csv = synthesised_csv(40, 4);
  const CliRun a = run("--scene " + scene("hydrojet_0deg") + " --data " + csv + " --out " + tmp("a.yaml"));
  const CliRun b = run("--scene " + scene("hydrojet_0deg") + " --data " + csv +
                       " --outer-diameter 0.01 --inner-diameter 0.0 --out " + tmp("b.yaml"));
  ASSERT_EQ(a.status, 0);
  ASSERT_EQ(b.status, 0);
  // Same stiffness, other cross-section: E scales with 1/I.
  const double Ia = kI, Ib = M_PI * std::pow(0.01, 4) / 64.0;
  EXPECT_NEAR(number_field(object_field(b.last_line(), "parameters"), "E") * Ib,
              number_field(object_field(a.last_line(), "parameters"), "E") * Ia, 1e-6 * 4.8e-4);
  EXPECT_EQ(config::load_scene(tmp("b.yaml")).rod.segments[0].stiffness.x() > 0, true);
}

TEST(CalibrateCli, BoundHitIsWarned) {
  // The truth's E (3.5 MPa) lies below the allowed range: the fit stops at the bound and says so.
  const std::string csv = synthesised_csv(40, 4);
  const CliRun r =
      run("--scene " + scene("hydrojet_0deg") + " --data " + csv + " --bound E=4.2e6:5e6 --out " + tmp("bd.yaml"));
  ASSERT_NE(r.status, 2) << r.err;
  EXPECT_NEAR(number_field(object_field(r.last_line(), "parameters"), "E"), 4.2e6, 1.0);
  EXPECT_NE(r.last_line().find("E ended at its bound"), std::string::npos) << r.last_line();
  EXPECT_NE(r.err.find("warning: E ended at its bound"), std::string::npos) << r.err;
}

/// The two-segment robot of config/scenes with other precurvatures and stiffnesses and its tip
/// mount turned by 0.05 rad about the tip axis, written out independently of the calibration code.
const char* kTwoSegmentTruth =
    "rod:\n  segments:\n"
    "    - {length: 0.05, bending_stiffness: [1.3e-3, 1.3e-3], torsional_stiffness: 1.15e-3,"
    " precurvature: [0.8, -0.6, 0.0], linear_density: 0.02}\n"
    "    - {length: 0.04, bending_stiffness: [4.6e-4, 4.6e-4], torsional_stiffness: 3.1e-4,"
    " precurvature: [-0.4, 2.6, 0.0], linear_density: 0.015}\n"
    "tip: {mass: 0.003}\ngravity: [0.0, 0.0, 9.81]\nsolver: {steps: 16, residual_tolerance: 1.0e-13}\n"
    "loads:\n  - {at: 0.05, mass: 0.001}\n"
    "actuators:\n"
    "  - {name: tip_px, direction: [0.99875026039496628, 0.049979169270678331, 0.0], max_force: 0.15}\n"
    "  - {name: tip_nx, direction: [-0.99875026039496628, -0.049979169270678331, 0.0], max_force: 0.15}\n"
    "  - {name: tip_py, direction: [-0.049979169270678331, 0.99875026039496628, 0.0], max_force: 0.15}\n"
    "  - {name: tip_ny_arm, position: [0.0039950010415798651, 0.00019991667708271332, 0.0],"
    " direction: [0.049979169270678331, -0.99875026039496628, 0.0], max_force: 0.15}\n"
    "  - {name: mid_px, at: 0.05, position: [0.0, 0.005, 0.0], direction: [1.0, 0.0, 0.0], max_force: 0.1}\n"
    "  - {name: mid_py, at: 0.05, position: [0.005, 0.0, 0.0], direction: [0.0, 1.0, 0.0], max_force: 0.1}\n";

TEST(CalibrateCli, FitsAnyRobotFromItsSceneAndWritesACompleteScene) {
  const std::string truth = write("two_truth.yaml", kTwoSegmentTruth), csv = tmp("two.csv"), out = tmp("two_fit.yaml");
  const CliRun syn = run("--scene " + truth + " --synthesize 50 --seed 3 --noise-deg 0.3 --out " + csv);
  ASSERT_EQ(syn.status, 0) << syn.err;
  std::ifstream head(csv);
  std::string header;
  std::getline(head, header);
  EXPECT_EQ(header, "q1,q2,q3,q4,q5,q6,qw,qx,qy,qz");

  std::remove(out.c_str());
  const CliRun r = run("--scene " + scene("two_segment_thrusters") + " --data " + csv + " --out " + out);
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  const std::string json = r.last_line();
  EXPECT_NE(json.find("\"converged\": true"), std::string::npos);
  EXPECT_NE(json.find("\"bending_scale\": \"per-segment\""), std::string::npos) << json;
  const std::string p = object_field(json, "parameters"), sd = object_field(json, "std");
  const std::string id = object_field(json, "identifiable");
  const std::pair<const char*, double> truths[] = {{"bend1", 1.3 / 1.5}, {"bend2", 1.15}, {"dg", 0.05}, {"uy2", 2.6}};
  for (const auto& [name, value] : truths) {
    SCOPED_TRACE(name);
    EXPECT_NE(id.find(std::string("\"") + name + "\": true"), std::string::npos) << id;
    EXPECT_LE(std::abs(number_field(p, name) - value), 4 * number_field(sd, name));
  }
  EXPECT_LT(number_field(json, "rms_rad"), 1.2 * 0.3 * M_PI / 180 * std::sqrt(3.0));

  // A complete scene: loads, keeps the robot's structure, and solves.
  config::Scene fitted;
  ASSERT_NO_THROW(fitted = config::load_scene(out));
  ASSERT_EQ(fitted.rod.segments.size(), 2u);
  ASSERT_EQ(fitted.rod.input_count(), 6);
  EXPECT_EQ(fitted.rod.actuators[3].name, "tip_ny_arm");
  EXPECT_EQ(fitted.rod.loads.size(), 1u);
  EXPECT_NEAR(fitted.rod.segments[0].stiffness.x(), 1.5e-3 * number_field(p, "bend1"), 1e-15);
  EXPECT_EQ(fitted.rod.segments[1].precurvature.y(), number_field(p, "uy2"));
  const double dg = number_field(p, "dg");
  EXPECT_NEAR(fitted.rod.actuators[0].direction.y(), std::sin(dg), 1e-3);  // da, db small
  rod::RodSolver solver(fitted.rod, fitted.solver);
  EXPECT_TRUE(solver.solve(rod::InputVector::Constant(6, 0.05)).converged);
  const YAML::Node cal = YAML::LoadFile(out)["calibration"];
  EXPECT_EQ(cal["bending_scale"].as<std::string>(), "per-segment");
  EXPECT_TRUE(cal["std"]["bend2"]);
}

TEST(CalibrateCli, AnyRobotsDataMustMatchItsActuators) {
  const std::string s2 = scene("two_segment_thrusters"), out = tmp("bad2.yaml");
  auto check = [&](const std::string& args, const std::string& message) {
    SCOPED_TRACE(args);
    const CliRun r = run(args);
    EXPECT_EQ(r.status, 2);
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
  };
  std::string rows;
  for (int i = 0; i < 12; ++i) rows += "0.1,0.05,0.02,1,0,0,0\n";
  const std::string three = write("three.csv", "q1,q2,q3,qw,qx,qy,qz\n" + rows);
  check("--scene " + s2 + " --data " + three + " --out " + out, "header has no column 'q4'");
  const std::string seven = write("seven.csv", "q1,q2,q3,q4,q5,q6,q7,qw,qx,qy,qz\n");
  check("--scene " + s2 + " --data " + seven + " --out " + out, "header has column 'q7' but the scene has 6 actuators");
  std::string six_rows;
  for (int i = 0; i < 12; ++i) six_rows += "0.1,0.05,0.02,0.01,-0.01,0.02,1,0,0,0\n";
  const std::string negative = write("negative.csv", "q1,q2,q3,q4,q5,q6,qw,qx,qy,qz\n" + six_rows);
  check("--scene " + s2 + " --data " + negative + " --out " + out, "q5 (mid_px) is negative");
  check("--scene " + s2 + " --data " + negative + " --out " + out + " --fit bend,bend1", "scale the same stiffness");
  check("--scene " + s2 + " --data " + negative + " --out " + out + " --fit E", "unknown parameter 'E' (ux1, uy1");
  check("--scene " + s2 + " --data " + negative + " --out " + out + " --outer-diameter 0.01",
        "--outer-diameter / --inner-diameter: only for a scene fitted in moduli");
  check("--scene " + s2 + " --data " + negative + " --out " + out + " --bending-scale some", "--bending-scale");
}

TEST(CalibrateCli, NotConvergedExitsOneAndWritesNoScene) {
  const std::string csv = synthesised_csv(40, 4), out = tmp("nc.yaml");
  std::remove(out.c_str());
  const CliRun r = run("--scene " + scene("hydrojet_0deg") + " --data " + csv + " --max-iterations 1 --out " + out);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.last_line().find("\"converged\": false"), std::string::npos);
  EXPECT_FALSE(std::ifstream(out).good());
  EXPECT_NE(r.err.find("did not converge"), std::string::npos);
}

TEST(CalibrateCli, BadInputExitsTwoNamingTheProblem) {
  const std::string s0 = scene("hydrojet_0deg"), out = tmp("bad.yaml");
  auto check = [&](const std::string& args, const std::string& message) {
    SCOPED_TRACE(args);
    const CliRun r = run(args);
    EXPECT_EQ(r.status, 2);
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
  };
  const std::string head = "q1,q2,q3,qw,qx,qy,qz\n";
  std::string rows;
  for (int i = 0; i < 10; ++i) rows += "0.1,0.05,0.02,1,0,0,0\n";
  const std::string nan = write("nan.csv", head + rows + "0.1,NaN,0.02,1,0,0,0\n" + rows);
  check("--scene " + s0 + " --data " + nan + " --out " + out, nan + ":12: q2 (jet2) is not finite");
  const std::string nonunit = write("nonunit.csv", head + rows + "0.1,0.05,0.02,0.5,0,0,0\n");
  check("--scene " + s0 + " --data " + nonunit + " --out " + out,
        nonunit + ":12: quaternion (qw,qx,qy,qz) is not unit");
  const std::string few = write("few.csv", head + "0.1,0.05,0.02,1,0,0,0\n0.1,0.05,0.02,1,0,0,0\n");
  check("--scene " + s0 + " --data " + few + " --out " + out, "too few samples: 2 for 7 fitted parameters");
  std::string zeros;
  for (int i = 0; i < 10; ++i) zeros += "0,0,0,1,0,0,0\n";
  const std::string zero = write("zero.csv", head + zeros);
  check("--scene " + s0 + " --data " + zero + " --out " + out, "every actuator input is zero");
  const std::string nocol = write("nocol.csv", "q1,q2,q3,qw,qx,qy\n");
  check("--scene " + s0 + " --data " + nocol + " --out " + out, "header has no column 'qz'");
  check("--scene " + s0 + " --data " + tmp("missing.csv") + " --out " + out, "cannot read data file");
  check("--scene " + s0 + " --data " + zero + " --fit ux,EI --out " + out, "--fit: unknown parameter 'EI'");
  check("--data " + zero + " --out " + out, "--scene: missing");
  check("--scene " + s0 + " --data " + zero, "--out: missing");
  check("--scene " + s0 + " --data " + zero + " --out " + out + " --bogus 1", "unknown option '--bogus'");
  check("--scene " + s0 + " --data " + zero + " --out " + out + " --outer-diameter 0.005", "inner_diameter");
  check("--scene " + s0 + " --data " + zero + " --out " + out + " --bound E=1", "--bound: 'E=1' is not NAME=LO:HI");
  check("--scene " + s0 + " --data " + zero + " --out " + out + " --bound EI=1:2", "--bound: unknown parameter 'EI'");
  const std::string good = synthesised_csv(20, 6);
  check("--scene " + s0 + " --data " + good + " --out " + out + " --bound E=1e7:2e7", "bounds of E: the start");
  const std::string nojets = write("nojets.yaml",
                                   "rod: {length: 0.09, bending_stiffness: [6e-4, 6e-4], torsional_stiffness: 2e-4}\n"
                                   "tip: {mass: 0.0}\ngravity: [0, 0, 9.81]\n");
  check("--scene " + nojets + " --data " + zero + " --out " + out, "actuators: none");
}

// ---------------------------------------------------------------------------------------------
// rosbag input
// ---------------------------------------------------------------------------------------------

/// A bag like the driver's: 100 Hz tracker poses (tip and base, tracker frame, base hung down) and
/// jet states (flows) over `holds` random jet-force holds of 2 s; each hold starts with 0.6 s of
/// ringing; 0.3°/axis tracker noise, 5e-8 m³/s flow noise. Topics under `prefix`.
void write_bag(const std::string& path, const config::Scene& truth, int holds, const std::string& prefix,
               bool with_jets = true) {
  rosbag::Bag bag(path, rosbag::bagmode::Write);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Eigen::Matrix3d Rb = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  auto quat = [](const Eigen::Matrix3d& R, geometry_msgs::Quaternion* q) {
    const Eigen::Quaterniond e(R);
    q->w = e.w(), q->x = e.x(), q->y = e.y(), q->z = e.z();
  };
  double t = 1.0;
  Eigen::Matrix3d R_prev = Eigen::Matrix3d::Identity();
  for (int h = 0; h < holds; ++h) {
    Eigen::Vector3d q;
    for (int i = 0; i < 3; ++i) q[i] = 0.12 * u01(rng);
    const Eigen::Matrix3d R = calibration::predict_tip_rotation(truth, q);
    const Eigen::Vector3d step = so3::log(R_prev.transpose() * R);
    for (int k = 0; k < 200; ++k, t += 0.01) {
      const double tau = k * 0.01;
      const Eigen::Matrix3d Rt = R * so3::exp(-step * std::exp(-8.0 * tau) * std::cos(2 * M_PI * 5 * tau));
      const ros::Time stamp(t);
      geometry_msgs::PoseStamped tip, base;
      tip.header.stamp = base.header.stamp = stamp;
      tip.header.frame_id = base.header.frame_id = "tracker";
      quat(Rb * Rt * so3::exp(Eigen::Vector3d(n01(rng), n01(rng), n01(rng)) * 0.3 * M_PI / 180), &tip.pose.orientation);
      quat(Rb * so3::exp(Eigen::Vector3d(n01(rng), n01(rng), n01(rng)) * 0.3 * M_PI / 180), &base.pose.orientation);
      bag.write(prefix + "tracker/tip_pose", stamp, tip);
      bag.write(prefix + "tracker/base_pose", stamp, base);
      if (with_jets) {
        hydrojet_control::JetState js;
        js.header.stamp = stamp;
        js.flow.resize(3);
        js.force.resize(3);
        js.flow_valid.resize(3);
        for (int i = 0; i < 3; ++i) {
          js.flow[i] = actuation::flow_from_force(q[i], truth.nozzle) + 5e-8 * n01(rng);
          js.force[i] = actuation::force_from_flow(js.flow[i], truth.nozzle);
          js.flow_valid[i] = true;
        }
        bag.write(prefix + "jets/state", stamp, js);
      }
    }
    R_prev = R;
  }
  bag.close();
}

TEST(CalibrateCli, FitsARosbagOfTheDriversTopics) {
  const config::Scene truth = config::parse_scene(kTruthScene);
  const std::string bag = tmp("data.bag"), out = tmp("bagfit.yaml"), samples = tmp("bag_samples.csv");
  write_bag(bag, truth, 30, "/hydrojet/");  // namespaced topics match by suffix
  const CliRun r =
      run("--scene " + scene("hydrojet_0deg") + " --data " + bag + " --samples-out " + samples + " --out " + out);
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  EXPECT_NE(r.out.find("6000 paired points (0 skipped)"), std::string::npos) << r.out;
  const std::string json = r.last_line();
  EXPECT_EQ(number_field(json, "samples"), 30);  // one per hold
  // Averaged samples: the residual is far below the raw 0.3°/axis noise.
  EXPECT_LT(number_field(json, "rms_rad"), 0.2 * M_PI / 180);
  const std::string p = object_field(json, "parameters"), s = object_field(json, "std");
  for (int i = 0; i < 7; ++i) {
    SCOPED_TRACE(kNames[i]);
    EXPECT_LE(std::abs(number_field(p, kNames[i]) - kTruth[i]), 4 * number_field(s, kNames[i]));
  }
  EXPECT_NO_THROW(config::load_scene(out));
  // --samples-out wrote the extracted samples as CSV the tool reads back.
  std::ifstream f(samples);
  std::string header;
  std::getline(f, header);
  EXPECT_EQ(header, "q1,q2,q3,qw,qx,qy,qz");

  const std::string nojets = tmp("nojets.bag");
  write_bag(nojets, truth, 3, "/", false);
  const CliRun bad = run("--scene " + scene("hydrojet_0deg") + " --data " + nojets + " --out " + out);
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.err.find("no hydrojet_control/JetState messages on a topic 'jets/state'"), std::string::npos)
      << bad.err;
  // A bag holds three jets' flows: a robot described by its actuators gives its data as CSV.
  const CliRun other = run("--scene " + scene("two_segment_thrusters") + " --data " + bag + " --out " + out);
  EXPECT_EQ(other.status, 2);
  EXPECT_NE(other.err.find("this scene has no jets section"), std::string::npos) << other.err;
}

}  // namespace

// Bags recorded before the per-actuator arrays (JetState with float64[3] flow, force, valve_command
// and bool[3] flow_valid: another md5, so instantiate() refuses it) are still read, from their bytes;
// a current JetState of three jets as well, and one with another jet count is skipped.
TEST(BagReader, ReadsJetStatesRecordedWithTheThreeJetArrays) {
  namespace ser = ros::serialization;
  const std::string path = tmp("old_layout.bag");
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    for (int k = 1; k <= 3; ++k) {
      const ros::Time stamp(100.0 + k);
      std::vector<uint8_t> buf(4 + 8 + 4 + 9 * 8 + 3);
      ser::OStream o(buf.data(), static_cast<uint32_t>(buf.size()));
      std_msgs::Header h;
      h.stamp = stamp;
      ser::serialize(o, h);
      for (int i = 0; i < 9; ++i) ser::serialize(o, (i < 3 ? 1e-6 * k * (i + 1) : 0.5));
      for (int i = 0; i < 3; ++i) ser::serialize(o, static_cast<uint8_t>(k != 2 || i != 1));
      topic_tools::ShapeShifter ss;
      ss.morph("0123456789abcdef0123456789abcdef", "hydrojet_control/JetState",
               "Header header\nfloat64[3] flow\nfloat64[3] force\nfloat64[3] valve_command\nbool[3] flow_valid\n", "");
      ser::IStream in(buf.data(), static_cast<uint32_t>(buf.size()));
      ss.read(in);
      bag.write("jets/state", stamp, ss);
    }
    hydrojet_control::JetState now, four;
    now.header.stamp = ros::Time(110.0);
    now.flow = {2e-6, 3e-6, 4e-6};
    now.force = now.valve_command = {0.0, 0.0, 0.0};
    now.flow_valid = {true, true, true};
    // Another topic (matched by suffix): rosbag keeps one connection, so one md5, per topic.
    bag.write("/rig/jets/state", now.header.stamp, now);
    four = now;
    four.header.stamp = ros::Time(111.0);
    four.flow.push_back(1e-6);
    four.flow_valid.push_back(true);
    bag.write("/rig/jets/state", four.header.stamp, four);
    geometry_msgs::PoseStamped p;
    p.header.stamp = ros::Time(100.0);
    p.pose.orientation.w = 1.0;
    bag.write("tracker/tip_pose", p.header.stamp, p);
    bag.write("tracker/base_pose", p.header.stamp, p);
  }
  const calibration::BagRecords r = calibration::read_bag(path, calibration::BagTopics());
  ASSERT_EQ(r.jets.size(), 4u);
  for (int k = 1; k <= 3; ++k) {
    EXPECT_DOUBLE_EQ(r.jets[k - 1].t, 100.0 + k);
    EXPECT_EQ(r.jets[k - 1].flow, Eigen::Vector3d(1e-6 * k, 2e-6 * k, 3e-6 * k));
    EXPECT_EQ(r.jets[k - 1].valid, k != 2);
  }
  EXPECT_EQ(r.jets[3].flow, Eigen::Vector3d(2e-6, 3e-6, 4e-6));
  EXPECT_TRUE(r.jets[3].valid);
}
