// The `calibrate` command line (see app.h and docs/calibration.md).
#include "hydrojet_control/calibration/app.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "hydrojet_control/calibration/bag_reader.h"
#include "hydrojet_control/calibration/calibrator.h"
#include "hydrojet_control/calibration/scene_writer.h"
#include "hydrojet_control/calibration/synthetic.h"
#include "hydrojet_control/util/json_writer.h"

#include <yaml-cpp/yaml.h>

namespace hydrojet {
namespace calibration {
namespace {

/// Bad command-line input (exit 2).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

double parse_double(const std::string& opt, const std::string& s) {
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v))
    throw UsageError(opt + ": '" + s + "' is not a finite number");
  return v;
}

int parse_int(const std::string& opt, const std::string& s, int lo, int hi) {
  const double v = parse_double(opt, s);
  if (v != std::floor(v) || v < lo || v > hi)
    throw UsageError(opt + ": must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
                     s);
  return static_cast<int>(v);
}

double positive(const std::string& opt, const std::string& s) {
  const double v = parse_double(opt, s);
  if (!(v > 0.0)) throw UsageError(opt + ": must be positive, got " + s);
  return v;
}

std::string read_text(const std::string& path, const std::string& what) {
  std::ifstream f(path);
  if (!f) throw UsageError(what + ": cannot read file '" + path + "'");
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

void write_text(const std::string& path, const std::string& text, const std::string& what) {
  std::ofstream f(path);
  f << text;
  f.close();
  if (!f) throw UsageError(what + ": cannot write file '" + path + "'");
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof(b), f, v);
  return b;
}

std::string json_params(const Zeta& zeta, const ZetaVector& v, const ParamMask* only = nullptr) {
  util::JsonObject o;
  for (int i = 0; i < zeta.size(); ++i) {
    if ((only && !(*only)[i]) || !std::isfinite(v[i]))
      o.add_null(zeta[i].name);
    else
      o.add(zeta[i].name, v[i]);
  }
  return o.str();
}

std::string json_strings(const std::vector<std::string>& v) {
  std::string s = "[";
  for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + util::JsonObject::quote(v[i]);
  return s + "]";
}

struct Args {
  std::string scene, data, out, samples_out;
  std::string fit;  ///< empty: the scene's default (Zeta::default_fit)
  double outer = -1.0, inner = -1.0;
  CalibrationOptions opt;
  QuasistaticOptions qs;
  BagTopics topics;
  std::vector<std::string> bounds;  ///< --bound NAME=LO:HI, applied after the defaults
  int synthetic_samples = 0;        ///< --synthesize N
  double noise_deg = 0.5, max_force_fraction = 0.9;
  unsigned seed = 1;
  bool help = false;
};

/// --scene, --data, --out, --samples-out, --fit, --bound, the cross-section and the fit's options;
/// false when `k` is none of them.
bool set_fit_option(const std::string& k, const std::string& v, Args* r) {
  if (k == "--scene")
    r->scene = v;
  else if (k == "--data")
    r->data = v;
  else if (k == "--out")
    r->out = v;
  else if (k == "--samples-out")
    r->samples_out = v;
  else if (k == "--fit")
    r->fit = v;
  else if (k == "--bending-scale") {
    if (v == "auto")
      r->opt.bending_scale = BendingScale::kAuto;
    else if (v == "per-segment")
      r->opt.bending_scale = BendingScale::kPerSegment;
    else
      throw UsageError(k + ": unknown value '" + v + "' (auto, per-segment)");
  } else if (k == "--bound")
    r->bounds.push_back(v);
  else if (k == "--outer-diameter")
    r->outer = positive(k, v);
  else if (k == "--inner-diameter") {
    r->inner = parse_double(k, v);
    if (r->inner < 0) throw UsageError(k + ": must not be negative");
  } else if (k == "--loss") {
    if (v == "none")
      r->opt.loss = Loss::kNone;
    else if (v == "huber")
      r->opt.loss = Loss::kHuber;
    else if (v == "cauchy")
      r->opt.loss = Loss::kCauchy;
    else
      throw UsageError(k + ": unknown loss '" + v + "' (none, huber, cauchy)");
  } else if (k == "--loss-scale")
    r->opt.loss_scale = positive(k, v);
  else if (k == "--max-iterations")
    r->opt.max_iterations = parse_int(k, v, 1, 100000);
  else if (k == "--threads")
    r->opt.num_threads = parse_int(k, v, 1, 256);
  else
    return false;
  return true;
}

/// The bag's topics and the quasistatic extraction's thresholds; false when `k` is none of them.
bool set_bag_option(const std::string& k, const std::string& v, Args* r) {
  if (k == "--tip-topic")
    r->topics.tip = v;
  else if (k == "--base-topic")
    r->topics.base = v;
  else if (k == "--jets-topic")
    r->topics.jets = v;
  else if (k == "--window")
    r->qs.window = positive(k, v);
  else if (k == "--max-force-std")
    r->qs.max_force_std = positive(k, v);
  else if (k == "--max-force-drift")
    r->qs.max_force_drift = positive(k, v);
  else if (k == "--max-angle-std")
    r->qs.max_angle_std = positive(k, v);
  else if (k == "--max-angle-drift")
    r->qs.max_angle_drift = positive(k, v);
  else if (k == "--max-pair-dt")
    r->qs.max_pair_dt = positive(k, v);
  else
    return false;
  return true;
}

/// --synthesize and its options; false when `k` is none of them.
bool set_synthesis_option(const std::string& k, const std::string& v, Args* r) {
  if (k == "--synthesize")
    r->synthetic_samples = parse_int(k, v, 1, 1000000);
  else if (k == "--noise-deg") {
    r->noise_deg = parse_double(k, v);
    if (r->noise_deg < 0) throw UsageError(k + ": must not be negative");
  } else if (k == "--seed")
    r->seed = static_cast<unsigned>(parse_int(k, v, 0, 2147483647));
  else if (k == "--max-force-fraction") {
    r->max_force_fraction = positive(k, v);
    if (r->max_force_fraction > 1.0) throw UsageError(k + ": must lie in (0, 1]");
  } else
    return false;
  return true;
}

/// The required options of the chosen mode.
void check_required(const Args& r) {
  if (r.scene.empty()) throw UsageError("--scene: missing (the scene YAML with geometry and starting values)");
  if (r.synthetic_samples == 0 && r.data.empty()) throw UsageError("--data: missing (CSV or rosbag)");
  if (r.out.empty())
    throw UsageError(r.synthetic_samples ? "--out: missing (CSV to write)" : "--out: missing (scene YAML to write)");
}

Args parse_args(const std::vector<std::string>& a) {
  Args r;
  for (size_t i = 0; i < a.size(); ++i) {
    const std::string& k = a[i];
    if (k == "--help" || k == "-h") {
      r.help = true;
      continue;
    }
    if (k.rfind("--", 0) != 0) throw UsageError("unexpected argument '" + k + "'");
    if (i + 1 >= a.size()) throw UsageError(k + ": missing value");
    const std::string v = a[++i];
    if (!set_fit_option(k, v, &r) && !set_bag_option(k, v, &r) && !set_synthesis_option(k, v, &r))
      throw UsageError("unknown option '" + k + "' (see --help)");
  }
  if (!r.help) check_required(r);
  return r;
}

/// The scene (its text, for the calibrated copy), the cross-section (the scene's, or the command
/// line's diameters; the paper's form only) and its ζ.
struct StartScene {
  std::string text;
  config::Scene scene;
  CrossSection cs;
  std::optional<Zeta> zeta;
};

StartScene load_start_scene(const Args& a) {
  StartScene s;
  s.text = read_text(a.scene, "--scene");
  s.scene = config::parse_scene(s.text);
  s.cs = cross_section_from_scene_text(s.text, CrossSection());
  if (a.outer > 0) s.cs.outer_diameter = a.outer;
  if (a.inner >= 0) s.cs.inner_diameter = a.inner;
  const std::string cse = s.cs.validate();
  if (!cse.empty()) throw UsageError("cross-section: " + cse + " (--outer-diameter / --inner-diameter)");
  s.zeta.emplace(s.scene, s.cs);
  if (!s.zeta->paper_form() && (a.outer > 0 || a.inner >= 0))
    throw UsageError(
        "--outer-diameter / --inner-diameter: only for a scene fitted in moduli (one segment with a jets section); "
        "this scene's stiffness is fitted as scales");
  return s;
}

/// The fit's options: --fit as a mask of the scene's ζ, the --bound overrides applied to the
/// default bounds.
CalibrationOptions calibration_options(const Args& a, const StartScene& s) {
  const Zeta& zeta = *s.zeta;
  CalibrationOptions opt = a.opt;
  if (!a.fit.empty()) {
    try {
      opt.fit = zeta.parse(a.fit);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--fit: ") + e.what());
    }
  }
  if (a.bounds.empty()) return opt;
  opt.has_bounds = true;
  opt.bounds = default_bounds(zeta);
  for (const std::string& b : a.bounds) {
    const size_t eq = b.find('='), colon = b.find(':', eq == std::string::npos ? 0 : eq);
    if (eq == std::string::npos || colon == std::string::npos)
      throw UsageError("--bound: '" + b + "' is not NAME=LO:HI (e.g. E=1e6:1e7)");
    const int i = zeta.index(b.substr(0, eq));
    if (i < 0) throw UsageError("--bound: unknown parameter '" + b.substr(0, eq) + "' (" + zeta.names() + ")");
    opt.bounds.lower[i] = parse_double("--bound " + b.substr(0, eq), b.substr(eq + 1, colon - eq - 1));
    opt.bounds.upper[i] = parse_double("--bound " + b.substr(0, eq), b.substr(colon + 1));
    if (!(opt.bounds.lower[i] < opt.bounds.upper[i])) throw UsageError("--bound " + b + ": LO must be below HI");
  }
  return opt;
}

/// --synthesize: writes samples of the scene's own model and reports them.
int run_synthesis(const Args& a, const StartScene& s, std::ostream& out) {
  SyntheticOptions so;
  so.samples = a.synthetic_samples;
  so.noise_rad = a.noise_deg * M_PI / 180.0;
  so.seed = a.seed;
  so.max_force_fraction = a.max_force_fraction;
  const std::vector<Sample> samples = synthesise(s.scene, so);
  write_text(a.out, to_csv(samples), "--out");
  util::JsonObject j;
  j.add("samples", static_cast<int>(samples.size()))
      .add("noise_rad", so.noise_rad)
      .add("seed", static_cast<int>(a.seed));
  j.raw("parameters", json_params(*s.zeta, s.zeta->start())).add("out", a.out);
  out << "calibrate: wrote " << samples.size() << " synthetic samples of the scene's model (noise " << a.noise_deg
      << " deg per axis) to " << a.out << "\n"
      << j.str() << "\n";
  return 0;
}

/// The static samples: a CSV, or the quasistatic intervals of a rosbag (summarised in `rep`).
std::vector<Sample> read_samples(const Args& a, const config::Scene& scene, std::ostream& rep) {
  if (!is_rosbag(a.data)) return read_csv(a.data, scene.rod.actuators);
  if (!scene.jets)
    throw UsageError(
        "--data: a rosbag holds the three jets' flows (jets/state); this scene has no jets section, "
        "give its data as a CSV (q1..q" +
        std::to_string(scene.rod.input_count()) + ",qw,qx,qy,qz)");
  const BagRecords br = read_bag(a.data, a.topics);
  const Extraction ex = extract_quasistatic(br.jets, br.tip, br.base, scene.nozzle, a.qs);
  rep << "bag " << a.data << ": " << br.tip.size() << " tip, " << br.base.size() << " base, " << br.jets.size()
      << " jet-state messages; " << ex.paired_points << " paired points (" << ex.skipped_points << " skipped); "
      << ex.quasistatic_windows << " of " << ex.windows << " windows quasistatic; " << ex.samples.size()
      << " static samples (" << ex.merged_intervals << " repeated intervals merged)\n";
  return ex.samples;
}

/// The table of start, estimate and std per parameter, and the correlations of the fitted ones.
void report_parameters(const Zeta& zeta, const CalibrationResult& res, std::ostream& rep) {
  rep << "parameter        start            estimate         std              unit\n";
  for (int i = 0; i < zeta.size(); ++i) {
    char line[200];
    std::snprintf(line, sizeof(line), "%-6s %-9s %-16.6g %-16.6g %-16s %s\n", zeta[i].name.c_str(),
                  res.fitted[i] ? "" : "(fixed)", res.start[i], res.zeta[i],
                  res.fitted[i] && std::isfinite(res.stddev[i]) ? fmt("%.3g", res.stddev[i]).c_str() : "-",
                  zeta[i].unit.empty() ? "(scale)" : zeta[i].unit.c_str());
    rep << line;
  }
  rep << "correlations:\n       ";
  for (int j = 0; j < zeta.size(); ++j)
    if (res.fitted[j]) rep << std::string(8 - std::min<size_t>(7, zeta[j].name.size()), ' ') << zeta[j].name;
  rep << "\n";
  for (int i = 0; i < zeta.size(); ++i) {
    if (!res.fitted[i]) continue;
    rep << zeta[i].name << std::string(7 - std::min<size_t>(6, zeta[i].name.size()), ' ');
    for (int j = 0; j < zeta.size(); ++j)
      if (res.fitted[j])
        rep << (std::isfinite(res.correlation(i, j)) ? fmt("%8.3f", res.correlation(i, j)) : std::string("       -"));
    rep << "\n";
  }
}

std::string input_list(const rod::InputVector& q) {
  std::string s = "[";
  for (Eigen::Index i = 0; i < q.size(); ++i) s += (i ? ", " : "") + fmt("%.4f", q[i]);
  return s + "]";
}

/// The per-sample errors, the RMS, the fit's cost and its warnings (also on `err`).
void report_residuals(const CalibrationResult& res, const std::vector<Sample>& samples, std::ostream& rep,
                      std::ostream& err) {
  rep << "per-sample orientation error [deg]:\n";
  for (size_t k = 0; k < res.sample_error_rad.size(); ++k) {
    char line[300];
    std::snprintf(line, sizeof(line), "  %-28s q = %s N  %.3f\n", samples[k].origin.c_str(),
                  input_list(samples[k].inputs).c_str(), res.sample_error_rad[k] * 180.0 / M_PI);
    rep << line;
  }
  rep << "RMS residual: " << fmt("%.6g", res.rms_rad) << " rad (" << fmt("%.3f", res.rms_rad * 180 / M_PI)
      << " deg; start " << fmt("%.3f", res.start_rms_rad * 180 / M_PI) << " deg); sigma per axis "
      << fmt("%.3g", res.sigma_rad) << " rad\n";
  rep << "fit: " << res.iterations << " iterations, " << res.rod_solves << " rod solves (" << res.failed_solves
      << " failed), " << fmt("%.3f", res.time_s) << " s; " << res.message << "\n";
  for (const std::string& w : res.warnings) {
    rep << "WARNING: " << w << "\n";
    err << "calibrate: warning: " << w << "\n";
  }
}

/// "per-segment" / "common" when the scene has segments of their own bending scale, else "".
std::string bending_scale_mode(const Zeta& zeta, const CalibrationResult& res) {
  if (zeta.common_bending_scale() < 0) return "";
  if (res.fitted[zeta.common_bending_scale()]) return "common";
  for (int k : zeta.segment_bending_scales())
    if (res.fitted[k]) return "per-segment";
  return "";
}

/// The `calibration` section of the output scene: data, start, what was fitted and how well.
YAML::Node calibration_summary(const Args& a, const Zeta& zeta, const CalibrationResult& res, size_t samples) {
  YAML::Node cal(YAML::NodeType::Map);
  cal["data"] = a.data;
  cal["start_scene"] = a.scene;
  cal["samples"] = static_cast<int>(samples);
  YAML::Node fl(YAML::NodeType::Sequence), sd(YAML::NodeType::Map), id(YAML::NodeType::Map);
  for (int i = 0; i < zeta.size(); ++i) {
    if (!res.fitted[i]) continue;
    fl.push_back(zeta[i].name);
    sd[zeta[i].name] = std::isfinite(res.stddev[i]) ? YAML::Node(yaml_number(res.stddev[i])) : YAML::Node();
    id[zeta[i].name] = static_cast<bool>(res.identifiable[i]);
  }
  fl.SetStyle(YAML::EmitterStyle::Flow);
  sd.SetStyle(YAML::EmitterStyle::Flow);
  id.SetStyle(YAML::EmitterStyle::Flow);
  cal["fitted"] = fl;
  cal["rms_rad"] = yaml_number(res.rms_rad);
  cal["start_rms_rad"] = yaml_number(res.start_rms_rad);
  cal["std"] = sd;
  cal["identifiable"] = id;
  const std::string mode = bending_scale_mode(zeta, res);
  if (!mode.empty()) cal["bending_scale"] = mode;
  return cal;
}

/// Writes the calibrated scene when the fit converged; true when written.
bool write_calibrated_scene(const Args& a, const StartScene& s, const CalibrationResult& res, size_t samples,
                            std::ostream& rep, std::ostream& err) {
  if (!res.converged) {
    rep << "not converged: " << a.out << " not written\n";
    err << "calibrate: the fit did not converge (" << res.message << "); " << a.out << " not written\n";
    return false;
  }
  const std::string comment = "Scene calibrated by `calibrate` (paper §6.2, eq. 27).\nData: " + a.data +
                              "; start: " + a.scene + ".\nRMS orientation residual " + fmt("%.4g", res.rms_rad) +
                              " rad over " + std::to_string(samples) +
                              " samples; the `calibration` section summarises the fit (load_scene ignores it).";
  write_text(a.out,
             calibrated_scene_yaml(s.text, *s.zeta, res.zeta, comment, calibration_summary(a, *s.zeta, res, samples)),
             "--out");
  rep << "wrote " << a.out << "\n";
  return true;
}

/// The last stdout line: the result as one JSON object.
std::string result_json(const Zeta& zeta, const CalibrationResult& res, size_t samples, const std::string* written) {
  util::JsonObject j;
  j.add("converged", res.converged).add("rms_rad", res.rms_rad);
  j.raw("parameters", json_params(zeta, res.zeta));
  j.raw("std", json_params(zeta, res.stddev, &res.fitted));
  j.add("time_s", res.time_s);
  j.add("samples", static_cast<int>(samples)).add("start_rms_rad", res.start_rms_rad);
  j.add("sigma_rad", res.sigma_rad).add("iterations", res.iterations).add("rod_solves", res.rod_solves);
  util::JsonObject ident;
  for (int i = 0; i < zeta.size(); ++i)
    if (res.fitted[i]) ident.add(zeta[i].name, static_cast<bool>(res.identifiable[i]));
  j.raw("identifiable", ident.str());
  const std::string mode = bending_scale_mode(zeta, res);
  if (!mode.empty()) j.add("bending_scale", mode);
  j.raw("warnings", json_strings(res.warnings));
  if (written) j.add("out", *written);
  return j.str();
}

/// Fit mode: samples → fit → report, calibrated scene and JSON. 0 converged, 1 not.
int run_fit(const Args& a, const StartScene& s, const CalibrationOptions& opt, std::ostream& out, std::ostream& err) {
  std::ostringstream rep;  // the report; written to `out` only when the input was good
  const std::vector<Sample> samples = read_samples(a, s.scene, rep);
  if (!a.samples_out.empty()) write_text(a.samples_out, to_csv(samples), "--samples-out");
  const Zeta& zeta = *s.zeta;
  const Eigen::Vector3d& k = s.scene.rod.segments[0].stiffness;
  if (zeta.paper_form() && std::abs(k.x() - k.y()) > 1e-9 * std::abs(k.x()))
    rep << "note: the scene's EI_x and EI_y differ; E starts from their mean and the output is isotropic\n";

  const CalibrationResult res = calibrate(zeta, samples, opt);

  std::string fitted_list;
  for (int i = 0; i < zeta.size(); ++i)
    if (res.fitted[i]) fitted_list += (fitted_list.empty() ? "" : " ") + zeta[i].name;
  rep << "calibrate: " << samples.size() << " samples from " << a.data << "; fitting " << fitted_list;
  if (zeta.paper_form())
    rep << "; cross-section D = " << s.cs.outer_diameter << " m, d = " << s.cs.inner_diameter << " m";
  rep << "\n";
  report_parameters(zeta, res, rep);
  report_residuals(res, samples, rep, err);
  const bool wrote = write_calibrated_scene(a, s, res, samples.size(), rep, err);
  out << rep.str() << result_json(zeta, res, samples.size(), wrote ? &a.out : nullptr) << "\n";
  return res.converged ? 0 : 1;
}

}  // namespace

