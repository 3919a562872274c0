// Rod-solver benchmarks on the HydroJet scene along a path of jet forces (scripts/bench runs them).
//   BM_ColdSolve             solve with no warm start (reset before each solve)
//   BM_WarmSolve             solve warm-started from the previous point of the path
//   BM_WarmSolveCompliance   the same plus C^b
//   BM_WarmSolveGeneral, BM_WarmSolveComplianceGeneral
//                            the same with the general right-hand side (every term, Cosserat form)
//                            instead of the one compiled for the scene's terms: the specialisation gain
//   BM_GeneralWarmSolveJacobian  the second robot (config/scenes/two_segment_thrusters.yaml, RodSolver):
//                            warm solve + C^b and J_q along a 200-point input path
//   BM_GeneralWarmSolveJacobianHydroJet  the HydroJet's 30° scene on RodSolver (its three jets
//                            as actuators), for the cost of the general path against BM_WarmSolveCompliance
//   BM_StabilityMap3000/0, /30
//                            σ_c over 3000 jet-force combinations (paper Figs. 12–13), 0° and 30°
//                            scenes, warm-started along a serpentine: solve + C^b + stability
//   BM_LookAt                one warm look-at solve (control/look_at.h) toward a point 60 mm beyond
//                            the tip that moves by 0.2 mm per call (one control cycle)
//   BM_ReachableClip         ReachableSet::clip of a random direction outside the set
//   BM_ReachableSetCompute   ReachableSet::compute (the controller's start), 30° scene
//   BM_LateralModes          the rod's two lowest lateral modes about the equilibrium
//                            (control/modal_model.h: five warm solves and their shapes), along the path
//   BM_ControlCycle          one Controller::update of the 20 s spiral, closed loop (counter p99_us)
//   BM_ControlCyclePapersLaw the same with the fast-path elements off (the paper's law)
// The path benchmarks report the counter tip_error_m: the largest tip-position error along the
// path against a reference (RK8, 256 steps, residual 1e-13).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "../bench/numerics_cases.h"
#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/control/controller.h"
#include "hydrojet_control/control/look_at.h"
#include "hydrojet_control/control/modal_model.h"
#include "hydrojet_control/control/reachable_set.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/stability.h"

