#include "hydrojet_control/calibration/samples.h"
#include "hydrojet_control/util/files.h"
#include "hydrojet_control/util/format.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace hydrojet {
namespace calibration {
namespace {

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  const size_t b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> f;
  std::string cur;
  std::stringstream ss(line);
  while (std::getline(ss, cur, ',')) f.push_back(trim(cur));
  if (!line.empty() && line.back() == ',') f.push_back("");
  return f;
}

/// Strict number parse: the whole field must be a number (nan/inf are parsed, then rejected by
/// the caller with a clearer message).
bool parse_number(const std::string& s, double* v) {
  if (s.empty()) return false;
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size();
}

using util::num;

/// The column name of input i (0-based): "q1".
std::string input_column(int i) { return "q" + std::to_string(i + 1); }

/// Checks one sample's values; returns "" or the problem.
std::string sample_problem(const rod::InputVector& q, const Eigen::Vector4d& wxyz,
                           const std::vector<rod::Actuator>& actuators) {
  if (q.size() != static_cast<Eigen::Index>(actuators.size()))
    return std::to_string(q.size()) + " inputs, the scene has " + std::to_string(actuators.size()) + " actuators";
  for (int i = 0; i < q.size(); ++i) {
    const std::string c = input_column(i) + " (" + actuators[i].name + ")";
    if (!std::isfinite(q[i])) return c + " is not finite (" + num(q[i]) + ")";
    if (q[i] < 0.0 && actuators[i].min_force >= 0.0)
      return c + " is negative (" + num(q[i]) + " N): the actuator cannot pull (min_force " +
             num(actuators[i].min_force) + " N)";
  }
  static const char* wn[4] = {"qw", "qx", "qy", "qz"};
  for (int i = 0; i < 4; ++i)
    if (!std::isfinite(wxyz[i])) return std::string(wn[i]) + " is not finite (" + num(wxyz[i]) + ")";
  const double n = wxyz.norm();
  if (std::abs(n - 1.0) > kUnitQuaternionTolerance)
    return "quaternion (qw,qx,qy,qz) is not unit: norm " + num(n) + " (tolerance " + num(kUnitQuaternionTolerance) +
           ")";
  return "";
}

/// Name of column c of header_columns()' order for N inputs: q1..qN, then qw, qx, qy, qz.
std::string column_name(size_t c, int n) {
  static const char* const quaternion[4] = {"qw", "qx", "qy", "qz"};
  return c < static_cast<size_t>(n) ? input_column(static_cast<int>(c)) : quaternion[c - n];
}

/// "q<k>" with k digits: k (capped at 9999), else −1.
int input_number(const std::string& h) {
  if (h.size() < 2 || h[0] != 'q' ||
      !std::all_of(h.begin() + 1, h.end(), [](unsigned char c) { return std::isdigit(c) != 0; }))
    return -1;
  return h.size() > 5 ? 9999 : std::atoi(h.c_str() + 1);
}

/// Column indices from the header: q1..qN first, then qw, qx, qy, qz.
std::vector<int> header_columns(const std::vector<std::string>& f, int n, const std::string& where) {
  std::vector<std::string> cols;
  for (size_t c = 0; c < static_cast<size_t>(n) + 4; ++c) cols.push_back(column_name(c, n));
  std::vector<int> idx(cols.size(), -1);
  for (size_t i = 0; i < f.size(); ++i) {
    const std::string h = lower(f[i]);
    const int k = input_number(h);
    if (k == 0 || k > n)
      throw DataError(where + ": header has column '" + h + "' but the scene has " + std::to_string(n) +
                      " actuators (q1..q" + std::to_string(n) + ")");
    for (size_t c = 0; c < cols.size(); ++c)
      if (h == cols[c]) {
        if (idx[c] >= 0) throw DataError(where + ": header names column '" + cols[c] + "' twice");
        idx[c] = static_cast<int>(i);
      }
  }
  for (size_t c = 0; c < cols.size(); ++c)
    if (idx[c] < 0)
      throw DataError(where + ": header has no column '" + cols[c] + "' (needs q1..q" + std::to_string(n) +
                      ",qw,qx,qy,qz)");
  return idx;
}

}  // namespace

