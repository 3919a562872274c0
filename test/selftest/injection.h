// The self-test's switch (scripts/ci_selftest): HYDROJET_SELFTEST_INJECT names the one kind of
// failure a probe is to produce; unset (as in every normal build and run) the probes pass.
#pragma once

#include <cstdlib>
#include <cstring>

namespace hydrojet {
namespace selftest {

inline bool injected(const char* kind) {
  const char* v = std::getenv("HYDROJET_SELFTEST_INJECT");
  return v != nullptr && std::strcmp(v, kind) == 0;
}

/// Memory that nothing points to any more: LeakSanitizer's report at exit.
inline void leak(std::size_t bytes) {
  static void* volatile sink;
  sink = std::malloc(bytes);
  std::memset(sink, 1, bytes);
  sink = nullptr;
}

}  // namespace selftest
}  // namespace hydrojet
