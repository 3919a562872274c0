// experiment: the paper's §7 experiment on the simulated plant, in one process (no transport).
// The spiral of §7.1 (or a path file, --path) in open and closed loop, at 0° and 30° base tilt,
// several seeds each. --start rest (the default) is the paper's protocol: from rest, onto the path at
// once; --start on-path approaches the path's first direction first and measures from its clock's
// start. Prints a table like §7.5–7.7, writes CSV per run and a summary, and as its last line one
// JSON object:
//   {"runs": [{"mode", "tilt_deg", "seed", "rms_rad", "rms_true_rad", "water_ml_per_min", "start",
//              "approach_time_s", "completed", "aborted_at_s"}, ...], "realtime_factor": r}
// water_ml_per_min: the jets' mean total flow by eq. (26) on the plant's jet forces.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>
#include <string>
#include <sys/stat.h>
#include <thread>
#include <vector>

#include "hydrojet_control/config/controller_config.h"
#include "hydrojet_control/config/plant_config.h"
#include "hydrojet_control/sim/closed_loop_run.h"
#include "hydrojet_control/util/json_writer.h"

using namespace hydrojet;

namespace {

struct Job {
  control::LoopMode mode;
  int tilt_deg;
  unsigned seed;
  int config = 0;  ///< index into Setup's configurations
  sim::RunResult result;
};

void usage() {
  std::cerr << "usage: experiment (--scene0 FILE --scene30 FILE | --scene FILE) --plant FILE --controller FILE\n"
               "                  [--out DIR] [--quick] [--seeds N] [--duration S] [--threads N]\n"
               "                  [--path FILE] [--start rest|on-path]\n"
               "  --scene FILE: one scene (any robot) at the base tilt of its gravity, instead of the two\n"
               "  --path FILE: a path file (t, theta, phi rows, CSV or YAML) instead of the spiral; its own\n"
               "               duration sets the run's (--duration is the spiral's)\n"
               "  --start rest: the paper's protocol (default); on-path: approach the path's first direction,\n"
               "               then start its clock; the error counts from there\n";
}

void write_run_csv(const std::string& path, const sim::RunResult& r) {
  std::ofstream f(path);
  const int n = r.samples.empty() ? 3 : static_cast<int>(r.samples.front().jet_force.size());
  f << "t,des_x,des_y,des_z,meas_x,meas_y,meas_z,tip_x,tip_y,tip_z,err_geodesic,err_pitch_yaw,true_x,true_y,true_z,"
       "err_true";
  for (int i = 0; i < n; ++i) f << ",q" << i + 1;  // actuator forces [N]
  // Contact (docs/contact.md): the truth (normal force [N], clearance [m], external force [N]) and the
  // controller's flag and estimate [N], base frame.
  f << ",contact_force,clearance,ext_x,ext_y,ext_z,contact_flag,est_x,est_y,est_z\n";
  char buf[512];
  for (const auto& s : r.samples) {
    std::snprintf(buf, sizeof(buf), "%.3f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6e,%.6e,%.6e,%.6e,%.6e", s.t, s.desired.x(),
                  s.desired.y(), s.desired.z(), s.measured.x(), s.measured.y(), s.measured.z(), s.tip_position.x(),
                  s.tip_position.y(), s.tip_position.z(), s.error_geodesic, s.error_pitch_yaw);
    f << buf;
    std::snprintf(buf, sizeof(buf), ",%.6f,%.6f,%.6f,%.6e", s.truth.x(), s.truth.y(), s.truth.z(), s.error_true);
    f << buf;
    for (int i = 0; i < s.jet_force.size(); ++i) {
      std::snprintf(buf, sizeof(buf), ",%.5f", s.jet_force[i]);
      f << buf;
    }
    std::snprintf(buf, sizeof(buf), ",%.6f,%.6e,%.6f,%.6f,%.6f,%d,%.6f,%.6f,%.6f", s.contact_force, s.clearance,
                  s.external_force.x(), s.external_force.y(), s.external_force.z(), s.contact_flag ? 1 : 0,
                  s.external_force_estimate.x(), s.external_force_estimate.y(), s.external_force_estimate.z());
    f << buf << "\n";
  }
}

/// The command line.
struct Args {
  std::string scene0, scene30, scene, plant_file, controller_file, out = ".build/experiment";
  std::string path_file;                       ///< --path: a path file instead of the spiral
  sim::RunStart start = sim::RunStart::kRest;  ///< --start
  bool quick = false;
  int seeds = 5, threads = 2;
  double duration = 0.0;  ///< path duration [s]; 0 = the controller file's
};

/// The configurations (0° and 30° base tilt, or the one --scene): controller options, model and
/// plant of each.
struct Setup {
  config::ControllerNodeOptions copt;
  int count = 2;
  int tilt_deg[2] = {0, 30};
  control::RobotModel model[2];
  plant::PlantModel plant[2];
  std::shared_ptr<const control::Path> path;  ///< --path's (null: the controller file's spiral)
};

/// Parses the command line into *a; returns false (after printing why) on a usage error.
bool parse_args(int argc, char** argv, Args* a) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "experiment: " << arg << ": expects a value\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "--scene0")
      a->scene0 = next();
    else if (arg == "--scene")
      a->scene = next();
    else if (arg == "--scene30")
      a->scene30 = next();
    else if (arg == "--plant")
      a->plant_file = next();
    else if (arg == "--controller")
      a->controller_file = next();
    else if (arg == "--out")
      a->out = next();
    else if (arg == "--quick")
      a->quick = true;
    else if (arg == "--seeds")
      a->seeds = std::atoi(next().c_str());
    else if (arg == "--duration")
      a->duration = std::atof(next().c_str());
    else if (arg == "--threads")
      a->threads = std::atoi(next().c_str());
    else if (arg == "--path")
      a->path_file = next();
    else if (arg == "--start") {
      const std::string v = next();
      if (!sim::parse_run_start(v, &a->start)) {
        std::cerr << "experiment: --start: must be rest or on-path, got '" << v << "'\n";
        return false;
      }
    } else {
      std::cerr << "experiment: " << arg << ": unknown argument\n";
      usage();
      return false;
    }
  }
  return true;
}

