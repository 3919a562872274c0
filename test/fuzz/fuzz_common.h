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

}  // namespace fuzz
}  // namespace hydrojet
