#include "hydrojet_control/calibration/quasistatic.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "hydrojet_control/rod/so3.h"

namespace hydrojet {
namespace calibration {
namespace {

/// std::sort, not std::stable_sort: the latter's temporary buffer ignores the over-alignment of
/// the Eigen members (a crash with AVX). Equal stamps keep no particular order (pairing is by time).
template <class R>
void sort_by_time(std::vector<R>* v) {
  std::sort(v->begin(), v->end(), [](const R& a, const R& b) { return a.t < b.t; });
}

/// Index of the record nearest to t within tol, or -1. `v` sorted by t.
template <class R>
int nearest(const std::vector<R>& v, double t, double tol) {
  auto it = std::lower_bound(v.begin(), v.end(), t, [](const R& r, double x) { return r.t < x; });
  int best = -1;
  double bd = tol;
  for (auto c : {it, it == v.begin() ? it : it - 1}) {
    if (c == v.end()) continue;
    const double d = std::abs(c->t - t);
    if (d <= bd) bd = d, best = static_cast<int>(c - v.begin());
  }
  return best;
}

bool usable(const Eigen::Quaterniond& q) { return q.coeffs().allFinite() && std::abs(q.norm() - 1.0) < 0.01; }

struct Point {
  double t;
  Eigen::Vector3d F;
  Eigen::Matrix3d R;
};

struct WindowStats {
  Eigen::Vector3d F_mean;
  Eigen::Matrix3d R_mean;
  double force_std = 0.0, force_drift = 0.0, angle_std = 0.0, angle_drift = 0.0;
};

WindowStats stats(const std::vector<Point>& p, int s, int e, double t_half) {
  WindowStats w;
  const int n = e - s + 1;
  const Eigen::Matrix3d& Rref = p[(s + e) / 2].R;
  Eigen::Vector3d F_sum = Eigen::Vector3d::Zero(), F1 = F_sum, F2 = F_sum, v_sum = F_sum, v1 = F_sum, v2 = F_sum;
  int n1 = 0, n2 = 0;
  std::vector<Eigen::Vector3d> v(n);
  for (int k = 0; k < n; ++k) {
    const Point& q = p[s + k];
    v[k] = so3::log(Rref.transpose() * q.R);
    F_sum += q.F;
    v_sum += v[k];
    if (q.t <= t_half)
      F1 += q.F, v1 += v[k], ++n1;
    else
      F2 += q.F, v2 += v[k], ++n2;
  }
  w.F_mean = F_sum / n;
  const Eigen::Vector3d m = v_sum / n;
  w.R_mean = Rref * so3::exp(m);
  Eigen::Vector3d F_var = Eigen::Vector3d::Zero();
  double a2 = 0.0;
  for (int k = 0; k < n; ++k) {
    F_var += (p[s + k].F - w.F_mean).cwiseAbs2();
    a2 += (v[k] - m).squaredNorm();
  }
  w.force_std = std::sqrt((F_var / std::max(1, n - 1)).maxCoeff());
  w.angle_std = std::sqrt(a2 / n);
  if (n1 > 0 && n2 > 0) {
    w.force_drift = (F2 / n2 - F1 / n1).cwiseAbs().maxCoeff();
    w.angle_drift = (v2 / n2 - v1 / n1).norm();
  } else {
    w.force_drift = w.angle_drift = std::numeric_limits<double>::infinity();
  }
  return w;
}

/// Pairs every tip pose with the nearest base pose and jet state (within max_pair_dt): the jet
/// forces (eq. 26) and the tip orientation in the base frame at each time point. All three sorted
/// by time; unpaired or unusable records are counted in ex->skipped_points.
std::vector<Point> pair_records(const std::vector<JetRecord>& jets, const std::vector<PoseRecord>& tip,
                                const std::vector<PoseRecord>& base, const actuation::Nozzle& nozzle,
                                const QuasistaticOptions& o, Extraction* ex) {
  std::vector<Point> pts;
  pts.reserve(tip.size());
  for (const PoseRecord& tr : tip) {
    const int b = nearest(base, tr.t, o.max_pair_dt);
    const int j = nearest(jets, tr.t, o.max_pair_dt);
    if (b < 0 || j < 0 || !usable(tr.orientation) || !usable(base[b].orientation) || !jets[j].valid ||
        !jets[j].flow.allFinite()) {
      ++ex->skipped_points;
      continue;
    }
    Point p;
    p.t = tr.t;
    for (int i = 0; i < 3; ++i) p.F[i] = actuation::force_from_flow(jets[j].flow[i], nozzle);
    p.R = base[b].orientation.normalized().toRotationMatrix().transpose() *
          tr.orientation.normalized().toRotationMatrix();
    pts.push_back(p);
  }
  return pts;
}

bool is_quasistatic(const WindowStats& w, const QuasistaticOptions& o) {
  return w.force_std <= o.max_force_std && w.force_drift <= o.max_force_drift && w.angle_std <= o.max_angle_std &&
         w.angle_drift <= o.max_angle_drift;
}

/// A run of quasistatic windows (end time, statistics).
using Run = std::vector<std::pair<double, WindowStats>>;

/// The run's sample: from the last window that ends at least end_guard before the run does (the
/// last windows of a run may already hold the first few points of the next transient, before it
/// shows in the tests).
void emit_sample(const Run& run, const QuasistaticOptions& o, Extraction* ex) {
  const double last_end = run.back().first;
  for (auto it = run.rbegin(); it != run.rend(); ++it) {
    if (it->first > last_end - o.end_guard + 1e-9) continue;
    Sample smp;
    smp.inputs = it->second.F_mean.cwiseMax(0.0);
    smp.tip_orientation = Eigen::Quaterniond(it->second.R_mean).normalized();
    char b[64];
    std::snprintf(b, sizeof(b), "bag t=%.2f s", it->first);
    smp.origin = b;
    // A noise spike or a slow creep can split one hold into two intervals: when the previous
    // sample has the same jet forces (within max_force_drift) it is the same hold, and the later
    // (more settled) sample replaces it.
    if (!ex->samples.empty()) {
      const double dF = (ex->samples.back().inputs - smp.inputs).cwiseAbs().maxCoeff();
      if (dF <= o.max_force_drift) {
        ex->samples.pop_back();
        ex->sample_time.pop_back();
        ++ex->merged_intervals;
      }
    }
    ex->samples.push_back(smp);
    ex->sample_time.push_back(it->first);
    return;
  }
}

/// Sliding windows ending at every point; each run of quasistatic windows gives one sample.
void scan_windows(const std::vector<Point>& pts, const QuasistaticOptions& o, Extraction* ex) {
  int s = 0;
  Run run;
  for (int e = 0; e < static_cast<int>(pts.size()); ++e) {
    const double t_end = pts[e].t;
    while (pts[s].t <= t_end - o.window) ++s;
    bool quasistatic = false;
    const int n = e - s + 1;
    if (n >= o.min_points && t_end - pts[s].t >= 0.75 * o.window) {
      ++ex->windows;
      const WindowStats w = stats(pts, s, e, t_end - 0.5 * o.window);
      quasistatic = is_quasistatic(w, o);
      if (quasistatic) {
        ++ex->quasistatic_windows;
        run.emplace_back(t_end, w);
      }
    }
    if (!quasistatic && !run.empty()) {
      emit_sample(run, o, ex);
      run.clear();
    }
  }
  if (!run.empty()) emit_sample(run, o, ex);
}

}  // namespace

std::string QuasistaticOptions::validate() const {
  if (!(window > 0.0 && std::isfinite(window))) return "window: must be positive";
  if (!(max_force_std > 0.0)) return "max_force_std: must be positive";
  if (!(max_force_drift > 0.0)) return "max_force_drift: must be positive";
  if (!(max_angle_std > 0.0)) return "max_angle_std: must be positive";
  if (!(max_angle_drift > 0.0)) return "max_angle_drift: must be positive";
  if (!(max_pair_dt >= 0.0)) return "max_pair_dt: must not be negative";
  if (min_points < 2) return "min_points: must be at least 2";
  if (!(end_guard >= 0.0)) return "end_guard: must not be negative";
  return "";
}

Extraction extract_quasistatic(const std::vector<JetRecord>& jets_in, const std::vector<PoseRecord>& tip_in,
                               const std::vector<PoseRecord>& base_in, const actuation::Nozzle& nozzle,
                               const QuasistaticOptions& o) {
  const std::string oe = o.validate();
  if (!oe.empty()) throw DataError("quasistatic options: " + oe);
  std::vector<JetRecord> jets = jets_in;
  std::vector<PoseRecord> tip = tip_in, base = base_in;
  sort_by_time(&jets);
  sort_by_time(&tip);
  sort_by_time(&base);

  Extraction ex;
  const std::vector<Point> pts = pair_records(jets, tip, base, nozzle, o, &ex);
  ex.paired_points = static_cast<int>(pts.size());
  if (pts.empty())
    throw DataError("no tracker pose could be paired with a base pose and a jet state within " +
                    std::to_string(o.max_pair_dt) + " s (" + std::to_string(tip.size()) + " tip, " +
                    std::to_string(base.size()) + " base, " + std::to_string(jets.size()) + " jet records)");
  scan_windows(pts, o, &ex);
  return ex;
}

}  // namespace calibration
}  // namespace hydrojet
