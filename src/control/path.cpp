#include "hydrojet_control/control/path.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

namespace hydrojet {
namespace control {
namespace {

bool finite(double v) { return std::isfinite(v); }

/// "<field>: <rule>, got <v>" (the validate() convention of the option structs).
std::string bad(const std::string& field, double v, const std::string& rule) {
  std::ostringstream os;
  os << field << ": " << rule << ", got " << v;
  return os.str();
}

/// Eq. (28) as a Path: the same SpiralPath::direction_at, so the directions are bit-identical.
class SpiralPathImpl : public Path {
 public:
  explicit SpiralPathImpl(const SpiralPath& spiral) : spiral_(spiral) {}
  Vec3 direction_at(double t) const override { return spiral_.direction_at(t); }
  double duration() const override { return spiral_.duration; }
  const char* type() const override { return "spiral"; }

 private:
  SpiralPath spiral_;
};

/// Piecewise linear in (ϑ, φ): the raster's rows (ϑ constant) and the meridian steps between them
/// (φ constant) are both straight in these coordinates.
class AnglePolyline : public Path {
 public:
  struct Corner {
    double t, theta, phi;
  };
  explicit AnglePolyline(std::vector<Corner> corners) : corners_(std::move(corners)) {}
  Vec3 direction_at(double t) const override {
    const auto next =
        std::upper_bound(corners_.begin(), corners_.end(), t, [](double x, const Corner& c) { return x < c.t; });
    if (next == corners_.begin()) return direction(corners_.front().theta, corners_.front().phi);
    if (next == corners_.end()) return direction(corners_.back().theta, corners_.back().phi);
    const Corner& a = *(next - 1);
    const double s = (t - a.t) / (next->t - a.t);
    return direction(a.theta + s * (next->theta - a.theta), a.phi + s * (next->phi - a.phi));
  }
  double duration() const override { return corners_.back().t; }
  const char* type() const override { return "raster"; }

 private:
  std::vector<Corner> corners_;  ///< strictly increasing t (segments of zero length are dropped)
};

/// Great-circle arcs between consecutive directions, each at constant angular speed (slerp).
class GreatCirclePath : public Path {
 public:
  GreatCirclePath(const std::vector<Waypoint>& waypoints, const char* type) : points_(waypoints), type_(type) {
    for (size_t i = 0; i + 1 < points_.size(); ++i) {
      const Vec3& a = points_[i].direction;
      const Vec3& b = points_[i + 1].direction;
      const Vec3 normal_part = b - a.dot(b) * a;  // toward b, perpendicular to a
      arcs_.push_back(
          Arc{normal_part.norm() > 0.0 ? Vec3(normal_part.normalized()) : Vec3::Zero(), geodesic_error(a, b)});
    }
  }
  Vec3 direction_at(double t) const override {
    const auto next =
        std::upper_bound(points_.begin(), points_.end(), t, [](double x, const Waypoint& w) { return x < w.t; });
    if (next == points_.begin()) return points_.front().direction;
    if (next == points_.end()) return points_.back().direction;
    const size_t i = static_cast<size_t>(next - points_.begin()) - 1;
    const double angle = arcs_[i].angle * (t - points_[i].t) / (next->t - points_[i].t);
    return std::cos(angle) * points_[i].direction + std::sin(angle) * arcs_[i].toward;
  }
  double duration() const override { return points_.back().t; }
  const char* type() const override { return type_; }

