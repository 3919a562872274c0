// The one reader behind every configuration of the stack: scene files, plant files, controller,
// rig, plant-node and recorder options (YAML files or private ROS parameters turned into YAML).
// Typed, validated access by paths as the user writes them ("pd/kp", "rod.length"); every
// error names the full key ("~pd/kp: must be a number, got 'fast'"); keys read are remembered,
// so that reject_unknown() names a key nobody asked for (a typo does not pass silently). An empty
// (null) value counts as absent. ROS-free, header-only (yaml-cpp only).
#pragma once

#include <yaml-cpp/yaml.h>

#include <climits>
#include <initializer_list>
#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace config {

/// A configuration key is missing or invalid. key() is its full path ("rod.length",
/// "~pd/kp"; empty for errors about the input as a whole), detail() what is wrong with it.
///
/// The error family and who throws (every layer of the stack follows this rule):
///   - Configuration parsing (scene and plant files, controller, rig, node and recorder options)
///     throws a KeyError subclass naming the key: SceneError (config/scene.h), ParamError
///     (config/controller_config.h), RigOptionsError (devices/rig_config.h).
///   - Core numerics (rod, actuation, control, plant, sim, calibration fit) never throw on bad
///     numbers: they return a status (RodSolution::converged/message, a bool plus error() or
///     last_error(), CalibrationResult::converged/warnings). Descriptions and options check
///     themselves with validate() (an empty string or "<field>: <what>"); a constructor or entry
///     point handed one that fails validate() throws std::invalid_argument with that message
///     before any numerics run (a programming or configuration error, not a numerical outcome).
///     Measured data that cannot be used throw calibration::DataError.
///   - Nodes catch at start-up, log "<node>: refusing to start: <error>" and exit non-zero; once
///     running they report failures as status (diagnostics, ControllerStatus), never by throwing.
///   - Tools print "<tool>: <error>" on stderr and exit non-zero (2 for bad input).
class KeyError : public std::runtime_error {
 public:
  KeyError(const std::string& key, const std::string& detail)
      : std::runtime_error(key.empty() ? detail : key + ": " + detail), key_(key), detail_(detail) {}
  const std::string& key() const { return key_; }
  const std::string& detail() const { return detail_; }

 private:
  std::string key_;
  std::string detail_;
};

/// Typed access to a YAML tree. `Error` is thrown as Error(key, detail) (a KeyError subclass, so
/// each consumer keeps its own error type).
template <class Error>
class YamlTree {
 public:
  /// `separator` splits paths ('/' for ROS-style options, '.' for scene and plant files);
  /// `prefix` goes in front of every key named in an error ("~" for private ROS parameters,
  /// "plant.valves[1]." for an item of a list).
  explicit YamlTree(const YAML::Node& root, char separator = '/', std::string prefix = "")
      : root_(root), sep_(separator), prefix_(std::move(prefix)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& detail) const {
    throw Error(prefix_ + path, detail);
  }
  std::string key(const std::string& path) const { return prefix_ + path; }

  /// The node at `path`, or an undefined node when the key (or a parent) is absent or null.
  YAML::Node find(const std::string& path) const {
    YAML::Node n = YAML::Clone(root_);
    size_t start = 0;
    for (;;) {
      const size_t end = path.find(sep_, start);
      const std::string part = path.substr(start, end == std::string::npos ? std::string::npos : end - start);
      if (!n.IsMap() || !n[part] || n[part].IsNull()) return YAML::Node(YAML::NodeType::Undefined);
      n = n[part];
      if (end == std::string::npos) return n;
      start = end + 1;
    }
  }
  bool has(const std::string& path) const { return find(path).IsDefined(); }

  /// A required mapping (a section): "missing" or "must be a mapping" otherwise.
  YAML::Node section(const std::string& path) {
    read_.insert(path);
    const YAML::Node n = find(path);
    if (!n.IsDefined()) fail(path, "missing");
    if (!n.IsMap()) fail(path, "must be a mapping");
    return n;
  }

  /// A finite number; required (no fallback) or optional.
  double number(const std::string& path) {
    read_.insert(path);
    const YAML::Node n = find(path);
    if (!n.IsDefined()) fail(path, "missing");
    return to_number(n, path);
  }
  double number(const std::string& path, double fallback) { return absent(path) ? fallback : number(path); }
  double positive(const std::string& path) { return check_positive(path, number(path)); }
  double positive(const std::string& path, double fallback) { return absent(path) ? fallback : positive(path); }
  double nonnegative(const std::string& path) { return check_nonnegative(path, number(path)); }
  double nonnegative(const std::string& path, double fallback) { return absent(path) ? fallback : nonnegative(path); }

  /// An integer (written as one: 3, not 3.5) in [lo, hi].
  int integer(const std::string& path, int fallback, int lo = INT_MIN, int hi = INT_MAX) {
    if (absent(path)) return fallback;
    const double v = number(path);
    if (v != std::floor(v) || v < lo || v > hi) {
      std::string range;
      if (lo != INT_MIN || hi != INT_MAX) range = " in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
      fail(path, "must be an integer" + range + ", got " + format(v));
    }
    return static_cast<int>(v);
  }

  bool boolean(const std::string& path, bool fallback) {
    read_.insert(path);
    const YAML::Node n = find(path);
    if (!n.IsDefined()) return fallback;
    try {
      return n.as<bool>();
    } catch (const YAML::Exception&) {
      fail(path, "must be true or false, got '" + scalar_text(n) + "'");
    }
  }