/// Checks the arguments and applies --quick; returns false (after printing why) when unusable.
bool check_args(Args* a) {
  const bool two = !a->scene0.empty() && !a->scene30.empty();
  if (two == !a->scene.empty() || a->controller_file.empty()) {
    usage();
    return false;
  }
  if (a->seeds < 1 || a->threads < 1 || a->duration < 0) {
    std::cerr << "experiment: --seeds, --threads must be >= 1 and --duration >= 0\n";
    return false;
  }
  if (a->quick) {
    a->seeds = std::min(a->seeds, 2);
    if (a->duration == 0.0) a->duration = 120.0;
  }
  return true;
}

/// Loads the controller options, both scenes and the plant; returns false (after printing why) on
/// a configuration error.
bool load_setup(const Args& a, Setup* s) {
  try {
    s->copt = config::load_controller_options(a.controller_file);
    for (const std::string& w : s->copt.warnings) std::fprintf(stderr, "experiment: %s\n", w.c_str());
    if (a.duration > 0.0) s->copt.controller.path.duration = a.duration;
    if (!a.path_file.empty()) s->path = control::load_path_file(a.path_file);
    const std::string scenes[2] = {a.scene.empty() ? a.scene0 : a.scene, a.scene30};
    s->count = a.scene.empty() ? 2 : 1;
    for (int k = 0; k < s->count; ++k) {
      const config::Scene sc = config::load_scene(scenes[k]);
      s->model[k] = config::make_controller_model(sc, s->copt.flow_regulator);
      s->plant[k] = config::load_plant(sc, a.plant_file);
      const Eigen::Vector3d g = sc.rod.gravity;
      if (s->count == 1) s->tilt_deg[k] = sim::base_tilt_deg(g);
    }
  } catch (const std::exception& e) {
    std::cerr << "experiment: " << e.what() << "\n";
    return false;
  }
  return true;
}

/// Open and closed loop in every configuration, seeds 1..seeds each.
std::vector<Job> make_jobs(const Setup& setup, int seeds) {
  std::vector<Job> jobs;
  for (int k = 0; k < setup.count; ++k)
    for (control::LoopMode m : {control::LoopMode::kOpen, control::LoopMode::kClosed})
      for (int s = 0; s < seeds; ++s) jobs.push_back({m, setup.tilt_deg[k], static_cast<unsigned>(s + 1), k, {}});
  return jobs;
}

