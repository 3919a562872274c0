// Stability map (scripts/stability_map; paper §7.8, Figs. 12–13): σ_c and the eigenvalue indicator
// over 3000 jet-force combinations q < q_max for a scene, warm-started along a serpentine path.
// CSV rows: q1,q2,q3,fx,fy,converged,sigma_c,eig_min,tip_x,tip_y,tip_z,fold_crossings
// Last stdout line: one JSON object with the solver time (solve + C^b + stability, all points).
//
//   stability_map --scene FILE [--scale S] [--integrator NAME] [--steps N] [--tol X] [--out FILE.csv]
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>

#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/rod/stability.h"
#include "numerics_cases.h"

using namespace hydrojet;

int main(int argc, char** argv) {
  std::string scene_file, out, integrator;
  double scale = 1.0, tol = 0.0;
  int steps = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--scene" && i + 1 < argc) {
      scene_file = argv[++i];
    } else if (a == "--scale" && i + 1 < argc) {
      scale = std::atof(argv[++i]);
    } else if (a == "--integrator" && i + 1 < argc) {
      integrator = argv[++i];
    } else if (a == "--steps" && i + 1 < argc) {
      steps = std::atoi(argv[++i]);
    } else if (a == "--tol" && i + 1 < argc) {
      tol = std::atof(argv[++i]);
    } else if (a == "--out" && i + 1 < argc) {
      out = argv[++i];
    } else {
      std::cerr << "usage: stability_map --scene FILE [--scale S] [--integrator NAME] [--steps N] [--tol X] "
                   "[--out FILE.csv]\n";
      return 2;
    }
  }
  if (scene_file.empty() || !(scale > 0.0)) {
    std::cerr << "stability_map: --scene is required and --scale must be positive\n";
    return 2;
  }
  config::Scene sc;
  try {
    sc = config::load_scene(scene_file);
  } catch (const config::SceneError& e) {
    std::cerr << "stability_map: " << e.what() << "\n";
    return 2;
  }
  if (!sc.jets) {
    std::cerr << "stability_map: scene has no jets section\n";
    return 2;
  }
  if (!integrator.empty() && !rod::parse_integrator(integrator, &sc.solver.integrator.type)) {
    std::cerr << "stability_map: unknown integrator " << integrator << "\n";
    return 2;
  }
  if (steps > 0) sc.solver.integrator.steps = steps;
  if (tol > 0.0) sc.solver.integrator.tolerance = tol;
  const actuation::JetMap jets(*sc.jets);
  const std::vector<rod::Vec3> grid = numerics::stability_grid(scale * hydrojet::numerics::jet_max_force(sc));
  struct Row {
    rod::Vec3 q, f, tip;
    bool converged;
    double sigma, eig;
    int folds;
  };
  std::vector<Row> rows(grid.size());
  rod::RodSolver solver(hydrojet::numerics::bare(sc), sc.solver);
  int failures = 0, folds = 0;
  double min_sigma = 1e300, min_eig = 1e300;
  const auto t0 = std::chrono::steady_clock::now();
  for (size_t i = 0; i < grid.size(); ++i) {
    const rod::Vec6 w6 = jets.wrench(grid[i]);
    rod::TipWrench w;
    w.force = w6.head<3>();
    w.moment = w6.tail<3>();
    const rod::RodSolution s = solver.solve(w);
    Row& r = rows[i];
    r.q = grid[i];
    r.f = w.force;
    r.converged = s.converged;
    r.tip = s.tip_position;
    r.folds = s.fold_crossings;
    r.sigma = r.eig = NAN;
    if (s.converged) {
      const rod::Compliance C = solver.compliance();
      const rod::StabilityReport st = rod::stability(C.body, sc.actuated);
      if (C.ok && st.ok) {
        r.sigma = st.margin;
        r.eig = st.eig_min;
      }
    }
    failures += s.converged ? 0 : 1;
    folds += s.fold_crossings;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  int unstable = 0;
  for (const Row& r : rows) {
    if (std::isfinite(r.sigma)) min_sigma = std::min(min_sigma, r.sigma);
    if (std::isfinite(r.eig)) min_eig = std::min(min_eig, r.eig);
    if (std::isfinite(r.eig) && r.eig <= 0.0) ++unstable;
  }
  if (!out.empty()) {
    std::ofstream f(out);
    f << "q1,q2,q3,fx,fy,converged,sigma_c,eig_min,tip_x,tip_y,tip_z,fold_crossings\n";
    char buf[400];
    for (const Row& r : rows) {
      std::snprintf(buf, sizeof buf, "%.6g,%.6g,%.6g,%.6g,%.6g,%d,%.8g,%.8g,%.8g,%.8g,%.8g,%d\n", r.q[0], r.q[1],
                    r.q[2], r.f[0], r.f[1], r.converged ? 1 : 0, r.sigma, r.eig, r.tip[0], r.tip[1], r.tip[2], r.folds);
      f << buf;
    }
  }
  std::printf(
      "{\"scene\": \"%s\", \"scale\": %g, \"points\": %zu, \"solver_time_s\": %.6f, \"failures\": %d, "
      "\"fold_crossings\": %d, \"min_sigma_c\": %.6g, \"min_eig\": %.6g, \"unstable_points\": %d, "
      "\"integrator\": \"%s\", \"steps\": %d}\n",
      scene_file.c_str(), scale, grid.size(), seconds, failures, folds, min_sigma, min_eig, unstable,
      rod::integrator_name(sc.solver.integrator.type), sc.solver.integrator.steps);
  return failures == 0 ? 0 : 1;
}
