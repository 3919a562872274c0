// rod_fk: solves the scene's rod model (the HydroJet, or any follower-actuated rod) for tip wrenches and prints one
// JSON object per solve. The interface is a contract other tools rely on (docs/numerics.md, "rod_fk"); keep it stable.
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "hydrojet_control/config/scene.h"
#include "hydrojet_control/config/wrench_batch.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/rod_solver.h"
#include "hydrojet_control/rod/stability.h"
#include "hydrojet_control/util/json_writer.h"

using hydrojet::rod::Vec3;
using hydrojet::util::JsonObject;

namespace {

const char* kUsage =
    "usage: rod_fk --scene FILE [--force FX FY FZ] [--moment MX MY MZ] [--integrator NAME]\n"
    "              [--steps N] [--tol X] [--compliance] [--shape K] [--batch FILE|-]\n"
    "              [--jets Q1 Q2 Q3]   (jet forces [N] through the scene's jet map, eq. 24)\n"
    "              [--actuators Q1 ... QN]   (the scene's actuators' inputs [N], in scene order)\n"
    "  --integrator: rk4 | rk8 | dopri5 | cvode-adams | cvode-bdf (default: the scene's)\n";

/// Bad input: one line on stderr naming the argument or key, nothing on stdout, exit 2.
struct BadInput {
  std::string what;
};

double parse_number(const std::string& text, const std::string& arg) {
  try {
    return hydrojet::config::parse_finite_number(text, arg);
  } catch (const hydrojet::config::BatchError& e) {
    throw BadInput{e.what()};
  }
}

struct Options {
  std::string scene;
  hydrojet::rod::TipWrench wrench;
  std::string integrator;
  int steps = 0;
  double tol = 0.0;
  bool compliance = false;
  int shape = 0;
  std::string batch;
  bool have_jets = false;
  Vec3 jets = Vec3::Zero();       ///< jet forces [N]
  std::vector<double> actuators;  ///< --actuators: inputs [N] in scene order (checked against the scene)
  bool have_actuators = false;
  bool have_wrench = false;
};

Options parse_args(int argc, char** argv) {
  Options o;
  auto need = [&](int i, int n, const std::string& a) {
    if (i + n >= argc) throw BadInput{a + ": expects " + std::to_string(n) + " value(s)"};
  };
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--scene") {
      need(i, 1, a);
      o.scene = argv[++i];
    } else if (a == "--force" || a == "--moment") {
      need(i, 3, a);
      Vec3 v;
      for (int k = 0; k < 3; ++k) v[k] = parse_number(argv[++i], a);
      (a == "--force" ? o.wrench.force : o.wrench.moment) = v;
      o.have_wrench = true;
    } else if (a == "--jets") {
      need(i, 3, a);
      for (int k = 0; k < 3; ++k) {
        o.jets[k] = parse_number(argv[++i], a);
        if (o.jets[k] < 0.0) throw BadInput{a + ": jet forces must not be negative"};
      }
      o.have_jets = true;
    } else if (a == "--actuators") {
      // As many numbers as follow (a negative number is an input: options start with "--").
      while (i + 1 < argc && std::strncmp(argv[i + 1], "--", 2) != 0) o.actuators.push_back(parse_number(argv[++i], a));
      if (o.actuators.empty()) throw BadInput{a + ": expects one input per actuator of the scene"};
      o.have_actuators = true;
    } else if (a == "--integrator") {
      need(i, 1, a);
      o.integrator = argv[++i];
    } else if (a == "--steps") {
      need(i, 1, a);
      const double v = parse_number(argv[++i], a);
      if (v < 1 || v > 100000 || v != std::floor(v)) throw BadInput{a + ": must be an integer in [1, 100000]"};
      o.steps = static_cast<int>(v);
    } else if (a == "--tol") {
      need(i, 1, a);
      o.tol = parse_number(argv[++i], a);
      if (!(o.tol > 0.0)) throw BadInput{a + ": must be positive"};
    } else if (a == "--compliance") {
      o.compliance = true;
    } else if (a == "--shape") {
      need(i, 1, a);
      const double v = parse_number(argv[++i], a);
      if (v < 1 || v > 100000 || v != std::floor(v)) throw BadInput{a + ": must be an integer in [1, 100000]"};
      o.shape = static_cast<int>(v);
    } else if (a == "--batch") {
      need(i, 1, a);
      o.batch = argv[++i];
    } else if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      std::exit(0);
    } else {
      throw BadInput{a + ": unknown argument"};
    }
  }
  if (o.scene.empty()) throw BadInput{"--scene: missing (required)"};
  if (o.have_jets && (o.have_wrench || !o.batch.empty()))
    throw BadInput{"--jets: cannot be combined with --force/--moment/--batch"};
  if (o.have_actuators && (o.have_jets || o.have_wrench || !o.batch.empty()))
    throw BadInput{"--actuators: cannot be combined with --jets/--force/--moment/--batch"};
  return o;
}

