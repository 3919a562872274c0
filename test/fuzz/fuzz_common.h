// Shared by the libFuzzer harnesses of test/fuzz/ (built by scripts/fuzz with clang-14,
// -fsanitize=fuzzer,address,undefined; see docs/robustness.md).
//
// Each harness feeds outside bytes or text to one parser and checks, besides "no crash and no
// sanitizer report", the parser's own contract: it fails only with its declared error type (any
// other exception escapes and libFuzzer reports it as a crash), and what it accepts satisfies the
// documented invariants (finite numbers, ranges, round trips). FUZZ_CHECK aborts with the message,
// which libFuzzer reports as a crash and saves the input.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <yaml-cpp/yaml.h>

#define FUZZ_CHECK(cond, msg)                                                                      \
  do {                                                                                             \
    if (!(cond)) {                                                                                 \
      std::fprintf(stderr, "%s:%d: contract violated: %s (%s)\n", __FILE__, __LINE__, msg, #cond); \
      std::abort();                                                                                \
    }                                                                                              \
  } while (0)

namespace hydrojet {
namespace fuzz {

inline std::string as_text(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

/// The input as a YAML document, for the harnesses of parameter trees: false for an input over
/// 8 KiB or one that is not YAML (a syntax error is the loader's, not the parser's under test).
inline bool as_yaml(const uint8_t* data, size_t size, YAML::Node* root) {
  if (size > 8192) return false;
  try {
    *root = YAML::Load(as_text(data, size));
  } catch (const YAML::Exception&) {
    return false;
  }
  return true;
}

}  // namespace fuzz
}  // namespace hydrojet
