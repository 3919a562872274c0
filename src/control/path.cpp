#include "hydrojet_control/control/path.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <yaml-cpp/yaml.h>

#include "hydrojet_control/util/files.h"
#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {
namespace {

bool finite(double v) { return std::isfinite(v); }

using util::num;

/// "<field>: <rule>, got <v>" (the validate() convention of the option structs), v as a double.
std::string bad(const std::string& field, double v, const std::string& rule) { return util::bad(field, v, rule); }

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

/// The waypoints normalised and checked against `limits`; std::invalid_argument naming the first bad
/// field.
std::vector<Waypoint> checked_waypoints(std::vector<Waypoint> w, const FieldName& name, const PathLimits& limits) {
  if (w.empty()) throw std::invalid_argument(name(0, "") + "no waypoints");
  if (w.size() > limits.max_points)
    throw std::invalid_argument(name(0, "") + std::to_string(w.size()) + " points, more than the limit of " +
                                std::to_string(limits.max_points));
  for (size_t i = 0; i < w.size(); ++i) {
    if (!finite(w[i].t)) throw std::invalid_argument(bad(name(i, "t"), w[i].t, "must be finite"));
    if (i == 0 && w[i].t < 0.0) throw std::invalid_argument(bad(name(i, "t"), w[i].t, "must be >= 0"));
    if (i > 0 && !(w[i].t > w[i - 1].t))
      throw std::invalid_argument(bad(name(i, "t"), w[i].t, "must be greater than the previous time"));
    if (w[i].t > limits.max_duration)
      throw std::invalid_argument(bad(name(i, "t"), w[i].t, "must be at most " + num(limits.max_duration) + " s"));
    if (!unit_direction(w[i].direction, &w[i].direction))
      throw std::invalid_argument(name(i, "direction") + ": must be finite and non-zero");
    if (i == 0) continue;
    if (w[i].direction.dot(w[i - 1].direction) < -1.0 + 1e-12)
      throw std::invalid_argument(name(i, "direction") +
                                  ": opposite to the previous direction (the great circle between them is undefined)");
    const double speed = geodesic_error(w[i - 1].direction, w[i].direction) / (w[i].t - w[i - 1].t);
    if (speed > limits.max_speed)
      throw std::invalid_argument(bad(name(i, "t"), w[i].t,
                                      "reached at " + num(speed) + " rad/s from the previous point, faster than " +
                                          num(limits.max_speed) + " rad/s"));
  }
  return w;
}

/// One row of a path file: t, ϑ, φ and where it came from.
struct TableRow {
  double t, theta, phi;
  std::string where;  ///< "file:line" (CSV) or "file:line: entry i" (YAML)
};

std::unique_ptr<Path> path_from_rows(const std::vector<TableRow>& rows, const std::string& file,
                                     const PathLimits& limits) {
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
  return std::make_unique<GreatCirclePath>(checked_waypoints(w, name, limits), "file");
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
std::vector<TableRow> read_csv(std::istream& in, const std::string& file, const PathLimits& limits) {
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
    if (rows.size() == limits.max_points)
      throw std::invalid_argument(where + ": more than the limit of " + std::to_string(limits.max_points) + " rows");
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

std::vector<TableRow> read_yaml(const std::string& text, const std::string& file, const PathLimits& limits) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw std::invalid_argument(file + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  if (!root.IsSequence()) throw std::invalid_argument(file + ": expected a sequence of [t, theta, phi] entries");
  if (root.size() > limits.max_points)
    throw std::invalid_argument(file + ": " + std::to_string(root.size()) + " entries, more than the limit of " +
                                std::to_string(limits.max_points));
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

/// "<field>: must be finite" for the first non-finite value of a goal, whether its type uses it or not.
void require_finite(const std::vector<std::pair<const char*, double>>& fields) {
  for (const auto& [name, v] : fields)
    if (!finite(v)) throw std::invalid_argument(bad(name, v, "must be finite"));
}

}  // namespace

std::unique_ptr<Path> make_spiral(const SpiralPath& spiral) { return std::make_unique<SpiralPathImpl>(spiral); }

std::string validate_spiral(const SpiralPath& s, const PathLimits& limits) {
  for (const auto& [name, v] :
       {std::pair<const char*, double>{"theta_start", s.theta_start}, {"theta_end", s.theta_end}})
    if (!finite(v) || v < 0.0 || v > M_PI) return bad(name, v, "must lie in [0, pi]");
  if (!finite(s.phi_start)) return bad("phi_start", s.phi_start, "must be finite");
  if (!finite(s.phi_end)) return bad("phi_end", s.phi_end, "must be finite");
  if (!finite(s.duration) || !(s.duration > 0.0) || s.duration > limits.max_duration)
    return bad("duration", s.duration, "must lie in (0, " + num(limits.max_duration) + "] s");
  // Eq. (28)'s speed is sqrt(ς² + sin²ϑ ε²); its largest sin ϑ over the ϑ range bounds it.
  const double lo = std::min(s.theta_start, s.theta_end), hi = std::max(s.theta_start, s.theta_end);
  const double sin_max = lo <= M_PI_2 && hi >= M_PI_2 ? 1.0 : std::max(std::sin(lo), std::sin(hi));
  const double speed = std::hypot(s.theta_rate(), sin_max * s.phi_rate());
  if (!(speed <= limits.max_speed))
    return bad("duration", s.duration,
               "makes the spiral move at " + num(speed) + " rad/s, faster than " + num(limits.max_speed) + " rad/s");
  return "";
}

std::string RasterOptions::validate(const PathLimits& limits) const {
  if (!finite(theta_min) || theta_min < 0.0 || theta_min > M_PI)
    return bad("theta_min", theta_min, "must lie in [0, pi]");
  if (!finite(theta_max) || theta_max < theta_min || theta_max > M_PI)
    return bad("theta_max", theta_max, "must lie in [theta_min, pi]");
  if (rows < 1 || static_cast<std::size_t>(rows) > limits.max_points)
    return bad("rows", rows, "must lie in [1, " + std::to_string(limits.max_points) + "]");
  if (!finite(phi_start)) return bad("phi_start", phi_start, "must be finite");
  if (!finite(phi_end) || phi_end == phi_start)
    return bad("phi_end", phi_end, "must be finite and differ from phi_start");
  if (!finite(speed) || !(speed > 0.0) || speed > limits.max_speed)
    return bad("speed", speed, "must lie in (0, " + num(limits.max_speed) + "] rad/s");
  // Its length bounds its duration: every row at most |Δφ| of arc, the meridian steps ϑ_max − ϑ_min.
  const double length = rows * std::abs(phi_end - phi_start) + (theta_max - theta_min);
  if (!(length / speed <= limits.max_duration))
    return bad("speed", speed,
               "would make the raster last up to " + num(length / speed) + " s, longer than " +
                   num(limits.max_duration) + " s");
  return "";
}

std::unique_ptr<Path> make_raster(const RasterOptions& r, const PathLimits& limits) {
  if (std::string err = r.validate(limits); !err.empty()) throw std::invalid_argument(err);
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

std::unique_ptr<Path> make_waypoints(const std::vector<Waypoint>& waypoints, const PathLimits& limits) {
  const FieldName name = [](size_t i, const char* field) {
    return *field ? "waypoints[" + std::to_string(i) + "]." + field : std::string("waypoints: ");
  };
  return std::make_unique<GreatCirclePath>(checked_waypoints(waypoints, name, limits), "waypoints");
}

std::unique_ptr<Path> load_path_file(const std::string& file, const PathLimits& limits) {
  const bool csv = ends_with(file, ".csv");
  if (!csv && !ends_with(file, ".yaml") && !ends_with(file, ".yml"))
    throw std::invalid_argument(file + ": unknown path file type (expected .csv, .yaml or .yml)");
  std::string text;
  if (const std::string err = util::read_regular_file(file, &text, limits.max_file_bytes); !err.empty())
    throw std::invalid_argument(file + ": " + err);
  if (csv) {
    std::istringstream in(text);
    return path_from_rows(read_csv(in, file, limits), file, limits);
  }
  return path_from_rows(read_yaml(text, file, limits), file, limits);
}

std::unique_ptr<Path> make_goal_path(const PathGoal& g, const SpiralPath& configured, const PathLimits& limits) {
  const SpiralPath& s = g.spiral;
  const RasterOptions& r = g.raster;
  require_finite({{"theta_start", s.theta_start},
                  {"theta_end", s.theta_end},
                  {"phi_start", s.phi_start},
                  {"phi_end", s.phi_end},
                  {"duration", s.duration},
                  {"theta_min", r.theta_min},
                  {"theta_max", r.theta_max},
                  {"raster_phi_start", r.phi_start},
                  {"raster_phi_end", r.phi_end},
                  {"speed", r.speed}});
  for (size_t i = 0; i < g.times.size(); ++i)
    if (!finite(g.times[i]))
      throw std::invalid_argument(bad("times[" + std::to_string(i) + "]", g.times[i], "must be finite"));
  for (size_t i = 0; i < g.directions.size(); ++i)
    if (!g.directions[i].allFinite())
      throw std::invalid_argument("directions[" + std::to_string(i) + "]: must be finite");
  if (g.times.size() > limits.max_points || g.directions.size() > limits.max_points)
    throw std::invalid_argument("times, directions: more than the limit of " + std::to_string(limits.max_points));
  if (g.type == "spiral") {
    const bool own = s.duration > 0.0;  // else the configured spiral (action/FollowPath.action)
    if (std::string err = validate_spiral(own ? s : configured, limits); !err.empty())
      throw std::invalid_argument(std::string(own ? "" : "the configured spiral: ") + err);
    const SpiralPath& chosen = own ? s : configured;
    return make_spiral(chosen);
  }
  if (g.type == "raster") {
    try {
      return make_raster(r, limits);
    } catch (const std::invalid_argument& e) {
      // The goal's own names for the raster's φ range.
      std::string what = e.what();
      if (what.rfind("phi_", 0) == 0) what = "raster_" + what;
      throw std::invalid_argument(what);
    }
  }
  if (g.type == "waypoints") {
    if (g.times.size() != g.directions.size())
      throw std::invalid_argument("waypoints: need as many times as directions, got " + std::to_string(g.times.size()) +
                                  " and " + std::to_string(g.directions.size()));
    std::vector<Waypoint> w(g.times.size());
    for (size_t i = 0; i < w.size(); ++i) w[i].t = g.times[i], w[i].direction = g.directions[i];
    return make_waypoints(w, limits);
  }
  if (g.type == "file") return load_path_file(g.file, limits);
  throw std::invalid_argument("type: must be spiral, raster, waypoints or file, got '" + g.type + "'");
}

}  // namespace control
}  // namespace hydrojet