 private:
  struct Arc {
    Vec3 toward;   ///< unit tangent at the start of the arc
    double angle;  ///< [rad]
  };
  std::vector<Waypoint> points_;
  std::vector<Arc> arcs_;
  const char* type_;
};

/// Names a field of waypoint i in error messages ("waypoints[2].t", "path.csv:7: t").
using FieldName = std::function<std::string(size_t i, const char* field)>;

/// The waypoints normalised and checked; std::invalid_argument naming the first bad field.
std::vector<Waypoint> checked_waypoints(std::vector<Waypoint> w, const FieldName& name) {
  if (w.empty()) throw std::invalid_argument(name(0, "") + "no waypoints");
  for (size_t i = 0; i < w.size(); ++i) {
    if (!finite(w[i].t)) throw std::invalid_argument(bad(name(i, "t"), w[i].t, "must be finite"));
    if (i == 0 && w[i].t < 0.0) throw std::invalid_argument(bad(name(i, "t"), w[i].t, "must be >= 0"));
    if (i > 0 && !(w[i].t > w[i - 1].t))
      throw std::invalid_argument(bad(name(i, "t"), w[i].t, "must be greater than the previous time"));
    const double n = w[i].direction.norm();
    if (!w[i].direction.allFinite() || !(n > 0.0))
      throw std::invalid_argument(name(i, "direction") + ": must be finite and non-zero");
    w[i].direction /= n;
    if (i > 0 && w[i].direction.dot(w[i - 1].direction) < -1.0 + 1e-12)
      throw std::invalid_argument(name(i, "direction") +
                                  ": opposite to the previous direction (the great circle between them is undefined)");
  }
  return w;
}

/// One row of a path file: t, ϑ, φ and where it came from.
struct TableRow {
  double t, theta, phi;
  std::string where;  ///< "file:line" (CSV) or "file:line: entry i" (YAML)
};

std::unique_ptr<Path> path_from_rows(const std::vector<TableRow>& rows, const std::string& file) {
  if (rows.empty()) throw std::invalid_argument(file + ": no rows of t, theta, phi");
  std::vector<Waypoint> w(rows.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    const TableRow& r = rows[i];
    if (!finite(r.theta) || !finite(r.phi))
      throw std::invalid_argument(r.where + ": theta and phi must be finite numbers");
    w[i].t = r.t;
    w[i].direction = direction(r.theta, r.phi);
  }
  const FieldName name = [&rows](size_t i, const char* field) {
    return rows[i].where + ": " + (std::string(field) == "direction" ? std::string("theta, phi") : field);
  };
  return std::make_unique<GreatCirclePath>(checked_waypoints(w, name), "file");
}

/// A number, or nothing when the token is not one (the whole token must be used).
bool parse_number(const std::string& token, double* v) {
  std::istringstream is(token);
  is >> *v;
  return !is.fail() && (is >> std::ws).eof();
}

/// A CSV line split at commas and white space.
std::vector<std::string> split_fields(const std::string& line) {
  std::string s = line;
  std::replace(s.begin(), s.end(), ',', ' ');
  std::istringstream is(s);
  std::vector<std::string> fields;
  for (std::string f; is >> f;) fields.push_back(f);
  return fields;
}

/// Rows of t, ϑ, φ; '#' starts a comment; the first content line may be a header.
std::vector<TableRow> read_csv(std::istream& in, const std::string& file) {
  std::vector<TableRow> rows;
  bool first = true;
  int line_no = 0;
  for (std::string line; std::getline(in, line);) {
    ++line_no;
    line = line.substr(0, line.find('#'));
    const std::vector<std::string> fields = split_fields(line);
    if (fields.empty()) continue;
    const std::string where = file + ":" + std::to_string(line_no);
    double v[3];
    bool numbers = fields.size() == 3;
    for (size_t k = 0; k < fields.size() && k < 3; ++k) numbers = parse_number(fields[k], &v[k]) && numbers;
    const bool header = first && !parse_number(fields[0], &v[0]);
    first = false;
    if (header) continue;
    if (!numbers) throw std::invalid_argument(where + ": expected three numbers t, theta, phi, got '" + line + "'");
    rows.push_back({v[0], v[1], v[2], where});
  }
  return rows;
}

/// A number of a YAML entry, or std::invalid_argument naming it.
double yaml_number(const YAML::Node& n, const std::string& where, const char* field) {
  try {
    if (n && n.IsScalar()) return n.as<double>();
  } catch (const YAML::Exception&) {
  }
  throw std::invalid_argument(where + ": " + field + ": expected a number");
}

TableRow yaml_row(const YAML::Node& e, const std::string& where) {
  static const char* const kFields[3] = {"t", "theta", "phi"};
  double v[3];
  if (e.IsSequence() && e.size() == 3) {
    for (int k = 0; k < 3; ++k) v[k] = yaml_number(e[k], where, kFields[k]);
  } else if (e.IsMap()) {
    for (const auto& kv : e) {
      if (!kv.first.IsScalar()) throw std::invalid_argument(where + ": a key must be a plain name");
      const std::string key = kv.first.Scalar();
      if (key != "t" && key != "theta" && key != "phi")
        throw std::invalid_argument(where + ": unknown key '" + key + "'");
    }
    for (int k = 0; k < 3; ++k) v[k] = yaml_number(e[kFields[k]], where, kFields[k]);
  } else {
    throw std::invalid_argument(where + ": expected [t, theta, phi] or {t: ..., theta: ..., phi: ...}");
  }
  return {v[0], v[1], v[2], where};
}

std::vector<TableRow> read_yaml(const std::string& text, const std::string& file) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw std::invalid_argument(file + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  if (!root.IsSequence()) throw std::invalid_argument(file + ": expected a sequence of [t, theta, phi] entries");
  std::vector<TableRow> rows;
  for (size_t i = 0; i < root.size(); ++i) {
    const YAML::Node e = root[i];
    rows.push_back(yaml_row(e, file + ":" + std::to_string(e.Mark().line + 1) + ": entry " + std::to_string(i)));
  }
  return rows;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

std::unique_ptr<Path> make_spiral(const SpiralPath& spiral) { return std::make_unique<SpiralPathImpl>(spiral); }

std::string RasterOptions::validate() const {
  if (!finite(theta_min) || theta_min < 0.0 || theta_min > M_PI)
    return bad("theta_min", theta_min, "must lie in [0, pi]");
  if (!finite(theta_max) || theta_max < theta_min || theta_max > M_PI)
    return bad("theta_max", theta_max, "must lie in [theta_min, pi]");
  if (rows < 1) return bad("rows", rows, "must be >= 1");
  if (!finite(phi_start)) return bad("phi_start", phi_start, "must be finite");
  if (!finite(phi_end) || phi_end == phi_start)
    return bad("phi_end", phi_end, "must be finite and differ from phi_start");
  if (!finite(speed) || !(speed > 0.0)) return bad("speed", speed, "must be finite and > 0");
  return "";
}

std::unique_ptr<Path> make_raster(const RasterOptions& r) {
  if (std::string err = r.validate(); !err.empty()) throw std::invalid_argument(err);
  std::vector<AnglePolyline::Corner> corners;
  double t = 0.0;
  // Appends the corner reached from the last one at r.speed of arc. A step of zero arc (a row at
  // ϑ = 0) only renames the last corner's φ, so that the next meridian step keeps φ constant.
  const auto go_to = [&corners, &t, &r](double theta, double phi) {
    if (!corners.empty()) {
      AnglePolyline::Corner& c = corners.back();
      const double arc = c.theta == theta ? std::abs(phi - c.phi) * std::sin(theta) : std::abs(theta - c.theta);
      if (!(arc > 0.0)) {
        c.phi = phi;
        return;
      }
      t += arc / r.speed;
    }
    corners.push_back({t, theta, phi});
  };
  for (int i = 0; i < r.rows; ++i) {
    const double theta = r.rows == 1 ? r.theta_min : r.theta_min + (r.theta_max - r.theta_min) * i / (r.rows - 1);
    const bool forward = i % 2 == 0;
    go_to(theta, forward ? r.phi_start : r.phi_end);  // along the meridian from the last row's end
    go_to(theta, forward ? r.phi_end : r.phi_start);  // along the row
  }
  return std::make_unique<AnglePolyline>(corners);
}

std::unique_ptr<Path> make_waypoints(const std::vector<Waypoint>& waypoints) {
  const FieldName name = [](size_t i, const char* field) {
    return *field ? "waypoints[" + std::to_string(i) + "]." + field : std::string("waypoints: ");
  };
  return std::make_unique<GreatCirclePath>(checked_waypoints(waypoints, name), "waypoints");
}

std::unique_ptr<Path> load_path_file(const std::string& file) {
  const bool csv = ends_with(file, ".csv");
  if (!csv && !ends_with(file, ".yaml") && !ends_with(file, ".yml"))
    throw std::invalid_argument(file + ": unknown path file type (expected .csv, .yaml or .yml)");
  std::ifstream in(file);
  if (!in) throw std::invalid_argument(file + ": cannot be read");
  if (csv) return path_from_rows(read_csv(in, file), file);
  std::stringstream text;
  text << in.rdbuf();
  return path_from_rows(read_yaml(text.str(), file), file);
}

}  // namespace control
}  // namespace hydrojet