std::vector<hydrojet::rod::TipWrench> read_batch(const std::string& src) {
  std::ifstream file;
  std::istream* in = &std::cin;
  if (src != "-") {
    file.open(src);
    if (!file) throw BadInput{"--batch: cannot read file '" + src + "'"};
    in = &file;
  }
  try {
    return hydrojet::config::parse_wrench_batch(*in);
  } catch (const hydrojet::config::BatchError& e) {
    throw BadInput{e.what()};
  }
}

/// --actuators: one input per actuator, each within its [min_force, max_force].
void check_inputs(const hydrojet::config::Scene& scene, const std::vector<double>& q) {
  const auto& acts = scene.rod.actuators;
  if (q.size() != acts.size())
    throw BadInput{"--actuators: the scene has " + std::to_string(acts.size()) + " actuator(s), got " +
                   std::to_string(q.size()) + " input(s)"};
  const std::string e = scene.rod.check_inputs(Eigen::Map<const Eigen::VectorXd>(q.data(), q.size()));
  if (!e.empty()) throw BadInput{"--actuators: " + e};
}

/// The scene with the command line's integrator overrides; --jets are the inputs of its three jets.
hydrojet::config::Scene load_scene(Options* opt) {
  hydrojet::config::Scene scene = hydrojet::config::load_scene(opt->scene);
  if (!opt->integrator.empty() && !hydrojet::rod::parse_integrator(opt->integrator, &scene.solver.integrator.type))
    throw BadInput{"--integrator: unknown integrator '" + opt->integrator + "' (" + hydrojet::rod::integrator_names() +
                   ")"};
  if (opt->steps) scene.solver.integrator.steps = opt->steps;
  if (opt->tol > 0.0) scene.solver.integrator.tolerance = opt->tol;
  if (opt->have_jets) {
    if (!scene.jets) throw BadInput{"--jets: scene " + opt->scene + " has no jets section"};
    opt->actuators.assign(opt->jets.data(), opt->jets.data() + 3);
  }
  if (opt->have_actuators) check_inputs(scene, opt->actuators);
  return scene;
}

/// --compliance: C^b, J_q and the stability of eq. (23): on the scene's tip.actuated for a rod with
/// its actuators at the tip (the paper's σ_c), else on the block of C^b on the actuators' equivalent
/// tip wrenches. Null when not converged.
void add_compliance(hydrojet::rod::RodSolver& solver, const hydrojet::config::Scene& scene, bool converged,
                    JsonObject* j) {
  const bool actuated = solver.input_count() > 0;
  if (!converged) {
    j->add_null("compliance").add_null("stability_margin").add_null("stability_eig_min");
    if (actuated) j->add_null("actuation_jacobian");
    return;
  }
  const auto tc0 = std::chrono::steady_clock::now();
  const hydrojet::rod::Compliance c = solver.compliance();
  const auto tc1 = std::chrono::steady_clock::now();
  const auto st = actuated && !scene.rod.tip_actuated_uniform()
                      ? hydrojet::rod::stability(c.body, hydrojet::rod::equivalent_tip_wrenches(c.body, c.actuation),
                                                 scene.rod.length())
                      : hydrojet::rod::stability(c.body, scene.actuated);
  j->add("compliance", c.body)
      .add("stability_margin", st.margin)
      .add("stability_eig_min", st.eig_min)
      .add("compliance_time_us", std::chrono::duration<double, std::micro>(tc1 - tc0).count());
  if (actuated) j->add("actuation_jacobian", Eigen::MatrixXd(c.actuation));
}

