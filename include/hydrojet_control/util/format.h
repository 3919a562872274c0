// Numbers in messages, and the "<field>: <rule>, got <value>" of every options struct's validate().
// One helper, so that a value prints the same in every message (ostream's default: 6 significant digits).
#pragma once

#include <sstream>
#include <string>

namespace hydrojet {
namespace util {

/// `v` as ostream prints it ("0.3", "1e-06", "nan").
template <typename T>
std::string num(T v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

/// "<field>: <rule>, got <v>".
template <typename T>
std::string bad(const std::string& field, T v, const std::string& rule) {
  return field + ": " + rule + ", got " + num(v);
}

/// "" when lo ≤ v ≤ hi, else "<field>: must lie in [lo, hi], got v" (NaN is outside).
inline std::string check_range(const std::string& field, double v, double lo, double hi) {
  if (v >= lo && v <= hi) return "";
  return bad(field, v, "must lie in [" + num(lo) + ", " + num(hi) + "]");
}

/// `error` ("<field>: ...") with "<group>/" before its field; "" stays "".
inline std::string in_group(const std::string& group, const std::string& error) {
  return error.empty() ? error : group + "/" + error;
}

}  // namespace util
}  // namespace hydrojet
