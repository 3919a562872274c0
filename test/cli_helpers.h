// Running a command-line tool as a user does (stdin, stdout, stderr, exit status) and reading
// fields of its one-line JSON output. Shared by the CLI tests (rod_fk, calibrate) and the
// calibration rostest.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace hydrojet {
namespace test {

struct CliRun {
  int status = -1;  ///< exit status (-1: killed by a signal)
  std::string out;  ///< stdout
  std::string err;  ///< stderr
  /// The last non-empty line of stdout (the tools' JSON summary).
  std::string last_line() const {
    const size_t e = out.find_last_not_of('\n');
    if (e == std::string::npos) return "";
    const size_t b = out.rfind('\n', e);
    const size_t from = b == std::string::npos ? 0 : b + 1;
    return out.substr(from, e - from + 1);
  }
};

/// Runs `program args` through the shell with `stdin_text` on stdin.
inline CliRun run_cli(const std::string& program, const std::string& args, const std::string& stdin_text = "") {
  const std::string base = ::testing::TempDir() + "cli_" + std::to_string(getpid());
  const std::string in = base + "_in.txt", err = base + "_err.txt";
  std::ofstream(in) << stdin_text;
  const std::string cmd = program + " " + args + " < " + in + " 2> " + err;
  CliRun r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  const int st = pclose(p);
  std::ifstream e(err);
  r.err.assign(std::istreambuf_iterator<char>(e), std::istreambuf_iterator<char>());
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  std::remove(in.c_str());
  std::remove(err.c_str());
  return r;
}

/// The text of `"key": {...}` (a flat object) in a JSON line, or "".
inline std::string object_field(const std::string& json, const std::string& key) {
  const size_t i = json.find("\"" + key + "\": {");
  if (i == std::string::npos) return "";
  const size_t a = json.find('{', i), b = json.find('}', a);
  return json.substr(a, b - a + 1);
}

/// A number field `"key": x`; NaN when absent or null.
inline double number_field(const std::string& json, const std::string& key) {
  const size_t i = json.find("\"" + key + "\": ");
  if (i == std::string::npos) return std::nan("");
  const std::string rest = json.substr(i + key.size() + 4);
  if (rest.compare(0, 4, "null") == 0) return std::nan("");
  return std::stod(rest);
}

/// The numbers of a flat JSON array field `"key": [a, b, c]` (empty when absent).
inline std::vector<double> array_field(const std::string& json, const std::string& key) {
  std::vector<double> v;
  size_t i = json.find("\"" + key + "\": [");
  if (i == std::string::npos) return v;
  i = json.find('[', i) + 1;
  const size_t end = json.find(']', i);
  const std::string body = json.substr(i, end - i);
  size_t pos = 0;
  while (pos < body.size()) {
    size_t used = 0;
    v.push_back(std::stod(body.substr(pos), &used));
    pos += used;
    while (pos < body.size() && (body[pos] == ',' || body[pos] == ' ')) ++pos;
  }
  return v;
}

}  // namespace test
}  // namespace hydrojet