std::string calibrate_usage() {
  return "usage: calibrate --scene FILE --data FILE [--fit NAME,...] --out FILE.yaml\n"
         "                 [--bending-scale auto|per-segment] [--bound NAME=LO:HI ...]\n"
         "                 [--outer-diameter M] [--inner-diameter M]\n"
         "                 [--loss none|huber|cauchy]\n"
         "                 [--loss-scale RAD] [--max-iterations N] [--threads N]\n"
         "                 [--samples-out FILE.csv]\n"
         "       bag data: [--tip-topic T] [--base-topic T] [--jets-topic T] [--window S]\n"
         "                 [--max-force-std N] [--max-force-drift N] [--max-angle-std RAD]\n"
         "                 [--max-angle-drift RAD] [--max-pair-dt S]\n"
         "       calibrate --scene TRUTH.yaml --synthesize N [--noise-deg DEG] [--seed K]\n"
         "                 [--max-force-fraction F] --out DATA.csv\n"
         "Fits zeta to measured tip orientations. One segment with a jets section (the HydroJet):\n"
         "zeta = [ux, uy, E, G, da, db, dg] (paper eq. 27; diameters for E and G). Any other scene:\n"
         "per segment k ux<k>, uy<k> [1/m] and a bending-stiffness scale bend<k> (one common scale\n"
         "`bend` when the data cannot tell the segments apart), a torsional scale `twist`, and the\n"
         "tip actuators' mount rotation da, db, dg [rad]. --fit defaults to all of them (twist only\n"
         "when an actuator twists the rod).\n"
         "--data: CSV with header q1..qN,qw,qx,qy,qz (one input [N] per actuator in the scene's\n"
         "order, tip-in-base quaternion) or, for a jets scene, a rosbag of tracker/tip_pose,\n"
         "tracker/base_pose, jets/state. Last stdout line: one JSON object. Exit: 0 converged,\n"
         "1 not converged, 2 bad input.\n";
}

int run_calibrate(const std::vector<std::string>& argv, std::ostream& out, std::ostream& err) {
  try {
    const Args a = parse_args(argv);
    if (a.help) {
      out << calibrate_usage();
      return 0;
    }
    const StartScene s = load_start_scene(a);
    const CalibrationOptions opt = calibration_options(a, s);  // --bound is checked in either mode
    if (a.synthetic_samples > 0) return run_synthesis(a, s, out);
    return run_fit(a, s, opt, out, err);
  } catch (const UsageError& e) {
    err << "calibrate: " << e.what() << "\n";
  } catch (const config::SceneError& e) {
    err << "calibrate: scene: " << e.what() << "\n";
  } catch (const DataError& e) {
    err << "calibrate: data: " << e.what() << "\n";
  } catch (const std::invalid_argument& e) {
    err << "calibrate: " << e.what() << "\n";
  } catch (const std::exception& e) {
    err << "calibrate: error: " << e.what() << "\n";
  }
  return 2;
}

}  // namespace calibration
}  // namespace hydrojet