namespace {

using hydrojet::rod::TipWrench;
using hydrojet::rod::Vec3;

hydrojet::config::Scene scene() {
  return hydrojet::config::load_scene(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/hydrojet_30deg.yaml");
}

/// Jet map of eq. (24), Table 1 misalignments.
Vec3 jets(double q1, double q2, double q3) {
  const double p3 = M_PI / 3.0, da = 0.12, db = 0.06, dg = -0.08;
  return Vec3(std::sin(p3 - db) * q1 + std::sin(da) * q2 - std::sin(p3 - dg) * q3,
              std::cos(p3 - db) * q1 - std::cos(da) * q2 + std::cos(p3 - dg) * q3, 0.0);
}

/// A closed path through the actuation space: 200 points, consecutive points 10 ms apart on a
/// spiral-like sweep (as a 100 Hz controller would request them).
const std::vector<TipWrench>& path() {
  static std::vector<TipWrench> p = [] {
    std::vector<TipWrench> v;
    for (int i = 0; i < 200; ++i) {
      const double t = 2.0 * M_PI * i / 200.0;
      TipWrench w;
      w.force = jets(0.12 + 0.11 * std::sin(t), 0.11 + 0.10 * std::sin(t + 2.1), 0.12 + 0.11 * std::sin(t + 4.2));
      v.push_back(w);
    }
    return v;
  }();
  return p;
}

double path_tip_error(const hydrojet::config::Scene& sc) {
  hydrojet::rod::ShootingOptions ref = sc.solver;
  ref.integrator.type = hydrojet::rod::IntegratorType::kRk8;
  ref.integrator.steps = 256;
  ref.residual_tolerance = 1e-13;
  hydrojet::rod::RodSolver a(hydrojet::numerics::bare(sc), sc.solver), b(hydrojet::numerics::bare(sc), ref);
  double worst = 0.0;
  for (const auto& w : path()) {
    const auto sa = a.solve(w), sb = b.solve(w);
    if (!sa.converged || !sb.converged) return NAN;
    worst = std::max(worst, (sa.tip_position - sb.tip_position).norm());
  }
  return worst;
}

void BM_ColdSolve(benchmark::State& state) {
  const auto sc = scene();
  hydrojet::rod::RodSolver s(hydrojet::numerics::bare(sc), sc.solver);
  size_t i = 0;
  for (auto _ : state) {
    s.reset();
    benchmark::DoNotOptimize(s.solve(path()[i++ % path().size()]));
  }
  state.counters["tip_error_m"] = path_tip_error(sc);
}

void BM_WarmSolve(benchmark::State& state) {
  const auto sc = scene();
  hydrojet::rod::RodSolver s(hydrojet::numerics::bare(sc), sc.solver);
  size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(s.solve(path()[i++ % path().size()]));
  state.counters["tip_error_m"] = path_tip_error(sc);
}

void BM_WarmSolveCompliance(benchmark::State& state) {
  const auto sc = scene();
  hydrojet::rod::RodSolver s(hydrojet::numerics::bare(sc), sc.solver);
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(s.solve(path()[i++ % path().size()]));
    benchmark::DoNotOptimize(s.compliance());
  }
  state.counters["tip_error_m"] = path_tip_error(sc);
}

void BM_LateralModes(benchmark::State& state) {
  const auto sc = scene();
  hydrojet::rod::RodSolver s(hydrojet::numerics::bare(sc), sc.solver);
  size_t i = 0;
  for (auto _ : state) {
    const TipWrench& w = path()[i++ % path().size()];
    s.solve(w);  // the controller's warm start moves along the path
    benchmark::DoNotOptimize(hydrojet::control::lateral_modes(s, hydrojet::rod::InputVector(0), w));
  }
}

hydrojet::rod::ShootingOptions general(hydrojet::rod::ShootingOptions s) {
  s.specialise_model = false;
  return s;
}

void BM_WarmSolveGeneral(benchmark::State& state) {
  const auto sc = scene();
  hydrojet::rod::RodSolver s(hydrojet::numerics::bare(sc), general(sc.solver));
  size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(s.solve(path()[i++ % path().size()]));
  state.SetLabel(s.variant_name());
}

void BM_WarmSolveComplianceGeneral(benchmark::State& state) {
  const auto sc = scene();
  hydrojet::rod::RodSolver s(hydrojet::numerics::bare(sc), general(sc.solver));
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(s.solve(path()[i++ % path().size()]));
    benchmark::DoNotOptimize(s.compliance());
  }
  state.SetLabel(s.variant_name());
}

