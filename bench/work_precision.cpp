// Work-precision driver (scripts/work_precision): tip error against run time for every integrator
// on the scenes of bench/numerics_cases.h. One CSV row per (scene, method, parameter):
//   scene, method, param, converged, pos_err_m, rot_err_rad, compliance_rel_err, warm_us, warm_cb_us,
//   cold_us, rhs_per_warm_solve, newton_per_warm_solve, segments, failures
// plus a reference table (agreement of the two reference methods) and a machine description.
// Times: median over repetitions of the mean time per solve along a closed path of 8 wrenches
// around the scene's wrench (±2 % of |f|, as consecutive requests of a 100 Hz controller).
//
//   work_precision [--quick] [--out DIR] [--scenes a,b,...]
//   work_precision --stiffness               eigenvalues of ∂f/∂y along each case's solution: is the
//                                            rod ODE stiff? (docs/work_precision.md)
//   work_precision --extreme [--out DIR]     the stiff and extreme cases (docs/stability.md): per case
//                                            and integrator, converged within 1e-6·L/9 cm of the
//                                            reference, or the reason it did not; markdown table
#include <sys/utsname.h>
#include <sundials/sundials_config.h>

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "numerics_cases.h"

#ifndef HYDROJET_CXX_FLAGS
#define HYDROJET_CXX_FLAGS "unknown"
#endif

using namespace hydrojet;
using namespace hydrojet::numerics;

