// Operator control's core pieces, each against an independent truth: paths (slerp
// waypoints vs the closed form, raster rows and speed, the spiral bit for bit, the file loaders), the
// reachable set (contains() vs the sweep samples, clip() vs a brute-force nearest point of the
// boundary, the §7 spiral inside at 0° and 30°) and the look-at solver (the aimed line through the
// point on a second, independent model solve; refusals).
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <stdexcept>

#include "hydrojet_control/actuation/allocation.h"
#include "hydrojet_control/control/look_at.h"
#include "hydrojet_control/control/path.h"
#include "hydrojet_control/control/reachable_set.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "test_helpers.h"

using namespace hydrojet;
using control::Vec3;

namespace {

double angle(const Vec3& a, const Vec3& b) { return control::geodesic_error(a, b); }

/// The message of the std::invalid_argument that f throws ("" if none).
template <class F>
std::string error_of(F f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

/// Whether `msg` contains `part` (the message shown when not).
const auto has = [](const std::string& msg, const std::string& part) {
  return msg.find(part) != std::string::npos ? ::testing::AssertionSuccess()
                                             : ::testing::AssertionFailure() << "'" << msg << "'";
};

std::string write_file(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

control::RobotModel model(const std::string& scene) {
  return config::make_controller_model(test::scene(scene), actuation::FlowRegulatorOptions());
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Paths
// ---------------------------------------------------------------------------------------------

TEST(Paths, SpiralThroughPathIsBitIdentical) {
  control::SpiralPath s;  // the §7.1 spiral of config/controller.yaml
  const auto p = control::make_spiral(s);
  EXPECT_STREQ(p->type(), "spiral");
  EXPECT_EQ(p->duration(), s.duration);
  for (double t = -3.0; t <= 650.0; t += 0.37) {
    const Vec3 a = p->direction_at(t), b = s.direction_at(t);
    for (int k = 0; k < 3; ++k) ASSERT_EQ(a[k], b[k]) << "t = " << t;
  }
}

TEST(Paths, WaypointsFollowTheGreatCircleAtConstantRate) {
  const Vec3 a = control::direction(0.3, 0.2), b = control::direction(0.9, 2.0), c = control::direction(0.1, -1.0);
  const auto p = control::make_waypoints({{1.0, 2.0 * a}, {5.0, b}, {7.0, 0.5 * c}});  // lengths normalised
  EXPECT_STREQ(p->type(), "waypoints");
  EXPECT_EQ(p->duration(), 7.0);
  const Vec3 normal = a.cross(b).normalized();
  for (double t = 1.0; t <= 5.0; t += 0.05) {
    const Vec3 d = p->direction_at(t);
    EXPECT_NEAR(d.norm(), 1.0, 1e-14);
    EXPECT_NEAR(d.dot(normal), 0.0, 1e-14) << "on the great circle through a and b";
    EXPECT_NEAR(angle(a, d), (t - 1.0) / 4.0 * angle(a, b), 1e-12) << "angle proportional to time";
    EXPECT_NEAR(angle(d, b), (5.0 - t) / 4.0 * angle(a, b), 1e-12) << "between a and b";
  }
  EXPECT_NEAR(angle(p->direction_at(6.0), b), 0.5 * angle(b, c), 1e-12);
  EXPECT_NEAR(angle(p->direction_at(-1.0), a), 0.0, 1e-15) << "holds the first before its time";
  EXPECT_NEAR(angle(p->direction_at(0.5), a), 0.0, 1e-15);
  EXPECT_NEAR(angle(p->direction_at(100.0), c), 0.0, 1e-15) << "holds the last after the end";
}

TEST(Paths, WaypointErrorsNameTheWaypoint) {
  using W = control::Waypoint;
  const Vec3 z = Vec3::UnitZ(), x = Vec3::UnitX();
  const auto err = [](const std::vector<W>& w) { return error_of([&] { control::make_waypoints(w); }); };
  EXPECT_EQ(err({}).rfind("waypoints:", 0), 0u) << err({});
  EXPECT_EQ(err({{-1.0, z}}).rfind("waypoints[0].t:", 0), 0u);
  EXPECT_EQ(err({{0.0, z}, {1.0, x}, {1.0, z}}).rfind("waypoints[2].t:", 0), 0u);
  EXPECT_EQ(err({{0.0, z}, {NAN, x}}).rfind("waypoints[1].t:", 0), 0u);
  EXPECT_EQ(err({{0.0, z}, {1.0, Vec3::Zero()}}).rfind("waypoints[1].direction:", 0), 0u);
  EXPECT_EQ(err({{0.0, Vec3(NAN, 0, 1)}}).rfind("waypoints[0].direction:", 0), 0u);
  EXPECT_EQ(err({{0.0, z}, {1.0, -z}}).rfind("waypoints[1].direction: opposite", 0), 0u);
  EXPECT_EQ(err({{0.0, z}, {1.0, x}}), "");
}

TEST(Paths, RasterRowsHaveConstantThetaAndTheSpeed) {
  control::RasterOptions r;
  r.theta_min = 0.2, r.theta_max = 0.6, r.rows = 3, r.phi_start = -1.0, r.phi_end = 1.0, r.speed = 0.05;
  const auto p = control::make_raster(r);
  EXPECT_STREQ(p->type(), "raster");
  // Closed form: rows of 2 sin ϑ_i of arc, two meridian steps of 0.2 rad, all at 0.05 rad/s.
  const double row[3] = {2.0 * std::sin(0.2) / 0.05, 2.0 * std::sin(0.4) / 0.05, 2.0 * std::sin(0.6) / 0.05};
  const double step = 0.2 / 0.05;
  ASSERT_NEAR(p->duration(), row[0] + row[1] + row[2] + 2.0 * step, 1e-9);
  const double row_start[3] = {0.0, row[0] + step, row[0] + row[1] + 2.0 * step};
  for (int i = 0; i < 3; ++i) {
    const double theta = 0.2 + 0.2 * i;
    for (double s = 0.0; s <= 1.0; s += 0.01) {
      const Vec3 d = p->direction_at(row_start[i] + s * row[i]);
      EXPECT_NEAR(control::bend_angle(d), theta, 1e-12) << "row " << i;
      const double phi = i % 2 == 0 ? -1.0 + 2.0 * s : 1.0 - 2.0 * s;  // boustrophedon
      EXPECT_NEAR(control::azimuth(d), phi, 1e-9) << "row " << i;
    }
  }
  const double dt = 1e-3;  // speed along the whole path, corners included
  for (double t = 0.0; t + dt <= p->duration(); t += 0.25)
    EXPECT_NEAR(angle(p->direction_at(t), p->direction_at(t + dt)) / dt, 0.05, 1e-6) << "t = " << t;
  EXPECT_NEAR(angle(p->direction_at(1e9), control::direction(0.6, 1.0)), 0.0, 1e-15);
}

TEST(Paths, RasterOptionsAreValidated) {
  const auto err = [](auto change) {
    control::RasterOptions r;
    change(r);
    return r.validate();
  };
  EXPECT_EQ(err([](control::RasterOptions&) {}), "");
  EXPECT_EQ(err([](control::RasterOptions& r) { r.rows = 0; }).rfind("rows:", 0), 0u);
  EXPECT_EQ(err([](control::RasterOptions& r) { r.speed = 0.0; }).rfind("speed:", 0), 0u);
  EXPECT_EQ(err([](control::RasterOptions& r) { r.theta_max = 0.1; }).rfind("theta_max:", 0), 0u);
  EXPECT_EQ(err([](control::RasterOptions& r) { r.theta_min = -0.1; }).rfind("theta_min:", 0), 0u);
  EXPECT_EQ(err([](control::RasterOptions& r) { r.phi_end = r.phi_start; }).rfind("phi_end:", 0), 0u);
  control::RasterOptions bad;
  bad.rows = 0;
  EXPECT_EQ(error_of([&] { control::make_raster(bad); }).rfind("rows:", 0), 0u);
}

TEST(PathFiles, CsvAndYamlGiveTheTableLinearOnTheSphere) {
  const std::string csv = write_file("path_good.csv",
                                     "t, theta, phi\n"
                                     "# a comment\n"
                                     "0, 0.1, 0.0\n"
                                     "2.0 0.5 1.0\n"
                                     "\n"
                                     "4,0.5,2.0   # the end\n");
  const std::string yaml = write_file("path_good.yaml",
                                      "- [0, 0.1, 0.0]\n"
                                      "- {t: 2.0, theta: 0.5, phi: 1.0}\n"
                                      "- [4, 0.5, 2.0]\n");
  for (const std::string& f : {csv, yaml}) {
    const auto p = control::load_path_file(f);
    EXPECT_STREQ(p->type(), "file");
    EXPECT_EQ(p->duration(), 4.0);
    const Vec3 d0 = control::direction(0.1, 0.0), d1 = control::direction(0.5, 1.0), d2 = control::direction(0.5, 2.0);
    EXPECT_NEAR(angle(p->direction_at(0.0), d0), 0.0, 1e-15) << f;
    EXPECT_NEAR(angle(p->direction_at(2.0), d1), 0.0, 1e-15) << f;
    EXPECT_NEAR(angle(p->direction_at(4.0), d2), 0.0, 1e-15) << f;
    EXPECT_NEAR(angle(p->direction_at(0.5), d0), 0.25 * angle(d0, d1), 1e-12) << f;
    EXPECT_NEAR(angle(p->direction_at(3.0), d2), 0.5 * angle(d1, d2), 1e-12) << f;
  }
}

TEST(PathFiles, BadFilesNameTheFileAndLine) {
  const auto err = [](const std::string& name, const std::string& text) {
    const std::string f = write_file(name, text);
    return error_of([&] { control::load_path_file(f); });
  };
  EXPECT_TRUE(has(err("bad_word.csv", "t,theta,phi\n0,0,0\n1,0.2,0\n2,zero,0\n"), "bad_word.csv:4: expected three"));
  EXPECT_TRUE(has(err("bad_count.csv", "0 0 0\n1 0.2\n"), "bad_count.csv:2: expected three"));
  EXPECT_TRUE(has(err("bad_time.csv", "0,0,0\n1,0.2,0\n1,0.3,0\n"), "bad_time.csv:3: t: must be greater"));
  EXPECT_TRUE(has(err("bad_theta.csv", "0,0,0\n1,nan,0\n"), "bad_theta.csv:2: expected three"));
  EXPECT_TRUE(has(err("bad_theta.yaml", "- [0, 0, 0]\n- [1, .inf, 0]\n"), "bad_theta.yaml:2: entry 1: theta and phi"));
  EXPECT_TRUE(has(err("empty.csv", "t,theta,phi\n"), "empty.csv: no rows"));
  EXPECT_TRUE(has(err("bad_key.yaml", "- [0, 0, 0]\n- {t: 1, theta: 0.2, psi: 0}\n"),
                  "bad_key.yaml:2: entry 1: unknown key 'psi'"));
  EXPECT_TRUE(has(err("missing.yaml", "- [0, 0, 0]\n- [1, 0.1, 0]\n- {t: 2, theta: 0.2}\n"),
                  "missing.yaml:3: entry 2: phi: expected a number"));
  EXPECT_TRUE(has(err("short.yaml", "- [0, 0, 0]\n- [1, 0.1]\n"), "short.yaml:2: entry 1: expected [t, theta, phi]"));
  EXPECT_TRUE(has(err("time.yaml", "- [0, 0, 0]\n- [0, 0.1, 0]\n"), "time.yaml:2: entry 1: t: must be greater"));
  EXPECT_TRUE(has(err("map.yaml", "t: 1\n"), "map.yaml: expected a sequence"));
  EXPECT_TRUE(has(err("syntax.yaml", "- [0, 0, 0]\n- [1, 0.1, 0\n"), "syntax.yaml:"));
  EXPECT_TRUE(has(err("path.txt", "0 0 0\n"), "path.txt: unknown path file type"));
  EXPECT_TRUE(
      has(error_of([] { control::load_path_file("/nonexistent/p.csv"); }), "/nonexistent/p.csv: cannot be read"));
}

// ---------------------------------------------------------------------------------------------
// Hostile input: directions normalised without overflow, goals checked field by field, bounds
// ---------------------------------------------------------------------------------------------

TEST(Directions, UnitDirectionSurvivesOverflowAndUnderflow) {
  const double big = std::numeric_limits<double>::max();
  const struct {
    Vec3 v, unit;
  } cases[] = {
      {Vec3(1e308, 1e308, 1e308), Vec3(1, 1, 1) / std::sqrt(3.0)},  // the plain norm is inf
      {Vec3(1.5e154, 0, 1.5e154), Vec3(1, 0, 1) / std::sqrt(2.0)},  // the plain norm's square is inf
      {Vec3(big, -big, 0), Vec3(1, -1, 0) / std::sqrt(2.0)},
      {Vec3(1e-320, 0, 0), Vec3(1, 0, 0)},  // a denormal: the plain norm is 0
      {Vec3(0, 3, 4), Vec3(0, 0.6, 0.8)},
  };
  for (const auto& c : cases) {
    Vec3 u;
    ASSERT_TRUE(control::unit_direction(c.v, &u)) << c.v.transpose();
    EXPECT_LT((u - c.unit).norm(), 1e-15) << c.v.transpose();
  }
  Vec3 untouched(7, 7, 7);
  for (const Vec3& v : {Vec3(0, 0, 0), Vec3(NAN, 0, 1), Vec3(INFINITY, 0, 0), Vec3(-INFINITY, 1, 1)}) {
    EXPECT_FALSE(control::unit_direction(v, &untouched)) << v.transpose();
    EXPECT_EQ(untouched, Vec3(7, 7, 7));
  }
}

namespace {

/// A goal of `type` with every field finite and in range (a 20 s spiral, a small raster, two waypoints).
control::PathGoal goal(const std::string& type) {
  control::PathGoal g;
  g.type = type;
  g.spiral = {0.0, 0.0, 0.5, 3.0, 20.0};
  g.raster = {0.1, 0.4, 3, -0.5, 0.5, 0.1};
  g.times = {0.0, 5.0};
  g.directions = {Vec3::UnitZ(), control::direction(0.3, 1.0)};
  return g;
}

std::string goal_error(const control::PathGoal& g) {
  return error_of([&] { control::make_goal_path(g, control::SpiralPath()); });
}
}  // namespace

TEST(PathGoals, EveryFieldIsCheckedWhetherItsTypeUsesItOrNot) {
  for (const char* type : {"spiral", "raster", "waypoints"}) EXPECT_EQ(goal_error(goal(type)), "") << type;
  // The configured spiral (duration 0) still needs finite fields; so does every type.
  for (const char* type : {"spiral", "raster", "waypoints"}) {
    control::PathGoal g = goal(type);
    g.spiral.duration = 0.0;
    g.spiral.theta_start = NAN;
    EXPECT_TRUE(has(goal_error(g), "theta_start: must be finite")) << type;
    g = goal(type);
    g.raster.speed = INFINITY;
    EXPECT_TRUE(has(goal_error(g), "speed: must be finite")) << type;
    g = goal(type);
    g.directions[1] = Vec3(0, NAN, 1);
    EXPECT_TRUE(has(goal_error(g), "directions[1]: must be finite")) << type;
    g = goal(type);
    g.times[0] = -INFINITY;
    EXPECT_TRUE(has(goal_error(g), "times[0]: must be finite")) << type;
  }
  EXPECT_TRUE(has(goal_error(goal("lissajous")), "type: must be spiral, raster, waypoints or file"));
}

TEST(PathGoals, PathsThatNeverEndOrRaceAreRefused) {
  control::PathGoal g = goal("spiral");
  g.spiral.theta_end = 1e12;  // beyond [0, pi]
  EXPECT_TRUE(has(goal_error(g), "theta_end: must lie in [0, pi]"));
  g = goal("spiral");
  g.spiral.duration = 1e300;
  EXPECT_TRUE(has(goal_error(g), "duration: must lie in (0, 3600] s"));
  g = goal("spiral");
  g.spiral.phi_end = 1e6;  // 1e6 rad of azimuth in 20 s
  EXPECT_TRUE(has(goal_error(g), "faster than 2 rad/s"));
  g = goal("raster");
  g.raster.rows = 2147483647;
  EXPECT_TRUE(has(goal_error(g), "rows: must lie in [1, 100000]"));
  g = goal("raster");
  g.raster.speed = 1e-300;  // a raster that would last 1e300 s
  EXPECT_TRUE(has(goal_error(g), "speed:"));
  g = goal("raster");
  g.raster.phi_end = 1e300;
  EXPECT_TRUE(has(goal_error(g), "speed:"));
  g = goal("raster");
  g.raster.phi_start = NAN;
  EXPECT_TRUE(has(goal_error(g), "raster_phi_start: must be finite"));
  g = goal("waypoints");
  g.times = {0.0, 1e-6};  // 0.3 rad in a microsecond
  EXPECT_TRUE(has(goal_error(g), "waypoints[1].t:"));
  g = goal("waypoints");
  g.times = {0.0, 5000.0};
  EXPECT_TRUE(has(goal_error(g), "waypoints[1].t: must be at most 3600 s"));
  g = goal("waypoints");
  g.times.assign(100001, 0.0);
  g.directions.assign(100001, Vec3::UnitZ());
  EXPECT_TRUE(has(goal_error(g), "more than the limit of 100000"));
}

TEST(PathGoals, WaypointDirectionsAreNormalisedWithoutOverflow) {
  control::PathGoal g = goal("waypoints");
  g.directions = {Vec3(0, 0, 1e308), Vec3(1e308, 0, 1e308)};
  const auto p = control::make_goal_path(g, control::SpiralPath());
  for (double t : {0.0, 2.5, 5.0}) {
    EXPECT_NEAR(p->direction_at(t).norm(), 1.0, 1e-15) << t;
    EXPECT_NEAR(control::bend_angle(p->direction_at(t)), M_PI / 4 * t / 5.0, 1e-12) << t;
  }
  g.directions = {Vec3::UnitZ(), Vec3(0, 0, 0)};
  EXPECT_TRUE(has(goal_error(g), "waypoints[1].direction: must be finite and non-zero"));
}

TEST(PathFiles, OnlyBoundedRegularFilesAreRead) {
  // A FIFO without a writer: opened without blocking, refused (reading it would wait for ever).
  const std::string fifo = ::testing::TempDir() + "path_fifo.csv";
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  control::PathGoal g = goal("file");
  g.file = fifo;
  EXPECT_TRUE(has(goal_error(g), "path_fifo.csv: not a regular file"));
  ::unlink(fifo.c_str());
  // Larger than the limit: refused from its size, before any parsing.
  const std::string big = write_file("path_big.csv", "0 0 0\n1 0.1 0\n");
  control::PathLimits limits;
  limits.max_file_bytes = 8;
  EXPECT_TRUE(has(error_of([&] { control::load_path_file(big, limits); }), "more than the limit of 8"));
  // More rows than the limit.
  limits = control::PathLimits();
  limits.max_points = 2;
  const std::string rows = write_file("path_rows.csv", "0 0 0\n1 0.1 0\n2 0.2 0\n");
  EXPECT_TRUE(has(error_of([&] { control::load_path_file(rows, limits); }), "path_rows.csv:3: more than the limit"));
  const std::string yaml = write_file("path_rows.yaml", "- [0, 0, 0]\n- [1, 0.1, 0]\n- [2, 0.2, 0]\n");
  EXPECT_TRUE(has(error_of([&] { control::load_path_file(yaml, limits); }), "3 entries, more than the limit"));
}

// ---------------------------------------------------------------------------------------------
// Reachable set
// ---------------------------------------------------------------------------------------------

namespace {

/// Computed once per scene (the sweep takes a fraction of a second).
const control::ReachableSet& reachable(const std::string& scene) {
  static std::map<std::string, control::ReachableSet> sets;
  auto it = sets.find(scene);
  if (it == sets.end()) it = sets.emplace(scene, control::ReachableSet::compute(model(scene), {})).first;
  return it->second;
}

/// Polar coordinates about the set's centre, from an independent basis.
struct Polar {
  Vec3 c, e1, e2;
  explicit Polar(const Vec3& centre) : c(centre) {
    e1 = c.cross(Vec3::UnitY()).normalized();
    e2 = c.cross(e1);
  }
  double radius(const Vec3& d) const { return angle(c, d); }
  double azimuth(const Vec3& d) const { return std::atan2(d.dot(e2), d.dot(e1)); }
  Vec3 point(double r, double a) const { return std::cos(r) * c + std::sin(r) * (std::cos(a) * e1 + std::sin(a) * e2); }
};

double azimuth_gap(double a, double b) { return std::abs(std::remainder(a - b, 2.0 * M_PI)); }

/// The nearest point of the boundary polyline by brute force: each arc sampled at n points.
double brute_force_distance(const control::ReachableSet& set, const Vec3& d, int n) {
  const auto& B = set.boundary();
  double best = 10.0;
  for (size_t k = 0; k < B.size(); ++k) {
    const Vec3 &a = B[k], &b = B[(k + 1) % B.size()];
    const Vec3 u = (b - a.dot(b) * a).normalized();
    for (int i = 0; i <= n; ++i)
      best = std::min(best, angle(d, std::cos(angle(a, b) * i / n) * a + std::sin(angle(a, b) * i / n) * u));
  }
  return best;
}

}  // namespace

class Reachable : public ::testing::TestWithParam<std::string> {};
INSTANTIATE_TEST_SUITE_P(Scenes, Reachable, ::testing::Values("hydrojet_0deg", "hydrojet_30deg"));

TEST_P(Reachable, ComputedQuicklyWithEveryBinFilled) {
  const control::ReachableSet& set = reachable(GetParam());
  ASSERT_FALSE(set.empty());
  EXPECT_EQ(set.boundary().size(), 72u);
  EXPECT_GT(set.samples().size(), 1000u);
  EXPECT_LT(set.compute_time(), 2.0);
  // The zero-force direction is the model's tip z-axis with the jets off.
  rod::RodSolver s(test::bare(test::scene(GetParam())), test::scene(GetParam()).solver);
  EXPECT_NEAR(angle(set.center(), s.solve(rod::TipWrench()).tip_rotation.col(2)), 0.0, 1e-12);
  std::printf("%s: %zu samples, compute %.3f s\n", GetParam().c_str(), set.samples().size(), set.compute_time());
  double lo = 10, hi = 0;
  for (const Vec3& b : set.boundary())
    lo = std::min(lo, angle(set.center(), b)), hi = std::max(hi, angle(set.center(), b));
  std::printf("  centre bend %.3f rad, boundary %.3f..%.3f rad from the centre\n", control::bend_angle(set.center()),
              lo, hi);
}

TEST_P(Reachable, ContainsAgreesWithTheSweepSamples) {
  const control::ReachableSet& set = reachable(GetParam());
  const Polar polar(set.center());
  double worst = 0.0;
  int outside = 0;
  for (const Vec3& s : set.samples()) {
    double moved = 0.0;
    set.clip(s, &moved);
    if (!set.contains(s)) ++outside;
    worst = std::max(worst, moved);
  }
  std::printf("%s: %d of %zu samples outside the polyline, by at most %.2e rad\n", GetParam().c_str(), outside,
              set.samples().size(), worst);
  // The polyline is inscribed (its vertices are samples), so it cuts the corners of the image of the
  // force polygon: a few samples lie outside it, by at most the chords' sag there (measured 1.2e-2 rad
  // at 0°, 1.4e-2 rad at 30°).
  EXPECT_LT(worst, 2e-2) << "a sample outside the boundary polyline by more than its chords' sag";
  EXPECT_LT(outside, static_cast<int>(set.samples().size()) / 500);
  // Random directions against the samples: one with a sample farther out at nearly its azimuth is
  // inside; one beyond every sample within two bins' azimuth is outside (margins above the sag).
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> az(-M_PI, M_PI), rad(0.0, 2.0);
  const double bin = 2.0 * M_PI / 72;
  int checked_in = 0, checked_out = 0;
  for (int i = 0; i < 3000; ++i) {
    const double a = az(rng), r = rad(rng);
    double near_max = 0.0, wide_max = 0.0;
    for (const Vec3& s : set.samples()) {
      const double gap = azimuth_gap(polar.azimuth(s), a), sr = polar.radius(s);
      if (gap < 0.1 * bin) near_max = std::max(near_max, sr);
      if (gap < 2.0 * bin) wide_max = std::max(wide_max, sr);
    }
    const Vec3 d = polar.point(r, a);
    if (near_max > r + 0.02) {
      EXPECT_TRUE(set.contains(d)) << "r " << r << " a " << a;
      ++checked_in;
    }
    if (wide_max < r - 0.01) {
      EXPECT_FALSE(set.contains(d)) << "r " << r << " a " << a;
      ++checked_out;
    }
  }
  EXPECT_GT(checked_in, 300);
  EXPECT_GT(checked_out, 300);
}

TEST_P(Reachable, ClipIsTheNearestPointOfTheBoundary) {
  const control::ReachableSet& set = reachable(GetParam());
  const Polar polar(set.center());
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> az(-M_PI, M_PI), rad(0.0, M_PI);
  int outside = 0;
  for (int i = 0; i < 400; ++i) {
    const Vec3 d = polar.point(rad(rng), az(rng));
    double moved = -1.0;
    const Vec3 c = set.clip(d, &moved);
    EXPECT_NEAR(c.norm(), 1.0, 1e-12);
    if (set.contains(d)) {
      EXPECT_EQ(moved, 0.0);
      EXPECT_NEAR(angle(c, d), 0.0, 1e-15);
      continue;
    }
    ++outside;
    EXPECT_NEAR(moved, angle(d, c), 1e-12);
    EXPECT_TRUE(set.contains(c)) << "the clipped direction is in the set";
    const double brute = brute_force_distance(set, d, 400);
    EXPECT_LE(moved, brute + 1e-12) << "no sampled boundary point is nearer";
    EXPECT_GE(moved, brute - 1e-5) << "the dense sample finds the same point";
  }
  EXPECT_GT(outside, 100);
}

TEST_P(Reachable, FarOutsideIsClippedOntoTheBoundary) {
  const control::ReachableSet& set = reachable(GetParam());
  for (const Vec3& far : {Vec3(-set.center()), Vec3(-Vec3::UnitZ()), Vec3(Vec3::UnitX())}) {
    double moved = 0.0;
    const Vec3 c = set.clip(far, &moved);
    EXPECT_FALSE(set.contains(far));
    EXPECT_TRUE(set.contains(c));
    EXPECT_GT(moved, 0.1);
    // On the boundary: a step of 1e-6 rad on towards `far` leaves the set.
    const Vec3 beyond = (c + 1e-6 * (far - far.dot(c) * c).normalized()).normalized();
    EXPECT_FALSE(set.contains(beyond));
    EXPECT_NEAR(moved, brute_force_distance(set, far, 400), 1e-5);
  }
}

TEST_P(Reachable, TheSection7SpiralIsInside) {
  const control::ReachableSet& set = reachable(GetParam());
  const control::SpiralPath spiral;
  double worst = 0.0, margin = 10.0;
  int outside = 0;
  for (double t = 0.0; t <= 600.0; t += 0.25) {
    double moved = 0.0;
    set.clip(spiral.direction_at(t), &moved);
    worst = std::max(worst, moved);
    if (moved > 0.0) ++outside;
    margin = std::min(margin, brute_force_distance(set, spiral.direction_at(t), 20));
  }
  std::printf("%s: spiral: %d of 2401 points outside (worst %.2e rad); closest to the boundary %.3f rad\n",
              GetParam().c_str(), outside, worst, margin);
  EXPECT_EQ(outside, 0);
  EXPECT_LT(worst, 1e-3);
}

TEST(ReachableSet, OptionsAreValidated) {
  control::ReachableSetOptions o;
  EXPECT_EQ(o.validate(), "");
  o.force_samples = 3;
  EXPECT_EQ(o.validate().rfind("force_samples:", 0), 0u);
  o = {};
  o.azimuth_bins = 4;
  EXPECT_EQ(o.validate().rfind("azimuth_bins:", 0), 0u);
  o = {};
  o.min_stability_margin = NAN;
  EXPECT_EQ(o.validate().rfind("min_stability_margin:", 0), 0u);
  EXPECT_EQ(error_of([&] { control::ReachableSet::compute(model("hydrojet_0deg"), o); }).rfind("min_stability", 0), 0u);
}

// A sweep is bounded work: beyond max_time it is refused, saying how far it got, instead of running
// for minutes (a scene with absurd actuator bounds took 90-330 s before).
TEST(ReachableSet, ASweepBeyondItsTimeBoundIsRefused) {
  control::ReachableSetOptions o;
  o.max_time = 0.0;
  EXPECT_EQ(o.validate().rfind("max_time:", 0), 0u);
  const auto refusal = [](const control::RobotModel& m, double max_time) {
    control::ReachableSetOptions options;
    options.max_time = max_time;
    try {
      control::ReachableSet::compute(m, options);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(refusal(model("hydrojet_0deg"), 1e-9).rfind("reachable set: the sweep took more than max_time", 0), 0u);
  control::RobotModel absurd = model("hydrojet_0deg");
  for (rod::Actuator& a : absurd.rod.actuators) a.max_force = 1e12;
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_NE(refusal(absurd, 0.5).find("max_time = 0.5 s"), std::string::npos);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 30.0);
}

TEST(ReachableSet, AMarginAboveEveryEquilibriumLeavesItEmpty) {
  control::ReachableSetOptions o;
  o.min_stability_margin = 100.0;  // N/m, far above the HydroJet's ~3 N/m
  o.force_samples = 4;
  const control::ReachableSet set = control::ReachableSet::compute(model("hydrojet_0deg"), o);
  EXPECT_TRUE(set.empty());
  EXPECT_FALSE(set.contains(set.center()));
  double moved = 0.0;
  EXPECT_EQ(set.clip(Vec3::UnitX(), &moved), set.center());
  EXPECT_NEAR(moved, angle(Vec3::UnitX(), set.center()), 1e-12);
}

// ---------------------------------------------------------------------------------------------
// Look-at
// ---------------------------------------------------------------------------------------------

namespace {

/// A second, independent model solve at the jet forces the result implies: jet forces allocated
/// exactly (λ = 0) for its tip force, the jet map's wrench, a fresh solver.
rod::RodSolution independent_fk(const std::string& scene, const control::LookAtResult& r) {
  const config::Scene sc = test::scene(scene);
  const actuation::JetMap jets(*sc.jets);
  const actuation::AllocationResult q =
      actuation::allocate(jets.planar(), r.tip_force, Eigen::Vector3d::Zero(), test::jet_max_force(sc), 0.0);
  EXPECT_TRUE(q.ok && q.reachable) << "the tip force is allocatable";
  rod::TipWrench w;
  w.force = jets.wrench(q.q).head<3>();
  w.moment = jets.wrench(q.q).tail<3>();
  rod::RodSolver s(test::bare(sc), sc.solver);
  const rod::RodSolution sol = s.solve(w);
  EXPECT_TRUE(sol.converged);
  return sol;
}

/// Distance of P from the line through the tip along its z-axis, and whether P is in front.
double line_distance(const rod::RodSolution& s, const Vec3& P, bool* in_front) {
  const Vec3 d = s.tip_rotation.col(2), v = P - s.tip_position;
  *in_front = v.dot(d) > 0.0;
  return (v - v.dot(d) * d).norm();
}

/// The jets-off tip position and direction.
std::pair<Vec3, Vec3> rest_pose(const std::string& scene) {
  rod::RodSolver s(test::bare(test::scene(scene)), test::scene(scene).solver);
  const rod::RodSolution sol = s.solve(rod::TipWrench());
  return {sol.tip_position, sol.tip_rotation.col(2)};
}

void expect_aimed(const std::string& scene, const Vec3& P, const control::LookAtResult& r) {
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_LE(r.miss_distance, 1e-6);
  const rod::RodSolution fk = independent_fk(scene, r);
  bool in_front = false;
  EXPECT_LE(line_distance(fk, P, &in_front), 1e-6) << "the line through the tip passes through P";
  EXPECT_TRUE(in_front);
  EXPECT_NEAR(angle(fk.tip_rotation.col(2), r.direction), 0.0, 1e-8);
  EXPECT_NEAR((fk.tip_position - r.tip_position).norm(), 0.0, 1e-9);
}

}  // namespace

class LookAt : public ::testing::TestWithParam<std::string> {};
INSTANTIATE_TEST_SUITE_P(Scenes, LookAt, ::testing::Values("hydrojet_0deg", "hydrojet_30deg"));

TEST_P(LookAt, AimsThroughThePointColdAndWarm) {
  const auto [tip, d0] = rest_pose(GetParam());
  const Vec3 side = d0.cross(Vec3::UnitX()).normalized(), up = d0.cross(side);
  control::LookAtSolver solver(model(GetParam()));
  // 60 mm beyond the tip, off its axis: cold (first call), then warm along a moving point.
  for (int i = 0; i < 12; ++i) {
    const Vec3 P = tip + 0.06 * d0 + 0.02 * std::cos(0.5 * i) * side + 0.015 * std::sin(0.5 * i) * up;
    const control::LookAtResult r = solver.solve(P);
    expect_aimed(GetParam(), P, r);
    if (i > 0) {
      EXPECT_LE(r.iterations, 5) << "warm";
    }
  }
  // A cold solve of the last point gives the same aim as the warm one.
  const Vec3 P = tip + 0.06 * d0 + 0.02 * std::cos(5.5) * side + 0.015 * std::sin(5.5) * up;
  const control::LookAtResult warm = solver.solve(P);
  solver.reset();
  const control::LookAtResult cold = solver.solve(P);
  expect_aimed(GetParam(), P, cold);
  EXPECT_NEAR(angle(warm.direction, cold.direction), 0.0, 2.0 * 1e-6 / 0.06) << "the same aim within the tolerance";
}

TEST_P(LookAt, AimsAtNearAndFarPoints) {
  const auto [tip, d0] = rest_pose(GetParam());
  const Vec3 side = d0.cross(Vec3::UnitX()).normalized();
  for (const double distance : {0.008, 0.015, 0.03, 0.2, 1.0}) {
    control::LookAtSolver solver(model(GetParam()));
    const Vec3 P = tip + distance * (d0 + 0.4 * side).normalized();
    const control::LookAtResult r = solver.solve(P);
    std::printf("%s: %.3f m: %d iterations\n", GetParam().c_str(), distance, r.iterations);
    expect_aimed(GetParam(), P, r);
  }
}

TEST_P(LookAt, RefusesPointsBehindTheCameraOrTooClose) {
  const auto [tip, d0] = rest_pose(GetParam());
  control::LookAtSolver solver(model(GetParam()));
  for (const Vec3& behind : {Vec3(tip - 0.05 * d0), Vec3(0.0, 0.0, -0.05)}) {
    const control::LookAtResult r = solver.solve(behind);
    EXPECT_FALSE(r.ok);
    EXPECT_NE(r.message.find("behind the camera"), std::string::npos) << r.message;
    EXPECT_FALSE(r.out_of_reach);
    solver.reset();  // cold as well
    EXPECT_NE(solver.solve(behind).message.find("behind the camera"), std::string::npos);
  }
  const control::LookAtResult close = solver.solve(tip + 0.003 * d0);
  EXPECT_FALSE(close.ok);
  EXPECT_NE(close.message.find("closer to the tip than min_distance"), std::string::npos) << close.message;
  EXPECT_FALSE(close.out_of_reach);
  const control::LookAtResult nan = solver.solve(Vec3(NAN, 0.0, 0.1));
  EXPECT_FALSE(nan.ok);
  EXPECT_NE(nan.message.find("not finite"), std::string::npos);
  for (const Vec3& far : {Vec3(tip + 2000.0 * d0), Vec3(1e308, 1e308, 1e308)}) {
    const control::LookAtResult r = solver.solve(far);
    EXPECT_FALSE(r.ok);
    EXPECT_FALSE(r.out_of_reach);
    EXPECT_NE(r.message.find("farther from the tip than max_distance"), std::string::npos) << r.message;
  }
  // A refusal does not move the warm start: the next good point is solved as before.
  expect_aimed(GetParam(), tip + 0.06 * d0, solver.solve(tip + 0.06 * d0));
}

TEST_P(LookAt, APointBeyondTheJetsReachGivesTheClosestAim) {
  const auto [tip, d0] = rest_pose(GetParam());
  // 1 m away, 100° from the jets-off axis: no allocatable force turns the tip that far.
  const Vec3 side = d0.cross(Vec3::UnitX()).normalized();
  const Vec3 P = tip + 1.0 * (std::cos(1.75) * d0 + std::sin(1.75) * side);
  control::LookAtSolver solver(model(GetParam()));
  const control::LookAtResult r = solver.solve(P);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.message.find("out of the jets' reach"), std::string::npos) << r.message;
  EXPECT_TRUE(r.out_of_reach);
  EXPECT_GT(r.miss_distance, 0.01);
  EXPECT_LT(angle(r.direction, (P - r.tip_position).normalized()), angle(d0, (P - tip).normalized()))
      << "turned towards the point";
}

TEST(LookAtOptions, AreValidated) {
  control::LookAtOptions o;
  EXPECT_EQ(o.validate(), "");
  o.max_iterations = 0;
  EXPECT_EQ(o.validate().rfind("max_iterations:", 0), 0u);
  o = {};
  o.tolerance = 0.0;
  EXPECT_EQ(o.validate().rfind("tolerance:", 0), 0u);
  o = {};
  o.min_distance = -1.0;
  EXPECT_EQ(o.validate().rfind("min_distance:", 0), 0u);
  EXPECT_EQ(error_of([&] { control::LookAtSolver(model("hydrojet_0deg"), o); }).rfind("min_distance:", 0), 0u);
}

// ---------------------------------------------------------------------------------------------
// Any robot: the second robot's reachable set and look-at, checked with an independent
// solve of its model (RodSolver at the returned inputs).

namespace {

rod::RodSolution general_fk(const config::Scene& sc, const rod::InputVector& q) {
  rod::RodSolver s(sc.rod, sc.solver);
  const rod::RodSolution sol = s.solve(q);
  EXPECT_TRUE(sol.converged) << sol.message;
  return sol;
}

}  // namespace

TEST(GeneralRobot, ReachableSetAroundItsRestDirection) {
  const config::Scene sc = test::scene("two_segment_thrusters");
  const control::ReachableSet set = control::ReachableSet::compute(model("two_segment_thrusters"), {});
  ASSERT_FALSE(set.empty());
  const rod::RodSolution rest = general_fk(sc, rod::InputVector::Zero(6));
  EXPECT_NEAR(angle(set.center(), rest.tip_rotation.col(2)), 0.0, 1e-9);
  EXPECT_GT(set.samples().size(), 1000u);
  double lo = 10.0;
  for (const Vec3& b : set.boundary()) lo = std::min(lo, angle(set.center(), b));
  std::printf("two_segment_thrusters: %zu samples in %.3f s, boundary at least %.3f rad from the centre\n",
              set.samples().size(), set.compute_time(), lo);
  EXPECT_GT(lo, 0.1) << "the thrusters bend it some way in every direction";
}

TEST(GeneralRobot, LookAtAimsThroughThePointWithInputsInTheirBounds) {
  const config::Scene sc = test::scene("two_segment_thrusters");
  const rod::RodSolution rest = general_fk(sc, rod::InputVector::Zero(6));
  const Vec3 tip = rest.tip_position, d0 = rest.tip_rotation.col(2);
  const Vec3 side = d0.cross(Vec3::UnitX()).normalized(), up = d0.cross(side);
  control::LookAtSolver solver(model("two_segment_thrusters"));
  for (int i = 0; i < 6; ++i) {
    const Vec3 P = tip + 0.06 * d0 + 0.02 * std::cos(1.1 * i) * side + 0.015 * std::sin(1.1 * i) * up;
    const control::LookAtResult r = solver.solve(P);
    ASSERT_TRUE(r.ok) << r.message;
    ASSERT_EQ(r.inputs.size(), 6);
    for (int k = 0; k < 6; ++k) {
      EXPECT_GE(r.inputs[k], sc.rod.actuators[k].min_force - 1e-12);
      EXPECT_LE(r.inputs[k], sc.rod.actuators[k].max_force + 1e-12);
    }
    const rod::RodSolution fk = general_fk(sc, r.inputs);
    bool in_front = false;
    EXPECT_LE(line_distance(fk, P, &in_front), 1e-6) << "the line through the tip passes through P";
    EXPECT_TRUE(in_front);
    EXPECT_NEAR(angle(fk.tip_rotation.col(2), r.direction), 0.0, 1e-8);
  }
  // Far beyond the thrusters' reach: the closest aim, flagged.
  const Vec3 P = tip + 1.0 * (std::cos(1.75) * d0 + std::sin(1.75) * side);
  const control::LookAtResult far = solver.solve(P);
  EXPECT_FALSE(far.ok);
  EXPECT_TRUE(far.out_of_reach) << far.message;
}