/// Warm solve + C^b + J_q of a general scene along 200 inputs, each actuator swept between 10 % and
/// 90 % of its range with its own phase.
void general_path_benchmark(benchmark::State& state, const std::string& name) {
  const auto sc = hydrojet::config::load_scene(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/" + name + ".yaml");
  hydrojet::rod::RodSolver s(sc.rod, sc.solver);
  const int N = s.input_count();
  std::vector<hydrojet::rod::InputVector> qs;
  for (int i = 0; i < 200; ++i) {
    hydrojet::rod::InputVector q(N);
    for (int j = 0; j < N; ++j) {
      const auto& a = sc.rod.actuators[j];
      q[j] = a.min_force + (a.max_force - a.min_force) * (0.5 + 0.4 * std::sin(2.0 * M_PI * i / 200.0 + 1.7 * j));
    }
    qs.push_back(q);
  }
  size_t i = 0, failed = 0;
  for (auto _ : state) {
    failed += !s.solve(qs[i++ % qs.size()]).converged;
    benchmark::DoNotOptimize(s.compliance());
  }
  state.counters["failed_solves"] = static_cast<double>(failed);
}

void BM_GeneralWarmSolveJacobian(benchmark::State& state) { general_path_benchmark(state, "two_segment_thrusters"); }
void BM_GeneralWarmSolveJacobianHydroJet(benchmark::State& state) { general_path_benchmark(state, "hydrojet_30deg"); }

void BM_StabilityMap3000(benchmark::State& state) {
  const auto sc = hydrojet::config::load_scene(std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/hydrojet_" +
                                               std::to_string(state.range(0)) + "deg.yaml");
  const hydrojet::actuation::JetMap jets(*sc.jets);
  const std::vector<Vec3> grid = hydrojet::numerics::stability_grid(hydrojet::numerics::jet_max_force(sc));
  std::vector<TipWrench> w(grid.size());
  for (size_t i = 0; i < grid.size(); ++i) {
    const hydrojet::rod::Vec6 w6 = jets.wrench(grid[i]);
    w[i].force = w6.head<3>();
    w[i].moment = w6.tail<3>();
  }
  double min_eig = 0.0;
  int failures = 0;
  for (auto _ : state) {
    hydrojet::rod::RodSolver s(hydrojet::numerics::bare(sc), sc.solver);
    min_eig = 1e300;
    failures = 0;
    for (const TipWrench& x : w) {
      if (!s.solve(x).converged) {
        ++failures;
        continue;
      }
      const hydrojet::rod::StabilityReport st = hydrojet::rod::stability(s.compliance().body, sc.actuated);
      min_eig = std::min(min_eig, st.eig_min);
    }
  }
  state.counters["points"] = static_cast<double>(w.size());
  state.counters["failures"] = failures;
  state.counters["min_eig"] = min_eig;
}

hydrojet::control::RobotModel robot_model() {
  return hydrojet::config::make_controller_model(scene(), hydrojet::actuation::FlowRegulatorOptions());
}

void BM_LookAt(benchmark::State& state) {
  using hydrojet::control::Vec3;
  hydrojet::control::LookAtSolver solver(robot_model());
  hydrojet::rod::RodSolver rest(hydrojet::numerics::bare(scene()), scene().solver);
  const hydrojet::rod::RodSolution s = rest.solve(TipWrench());
  const Vec3 d = s.tip_rotation.col(2), side = d.cross(Vec3::UnitX()).normalized(), up = d.cross(side);
  int i = 0, failures = 0, iterations = 0;
  for (auto _ : state) {
    const double a = 0.01 * i++;  // 0.2 mm per call on a circle of 20 mm radius
    const hydrojet::control::LookAtResult r =
        solver.solve(s.tip_position + 0.06 * d + 0.02 * (std::cos(a) * side + std::sin(a) * up));
    failures += r.ok ? 0 : 1;
    iterations += r.iterations;
  }
  state.counters["failures"] = failures;
  state.counters["iterations"] = static_cast<double>(iterations) / std::max(1, i);
}

void BM_ReachableClip(benchmark::State& state) {
  using hydrojet::control::Vec3;
  const hydrojet::control::ReachableSet set = hydrojet::control::ReachableSet::compute(robot_model(), {});
  std::mt19937 rng(3);
  std::normal_distribution<double> n;
  std::vector<Vec3> outside;
  while (outside.size() < 1000) {
    const Vec3 v = Vec3(n(rng), n(rng), n(rng)).normalized();
    if (!set.contains(v)) outside.push_back(v);
  }
  size_t i = 0;
  double moved = 0.0;
  for (auto _ : state) benchmark::DoNotOptimize(set.clip(outside[i++ % outside.size()], &moved));
}

void BM_ReachableSetCompute(benchmark::State& state) {
  const hydrojet::control::RobotModel m = robot_model();
  size_t samples = 0;
  for (auto _ : state) samples = hydrojet::control::ReachableSet::compute(m, {}).samples().size();
  state.counters["samples"] = static_cast<double>(samples);
}

}  // namespace

