// A minimal JSON object writer for the command-line tools (one object per line). Non-finite
// numbers are written as null, never as the invalid tokens nan/inf.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

namespace hydrojet {
namespace util {

class JsonObject {
 public:
  JsonObject& add(const std::string& key, double v) { return raw(key, num(v)); }
  JsonObject& add(const std::string& key, int v) { return raw(key, std::to_string(v)); }
  JsonObject& add(const std::string& key, bool v) { return raw(key, v ? "true" : "false"); }
  JsonObject& add(const std::string& key, const char* v) { return raw(key, quote(v)); }
  JsonObject& add(const std::string& key, const std::string& v) { return raw(key, quote(v)); }
  template <class Derived>
  JsonObject& add(const std::string& key, const Eigen::MatrixBase<Derived>& m) {
    return raw(key, matrix(m));
  }
  JsonObject& add_null(const std::string& key) { return raw(key, "null"); }
  /// Adds an already-serialised JSON value.
  JsonObject& raw(const std::string& key, const std::string& json) {
    body_ += (body_.empty() ? "" : ", ") + quote(key) + ": " + json;
    return *this;
  }
  std::string str() const { return "{" + body_ + "}"; }

  static std::string num(double v) {
    if (!std::isfinite(v)) return "null";
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.17g", v);
    return buf;
  }
  static std::string quote(const std::string& s) {
    std::string o = "\"";
    for (char c : s) {
      if (c == '"' || c == '\\') {
        o += '\\';
        o += c;
      } else if (static_cast<unsigned char>(c) < 0x20) {
        char buf[8];
        std::snprintf(buf, sizeof(buf), "\\u%04x", c);
        o += buf;
      } else {
        o += c;
      }
    }
    return o + "\"";
  }
  /// A vector (one row or column) as a flat list; a matrix as a list of rows.
  template <class Derived>
  static std::string matrix(const Eigen::MatrixBase<Derived>& m) {
    std::string o = "[";
    const bool flat = m.rows() == 1 || m.cols() == 1;
    if (flat) {
      for (Eigen::Index i = 0; i < m.size(); ++i) o += (i ? ", " : "") + num(m(i));
    } else {
      for (Eigen::Index r = 0; r < m.rows(); ++r) {
        o += r ? ", [" : "[";
        for (Eigen::Index c = 0; c < m.cols(); ++c) o += (c ? ", " : "") + num(m(r, c));
        o += "]";
      }
    }
    return o + "]";
  }

 private:
  std::string body_;
};

}  // namespace util
}  // namespace hydrojet