  std::string text(const std::string& path, const std::string& fallback) {
    read_.insert(path);
    const YAML::Node n = find(path);
    if (!n.IsDefined()) return fallback;
    if (!n.IsScalar()) fail(path, "must be a string");
    return n.Scalar();
  }

  /// A required list of exactly `count` finite numbers.
  std::vector<double> numbers(const std::string& path, size_t count) {
    read_.insert(path);
    const YAML::Node n = find(path);
    if (!n.IsDefined()) fail(path, "missing");
    if (!n.IsSequence() || n.size() != count) fail(path, "must be a list of " + std::to_string(count) + " numbers");
    std::vector<double> out;
    for (size_t i = 0; i < count; ++i) out.push_back(to_number(n[i], path + "[" + std::to_string(i) + "]"));
    return out;
  }
  /// A required list of min_count to max_count finite numbers.
  std::vector<double> number_list(const std::string& path, size_t min_count, size_t max_count) {
    read_.insert(path);
    const YAML::Node n = find(path);
    if (!n.IsDefined()) fail(path, "missing");
    if (!n.IsSequence() || n.size() < min_count || n.size() > max_count)
      fail(path, "must be a list of " + std::to_string(min_count) + " to " + std::to_string(max_count) + " numbers");
    std::vector<double> out;
    for (size_t i = 0; i < n.size(); ++i) out.push_back(to_number(n[i], path + "[" + std::to_string(i) + "]"));
    return out;
  }
  /// A required or optional 3-vector (any type constructible from three doubles, e.g. Eigen's).
  template <class V>
  V vec3(const std::string& path) {
    const std::vector<double> v = numbers(path, 3);
    return V(v[0], v[1], v[2]);
  }
  template <class V>
  V vec3(const std::string& path, const V& fallback) {
    return absent(path) ? fallback : vec3<V>(path);
  }

  /// Up front, for a section ("" = the root) with a fixed set of keys: "<section><sep><key>: unknown key" for any
  /// other key (so a misspelt required key is named as the typo, not as "missing"), and "must be a
  /// mapping" when it is not one. Nothing happens when the section is absent.
  void keys(const std::string& section, std::initializer_list<const char*> allowed) {
    keys(section, std::vector<std::string>(allowed.begin(), allowed.end()));
  }
  void keys(const std::string& section, const std::vector<std::string>& allowed) {
    const YAML::Node n = section.empty() ? root_ : find(section);
    if (!n.IsDefined() || n.IsNull()) return;
    if (!n.IsMap()) fail(section, "must be a mapping");
    std::set<std::string> ok(allowed.begin(), allowed.end());
    for (const auto& kv : n) {
      const std::string k = key_text(kv.first, section);
      if (!ok.count(k)) fail(section.empty() ? k : section + sep_ + k, "unknown key");
    }
  }

  /// Marks a key as known without reading it (read elsewhere, e.g. a list parsed item by item).
  void allow(const std::string& path) { read_.insert(path); }

  /// Throws "<key>: unknown key" for the first key below `under` (the whole tree when empty) that
  /// was never read. A mapping read as one value (section(), allow()) is not descended into
  /// unless keys below it were read too.
  void reject_unknown(const std::string& under = "") const {
    const YAML::Node n = under.empty() ? root_ : find(under);
    if (n.IsDefined()) visit(n, under);
  }

  static std::string format(double v) { return util::num(v); }

 private:
  /// Marks the key as read; true when it is absent (an optional key falls back to its default).
  bool absent(const std::string& path) {
    read_.insert(path);
    return !has(path);
  }
  static std::string scalar_text(const YAML::Node& n) { return n.IsScalar() ? n.Scalar() : "(not a scalar)"; }

  double to_number(const YAML::Node& n, const std::string& path) const {
    if (!n.IsScalar()) fail(path, "must be a number");
    double v;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      fail(path, "must be a number, got '" + n.Scalar() + "'");
    }
    if (!std::isfinite(v)) fail(path, "must be finite, got " + n.Scalar());
    return v;
  }
  double check_positive(const std::string& path, double v) const {
    if (!(v > 0.0)) fail(path, "must be positive, got " + format(v));
    return v;
  }
  double check_nonnegative(const std::string& path, double v) const {
    if (v < 0.0) fail(path, "must not be negative, got " + format(v));
    return v;
  }
  bool read_below(const std::string& path) const {
    const std::string head = path + sep_;
    for (const std::string& k : read_)
      if (k.compare(0, head.size(), head) == 0) return true;
    return false;
  }
  /// The text of a mapping key of the section at `path`. Keys are plain names: a mapping, list or
  /// null as a key ("? [a, b]: 1", "~: 1") fails naming the section (found by fuzzing: yaml-cpp
  /// throws its own BadConversion on these, which no caller expects).
  std::string key_text(const YAML::Node& key, const std::string& path) const {
    if (!key.IsScalar())
      fail(path.empty() ? std::string("(top level)") : path,
           std::string("a key must be a plain name, not a ") + (key.IsMap()        ? "mapping"
                                                                : key.IsSequence() ? "list"
                                                                                   : "null"));
    return key.Scalar();
  }
  void visit(const YAML::Node& n, const std::string& path) const {
    const bool read = !path.empty() && read_.count(path);
    if (!n.IsMap() || (read && !read_below(path))) {
      if (!path.empty() && !read) fail(path, "unknown key");
      return;
    }
    for (const auto& kv : n) {
      const std::string k = key_text(kv.first, path);
      visit(kv.second, path.empty() ? k : path + sep_ + k);
    }
  }

  YAML::Node root_;
  char sep_;
  std::string prefix_;
  std::set<std::string> read_;
};

}  // namespace config
}  // namespace hydrojet