std::vector<Sample> parse_csv(const std::string& text, const std::vector<rod::Actuator>& actuators,
                              const std::string& name) {
  const int n = static_cast<int>(actuators.size());
  if (n < 1 || n > rod::kMaxInputs)
    throw DataError(name + ": the scene has " + std::to_string(n) + " actuators (1 to " +
                    std::to_string(rod::kMaxInputs) + ")");
  std::stringstream in(text);
  std::string line;
  int lineno = 0;
  std::vector<int> idx;
  size_t nfields = 0;
  std::vector<Sample> out;
  while (std::getline(in, line)) {
    ++lineno;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const std::vector<std::string> f = split(t);
    const std::string where = name + ":" + std::to_string(lineno);
    if (idx.empty()) {
      nfields = f.size();
      idx = header_columns(f, n, where);
      continue;
    }
    if (f.size() != nfields)
      throw DataError(where + ": " + std::to_string(f.size()) + " fields, the header has " + std::to_string(nfields));
    std::vector<double> v(idx.size());
    for (size_t c = 0; c < idx.size(); ++c) {
      const std::string& s = f[idx[c]];
      if (!parse_number(s, &v[c]))
        throw DataError(where + ": column " + column_name(c, n) + ": '" + s + "' is not a number");
    }
    rod::InputVector q(n);
    for (int i = 0; i < n; ++i) q[i] = v[i];
    const Eigen::Vector4d wxyz(v[n], v[n + 1], v[n + 2], v[n + 3]);
    const std::string p = sample_problem(q, wxyz, actuators);
    if (!p.empty()) throw DataError(where + ": " + p);
    Sample s;
    s.inputs = q;
    s.tip_orientation = Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]).normalized();
    s.origin = where;
    out.push_back(s);
  }
  if (idx.empty()) throw DataError(name + ": empty (no header line q1..q" + std::to_string(n) + ",qw,qx,qy,qz)");
  return out;
}

std::vector<Sample> read_csv(const std::string& path, const std::vector<rod::Actuator>& actuators) {
  std::string text;
  if (const std::string err = util::read_regular_file(path, &text, 64u << 20); !err.empty())
    throw DataError("cannot read data file '" + path + "': " + err);
  return parse_csv(text, actuators, path);
}

void validate_samples(const std::vector<Sample>& samples, const std::vector<rod::Actuator>& actuators,
                      int fitted_params) {
  if (fitted_params < 1) throw DataError("no parameter to fit");
  if (samples.size() < static_cast<size_t>(fitted_params))
    throw DataError("too few samples: " + std::to_string(samples.size()) + " for " + std::to_string(fitted_params) +
                    " fitted parameters (need at least one sample per parameter; §6.2 used 40)");
  bool any_input = false;
  for (size_t i = 0; i < samples.size(); ++i) {
    const Sample& s = samples[i];
    const Eigen::Vector4d wxyz(s.tip_orientation.w(), s.tip_orientation.x(), s.tip_orientation.y(),
                               s.tip_orientation.z());
    const std::string p = sample_problem(s.inputs, wxyz, actuators);
    if (!p.empty()) throw DataError((s.origin.empty() ? "sample " + std::to_string(i + 1) : s.origin) + ": " + p);
    if (s.inputs.cwiseAbs().maxCoeff() > 0.0) any_input = true;
  }
  if (!any_input)
    throw DataError("every actuator input is zero: the data do not excite the rod (need varied input combinations)");
}

std::string to_csv(const std::vector<Sample>& samples) {
  const Eigen::Index n = samples.empty() ? 0 : samples.front().inputs.size();
  std::string o;
  for (Eigen::Index i = 0; i < n; ++i) o += input_column(static_cast<int>(i)) + ",";
  o += "qw,qx,qy,qz\n";
  char b[64];
  for (const Sample& s : samples) {
    for (Eigen::Index i = 0; i < s.inputs.size(); ++i) {
      std::snprintf(b, sizeof(b), "%.17g,", s.inputs[i]);
      o += b;
    }
    const double v[4] = {s.tip_orientation.w(), s.tip_orientation.x(), s.tip_orientation.y(), s.tip_orientation.z()};
    for (int i = 0; i < 4; ++i) {
      std::snprintf(b, sizeof(b), "%s%.17g", i ? "," : "", v[i]);
      o += b;
    }
    o += "\n";
  }
  return o;
}

}  // namespace calibration
}  // namespace hydrojet
