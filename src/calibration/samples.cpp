#include "hydrojet_control/calibration/samples.h"
#include "hydrojet_control/util/files.h"

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

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof(b), "%.6g", v);
  return b;
}

/// Checks one sample's values; returns "" or the problem.
std::string sample_problem(const Eigen::Vector3d& q, const Eigen::Vector4d& wxyz) {
  static const char* qn[3] = {"q1", "q2", "q3"};
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(q[i])) return std::string(qn[i]) + " is not finite (" + num(q[i]) + ")";
    if (q[i] < 0.0) return std::string(qn[i]) + " is negative (" + num(q[i]) + " N): a jet cannot pull";
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

}  // namespace

std::vector<Sample> parse_csv(const std::string& text, const std::string& name) {
  static const char* cols[7] = {"q1", "q2", "q3", "qw", "qx", "qy", "qz"};
  std::stringstream in(text);
  std::string line;
  int lineno = 0;
  int idx[7];
  std::fill(idx, idx + 7, -1);
  size_t nfields = 0;
  bool have_header = false;
  std::vector<Sample> out;
  while (std::getline(in, line)) {
    ++lineno;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const std::vector<std::string> f = split(t);
    const std::string where = name + ":" + std::to_string(lineno);
    if (!have_header) {
      nfields = f.size();
      for (size_t i = 0; i < f.size(); ++i) {
        const std::string h = lower(f[i]);
        for (int c = 0; c < 7; ++c)
          if (h == cols[c]) {
            if (idx[c] >= 0) throw DataError(where + ": header names column '" + cols[c] + "' twice");
            idx[c] = static_cast<int>(i);
          }
      }
      for (int c = 0; c < 7; ++c)
        if (idx[c] < 0)
          throw DataError(where + ": header has no column '" + cols[c] + "' (needs q1,q2,q3,qw,qx,qy,qz)");
      have_header = true;
      continue;
    }
    if (f.size() != nfields)
      throw DataError(where + ": " + std::to_string(f.size()) + " fields, the header has " + std::to_string(nfields));
    double v[7];
    for (int c = 0; c < 7; ++c) {
      const std::string& s = f[idx[c]];
      if (!parse_number(s, &v[c])) throw DataError(where + ": column " + cols[c] + ": '" + s + "' is not a number");
    }
    const Eigen::Vector3d q(v[0], v[1], v[2]);
    const Eigen::Vector4d wxyz(v[3], v[4], v[5], v[6]);
    const std::string p = sample_problem(q, wxyz);
    if (!p.empty()) throw DataError(where + ": " + p);
    Sample s;
    s.jet_force = q;
    s.tip_orientation = Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]).normalized();
    s.origin = where;
    out.push_back(s);
  }
  if (!have_header) throw DataError(name + ": empty (no header line q1,q2,q3,qw,qx,qy,qz)");
  return out;
}

std::vector<Sample> read_csv(const std::string& path) {
  std::string text;
  if (const std::string err = util::read_regular_file(path, &text, 64u << 20); !err.empty())
    throw DataError("cannot read data file '" + path + "': " + err);
  return parse_csv(text, path);
}

void validate_samples(const std::vector<Sample>& samples, int fitted_params) {
  if (fitted_params < 1) throw DataError("no parameter to fit");
  if (samples.size() < static_cast<size_t>(fitted_params))
    throw DataError("too few samples: " + std::to_string(samples.size()) + " for " + std::to_string(fitted_params) +
                    " fitted parameters (need at least one sample per parameter; §6.2 used 40)");
  bool any_force = false;
  for (size_t i = 0; i < samples.size(); ++i) {
    const Sample& s = samples[i];
    const Eigen::Vector4d wxyz(s.tip_orientation.w(), s.tip_orientation.x(), s.tip_orientation.y(),
                               s.tip_orientation.z());
    const std::string p = sample_problem(s.jet_force, wxyz);
    if (!p.empty()) throw DataError((s.origin.empty() ? "sample " + std::to_string(i + 1) : s.origin) + ": " + p);
    if (s.jet_force.maxCoeff() > 0.0) any_force = true;
  }
  if (!any_force)
    throw DataError("all jet forces are zero: the data do not excite the rod (need varied jet-force combinations)");
}

std::string to_csv(const std::vector<Sample>& samples) {
  std::string o = "q1,q2,q3,qw,qx,qy,qz\n";
  char b[64];
  for (const Sample& s : samples) {
    const double v[7] = {s.jet_force[0],        s.jet_force[1],        s.jet_force[2],       s.tip_orientation.w(),
                         s.tip_orientation.x(), s.tip_orientation.y(), s.tip_orientation.z()};
    for (int i = 0; i < 7; ++i) {
      std::snprintf(b, sizeof(b), "%s%.17g", i ? "," : "", v[i]);
      o += b;
    }
    o += "\n";
  }
  return o;
}

}  // namespace calibration
}  // namespace hydrojet