namespace {

struct Method {
  std::string name;   ///< line in the plots
  std::string param;  ///< "N=4" or "tol=1e-06"
  rod::ShootingOptions settings;
};

rod::ShootingOptions base_settings() {
  rod::ShootingOptions s;
  s.accuracy_tolerance = 0.0;  // measure the error, do not refuse under-resolved solves
  s.residual_tolerance = 1e-10;
  return s;
}

std::vector<Method> methods(bool quick) {
  std::vector<Method> m;
  auto fixed = [&](const char* name, rod::IntegratorType t, std::vector<int> ns) {
    for (int n : ns) {
      Method x{name, "N=" + std::to_string(n), base_settings()};
      x.settings.integrator.type = t;
      x.settings.integrator.steps = n;
      m.push_back(x);
    }
  };
  auto adaptive = [&](const std::string& name, rod::IntegratorType t, std::vector<double> tols, bool cvodes = false,
                      rod::NewtonBackend nb = rod::NewtonBackend::kEigen) {
    for (double tol : tols) {
      char p[32];
      std::snprintf(p, sizeof p, "tol=%.0e", tol);
      Method x{name, p, base_settings()};
      x.settings.integrator.type = t;
      x.settings.integrator.tolerance = tol;
      x.settings.integrator.cvodes_sensitivities = cvodes;
      x.settings.newton = nb;
      m.push_back(x);
    }
  };
  using T = rod::IntegratorType;
  if (quick) {
    fixed("rk4", T::kRk4, {4, 16, 64, 256});
    fixed("rk8", T::kRk8, {1, 2, 4, 8, 16});
    adaptive("dopri5", T::kDopri5, {1e-4, 1e-6, 1e-8, 1e-10, 1e-12});
    adaptive("cvode-adams", T::kCvodeAdams, {1e-4, 1e-8, 1e-12});
    adaptive("cvode-bdf", T::kCvodeBdf, {1e-4, 1e-8});
    return m;
  }
  const std::vector<double> tols = {1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12};
  fixed("rk4", T::kRk4, {4, 8, 16, 32, 64, 128, 256, 512});
  fixed("rk8", T::kRk8, {1, 2, 4, 8, 16, 32, 64});
  adaptive("dopri5", T::kDopri5, tols);
  adaptive("cvode-adams", T::kCvodeAdams, tols);
  adaptive("cvode-bdf", T::kCvodeBdf, tols);
  // The SUNDIALS alternatives measured against the Eigen path (CVODES sensitivities, then KINSOL):
  adaptive("cvode-adams+cvodes-sens", T::kCvodeAdams, {1e-4, 1e-6, 1e-8, 1e-10, 1e-12}, true);
  adaptive("cvode-bdf+cvodes-sens", T::kCvodeBdf, {1e-4, 1e-6, 1e-8, 1e-10, 1e-12}, true);
  {
    // KINSOL as the Newton iteration, with the default integrator (rk8, N steps).
    for (int n : {2, 4, 8, 16}) {
      Method x{"rk8+kinsol", "N=" + std::to_string(n), base_settings()};
      x.settings.integrator.type = T::kRk8;
      x.settings.integrator.steps = n;
      x.settings.newton = rod::NewtonBackend::kKinsol;
      m.push_back(x);
    }
  }
  return m;
}

double now_us() {
  return std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// Median over `reps` repetitions of the mean time of one call of `op` (each repetition runs whole
/// passes over the path until at least `min_us` elapsed).
double median_time(const std::function<void()>& pass, int per_pass, int reps, double min_us) {
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) {
    int n = 0;
    const double t0 = now_us();
    double t1 = t0;
    do {
      pass();
      n += per_pass;
      t1 = now_us();
    } while (t1 - t0 < min_us);
    t.push_back((t1 - t0) / n);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

std::string machine() {
  std::ifstream f("/proc/cpuinfo");
  std::string line, model = "unknown";
  int cpus = 0;
  while (std::getline(f, line)) {
    if (line.rfind("model name", 0) == 0 && model == "unknown") model = line.substr(line.find(':') + 2);
    if (line.rfind("processor", 0) == 0) ++cpus;
  }
  struct utsname u;
  uname(&u);
  std::ostringstream os;
  os << model << ", " << cpus << " logical CPUs, " << u.sysname << " " << u.release;
  return os.str();
}

/// Stiffness of the rod ODE along each case's solution: the eigenvalues λ of the 15×15 Jacobian
/// ∂f/∂y of the state equations, at 64 points from the tip to the base. Reported: max |λ|·L and the
/// extreme real parts (scaled by L). An ODE is stiff when |λ|·L ≫ 1 for modes the solution does not
/// follow; here the fast modes are the physical ±λ pairs of the boundary-value problem.
int stiffness() {
  std::printf("| case | λL estimate | max |λ|·L | min Re λ·L | max Re λ·L |\n|---|---|---|---|---|\n");
  std::vector<Case> all = work_precision_cases();
  for (const Case& c : extreme_cases()) all.push_back(c);
  for (const Case& c : all) {
    rod::ShootingOptions st = reference_settings(c, false);
    st.integrator.tolerance = 1e-10;
    rod::RodSolver solver(c.model, st);
    const rod::RodSolution sol = solver.solve(c.wrench);
    if (!sol.converged) {
      std::printf("| %s | not converged: %s | | | |\n", c.name.c_str(), sol.message.c_str());
      continue;
    }
    // Integrate the state from the tip (R(L) = tip rotation, R(0) = I at the solution).
    rod::RodOde<0, rod::CosseratGeneral> ode;
    const rod::RodSegment& p = c.model.segments.front();
    ode.k_diag = p.stiffness;
    ode.k_inv = p.stiffness.cwiseInverse();
    ode.u_tilde = p.precurvature;
    ode.length = p.length;
    ode.kse_inv = p.shear_extension_compliance(c.model.kind);
    ode.n_tip = sol.tip_rotation * c.wrench.force + c.model.tip_mass * c.model.gravity;
    ode.w_dist = p.linear_density * c.model.gravity;
    rod::RodOde<0, rod::CosseratGeneral>::State y = rod::RodOde<0, rod::CosseratGeneral>::State::Zero();
    Eigen::Map<Mat3>(y.data() + 3) = sol.tip_rotation;
    y.segment<3>(12) = ode.u_tilde + ode.k_inv.cwiseProduct(c.wrench.moment);
    double max_abs = 0, min_re = 0, max_re = 0;
    const int n = 64;
    for (int k = 0; k <= n; ++k) {
      const double sk = p.length * (1.0 - double(k) / n);
      if (k > 0) rod::integrate_rk8(ode, p.length * (1.0 - double(k - 1) / n), sk, 8, y);
      Eigen::Matrix<double, 15, 15> J;
      for (int j = 0; j < 15; ++j) {
        rod::RodOde<0, rod::CosseratGeneral>::State e = rod::RodOde<0, rod::CosseratGeneral>::State::Zero(), out;
        e[j] = 1.0;
        ode.jvp(sk, y, e, Vec3::Zero(), out);
        J.col(j) = out;
      }
      const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::Matrix<double, 15, 15>>(J, false).eigenvalues();
      for (int i = 0; i < ev.size(); ++i) {
        max_abs = std::max(max_abs, std::abs(ev[i]) * p.length);
        min_re = std::min(min_re, ev[i].real() * p.length);
        max_re = std::max(max_re, ev[i].real() * p.length);
      }
    }
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f |\n", c.name.c_str(), solver.growth_estimate(c.wrench), max_abs,
                min_re, max_re);
    std::fflush(stdout);
  }
  return 0;
}

/// The table of docs/stability.md: every extreme case with the integrators of the extreme tests.
int extreme(const std::string& out) {
  struct Config {
    const char* name;
    rod::IntegratorType type;
    int steps;
    double tol;
  };
  const Config configs[] = {{"rk8 ×4", rod::IntegratorType::kRk8, 4, 0.0},
                            {"rk8 ×32", rod::IntegratorType::kRk8, 32, 0.0},
                            {"dopri5 1e-10", rod::IntegratorType::kDopri5, 0, 1e-10},
                            {"cvode-adams 1e-10", rod::IntegratorType::kCvodeAdams, 0, 1e-10},
                            {"cvode-bdf 1e-10", rod::IntegratorType::kCvodeBdf, 0, 1e-10}};
  std::ofstream md(out + "/extreme_cases.md");
  md << "| case | λL | reference agreement [m] |";
  for (const Config& k : configs) md << " " << k.name << " |";
  md << "\n|---|---|---|";
  for (size_t i = 0; i < sizeof(configs) / sizeof(configs[0]); ++i) md << "---|";
  md << "\n";
  for (const Case& c : extreme_cases()) {
    const double t0 = now_us();
    const Reference ref = reference(c);
    const double tref = (now_us() - t0) / 1e6;
    rod::RodSolver probe(c.model, rod::ShootingOptions());
    char agree[32] = "none";
    if (ref.ok) std::snprintf(agree, sizeof agree, "%.0e", ref.agreement);
    char head[200];
    std::snprintf(head, sizeof head, "| %s | %.1f | %s |", c.name.c_str(), probe.growth_estimate(c.wrench), agree);
    md << head;
    std::printf("%s (reference %.1f s%s%s)\n", head, tref, ref.ok ? "" : ": ", ref.message.c_str());
    for (const Config& k : configs) {
      if (probe.growth_estimate(c.wrench) > 30.0 && k.type == rod::IntegratorType::kCvodeBdf) {
        // λL > 30 (the very soft rod under the full jet force): BDF ran for over 10 minutes.
        md << " not run (> 10 min) |";
        std::printf("   %-18s not run\n", k.name);
        continue;
      }
      rod::ShootingOptions st;
      st.integrator.type = k.type;
      if (k.steps) st.integrator.steps = k.steps;
      if (k.tol > 0.0) st.integrator.tolerance = k.tol;
      rod::RodSolver s(c.model, st);
      const double t1 = now_us();
      const rod::RodSolution sol = s.solve(c.wrench);
      const double ms = (now_us() - t1) / 1e3;
      char cell[400];
      if (!sol.converged) {
        std::string why = sol.message.substr(0, sol.message.find(';'));
        if (why.size() > 70) why = why.substr(0, 67) + "...";
        std::snprintf(cell, sizeof cell, " ✗ %s (%.3g ms) |", why.c_str(), ms);
      } else if (!ref.ok) {
        std::snprintf(cell, sizeof cell, " converged, no reference (%.3g ms, M = %d) |", ms, sol.segments);
      } else {
        const double err = (sol.tip_position - ref.position).norm();
        const std::string seg = sol.segments > 1 ? ", M = " + std::to_string(sol.segments) : "";
        std::snprintf(cell, sizeof cell, " %s %.0e m, %.3g ms%s%s |", err <= c.tolerance ? "✓" : "**✗ silent**", err,
                      ms, seg.c_str(), sol.fold_crossings ? ", fold reported" : "");
      }
      md << cell;
      std::printf("   %-18s%s\n", k.name, cell);
      std::fflush(stdout);
    }
    md << "\n";
    md.flush();
  }
  std::printf("wrote %s/extreme_cases.md\n", out.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, extreme_mode = false;
  std::string out = ".";
  std::vector<std::string> only;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") {
      quick = true;
    } else if (a == "--extreme") {
      extreme_mode = true;
    } else if (a == "--stiffness") {
      return stiffness();
    } else if (a == "--out" && i + 1 < argc) {
      out = argv[++i];
    } else if (a == "--scenes" && i + 1 < argc) {
      std::stringstream ss(argv[++i]);
      std::string t;
      while (std::getline(ss, t, ',')) only.push_back(t);
    } else {
      std::cerr << "usage: work_precision [--quick | --extreme] [--out DIR] [--scenes a,b,...]\n";
      return 2;
    }
  }
  if (extreme_mode) return extreme(out);
  const int reps = quick ? 3 : 7;
  const double min_us = quick ? 2e3 : 1e4;

  std::ofstream meta(out + "/work_precision_meta.txt");
  meta << "machine: " << machine() << "\n"
       << "compiler: g++ " << __VERSION__ << "\n"
       << "flags: " << HYDROJET_CXX_FLAGS << "\n"
       << "eigen: " << EIGEN_WORLD_VERSION << "." << EIGEN_MAJOR_VERSION << "." << EIGEN_MINOR_VERSION << "\n"
       << "sundials: " << SUNDIALS_VERSION << "\n"
       << "mode: " << (quick ? "quick" : "full") << ", " << reps << " repetitions, >= " << min_us / 1e3 << " ms each\n";

  std::ofstream refcsv(out + "/work_precision_reference.csv");
  refcsv << "scene,description,agreement_m,angle_agreement_rad,ref_ok,message\n";
  std::ofstream csv(out + "/work_precision.csv");
  csv << "scene,method,param,converged,pos_err_m,rot_err_rad,compliance_rel_err,warm_us,warm_cb_us,cold_us,"
         "rhs_per_warm_solve,newton_per_warm_solve,segments,failures\n";
  const double t_start = now_us();

  for (const Case& c : work_precision_cases()) {
    if (!only.empty() && std::find(only.begin(), only.end(), c.name) == only.end()) continue;
    const Reference ref = reference(c);
    refcsv << c.name << ",\"" << c.description << "\"," << ref.agreement << "," << ref.angle_agreement << "," << ref.ok
           << ",\"" << ref.message << "\"\n";
    std::printf("%-22s reference agreement %.1e m %s\n", c.name.c_str(), ref.agreement, ref.message.c_str());
    std::fflush(stdout);
    // The path of the timed warm solves: 8 wrenches on a small circle (2 % of |f|) around c.wrench.
    std::vector<rod::TipWrench> path;
    const double r = 0.02 * std::max(c.wrench.force.norm(), 0.01);
    for (int k = 0; k < 8; ++k) {
      rod::TipWrench w = c.wrench;
      w.force += r * Vec3(std::cos(2 * M_PI * k / 8), std::sin(2 * M_PI * k / 8), 0.0);
      path.push_back(w);
    }
    for (const Method& m : methods(quick)) {
      rod::RodSolver s(c.model, m.settings);
      const double tc0 = now_us();
      const rod::RodSolution sol = s.solve(c.wrench);
      const double cold = now_us() - tc0;
      int failures = sol.converged ? 0 : 1;
      double pos_err = NAN, rot_err = NAN, c_err = NAN, warm = NAN, warm_cb = NAN, rhs = NAN, newton = NAN;
      if (sol.converged && ref.ok) {
        pos_err = (sol.tip_position - ref.position).norm();
        rot_err = so3::log(ref.rotation.transpose() * sol.tip_rotation).norm();
        const rod::Compliance C = s.compliance();
        c_err = C.ok ? (C.body - ref.compliance).norm() / ref.compliance.norm() : NAN;
      }
      if (sol.converged) {
        // Work counters over one warm pass.
        long it = 0, ev = 0;
        for (const auto& w : path) {
          const rod::RodSolution t = s.solve(w);
          it += t.iterations;
          ev += t.rhs_evaluations;
          failures += t.converged ? 0 : 1;
        }
        rhs = double(ev) / path.size();
        newton = double(it) / path.size();
        const int per = static_cast<int>(path.size());
        const int r = cold > 2e4 ? 3 : reps;  // slow points (> 20 ms a solve): 3 repetitions suffice
        warm = median_time(
            [&] {
              for (const auto& w : path) s.solve(w);
            },
            per, r, min_us);
        warm_cb = median_time(
            [&] {
              for (const auto& w : path) {
                s.solve(w);
                s.compliance();
              }
            },
            per, r, min_us);
      }
      char row[512];
      std::snprintf(row, sizeof row, "%s,%s,%s,%d,%.6e,%.6e,%.6e,%.4f,%.4f,%.4f,%.1f,%.3f,%d,%d", c.name.c_str(),
                    m.name.c_str(), m.param.c_str(), sol.converged ? 1 : 0, pos_err, rot_err, c_err, warm, warm_cb,
                    cold, rhs, newton, sol.segments, failures);
      csv << row << "\n";
      csv.flush();
      std::printf("  %-24s %-10s conv %d  err %.1e m  warm %9.2f us  +C^b %9.2f us%s%s\n", m.name.c_str(),
                  m.param.c_str(), sol.converged ? 1 : 0, pos_err, warm, warm_cb, sol.converged ? "" : "  ",
                  sol.converged ? "" : sol.message.c_str());
      std::fflush(stdout);
    }
  }
  meta << "wall time: " << (now_us() - t_start) / 1e6 << " s\n";
  std::printf("wrote %s/work_precision.csv (%.1f s)\n", out.c_str(), (now_us() - t_start) / 1e6);
  return 0;
}
