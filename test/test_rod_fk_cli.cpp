// rod_fk as a user runs it: exit codes, one JSON line per solve, and errors that name the input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>
#include <cstdio>
#include <fstream>
#include <string>
#include <Eigen/Dense>

#include "cli_helpers.h"

namespace {

using hydrojet::test::array_field;
using hydrojet::test::CliRun;

CliRun run(const std::string& args, const std::string& stdin_text = "") {
  return hydrojet::test::run_cli(HYDROJET_ROD_FK, args, stdin_text);
}

std::string scene(const std::string& name) {
  return std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/" + name + ".yaml";
}

std::string write_scene(const std::string& text) {
  const std::string path = ::testing::TempDir() + "rod_fk_scene.yaml";
  std::ofstream(path) << text;
  return path;
}

const char* kGoodScene = R"(
rod: {length: 0.09, bending_stiffness: [6.01e-4, 6.01e-4], torsional_stiffness: 2.23e-4}
tip: {mass: 0.0}
gravity: [0, 0, 0]
)";

}  // namespace

TEST(RodFkCli, SolvesAndPrintsContractFields) {
  const CliRun r = run("--scene " + scene("hydrojet_0deg") + " --force 0.1 0.05 0 --compliance --shape 4");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1);
  for (const char* key :
       {"\"converged\": true", "\"iterations\"", "\"residual\"", "\"tip_position\"", "\"tip_quaternion_wxyz\"",
        "\"solve_time_us\"", "\"compliance\": [[", "\"stability_margin\"", "\"stability_eig_min\"", "\"shape\": [["})
    EXPECT_NE(r.out.find(key), std::string::npos) << key << "\n" << r.out;
  const auto q = array_field(r.out, "tip_quaternion_wxyz");
  ASSERT_EQ(q.size(), 4u);
  EXPECT_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0, 1e-12);
  EXPECT_GE(q[0], 0.0);
}

// --jets goes through the scene's jet map (eq. 24): the same pose as the equivalent --force.
TEST(RodFkCli, JetsMatchEquivalentForce) {
  const double p3 = M_PI / 3, da = 0.12, db = 0.06, dg = -0.08, q1 = 0.1, q2 = 0.05, q3 = 0.2;
  const double fx = std::sin(p3 - db) * q1 + std::sin(da) * q2 - std::sin(p3 - dg) * q3;
  const double fy = std::cos(p3 - db) * q1 - std::cos(da) * q2 + std::cos(p3 - dg) * q3;
  const CliRun a = run("--scene " + scene("hydrojet_0deg") + " --jets 0.1 0.05 0.2");
  char buf[128];
  std::snprintf(buf, sizeof(buf), " --force %.17g %.17g 0", fx, fy);
  const CliRun b = run("--scene " + scene("hydrojet_0deg") + buf);
  ASSERT_EQ(a.status, 0) << a.err;
  ASSERT_EQ(b.status, 0) << b.err;
  const auto pa = array_field(a.out, "tip_position"), pb = array_field(b.out, "tip_position");
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(pa[i], pb[i], 1e-12);
  EXPECT_EQ(run("--scene " + scene("hydrojet_0deg") + " --jets 0.1 -0.05 0").status, 2);
  EXPECT_EQ(run("--scene " + scene("hydrojet_0deg") + " --jets 0.1 0.05 0 --force 0 0 0").status, 2);
}

// --integrator takes the SUNDIALS methods too and reports the name; they agree with rk8.
TEST(RodFkCli, CvodeIntegratorsByName) {
  const CliRun a = run("--scene " + scene("hydrojet_30deg") + " --force 0.1 0.05 0 --compliance");
  ASSERT_EQ(a.status, 0) << a.err;
  for (const char* name : {"cvode-adams", "cvode-bdf", "dopri5"}) {
    const CliRun b =
        run("--scene " + scene("hydrojet_30deg") + " --force 0.1 0.05 0 --compliance --tol 1e-10 --integrator " + name);
    ASSERT_EQ(b.status, 0) << name << ": " << b.err;
    EXPECT_NE(b.out.find(std::string("\"integrator\": \"") + name + "\""), std::string::npos) << b.out;
    const auto pa = array_field(a.out, "tip_position"), pb = array_field(b.out, "tip_position");
    ASSERT_EQ(pb.size(), 3u);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(pa[i], pb[i], 1e-7) << name;
  }
}