namespace {

/// One control cycle (Controller::update, Algorithm 1 with the default config/controller.yaml: the
/// modal law, its estimator and first mode each cycle; or the paper's law, its fast-path elements off) of the §7 spiral
/// run at 20 s in closed loop against a quasi-static plant (the 30° scene's own rod, valves that set the flow at once);
/// only update() is timed. Counter p99_us: its 99th percentile.
void control_cycle(benchmark::State& state, bool papers_law) {
  namespace hc = hydrojet::control;
  const std::string dir = std::string(HYDROJET_SOURCE_DIR) + "/config/";
  const hydrojet::config::ControllerNodeOptions o = hydrojet::config::load_controller_options(dir + "controller.yaml");
  hc::ControllerOptions c = o.controller;
  c.path.duration = 20.0;
  if (papers_law) {
    c.control_law = hc::ControlLaw::kPapers;
    c.pd.ki = c.allocation.smoothing = 0.0;
  }
  const hydrojet::config::Scene sc = scene();
  hc::Controller ctl(hydrojet::config::make_controller_model(sc, o.flow_regulator), c);
  hydrojet::rod::RodSolver plant(hydrojet::numerics::bare(sc), sc.solver);
  const hydrojet::actuation::JetMap jets(*sc.jets);
  hc::ControllerInputs in;
  in.tip_valid = in.flow_valid = true;
  in.flows = hc::InputVector::Zero(3);
  std::vector<double> cycle_us;
  int aborts = 0;
  double t = 0.0;
  ctl.start(0.0);
  for (auto _ : state) {
    in.t = in.tip_stamp = in.flow_stamp = t;
    const auto t0 = std::chrono::steady_clock::now();
    const hc::ControllerOutput out = ctl.update(in);
    const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
    state.SetIterationTime(us * 1e-6);
    cycle_us.push_back(us);
    aborts += out.state == hc::ControllerState::kAborted;
    if (out.state != hc::ControllerState::kRunning) ctl.start(t);  // the path ended: again
    hydrojet::rod::TipWrench w;
    for (int i = 0; i < 3; ++i) in.flows[i] = std::clamp(out.valve_command[i], 0.0, 1.0) * 1.6e-5;
    hc::InputVector q(3);
    for (int i = 0; i < 3; ++i) q[i] = hydrojet::actuation::force_from_flow(in.flows[i], sc.nozzle);
    w.force = jets.wrench(Eigen::Vector3d(q)).head<3>();
    in.tip_rotation = plant.solve(w).tip_rotation;
    t += 0.01;
  }
  if (aborts > 0) state.SkipWithError("the controller aborted: the cycles timed are not the law's");
  std::sort(cycle_us.begin(), cycle_us.end());
  state.counters["p99_us"] = cycle_us.empty() ? 0.0 : cycle_us[static_cast<size_t>(0.99 * (cycle_us.size() - 1))];
}

}  // namespace

void BM_ControlCycle(benchmark::State& state) { control_cycle(state, false); }
void BM_ControlCyclePapersLaw(benchmark::State& state) { control_cycle(state, true); }

BENCHMARK(BM_ColdSolve)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_WarmSolve)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_WarmSolveCompliance)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_WarmSolveGeneral)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_WarmSolveComplianceGeneral)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GeneralWarmSolveJacobian)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GeneralWarmSolveJacobianHydroJet)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_StabilityMap3000)->Arg(0)->Arg(30)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_LookAt)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ReachableClip)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ReachableSetCompute)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_LateralModes)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ControlCycle)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(0.5);
BENCHMARK(BM_ControlCyclePapersLaw)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(0.5);
BENCHMARK_MAIN();