/// The fields of every solve's JSON line.
JsonObject solution_json(const hydrojet::rod::RodSolution& sol, const hydrojet::config::Scene& scene, double time_us) {
  JsonObject j;
  j.add("converged", sol.converged)
      .add("iterations", sol.iterations)
      .add("residual", sol.residual)
      .add("tip_position", sol.tip_position)
      .add("tip_quaternion_wxyz", hydrojet::so3::quaternion_wxyz(sol.tip_rotation))
      .add("solve_time_us", time_us)
      .add("rhs_evaluations", sol.rhs_evaluations)
      .add("continuation_steps", sol.continuation_steps)
      .add("shooting_jacobian_det", sol.jacobian_det)
      .add("integrator", hydrojet::rod::integrator_name(scene.solver.integrator.type))
      .add("fold_crossings", sol.fold_crossings);
  if (!sol.warning.empty()) j.add("warning", sol.warning);
  if (!sol.converged) j.add("message", sol.message);
  return j;
}

/// --shape K: K+1 backbone points from base to tip over all segments (null when not converged).
void add_shape(const hydrojet::rod::RodSolver& solver, bool converged, int K, JsonObject* j) {
  if (!converged) {
    j->add_null("shape");
    return;
  }
  std::string pts = "[";
  const auto shape = solver.shape(K);
  for (size_t i = 0; i < shape.size(); ++i) pts += (i ? ", " : "") + JsonObject::matrix(shape[i]);
  j->raw("shape", pts + "]");
}

/// One solve: the actuators' inputs (--jets, --actuators; zero otherwise) and the tip wrench w.
std::string solve_json(hydrojet::rod::RodSolver& solver, const hydrojet::config::Scene& scene, const Options& opt,
                       const hydrojet::rod::TipWrench& w, bool* converged) {
  hydrojet::rod::InputVector q = hydrojet::rod::InputVector::Zero(solver.input_count());
  for (int i = 0; i < q.size() && i < static_cast<int>(opt.actuators.size()); ++i) q[i] = opt.actuators[i];
  const auto t0 = std::chrono::steady_clock::now();
  const hydrojet::rod::RodSolution sol = solver.solve(q, w);
  const auto t1 = std::chrono::steady_clock::now();
  *converged = sol.converged;
  JsonObject j = solution_json(sol, scene, std::chrono::duration<double, std::micro>(t1 - t0).count());
  if (opt.compliance) add_compliance(solver, scene, sol.converged, &j);
  if (opt.shape > 0) add_shape(solver, sol.converged, opt.shape, &j);
  return j.str();
}

/// Solves every wrench, one JSON line each; true when all converged.
bool run_all(const hydrojet::config::Scene& scene, const Options& opt,
             const std::vector<hydrojet::rod::TipWrench>& wrenches) {
  hydrojet::rod::RodSolver solver(scene.rod, scene.solver);
  bool all_converged = true;
  for (const auto& w : wrenches) {
    bool converged = false;
    std::cout << solve_json(solver, scene, opt, w, &converged) << "\n";
    all_converged = all_converged && converged;
  }
  std::cout.flush();
  return all_converged;
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  hydrojet::config::Scene scene;
  std::vector<hydrojet::rod::TipWrench> wrenches;
  try {
    opt = parse_args(argc, argv);
    scene = load_scene(&opt);
    wrenches = opt.batch.empty() ? std::vector<hydrojet::rod::TipWrench>{opt.wrench} : read_batch(opt.batch);
  } catch (const BadInput& e) {
    std::cerr << "rod_fk: " << e.what << "\n";
    return 2;
  } catch (const hydrojet::config::SceneError& e) {
    std::cerr << "rod_fk: scene " << opt.scene << ": " << e.what() << "\n";
    return 2;
  }

  return run_all(scene, opt, wrenches) ? 0 : 1;
}
