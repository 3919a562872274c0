#include "hydrojet_control/config/wrench_batch.h"

#include <cmath>
#include <cstdlib>
#include <sstream>

namespace hydrojet {
namespace config {

double parse_finite_number(const std::string& text, const std::string& key) {
  // strtod stops at an embedded NUL: compare against the string's own length, not strlen.
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size()) throw BatchError(key, "not a number '" + text + "'");
  if (!std::isfinite(v)) throw BatchError(key, "not a finite number '" + text + "'");
  return v;
}

std::vector<rod::TipWrench> parse_wrench_batch(std::istream& in) {
  std::vector<rod::TipWrench> out;
  std::string line;
  for (int lineno = 1; std::getline(in, line); ++lineno) {
    for (char& c : line)
      if (c == ',' || c == '\t' || c == '\r') c = ' ';
    std::istringstream ss(line);
    std::vector<std::string> tok;
    std::string t;
    while (ss >> t) tok.push_back(t);
    if (tok.empty() || tok[0][0] == '#') continue;
    const std::string where = "--batch line " + std::to_string(lineno);
    if (tok.size() != 6)
      throw BatchError(where, "expected 6 numbers fx fy fz mx my mz, got " + std::to_string(tok.size()));
    rod::TipWrench w;
    for (int k = 0; k < 3; ++k) w.force[k] = parse_finite_number(tok[k], where);
    for (int k = 0; k < 3; ++k) w.moment[k] = parse_finite_number(tok[3 + k], where);
    out.push_back(w);
  }
  return out;
}

}  // namespace config
}  // namespace hydrojet