// A straight weightless rod with a small lateral force: linear beam tip deflection FL³/(3EI).
TEST(RodFkCli, BatchSolvesEachLineInOrder) {
  const std::string sc = write_scene(kGoodScene);
  const CliRun r = run("--scene " + sc + " --batch -", "1e-5 0 0 0 0 0\n# comment\n\n0, 1e-5, 0, 0, 0, 0\n");
  ASSERT_EQ(r.status, 0) << r.err;
  const size_t nl = r.out.find('\n');
  const std::string first = r.out.substr(0, nl), second = r.out.substr(nl + 1);
  const double delta = 1e-5 * 0.09 * 0.09 * 0.09 / (3 * 6.01e-4);
  EXPECT_NEAR(array_field(first, "tip_position")[0], delta, 1e-4 * delta);
  EXPECT_NEAR(array_field(second, "tip_position")[1], delta, 1e-4 * delta);
}

TEST(RodFkCli, BadInputExitsTwoAndNamesIt) {
  struct Case {
    std::string args, stdin_text, expect;
  };
  const std::string good = write_scene(kGoodScene);
  const std::vector<Case> cases = {
      {"--scene " + good + " --force nan 0 0", "", "--force"},
      {"--scene " + good + " --force 0.1 0", "", "--force"},
      {"--scene " + good + " --integrator euler", "", "--integrator"},
      {"--scene " + good + " --steps 0", "", "--steps"},
      {"--scene " + good + " --batch -", "0 0 0 0 0\n", "--batch line 1"},
      {"--scene " + good + " --batch -", "0 0 0 0 0 0\n0 0 inf 0 0 0\n", "--batch line 2"},
      {"--scene " + good + " --frobnicate", "", "--frobnicate"},
      {"--force 0 0 0", "", "--scene"},
      {"--scene /nonexistent.yaml", "", "cannot read"},
  };
  for (const Case& c : cases) {
    const CliRun r = run(c.args, c.stdin_text);
    EXPECT_EQ(r.status, 2) << c.args;
    EXPECT_TRUE(r.out.empty()) << c.args << " printed " << r.out;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << " -> " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  // Scene errors name the key.
  const std::vector<std::pair<std::string, std::string>> scenes = {
      {"rod: {length: 0.09, bending_stiffness: [-6.01e-4, 6.01e-4], torsional_stiffness: 2.23e-4}\ntip: {mass: "
       "0}\ngravity: [0,0,0]\n",
       "rod.bending_stiffness[0]"},
      {"rod: {bending_stiffness: [6.01e-4, 6.01e-4], torsional_stiffness: 2.23e-4}\ntip: {mass: 0}\ngravity: [0,0,0]\n",
       "rod.length"},
      {std::string(kGoodScene) + "solver: {colour: 1}\n", "solver.colour"},
      {"rod: {length: 0.09, bending_stiffness: [6.01e-4, 6.01e-4], torsional_stiffness: 2.23e-4, shear: 1}\ntip: "
       "{mass: 0}\ngravity: [0,0,0]\n",
       "rod.shear"},
  };
  for (const auto& s : scenes) {
    const CliRun r = run("--scene " + write_scene(s.first));
    EXPECT_EQ(r.status, 2);
    EXPECT_TRUE(r.out.empty());
    EXPECT_NE(r.err.find(s.second), std::string::npos) << r.err;
  }
}

// Exit 1 with "converged": false when a solve does not converge: one Newton step and no load
// continuation cannot finish a large bend from the cold start.
TEST(RodFkCli, NonConvergenceExitsOne) {
  const std::string sc =
      write_scene(std::string(kGoodScene) + "solver: {max_iterations: 1, max_continuation_steps: 0}\n");
  const CliRun r = run("--scene " + sc + " --batch -", "0 0 0 0 0 0\n0.2 0 0 0 0 0\n");
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  const size_t nl = r.out.find('\n');
  EXPECT_NE(r.out.substr(0, nl).find("\"converged\": true"), std::string::npos) << r.out;
  EXPECT_NE(r.out.substr(nl + 1).find("\"converged\": false"), std::string::npos) << r.out;
  EXPECT_NE(r.out.substr(nl + 1).find("\"message\""), std::string::npos) << r.out;
}

// The JSON carries the solver's report: fold_crossings always, warning when the solver sets one. A
// compressive follower force of 10 P_cr (P_cr = π² EI / (4 L²), the clamped-free Euler load) leaves
// a straight rod only its straight, unstable equilibrium (Beck's column has no bent ones): converged,
// with the warning; the HydroJet's moderate solve crosses no fold and carries no warning.
TEST(RodFkCli, CarriesFoldCrossingsAndTheWarning) {
  const double EI = 6.01e-4, L = 0.09;
  const double Pcr = M_PI * M_PI * EI / (4 * L * L);
  char text[256];
  std::snprintf(text, sizeof(text),
                "rod: {length: %g, bending_stiffness: [%g, %g], torsional_stiffness: 2.23e-4}\n"
                "tip: {mass: 0.0}\ngravity: [0, 0, 0]\n",
                L, EI, 1.2 * EI);
  const CliRun column = run("--scene " + write_scene(text) + " --compliance --force 0 0 " + std::to_string(-10 * Pcr));
  ASSERT_EQ(column.status, 0) << column.err;
  EXPECT_EQ(hydrojet::test::number_field(column.out, "fold_crossings"), 0.0) << column.out;
  EXPECT_NE(column.out.find("\"warning\": \"unstable equilibrium"), std::string::npos) << column.out;
  EXPECT_LE(hydrojet::test::number_field(column.out, "stability_eig_min"), 0.0) << column.out;
  const CliRun moderate = run("--scene " + scene("hydrojet_0deg") + " --force 0.1 0.05 0");
  ASSERT_EQ(moderate.status, 0) << moderate.err;
  EXPECT_EQ(hydrojet::test::number_field(moderate.out, "fold_crossings"), 0.0) << moderate.out;
  EXPECT_EQ(moderate.out.find("\"warning\""), std::string::npos) << moderate.out;
}

namespace {
/// The numbers of a nested JSON array field `"key": [[a, b], [c, d]]`, row by row.
std::vector<std::vector<double>> rows_field(const std::string& json, const std::string& key) {
  std::vector<std::vector<double>> rows;
  size_t i = json.find("\"" + key + "\": [[");
  if (i == std::string::npos) return rows;
  i = json.find("[[", i) + 1;
  const size_t end = json.find("]]", i);
  while (i < end) {
    const size_t a = json.find('[', i), b = json.find(']', a);
    rows.push_back(hydrojet::test::array_field("\"r\": " + json.substr(a, b - a + 1), "r"));
    i = b + 1;
  }
  return rows;
}

struct Pose {
  Eigen::Vector3d p;
  Eigen::Matrix3d R;
};
Pose pose_of(const std::string& json) {
  const auto p = array_field(json, "tip_position"), q = array_field(json, "tip_quaternion_wxyz");
  if (p.size() != 3 || q.size() != 4) {
    ADD_FAILURE() << "no tip pose in: '" << json << "'";
    return {Eigen::Vector3d::Constant(NAN), Eigen::Matrix3d::Constant(NAN)};
  }
  return {Eigen::Vector3d(p[0], p[1], p[2]), Eigen::Quaterniond(q[0], q[1], q[2], q[3]).toRotationMatrix()};
}

const char* kTipActuators = R"(
rod: {length: 0.09, bending_stiffness: [6.01e-4, 5.0e-4], torsional_stiffness: 2.23e-4, precurvature: [0.5, 0.0, 0.0]}
tip: {mass: 0.003}
gravity: [0, -9.81, 0]
actuators:
  - {name: a, direction: [1, 0, 0], position: [0, 0.004, 0.002], max_force: 0.2}
  - {name: b, direction: [0, 0.6, 0.8], max_force: 0.2, min_force: -0.2}
  - {name: c, direction: [0, -1, 0], position: [0.003, 0, 0], max_force: 0.2}
)";
}  // namespace