/// Runs the jobs on `threads` threads, reporting each on stderr as it ends.
void run_jobs(std::vector<Job>& jobs, const Setup& setup, int threads, sim::RunStart start) {
  std::mutex mu;
  size_t next_job = 0;
  auto worker = [&]() {
    while (true) {
      size_t j;
      {
        std::lock_guard<std::mutex> lock(mu);
        if (next_job >= jobs.size()) return;
        j = next_job++;
      }
      Job& job = jobs[j];
      control::ControllerOptions p = setup.copt.controller;
      p.mode = job.mode;
      sim::RunPlan plan;
      plan.path = setup.path;
      plan.start = start;
      plan.control_period = 1.0 / setup.copt.rate;
      job.result = sim::run_path(setup.model[job.config], p, setup.plant[job.config], job.seed, plan);
      std::lock_guard<std::mutex> lock(mu);
      std::fprintf(stderr, "  %-6s %2d deg seed %u: rms %.4f rad, %s (%.1f s simulated in %.1f s)\n",
                   control::to_string(job.mode), job.tilt_deg, job.seed, job.result.rms,
                   job.result.completed ? "completed" : ("ABORTED: " + job.result.reason).c_str(),
                   job.result.simulated_seconds, job.result.wall_seconds);
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
}

/// The run's contact figures (sim::ContactSummary): a figure with nothing to measure is null.
void add_contact(util::JsonObject& o, const sim::ContactSummary& c) {
  auto number_or_null = [&o](const char* key, double v) {
    if (std::isfinite(v))
      o.add(key, v);
    else
      o.add_null(key);
  };
  o.add("contact_onsets", c.onsets);
  number_or_null("detection_delay_s", c.detection_delay_s);
  o.add("missed_contact_s", c.missed_contact_s).add("false_contact_s", c.false_contact_s);
  o.add("max_contact_force_n", c.max_contact_force_n);
  number_or_null("max_contact_force_after_detection_n", c.max_contact_force_after_detection_n);
  o.add("external_force_rms_error_n", c.external_force_rms_error_n);
  number_or_null("min_clearance_m", c.min_clearance_m);
}

/// Writes a CSV per run and summary.csv into out; returns the JSON array of the runs and the
/// realtime factor (simulated / wall seconds over all runs).
std::string write_results(const std::vector<Job>& jobs, const std::string& out, double* realtime_factor) {
  mkdir(out.c_str(), 0755);
  std::ofstream summary(out + "/summary.csv");
  summary << "mode,tilt_deg,seed,completed,aborted_at_s,rms_rad,median_rad,q1_rad,q3_rad,max_rad,rms_pitch_yaw_rad,"
             "reason,start,approach_time_s,rms_true_rad\n";
  double sim_s = 0.0, wall_s = 0.0;
  std::string runs = "[";
  for (size_t j = 0; j < jobs.size(); ++j) {
    const Job& job = jobs[j];
    const sim::RunResult& r = job.result;
    const std::string name = std::string(control::to_string(job.mode)) + "_" + std::to_string(job.tilt_deg) +
                             "deg_seed" + std::to_string(job.seed);
    write_run_csv(out + "/run_" + name + ".csv", r);
    summary << control::to_string(job.mode) << "," << job.tilt_deg << "," << job.seed << "," << (r.completed ? 1 : 0)
            << "," << (r.aborted_at >= 0 ? std::to_string(r.aborted_at) : "") << "," << r.rms << "," << r.median << ","
            << r.q1 << "," << r.q3 << "," << r.max << "," << r.rms_pitch_yaw << ",\"" << r.reason << "\","
            << sim::to_string(r.start) << "," << r.approach_time << "," << r.rms_true << "\n";
    sim_s += r.simulated_seconds;
    wall_s += r.wall_seconds;
    util::JsonObject o;
    o.add("mode", control::to_string(job.mode)).add("tilt_deg", job.tilt_deg).add("seed", static_cast<int>(job.seed));
    o.add("rms_rad", r.rms).add("rms_true_rad", r.rms_true).add("water_ml_per_min", sim::ml_per_min(r.water_flow));
    o.add("start", sim::to_string(r.start)).add("approach_time_s", r.approach_time);
    o.add("completed", r.completed);
    if (r.aborted_at >= 0)
      o.add("aborted_at_s", r.aborted_at);
    else
      o.add_null("aborted_at_s");
    o.add("time_scale", r.time_scale).add("reach_limited_s", r.reach_limited_s).add("keep_out_s", r.keep_out_s);
    o.add("supervisor_fallbacks", r.supervisor_fallbacks).add("supervised_s", r.supervised_s);
    o.raw("identified", sim::identity_json(r.identified, true)).raw("plant_truth", sim::identity_json(r.truth, false));
    add_contact(o, r.contact);
    runs += (j ? ", " : "") + o.str();
  }
  *realtime_factor = wall_s > 0 ? sim_s / wall_s : 0.0;
  return runs + "]";
}

/// Table like §7.5–7.7: per configuration, RMS / median / IQR over the seeds' samples.
void print_table(const std::vector<Job>& jobs, const Args& a, double path_duration) {
  std::printf("\n%-8s %-5s %-6s %-10s %-10s %-10s %-10s %s\n", "mode", "tilt", "seed", "RMS [rad]", "median", "IQR",
              "max", "outcome");
  for (const Job& job : jobs) {
    const sim::RunResult& r = job.result;
    char outcome[160];
    if (r.completed)
      std::snprintf(outcome, sizeof(outcome), "completed");
    else
      std::snprintf(outcome, sizeof(outcome), "aborted at %.1f s: %s", r.aborted_at, r.reason.c_str());
    std::printf("%-8s %3d°  %-6u %-10.4f %-10.4f %-10.4f %-10.4f %s\n", control::to_string(job.mode), job.tilt_deg,
                job.seed, r.rms, r.median, r.q3 - r.q1, r.max, outcome);
  }
  std::printf("paper (hardware): open 0.09 / 0.18 rad, closed 0.03 / 0.035 rad RMS at 0° / 30°\n");
  std::printf("path %.0f s, %d seeds; CSV in %s\n", path_duration, a.seeds, a.out.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (!parse_args(argc, argv, &args) || !check_args(&args)) return 2;
  Setup setup;
  if (!load_setup(args, &setup)) return 2;
  std::vector<Job> jobs = make_jobs(setup, args.seeds);
  run_jobs(jobs, setup, args.threads, args.start);
  double realtime_factor = 0.0;
  const std::string runs = write_results(jobs, args.out, &realtime_factor);
  print_table(jobs, args, setup.copt.controller.path.duration);
  util::JsonObject last;
  last.raw("runs", runs).add("realtime_factor", realtime_factor);
  std::printf("%s\n", last.str().c_str());
  return 0;
}