// --actuators: the inputs go through the scene's actuators (the equivalent tip wrench gives the same
// pose), and actuation_jacobian matches central differences of full solves (columns: body twist
// (v, ω) = (Rᵀ δp, (Rᵀ δR)^∨) per unit input).
/// rod_fk's actuation_jacobian at inputs q on scene file sc against central differences of full
/// solves through the CLI (columns: body twist (v, ω) = (Rᵀ δp, (Rᵀ δR)^∨) per unit input). Returns
/// the JSON line of the solve at q.
std::string expect_jacobian_matches_central_differences(const std::string& sc, const std::vector<double>& q) {
  const double h = 1e-5;
  const int N = static_cast<int>(q.size());
  auto args = [&](int k, double dq) {
    std::string a = " --actuators";
    for (int i = 0; i < N; ++i) {
      char v[32];
      std::snprintf(v, sizeof(v), " %.17g", q[i] + (i == k ? dq : 0.0));
      a += v;
    }
    return "--scene " + sc + a;
  };
  const CliRun r = run(args(-1, 0.0) + " --compliance");
  EXPECT_EQ(r.status, 0) << r.err;
  const auto J = rows_field(r.out, "actuation_jacobian");
  EXPECT_EQ(J.size(), 6u) << r.out;
  if (J.size() != 6u || static_cast<int>(J[0].size()) != N) {
    ADD_FAILURE() << "actuation_jacobian is not 6 x " << N << ": " << r.out;
    return r.out;
  }
  const Pose base = pose_of(r.out);
  for (int k = 0; k < N; ++k) {
    const Pose plus = pose_of(run(args(k, h)).out), minus = pose_of(run(args(k, -h)).out);
    Eigen::Matrix<double, 6, 1> fd;
    fd.head<3>() = base.R.transpose() * (plus.p - minus.p) / (2 * h);
    const Eigen::Matrix3d dR = base.R.transpose() * (plus.R - minus.R) / (2 * h);  // ≈ ω^
    fd.tail<3>() << dR(2, 1), dR(0, 2), dR(1, 0);
    Eigen::Matrix<double, 6, 1> col;
    for (int i = 0; i < 6; ++i) col[i] = J[i][k];
    EXPECT_LT((col - fd).norm(), 1e-5 * col.norm()) << "input " << k << "\n"
                                                    << col.transpose() << "\n"
                                                    << fd.transpose();
  }
  return r.out;
}

TEST(RodFkCli, ActuatorsAndTheirJacobian) {
  const std::string sc = write_scene(kTipActuators);
  const double q[3] = {0.05, -0.04, 0.02};
  const std::string out = expect_jacobian_matches_central_differences(sc, {q[0], q[1], q[2]});
  // The equivalent tip wrench: Σ q_i (d_i, p_i × d_i).
  const Eigen::Vector3d d[3] = {{1, 0, 0}, {0, 0.6, 0.8}, {0, -1, 0}},
                        p[3] = {{0, 0.004, 0.002}, {0, 0, 0}, {0.003, 0, 0}};
  Eigen::Vector3d f = Eigen::Vector3d::Zero(), m = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i) f += q[i] * d[i], m += q[i] * p[i].cross(d[i]);
  char buf[256];
  std::snprintf(buf, sizeof(buf), " --force %.17g %.17g %.17g --moment %.17g %.17g %.17g", f.x(), f.y(), f.z(), m.x(),
                m.y(), m.z());
  const Pose base = pose_of(out), same = pose_of(run("--scene " + sc + buf).out);
  EXPECT_LT((base.p - same.p).norm(), 1e-12);
  // Wrong count and out-of-bounds inputs are named.
  const CliRun few = run("--scene " + sc + " --actuators 0.1 0.1");
  EXPECT_EQ(few.status, 2);
  EXPECT_NE(few.err.find("--actuators: the scene has 3 actuator(s), got 2"), std::string::npos) << few.err;
  const CliRun big = run("--scene " + sc + " --actuators 0.1 0.1 0.5");
  EXPECT_EQ(big.status, 2);
  EXPECT_NE(big.err.find("input 3 (c)"), std::string::npos) << big.err;
}

// A general scene (the second robot: two segments, a point mass, thrusters mid-body and at the tip):
// rod_fk solves it with the general solver, J_q from its sensitivities matches central differences,
// and --shape spans all segments (base at the origin, tip at tip_position, arc length L).
TEST(RodFkCli, GeneralSceneJacobianAndShape) {
  const std::string sc = scene("two_segment_thrusters");
  expect_jacobian_matches_central_differences(sc, {0.05, 0.01, 0.08, 0.02, 0.04, 0.03});
  const CliRun r = run("--scene " + sc + " --actuators 0.05 0.01 0.08 0.02 0.04 0.03 --shape 90");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto pts = rows_field(r.out, "shape");
  ASSERT_EQ(pts.size(), 91u) << r.out;
  const auto tip = array_field(r.out, "tip_position");
  double arc = 0.0;
  for (size_t i = 1; i < pts.size(); ++i)
    arc += std::sqrt(std::pow(pts[i][0] - pts[i - 1][0], 2) + std::pow(pts[i][1] - pts[i - 1][1], 2) +
                     std::pow(pts[i][2] - pts[i - 1][2], 2));
  EXPECT_NEAR(arc, 0.09, 1e-5);  // chords of 1 mm arcs: short by ~L κ² h²/24
  EXPECT_LT(std::abs(pts[0][0]) + std::abs(pts[0][1]) + std::abs(pts[0][2]), 1e-12);
  // The shape is integrated with extra cuts at its points: the same tip within the solver's
  // accuracy contract (1e-6 m).
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(pts[90][k], tip[k], 1e-6);
  // The tip moved away from its unloaded place (the thrusters act).
  const CliRun rest = run("--scene " + sc + " --actuators 0 0 0 0 0 0");
  ASSERT_EQ(rest.status, 0) << rest.err;
  const auto tip0 = array_field(rest.out, "tip_position");
  EXPECT_GT(std::hypot(tip[0] - tip0[0], tip[1] - tip0[1]), 1e-3);
}
